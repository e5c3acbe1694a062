// Replay backend: image sequences on disk played as a camera pair.
#include "fuzzystereo/capture/replay.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace fs::capture {

namespace stdfs = std::filesystem;

Clock Clock::steady() {
  Clock c;
  c.now_ns = [] {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
  c.sleep_until_ns = [](std::int64_t t) {
    std::this_thread::sleep_until(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(t)));
  };
  return c;
}

namespace {

bool is_image(const stdfs::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  static const char* kExt[] = {".png", ".jpg", ".jpeg", ".bmp", ".ppm", ".pgm", ".tif", ".tiff"};
  return std::any_of(std::begin(kExt), std::end(kExt), [&](const char* x) { return e == x; });
}

// Natural order: digit runs compare by value ("2" < "10"), the rest byte-wise.
bool natural_less(const std::string& a, const std::string& b) {
  std::size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) && std::isdigit(static_cast<unsigned char>(b[j]))) {
      std::size_t i2 = i, j2 = j;
      while (i2 < a.size() && std::isdigit(static_cast<unsigned char>(a[i2]))) ++i2;
      while (j2 < b.size() && std::isdigit(static_cast<unsigned char>(b[j2]))) ++j2;
      std::string na = a.substr(i, i2 - i), nb = b.substr(j, j2 - j);
      na.erase(0, std::min(na.find_first_not_of('0'), na.size()));
      nb.erase(0, std::min(nb.find_first_not_of('0'), nb.size()));
      if (na.size() != nb.size()) return na.size() < nb.size();
      if (na != nb) return na < nb;
      i = i2;
      j = j2;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return (a.size() - i) < (b.size() - j);
}

std::map<std::string, stdfs::path> images_in(const stdfs::path& dir) {
  std::map<std::string, stdfs::path> out;
  for (const auto& e : stdfs::directory_iterator(dir))
    if (e.is_regular_file() && is_image(e.path())) out[e.path().filename().string()] = e.path();
  return out;
}

// Two sub-folders paired by identical file names; throws naming the first unpaired image.
std::vector<PairPaths> pair_folders(const stdfs::path& ldir, const stdfs::path& rdir) {
  const auto l = images_in(ldir), r = images_in(rdir);
  std::vector<PairPaths> out;
  for (const auto& [name, path] : l) {
    auto it = r.find(name);
    if (it == r.end())
      throw CaptureError("replay: '" + path.string() + "' has no partner '" + (rdir / name).string() + "'");
    out.push_back({path.string(), it->second.string(), -1});
  }
  for (const auto& [name, path] : r)
    if (!l.count(name)) throw CaptureError("replay: '" + path.string() + "' has no partner '" + (ldir / name).string() + "'");
  return out;
}

// DIR/*_left.ext + DIR/*_right.ext paired by prefix.
std::vector<PairPaths> pair_suffixed(const stdfs::path& dir) {
  const auto all = images_in(dir);
  std::vector<PairPaths> out;
  auto split = [](const std::string& name, const std::string& tag, std::string& key) {
    const std::string stem = stdfs::path(name).stem().string();
    if (stem.size() < tag.size() || stem.compare(stem.size() - tag.size(), tag.size(), tag) != 0) return false;
    key = stem.substr(0, stem.size() - tag.size());
    return true;
  };
  std::map<std::string, stdfs::path> lefts, rights;
  for (const auto& [name, path] : all) {
    std::string key;
    if (split(name, "_left", key)) lefts[key] = path;
    else if (split(name, "_right", key)) rights[key] = path;
  }
  for (const auto& [key, path] : lefts) {
    auto it = rights.find(key);
    if (it == rights.end()) throw CaptureError("replay: '" + path.string() + "' has no partner '" + key + "_right.*' in '" + dir.string() + "'");
    out.push_back({path.string(), it->second.string(), -1});
  }
  for (const auto& [key, path] : rights)
    if (!lefts.count(key)) throw CaptureError("replay: '" + path.string() + "' has no partner '" + key + "_left.*' in '" + dir.string() + "'");
  return out;
}

// timestamps.csv: header "frame,timestamp_ns,left,right", then one row per pair (paths relative to DIR).
void read_timestamps(const stdfs::path& csv, std::vector<PairPaths>& pairs) {
  std::ifstream f(csv);
  if (!f) throw CaptureError("replay: cannot read '" + csv.string() + "'");
  std::map<std::string, std::int64_t> by_left;
  std::string line;
  int lineno = 0;
  while (std::getline(f, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || (lineno == 1 && line.rfind("frame", 0) == 0)) continue;
    std::istringstream ss(line);
    std::string frame, ts, left, right;
    if (!std::getline(ss, frame, ',') || !std::getline(ss, ts, ',') || !std::getline(ss, left, ',') ||
        !std::getline(ss, right))
      throw CaptureError("replay: '" + csv.string() + "' line " + std::to_string(lineno) +
                         ": expected frame,timestamp_ns,left,right");
    try {
      std::size_t used = 0;
      const long long t = std::stoll(ts, &used);
      if (used != ts.size() || t < 0) throw std::invalid_argument(ts);
      by_left[stdfs::path(left).filename().string()] = t;
    } catch (const std::exception&) {
      throw CaptureError("replay: '" + csv.string() + "' line " + std::to_string(lineno) + ": timestamp_ns '" + ts +
                         "' is not a non-negative integer");
    }
  }
  for (auto& p : pairs) {
    const std::string name = stdfs::path(p.left).filename().string();
    auto it = by_left.find(name);
    if (it == by_left.end())
      throw CaptureError("replay: '" + csv.string() + "' has no row for left image '" + name + "'");
    p.timestamp_ns = it->second;
  }
}

cv::Mat read_8bit(const std::string& path) {
  cv::Mat m = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (m.empty()) throw CaptureError("replay: cannot read image '" + path + "' (missing or not a decodable image)");
  if (m.depth() != CV_8U)
    throw CaptureError("replay: image '" + path + "' is not 8-bit (depth " + std::to_string(m.elemSize1() * 8) + " bit)");
  if (m.channels() == 4) cv::cvtColor(m, m, cv::COLOR_BGRA2BGR);
  return m;
}

}  // namespace

namespace {

std::vector<PairPaths> discover(const std::string& dir_text) {
  const stdfs::path dir(dir_text);
  std::error_code ec;
  if (!stdfs::is_directory(dir, ec)) throw CaptureError("replay: '" + dir_text + "' is not a directory");
  std::vector<PairPaths> pairs;
  if (stdfs::is_directory(dir / "left") && stdfs::is_directory(dir / "right")) {
    pairs = pair_folders(dir / "left", dir / "right");
    if (stdfs::is_regular_file(dir / "timestamps.csv")) read_timestamps(dir / "timestamps.csv", pairs);
  } else if (stdfs::is_directory(dir / "image_2") && stdfs::is_directory(dir / "image_3")) {
    pairs = pair_folders(dir / "image_2", dir / "image_3");
  } else if (stdfs::is_directory(dir / "image_0") && stdfs::is_directory(dir / "image_1")) {
    pairs = pair_folders(dir / "image_0", dir / "image_1");
  } else {
    pairs = pair_suffixed(dir);
  }
  std::sort(pairs.begin(), pairs.end(), [](const PairPaths& a, const PairPaths& b) {
    return natural_less(stdfs::path(a.left).filename().string(), stdfs::path(b.left).filename().string());
  });
  return pairs;
}

}  // namespace

std::vector<PairPaths> discover_image_sequence(const std::string& dir) {
  try {
    return discover(dir);
  } catch (const stdfs::filesystem_error& e) {  // e.g. a sub-folder without read permission
    throw CaptureError("replay: cannot list '" + e.path1().string() + "': " + e.code().message());
  }
}

ReplayCamera::ReplayCamera(std::string source, std::vector<PairPaths> pairs, ReplayOptions opt, Clock clock)
    : source_(std::move(source)), pairs_(std::move(pairs)), opt_(opt), clock_(std::move(clock)) {
  if (pairs_.empty()) throw CaptureError("replay: '" + source_ + "' has no stereo pairs");
  const bool recorded = std::all_of(pairs_.begin(), pairs_.end(), [](const PairPaths& p) { return p.timestamp_ns >= 0; });
  if (!recorded)
    for (auto& p : pairs_) p.timestamp_ns = -1;  // all or nothing
  if (recorded) {
    // One loop shifts every timestamp by the span of the sequence plus one mean frame interval.
    const std::int64_t first = pairs_.front().timestamp_ns, last = pairs_.back().timestamp_ns;
    const std::int64_t step = pairs_.size() > 1 ? (last - first) / std::int64_t(pairs_.size() - 1)
                              : opt_.rate_hz > 0 ? std::int64_t(1e9 / opt_.rate_hz) : 1;
    loop_span_ns_ = (last - first) + std::max<std::int64_t>(step, 1);
  }
}

void ReplayCamera::start() {
  started_ = true;
  next_ = 0;
  loops_ = 0;
  frame_id_ = 0;
  anchor_count_ = 0;
  anchor_ns_ = clock_.now_ns();
}

bool ReplayCamera::grab(StereoFrame& out) {
  if (!started_) throw CaptureError("replay: grab() before start() on '" + source_ + "'");
  if (next_ == pairs_.size()) {
    if (!opt_.loop) return false;
    next_ = 0;
    ++loops_;
  }
  const PairPaths& p = pairs_[next_];
  cv::Mat left = read_8bit(p.left), right = read_8bit(p.right);
  if (left.size() != right.size())
    throw CaptureError("replay: '" + p.left + "' is " + std::to_string(left.cols) + "x" + std::to_string(left.rows) +
                       " but '" + p.right + "' is " + std::to_string(right.cols) + "x" + std::to_string(right.rows));
  if (left.channels() != right.channels()) {  // grey + colour: both colour
    if (left.channels() == 1) cv::cvtColor(left, left, cv::COLOR_GRAY2BGR);
    if (right.channels() == 1) cv::cvtColor(right, right, cv::COLOR_GRAY2BGR);
  }
  // Pacing: pair k (counted from the anchor) is due at anchor + k * period.
  std::int64_t now = clock_.now_ns();
  if (opt_.rate_hz > 0) {
    const double period = 1e9 / opt_.rate_hz;
    const std::int64_t due = anchor_ns_ + std::int64_t(double(frame_id_ - anchor_count_) * period + 0.5);
    if (now < due) {
      clock_.sleep_until_ns(due);
      now = clock_.now_ns();
    } else if (now - due > std::int64_t(period)) {  // consumer late by more than a period: re-anchor
      anchor_ns_ = now;
      anchor_count_ = frame_id_;
    }
  }
  out.left = std::move(left);
  out.right = std::move(right);
  out.timestamp_ns = p.timestamp_ns >= 0 ? p.timestamp_ns + std::int64_t(loops_) * loop_span_ns_ : now;
  out.frame_id = frame_id_++;
  out.source = source_;
  ++next_;
  return true;
}

void ReplayCamera::stop() { started_ = false; }

}  // namespace fs::capture
