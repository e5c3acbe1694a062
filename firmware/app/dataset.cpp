// Dataset discovery and ground-truth decoding. Layouts (official archive folder names):
//   KITTI 2012  training/{colored_0,colored_1 | image_0,image_1}/NNNNNN_10.png, disp_occ/, calib/NNNNNN.txt
//   KITTI 2015  training/{image_2,image_3}/NNNNNN_10.png, disp_occ_0/, calib_cam_to_cam/NNNNNN.txt
//   Middlebury 2001-3  <scene>/{im3,im4}.png + disp3.pgm (/16, tsukuba); {im2,im6}.png + disp2.pgm
//                      (/8, venus); {im2,im6}.png + disp2.png (/4, teddy, cones)
//   Middlebury 2005-6  {ThirdSize,HalfSize,FullSize}/<scene>/{view1,view5}.png + disp1.png
//                      (stored value = full-size disparity, so /3, /2, /1)
//   Middlebury 2014    MiddEval3/training{Q,H,F}/<scene>/{im0,im1}.png + disp0GT.pfm + calib.txt
//   synthetic          fuzzystereo_sim.json + training/ in the KITTI 2015 layout (`fuzzystereo sim
//                      generate`, docs/simulator.md); search range from the marker's max_disparity
#include "dataset.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "io.hpp"

namespace fs::app {
namespace {

namespace stdfs = std::filesystem;

// Disparity search ranges per layout: fixed numbers that cover the scene type (never taken from
// the ground truth), multiples of 16. Max GT disparity of the frames we have in brackets.
constexpr int kMaxDispKitti = 160;        // KITTI 2012 000070: 147 px; 2015 000046: 66 px
constexpr int kMaxDispTsukuba = 16;       // 14 px
constexpr int kMaxDispVenus = 32;         // 19.75 px
constexpr int kMaxDispTeddyCones = 64;    // 52.75 / 55 px
constexpr int kMaxDisp2006Third = 80;     // 45 .. 76 px
constexpr int kMaxDisp2006Half = 128;     // 83 .. 108.5 px
constexpr int kMaxDisp2006Full = 256;     // twice the HalfSize range

constexpr const char* kLayoutsLookedFor =
    "KITTI 2012 (colored_0|image_0, colored_1|image_1, disp_occ), "
    "KITTI 2015 (image_2, image_3, disp_occ_0), "
    "Middlebury 2001-3 (im3/im4 + disp3.pgm, im2/im6 + disp2.pgm|disp2.png), "
    "Middlebury 2005-6 ({ThirdSize,HalfSize,FullSize}/<scene>/view1, view5, disp1.png), "
    "Middlebury 2014 (MiddEval3/training{Q,H,F}/<scene>/im0, im1, calib.txt, disp0GT.pfm), "
    "synthetic (fuzzystereo_sim.json + training/image_2, image_3, disp_occ_0)";

constexpr const char* kSimMarker = "fuzzystereo_sim.json";

constexpr int kMaxScanDepth = 6;

bool is_dir(const stdfs::path& p) {
  std::error_code ec;
  return stdfs::is_directory(p, ec);
}
bool is_file(const stdfs::path& p) {
  std::error_code ec;
  return stdfs::is_regular_file(p, ec);
}

std::string read_text(const stdfs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Sorted regular files in `dir` whose name ends with `suffix`.
std::vector<stdfs::path> files_ending(const stdfs::path& dir, const std::string& suffix) {
  std::vector<stdfs::path> out;
  std::error_code ec;
  for (const auto& e : stdfs::directory_iterator(dir, ec)) {
    const std::string n = e.path().filename().string();
    if (e.is_regular_file(ec) && n.size() > suffix.size() &&
        n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0)
      out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Width of a PNG from its IHDR chunk (0 when unreadable) — used to tell 2005-6 resolutions apart
// when the folder name does not say.
int png_width(const stdfs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::array<unsigned char, 24> h{};
  if (!in.read(reinterpret_cast<char*>(h.data()), static_cast<std::streamsize>(h.size()))) return 0;
  if (h[1] != 'P' || h[2] != 'N' || h[3] != 'G') return 0;
  return (h[16] << 24) | (h[17] << 16) | (h[18] << 8) | h[19];
}

// "KEY: v0 v1 ..." lines (KITTI calibration files).
std::map<std::string, std::vector<double>> parse_colon_lines(const std::string& text) {
  std::map<std::string, std::vector<double>> out;
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::istringstream vals(line.substr(colon + 1));
    std::vector<double> v;
    double x = 0.0;
    while (vals >> x) v.push_back(x);
    out[line.substr(0, colon)] = std::move(v);
  }
  return out;
}

// Rectified projection matrices P = K [I | t]: P[3] = -f * bx, so B = (P_l[3] - P_r[3]) / f.
Calibration calib_from_projections(const std::vector<double>* pl, const std::vector<double>* pr) {
  Calibration c;
  if (pl == nullptr || pr == nullptr || pl->size() < 12 || pr->size() < 12 || (*pl)[0] <= 0.0) return c;
  c.focal_px = (*pl)[0];
  c.baseline_m = ((*pl)[3] - (*pr)[3]) / c.focal_px;
  c.valid = c.baseline_m > 0.0;
  return c;
}

const std::vector<double>* find_key(const std::map<std::string, std::vector<double>>& m, const char* key) {
  const auto it = m.find(key);
  return it == m.end() ? nullptr : &it->second;
}

std::string frame_id(const stdfs::path& image) {
  std::string n = image.stem().string();  // "000046_10"
  const auto us = n.rfind('_');
  return us == std::string::npos ? n : n.substr(0, us);
}

// ---- detectors: each returns nullopt when `d` is not its layout ---------------------------------

std::optional<std::vector<Frame>> detect_kitti2015(const stdfs::path& d) {
  if (!is_dir(d / "image_2") || !is_dir(d / "image_3")) return std::nullopt;
  std::vector<Frame> frames;
  for (const auto& left : files_ending(d / "image_2", "_10.png")) {
    const auto file = left.filename();
    if (!is_file(d / "image_3" / file)) continue;
    Frame f;
    f.set = "kitti2015";
    f.name = frame_id(left);
    f.left_path = left.string();
    f.right_path = (d / "image_3" / file).string();
    if (is_file(d / "disp_occ_0" / file)) {
      f.gt_path = (d / "disp_occ_0" / file).string();
      f.gt_encoding = GtEncoding::Png16;
      f.gt_divisor = 256.0;
    }
    if (f.has_gt() && is_file(d / "disp_noc_0" / file)) {
      f.noc_path = (d / "disp_noc_0" / file).string();
      f.noc_encoding = NocEncoding::KittiDisp;
    }
    f.max_disparity = kMaxDispKitti;
    const auto calib = d / "calib_cam_to_cam" / (f.name + ".txt");
    if (is_file(calib)) f.calib = parse_kitti2015_calib(read_text(calib));
    frames.push_back(std::move(f));
  }
  return frames;
}

std::optional<std::vector<Frame>> detect_kitti2012(const stdfs::path& d) {
  const bool colour = is_dir(d / "colored_0") && is_dir(d / "colored_1");
  const bool grey = is_dir(d / "image_0") && is_dir(d / "image_1");
  if (!colour && !grey) return std::nullopt;
  const stdfs::path ldir = d / (colour ? "colored_0" : "image_0");
  const stdfs::path rdir = d / (colour ? "colored_1" : "image_1");
  std::vector<Frame> frames;
  for (const auto& left : files_ending(ldir, "_10.png")) {
    const auto file = left.filename();
    if (!is_file(rdir / file)) continue;
    Frame f;
    f.set = "kitti2012";
    f.name = frame_id(left);
    f.left_path = left.string();
    f.right_path = (rdir / file).string();
    if (is_file(d / "disp_occ" / file)) {
      f.gt_path = (d / "disp_occ" / file).string();
      f.gt_encoding = GtEncoding::Png16;
      f.gt_divisor = 256.0;
    }
    if (f.has_gt() && is_file(d / "disp_noc" / file)) {
      f.noc_path = (d / "disp_noc" / file).string();
      f.noc_encoding = NocEncoding::KittiDisp;
    }
    f.max_disparity = kMaxDispKitti;
    const auto calib = d / "calib" / (f.name + ".txt");
    if (is_file(calib)) f.calib = parse_kitti2012_calib(read_text(calib), colour);
    frames.push_back(std::move(f));
  }
  return frames;
}

std::optional<std::vector<Frame>> detect_middlebury2001_3(const stdfs::path& d) {
  struct Variant {
    const char *left, *right, *gt;
    double divisor;
    int max_disp;
  };
  static constexpr std::array<Variant, 3> kVariants{{
      {"im3.png", "im4.png", "disp3.pgm", 16.0, kMaxDispTsukuba},
      {"im2.png", "im6.png", "disp2.pgm", 8.0, kMaxDispVenus},
      {"im2.png", "im6.png", "disp2.png", 4.0, kMaxDispTeddyCones},
  }};
  for (const auto& v : kVariants) {
    if (!is_file(d / v.left) || !is_file(d / v.right) || !is_file(d / v.gt)) continue;
    Frame f;
    f.set = "middlebury2001-3";
    f.name = d.filename().string();
    f.left_path = (d / v.left).string();
    f.right_path = (d / v.right).string();
    f.gt_path = (d / v.gt).string();
    f.gt_encoding = GtEncoding::Png8;
    f.gt_divisor = v.divisor;
    f.max_disparity = v.max_disp;
    return std::vector<Frame>{std::move(f)};
  }
  return std::nullopt;
}

std::optional<std::vector<Frame>> detect_middlebury2005_6(const stdfs::path& d) {
  if (!is_file(d / "view1.png") || !is_file(d / "view5.png")) return std::nullopt;
  // The resolution decides the GT scale; the folder name says it, else the image width does
  // (ThirdSize widths 413-465, HalfSize 626-695, FullSize 1240-1390).
  const std::string parent = d.parent_path().filename().string();
  int divisor = 0;
  if (parent == "ThirdSize") divisor = 3;
  else if (parent == "HalfSize") divisor = 2;
  else if (parent == "FullSize") divisor = 1;
  else {
    const int w = png_width(d / "view1.png");
    divisor = w <= 0 ? 0 : (w < 560 ? 3 : (w < 1000 ? 2 : 1));
  }
  if (divisor == 0) return std::nullopt;
  Frame f;
  f.set = divisor == 3 ? "middlebury2006-third" : (divisor == 2 ? "middlebury2006-half" : "middlebury2006-full");
  f.name = d.filename().string();
  f.left_path = (d / "view1.png").string();
  f.right_path = (d / "view5.png").string();
  if (is_file(d / "disp1.png")) {
    f.gt_path = (d / "disp1.png").string();
    f.gt_encoding = GtEncoding::Png8;
    f.gt_divisor = divisor;
  }
  f.max_disparity = divisor == 3 ? kMaxDisp2006Third : (divisor == 2 ? kMaxDisp2006Half : kMaxDisp2006Full);
  return std::vector<Frame>{std::move(f)};
}

std::optional<std::vector<Frame>> detect_middlebury2014(const stdfs::path& d) {
  if (!is_file(d / "im0.png") || !is_file(d / "im1.png") || !is_file(d / "calib.txt")) return std::nullopt;
  int ndisp = 0;
  Frame f;
  f.calib = parse_middlebury2014_calib(read_text(d / "calib.txt"), &ndisp);
  if (ndisp <= 0)
    throw UserError("Middlebury 2014 calibration '" + (d / "calib.txt").string() + "' has no ndisp=N line (N > 0)");
  // Resolution from the MiddEval3 folder name (trainingQ/testH/...), else from the width.
  const std::string parent = d.parent_path().filename().string();
  char res = parent.empty() ? '?' : parent.back();
  if (res != 'Q' && res != 'H' && res != 'F') {
    const int w = png_width(d / "im0.png");
    res = w < 1000 ? 'Q' : (w < 2000 ? 'H' : 'F');
  }
  f.set = std::string("middlebury2014-") + res;
  f.name = d.filename().string();
  f.left_path = (d / "im0.png").string();
  f.right_path = (d / "im1.png").string();
  if (is_file(d / "disp0GT.pfm")) {
    f.gt_path = (d / "disp0GT.pfm").string();
    f.gt_encoding = GtEncoding::Pfm;
    if (is_file(d / "mask0nocc.png")) {
      f.noc_path = (d / "mask0nocc.png").string();
      f.noc_encoding = NocEncoding::MiddEvalMask;
    }
  }
  f.max_disparity = round_up_16(ndisp);  // calib.txt's ndisp is for this resolution
  return std::vector<Frame>{std::move(f)};
}

// A generated synthetic set: `d` holds the marker (then its training/ holds the frames), or `d` is
// that training/ folder.
std::optional<std::vector<Frame>> detect_synthetic(const stdfs::path& d) {
  stdfs::path marker = d / kSimMarker, training = d / "training";
  if (!is_file(marker) && d.filename() == "training" && is_file(d.parent_path() / kSimMarker)) {
    marker = d.parent_path() / kSimMarker;
    training = d;
  }
  if (!is_file(marker)) return std::nullopt;
  int max_disp = 0;
  try {
    const auto j = nlohmann::json::parse(read_text(marker));
    max_disp = j.at("max_disparity").get<int>();
  } catch (const nlohmann::json::exception& e) {
    throw UserError("synthetic set marker '" + marker.string() + "' is not valid: " + e.what());
  }
  if (max_disp < 16 || max_disp % 16 != 0)
    throw UserError("synthetic set marker '" + marker.string() + "': max_disparity = " + std::to_string(max_disp) +
                    " is not valid (a multiple of 16, >= 16)");
  auto frames = detect_kitti2015(training);
  if (!frames) return std::vector<Frame>{};
  for (auto& f : *frames) {
    f.set = "synthetic";
    f.max_disparity = max_disp;
  }
  return frames;
}

void scan(const stdfs::path& d, int depth, std::vector<Frame>& out) {
  using Detector = std::optional<std::vector<Frame>> (*)(const stdfs::path&);
  static constexpr std::array<Detector, 6> kDetectors{detect_synthetic, detect_kitti2015, detect_kitti2012, detect_middlebury2014,
                                                      detect_middlebury2005_6, detect_middlebury2001_3};
  for (const Detector det : kDetectors) {
    if (auto frames = det(d)) {
      out.insert(out.end(), std::make_move_iterator(frames->begin()), std::make_move_iterator(frames->end()));
      return;  // a layout's folder is not searched further
    }
  }
  if (depth >= kMaxScanDepth) return;
  std::vector<stdfs::path> subdirs;
  std::error_code ec;
  for (const auto& e : stdfs::directory_iterator(d, ec))
    if (e.is_directory(ec) && e.path().filename().string().front() != '.') subdirs.push_back(e.path());
  std::sort(subdirs.begin(), subdirs.end());
  for (const auto& s : subdirs) scan(s, depth + 1, out);
}

}  // namespace

int round_up_16(int n) { return std::max(16, (n + 15) / 16 * 16); }

Calibration parse_kitti2012_calib(const std::string& text, bool colour_cameras) {
  const auto m = parse_colon_lines(text);
  return colour_cameras ? calib_from_projections(find_key(m, "P2"), find_key(m, "P3"))
                        : calib_from_projections(find_key(m, "P0"), find_key(m, "P1"));
}

Calibration parse_kitti2015_calib(const std::string& text) {
  const auto m = parse_colon_lines(text);
  return calib_from_projections(find_key(m, "P_rect_02"), find_key(m, "P_rect_03"));
}

Calibration parse_middlebury2014_calib(const std::string& text, int* ndisp) {
  Calibration c;
  double baseline_mm = 0.0;
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = line.substr(0, eq);
    std::string val = line.substr(eq + 1);
    if (key == "cam0") {
      std::replace(val.begin(), val.end(), '[', ' ');
      std::istringstream(val) >> c.focal_px;
    } else if (key == "baseline") {
      std::istringstream(val) >> baseline_mm;
    } else if (key == "doffs") {
      std::istringstream(val) >> c.doffs_px;
    } else if (key == "ndisp" && ndisp != nullptr) {
      std::istringstream(val) >> *ndisp;
    }
  }
  c.baseline_m = baseline_mm / 1000.0;
  c.valid = c.focal_px > 0.0 && c.baseline_m > 0.0;
  return c;
}

std::vector<Frame> discover_dataset(const std::string& dir) {
  const stdfs::path root(dir);
  if (!is_dir(root)) throw UserError("dataset directory '" + dir + "' does not exist or is not a directory");
  std::vector<Frame> frames;
  scan(root, 0, frames);
  if (frames.empty())
    throw UserError("no stereo frames found under '" + dir + "'; layouts looked for: " + kLayoutsLookedFor);
  std::stable_sort(frames.begin(), frames.end(), [](const Frame& a, const Frame& b) {
    return a.set != b.set ? a.set < b.set : a.name < b.name;
  });
  return frames;
}

cv::Mat read_pfm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw UserError("cannot open PFM file '" + path + "'");
  std::string magic;
  int w = 0, h = 0;
  double scale = 0.0;
  in >> magic >> w >> h >> scale;
  if (!in || (magic != "Pf" && magic != "PF") || w <= 0 || h <= 0 || scale == 0.0 || w > (1 << 16) ||
      h > (1 << 16))
    throw UserError("'" + path + "' is not a valid PFM file (bad header)");
  in.get();  // the single whitespace character ending the header
  const int channels = magic == "PF" ? 3 : 1;
  const std::size_t count = std::size_t(w) * std::size_t(h) * std::size_t(channels);
  std::vector<std::uint32_t> raw(count);
  if (!in.read(reinterpret_cast<char*>(raw.data()), static_cast<std::streamsize>(count * 4)))
    throw UserError("PFM file '" + path + "' is truncated");
  const bool file_little = scale < 0.0;
  const bool host_little = std::endian::native == std::endian::little;
  cv::Mat out(h, w, CV_32FC1);
  for (int y = 0; y < h; ++y) {
    float* dst = out.ptr<float>(h - 1 - y);  // PFM rows are stored bottom-to-top
    for (int x = 0; x < w; ++x) {
      std::uint32_t bits = raw[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * std::size_t(channels)];
      if (file_little != host_little) bits = __builtin_bswap32(bits);
      std::memcpy(&dst[x], &bits, 4);
    }
  }
  return out;
}

FrameImages read_frame_images(const Frame& frame) {
  FrameImages im;
  im.left = read_image(frame.left_path, cv::IMREAD_COLOR);
  im.right = read_image(frame.right_path, cv::IMREAD_COLOR);
  if (im.left.size() != im.right.size())
    throw UserError("left image '" + frame.left_path + "' is " + std::to_string(im.left.cols) + "x" +
                    std::to_string(im.left.rows) + " but right image '" + frame.right_path + "' is " +
                    std::to_string(im.right.cols) + "x" + std::to_string(im.right.rows));
  return im;
}

cv::Mat load_ground_truth(const Frame& frame) {
  const std::string& p = frame.gt_path;
  cv::Mat gt;
  switch (frame.gt_encoding) {
    case GtEncoding::None:
      throw UserError("frame " + frame.set + "/" + frame.name + " has no ground truth");
    case GtEncoding::Png16: {
      const cv::Mat raw = cv::imread(p, cv::IMREAD_UNCHANGED);
      if (raw.empty()) throw UserError("cannot read ground truth '" + p + "'");
      if (raw.type() != CV_16UC1)
        throw UserError("ground truth '" + p + "' is not a 16-bit single-channel PNG (KITTI encoding)");
      raw.convertTo(gt, CV_32F, 1.0 / frame.gt_divisor);
      break;
    }
    case GtEncoding::Png8: {
      cv::Mat raw = cv::imread(p, cv::IMREAD_UNCHANGED);
      if (raw.empty()) throw UserError("cannot read ground truth '" + p + "'");
      if (raw.depth() != CV_8U) throw UserError("ground truth '" + p + "' is not an 8-bit image");
      if (raw.channels() > 1) cv::extractChannel(raw, raw, 0);
      raw.convertTo(gt, CV_32F, 1.0 / frame.gt_divisor);
      break;
    }
    case GtEncoding::Pfm: {
      gt = read_pfm(p);
      gt.forEach<float>([](float& v, const int*) {
        if (!std::isfinite(v)) v = 0.0f;  // inf = unknown -> 0
      });
      break;
    }
  }
  return gt;
}

cv::Mat load_nonoccluded_mask(const Frame& frame) {
  const std::string& p = frame.noc_path;
  if (frame.noc_encoding == NocEncoding::None)
    throw UserError("frame " + frame.set + "/" + frame.name + " has no non-occlusion mask");
  const cv::Mat raw = cv::imread(p, cv::IMREAD_UNCHANGED);
  if (raw.empty()) throw UserError("cannot read non-occlusion mask '" + p + "'");
  if (raw.channels() != 1) throw UserError("non-occlusion mask '" + p + "' is not a single-channel image");
  cv::Mat mask;
  if (frame.noc_encoding == NocEncoding::KittiDisp) {
    if (raw.type() != CV_16UC1)
      throw UserError("non-occluded disparity '" + p + "' is not a 16-bit single-channel PNG (KITTI encoding)");
    mask = raw > 0;
  } else {
    if (raw.type() != CV_8UC1) throw UserError("non-occlusion mask '" + p + "' is not an 8-bit image");
    mask = raw == 255;
  }
  return mask;
}

}  // namespace fs::app
