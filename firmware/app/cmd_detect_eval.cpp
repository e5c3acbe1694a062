// `fuzzystereo detect-eval`: detection metrics on a generated (simulator) dataset, per scenario type
// and overall. Layout and metric definitions: docs/detection.md ("Evaluation").
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "commands.hpp"
#include "config.hpp"
#include "detect_config.hpp"
#include "dataset.hpp"
#include "detect_io.hpp"
#include "fuzzystereo/detect.hpp"
#include "fuzzystereo/matcher.hpp"
#include "fuzzystereo/stages.hpp"
#include "io.hpp"

namespace fs::app {

namespace stdfs = std::filesystem;

namespace {

struct EvalOptions {
  std::string dataset, json, config, disparity_cache, fis;
  int limit = 0;
  int max_disparity = 0;
  bool oracle = false;
  double min_iou = 0.5;
  double max_rel_dist = 0.10;
  int min_visible = 300;
};

struct GtObstacle {
  int id = 0;
  std::array<int, 4> box{};
  double distance_m = 0;
  int visible = 0;
  bool truncated = false;
};

struct Tally {
  int frames = 0, gt = 0, dont_care = 0, detected = 0, detected_box = 0, fp = 0, detections = 0;
  double road_i = 0, road_u = 0, sky_i = 0, sky_u = 0;
  std::vector<double> rel_err;
  std::array<double, int(Stage::Count)> match_ms{};
  std::array<double, int(DetectStage::Count)> detect_ms{};
  nlohmann::json missed = nlohmann::json::array();  // per frame only: cared GT obstacles not detected
  nlohmann::json false_pos = nlohmann::json::array();  // per frame only: unmatched detections

  void add(const Tally& o) {
    frames += o.frames, gt += o.gt, dont_care += o.dont_care, detected += o.detected, detected_box += o.detected_box;
    fp += o.fp, detections += o.detections;
    road_i += o.road_i, road_u += o.road_u, sky_i += o.sky_i, sky_u += o.sky_u;
    rel_err.insert(rel_err.end(), o.rel_err.begin(), o.rel_err.end());
    for (std::size_t i = 0; i < match_ms.size(); ++i) match_ms[i] += o.match_ms[i];
    for (std::size_t i = 0; i < detect_ms.size(); ++i) detect_ms[i] += o.detect_ms[i];
  }
};

double iou(const std::array<int, 4>& a, const Obstacle& o) {
  const int x0 = std::max(a[0], o.x0), y0 = std::max(a[1], o.y0), x1 = std::min(a[2], o.x1), y1 = std::min(a[3], o.y1);
  if (x1 < x0 || y1 < y0) return 0.0;
  const double in = double(x1 - x0 + 1) * (y1 - y0 + 1);
  const double ua = double(a[2] - a[0] + 1) * (a[3] - a[1] + 1) + double(o.x1 - o.x0 + 1) * (o.y1 - o.y0 + 1) - in;
  return in / ua;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const double pos = q * double(v.size() - 1);
  const std::size_t lo = std::size_t(std::floor(pos)), hi = std::min(v.size() - 1, lo + 1);
  return v[lo] + (v[hi] - v[lo]) * (pos - double(lo));
}

nlohmann::json read_json(const stdfs::path& p) {
  std::ifstream f(p);
  if (!f) throw UserError("cannot read '" + p.string() + "'");
  try {
    return nlohmann::json::parse(f);
  } catch (const nlohmann::json::exception& e) {
    throw UserError("'" + p.string() + "' is not valid JSON: " + e.what());
  }
}

// Pixel-count intersection and union of a detected 0/1 mask with a GT 0/255 PNG.
void mask_iou(const ImageU8& det, const stdfs::path& gt_path, double* inter, double* uni) {
  const cv::Mat g = read_image(gt_path.string(), cv::IMREAD_GRAYSCALE);
  if (g.cols != det.width || g.rows != det.height) throw UserError("'" + gt_path.string() + "' does not match the image size");
  for (int y = 0; y < g.rows; ++y)
    for (int x = 0; x < g.cols; ++x) {
      const bool a = det.at(x, y) != 0, b = g.at<std::uint8_t>(y, x) != 0;
      *inter += a && b;
      *uni += a || b;
    }
}

Tally score_frame(const std::vector<GtObstacle>& gt, const DetectResult& r, const EvalOptions& o) {
  Tally t;
  t.frames = 1;
  t.detections = int(r.obstacles.size());
  std::vector<bool> gt_used(gt.size(), false), det_used(r.obstacles.size(), false);
  auto care = [&](const GtObstacle& g) { return g.visible >= o.min_visible; };
  auto rel = [&](const GtObstacle& g, const Obstacle& d) { return std::fabs(d.distance_m - g.distance_m) / g.distance_m; };
  struct Pair {
    double iou;
    std::size_t g, d;
  };
  std::vector<Pair> pairs;
  for (std::size_t g = 0; g < gt.size(); ++g)
    for (std::size_t d = 0; d < r.obstacles.size(); ++d) {
      const double v = iou(gt[g].box, r.obstacles[d]);
      if (v >= o.min_iou) pairs.push_back({v, g, d});
    }
  std::stable_sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.iou > b.iou; });
  // Pass 1: box and distance agree (greedy by IoU, one-to-one).
  for (const Pair& p : pairs)
    if (!gt_used[p.g] && !det_used[p.d] && rel(gt[p.g], r.obstacles[p.d]) <= o.max_rel_dist) {
      gt_used[p.g] = det_used[p.d] = true;
      if (care(gt[p.g])) ++t.detected;
    }
  // Pass 2: a detection on a don't-care obstacle's box is not a false positive, whatever its distance.
  for (const Pair& p : pairs)
    if (!care(gt[p.g]) && !det_used[p.d]) det_used[p.d] = true;
  for (std::size_t d = 0; d < r.obstacles.size(); ++d)
    if (!det_used[d]) {
      ++t.fp;
      const Obstacle& x = r.obstacles[d];
      t.false_pos.push_back({{"box", {x.x0, x.y0, x.x1, x.y1}}, {"distance_m", x.distance_m}, {"pixels", x.pixel_count}});
    }
  for (std::size_t g = 0; g < gt.size(); ++g) {
    if (!care(gt[g])) {
      ++t.dont_care;
      continue;
    }
    ++t.gt;
    // Distance error and box-only rate: the best-IoU detection of this obstacle (IoU >= min_iou).
    double best = 0;
    const Obstacle* bd = nullptr;
    for (const Obstacle& d : r.obstacles) {
      const double v = iou(gt[g].box, d);
      if (v >= o.min_iou && v > best) best = v, bd = &d;
    }
    if (bd) {
      ++t.detected_box;
      t.rel_err.push_back(rel(gt[g], *bd));
    }
    if (!gt_used[g]) {
      // What the nearest miss looked like: the detection with the largest IoU (any IoU).
      double bi = 0;
      const Obstacle* bo = nullptr;
      for (const Obstacle& d : r.obstacles)
        if (const double v = iou(gt[g].box, d); v > bi) bi = v, bo = &d;
      t.missed.push_back({{"id", gt[g].id},
                          {"box", gt[g].box},
                          {"distance_m", gt[g].distance_m},
                          {"visible_pixels", gt[g].visible},
                          {"truncated", gt[g].truncated},
                          {"best_iou", bi},
                          {"best_distance_m", bo ? nlohmann::json(bo->distance_m) : nlohmann::json(nullptr)}});
    }
  }
  return t;
}

nlohmann::json tally_json(const Tally& t, bool matched) {
  nlohmann::json j;
  const double f = std::max(1, t.frames);
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  j["frames"] = t.frames;
  j["gt_obstacles"] = t.gt;
  j["dont_care"] = t.dont_care;
  j["detections"] = t.detections;
  j["detected"] = t.detected;
  j["detection_rate"] = num(t.gt ? double(t.detected) / t.gt : NAN);
  j["detection_rate_box_only"] = num(t.gt ? double(t.detected_box) / t.gt : NAN);
  j["false_positives"] = t.fp;
  j["false_positives_per_frame"] = t.fp / f;
  j["road_iou"] = num(t.road_u > 0 ? t.road_i / t.road_u : NAN);
  j["sky_iou"] = num(t.sky_u > 0 ? t.sky_i / t.sky_u : NAN);
  j["distance_rel_error_median"] = num(quantile(t.rel_err, 0.5));
  j["distance_rel_error_p90"] = num(quantile(t.rel_err, 0.9));
  nlohmann::json m, d;
  double mt = 0, dt = 0;
  for (int i = 0; i < int(Stage::Count); ++i) m[stage_name(Stage(i))] = t.match_ms[std::size_t(i)] / f, mt += t.match_ms[std::size_t(i)] / f;
  for (int i = 0; i < int(DetectStage::Count); ++i)
    d[detect_stage_name(DetectStage(i))] = t.detect_ms[std::size_t(i)] / f, dt += t.detect_ms[std::size_t(i)] / f;
  j["ms_per_frame"] = {{"matcher", matched ? m : nlohmann::json(nullptr)},
                       {"matcher_total", matched ? nlohmann::json(mt) : nlohmann::json(nullptr)},
                       {"detect", d},
                       {"detect_total", dt},
                       {"detect_over_matcher", matched && mt > 0 ? nlohmann::json(dt / mt) : nlohmann::json(nullptr)}};
  return j;
}

void progress(std::size_t i, std::size_t n, const std::string& what) {
  if (isatty(2)) {
    const int width = 30, done = int(double(i) / double(n) * width);
    std::fprintf(stderr, "\r[%s%s] %zu/%zu %-24s", std::string(std::size_t(done), '#').c_str(),
                 std::string(std::size_t(width - done), ' ').c_str(), i, n, what.c_str());
    if (i == n) std::fprintf(stderr, "\n");
  } else if (i < n) {
    std::fprintf(stderr, "[%zu/%zu] %s\n", i + 1, n, what.c_str());
  }
  std::fflush(stderr);
}

// Matcher disparity cache (--disparity-cache DIR): DIR/NNNNNN_10.png is a 16-bit PNG holding
// q4 + 1 (0 = kInvalidDisp), so a cached map is bit-identical to the matcher's Q4 output (KITTI's
// d*256 with 0 = invalid would lose valid d = 0). DIR/matcher_config.toml records the matcher
// parameters the maps were made with; a different matcher config is refused (the cache would lie).
// Use: tuning detection parameters without re-running the matcher on every evaluation.
// The cache always holds the sparse ESR map (MatchResult::disp_esr, before [densify]); DIR/disparity_map.txt
// says so ("esr"; a cache without it predates the file and holds ESR maps too). With [detect] input =
// "dense", the densify stage is applied to the map after reading: densify() is a pure function of the ESR
// map, the right-reference WTA map (its occlusion fill; cached beside the ESR map as NNNNNN_10_right.png
// when the dense input needs it) and [densify], exactly what the matcher runs (matcher.cpp), so the
// result is bit-identical to the matcher's disp_final, and one cache serves every [densify] setting.
// The recorded matcher config therefore
// carries [densify] at its defaults with enabled = false (the settings the ESR maps are independent of).
constexpr const char* kCacheMap = "esr";

// The recorded matcher config without its [densify] section: the ESR maps do not depend on it, so a
// cache made before a [densify] field existed (or with other [densify] values) stays valid.
std::string without_densify_section(const std::string& toml) {
  std::istringstream in(toml);
  std::string line, out;
  bool skip = false;
  while (std::getline(in, line)) {
    if (!line.empty() && line.front() == '[') skip = line.rfind("[densify]", 0) == 0;
    if (!skip) out += line + "\n";
  }
  return out;
}

void check_cache_config(const stdfs::path& dir, const std::string& matcher_toml) {
  make_output_dir(dir.string());
  const stdfs::path mp = dir / "disparity_map.txt";
  if (stdfs::exists(mp)) {
    std::ifstream f(mp);
    std::string have;
    f >> have;
    if (have != kCacheMap)
      throw UserError("--disparity-cache '" + dir.string() + "' holds the '" + have + "' map (" + mp.string() +
                      "), this program caches the 'esr' map; use another directory or delete it");
  } else {
    std::ofstream f(mp);
    f << kCacheMap << "\n";
    if (!f) throw UserError("cannot write '" + mp.string() + "'");
  }
  const stdfs::path p = dir / "matcher_config.toml";
  if (stdfs::exists(p)) {
    std::ifstream f(p);
    const std::string have((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    if (without_densify_section(have) != without_densify_section(matcher_toml))
      throw UserError("--disparity-cache '" + dir.string() + "' was made with a different matcher config (" + p.string() +
                      "; [densify] is not compared); use another directory or delete it");
    return;
  }
  std::ofstream f(p);
  f << matcher_toml;
  if (!f) throw UserError("cannot write '" + p.string() + "'");
}

bool read_cached_disp(const stdfs::path& p, ImageI16* disp) {
  if (!stdfs::exists(p)) return false;
  const cv::Mat m = cv::imread(p.string(), cv::IMREAD_UNCHANGED);
  if (m.empty() || m.type() != CV_16UC1) throw UserError("'" + p.string() + "' is not a 16-bit disparity cache PNG");
  *disp = ImageI16(m.cols, m.rows);
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x) disp->at(x, y) = std::int16_t(int(m.at<std::uint16_t>(y, x)) - 1);
  return true;
}

void write_cached_disp(const stdfs::path& p, const ImageI16& disp) {
  cv::Mat m(disp.height, disp.width, CV_16UC1);
  for (int y = 0; y < disp.height; ++y)
    for (int x = 0; x < disp.width; ++x) m.at<std::uint16_t>(y, x) = std::uint16_t(std::max(0, disp.at(x, y) + 1));
  if (!cv::imwrite(p.string(), m)) throw UserError("cannot write '" + p.string() + "'");
}

void run_detect_eval(const EvalOptions& o) {
  check_output_file("--json", o.json);  // before the frames, not after them
  const stdfs::path root(o.dataset);
  const stdfs::path marker = root / "fuzzystereo_sim.json";
  if (!stdfs::is_regular_file(marker))
    throw UserError("'" + o.dataset + "' is not a generated dataset: no fuzzystereo_sim.json (expected the layout of "
                    "docs/detection.md: training/image_2, image_3, disp_occ_0, sim_gt)");
  const nlohmann::json meta = read_json(marker);
  const stdfs::path tr = root / "training";
  std::vector<std::string> stems;
  if (stdfs::is_directory(tr / "image_2"))
    for (const auto& e : stdfs::directory_iterator(tr / "image_2")) {
      const std::string n = e.path().filename().string();
      if (n.size() > 7 && n.substr(n.size() - 7) == "_10.png") stems.push_back(n.substr(0, n.size() - 4));
    }
  std::sort(stems.begin(), stems.end());
  if (stems.empty()) throw UserError("no frames in '" + (tr / "image_2").string() + "' (expected NNNNNN_10.png)");
  if (o.limit > 0 && std::size_t(o.limit) < stems.size()) stems.resize(std::size_t(o.limit));

  Config cfg = load_config(o.config);
  if (o.max_disparity > 0) cfg.matcher.cost.max_disparity = o.max_disparity;
  else if (meta.contains("max_disparity") && meta["max_disparity"].is_number_integer())
    cfg.matcher.cost.max_disparity = std::clamp(round_up_16(meta["max_disparity"].get<int>()), 16, 256);
  const DetectParams dp = detect_params_from(cfg.values);
  const Detector detector(dp);
  // [detect] input: the matcher runs without densify (its ESR map is what the cache holds); on the dense
  // input, densify() is applied below to the ESR map, fresh or cached (see check_cache_config).
  const DetectInput input = detect_input_from(cfg.values);
  const bool densify_after = !o.oracle && input == DetectInput::Dense && cfg.matcher.densify.enabled;
  const bool need_right = densify_after && cfg.matcher.densify.occlusion_fill;  // the occlusion fill reads it
  MatcherParams esr_params = detection_matcher_params(cfg.matcher, cfg.values);  // [detect] matcher_boundary
  esr_params.densify = DensifyParams{};
  esr_params.densify.enabled = false;
  std::unique_ptr<Matcher> matcher;
  if (!o.oracle) matcher = std::make_unique<Matcher>(esr_params, load_fis_definition(o.fis));
  const bool use_cache = !o.oracle && !o.disparity_cache.empty();
  if (use_cache && !o.fis.empty())
    throw UserError("--fis with --disparity-cache: the cache records the matcher config, not the FIS; use a fresh cache "
                    "directory without --fis, or no cache");
  if (use_cache) check_cache_config(o.disparity_cache, config_to_toml(esr_params));
  double densify_ms = 0;  // all frames, also cached ones
  bool timed = !o.oracle;  // false once a frame's disparity came from the cache (no matcher timing)

  std::map<std::string, Tally> per_type;
  Tally all;
  nlohmann::json frames = nlohmann::json::array();
  for (std::size_t i = 0; i < stems.size(); ++i) {
    const std::string& s = stems[i];
    progress(i, stems.size(), s);
    const nlohmann::json g = read_json(tr / "sim_gt" / (s + ".json"));
    const std::string type = g.value("type", std::string("unknown"));
    const StereoCalib calib = calib_from_json(g, (tr / "sim_gt" / (s + ".json")).string());
    std::vector<GtObstacle> gt;
    for (const auto& ob : g.value("obstacles", nlohmann::json::array())) {
      // An obstacle outside the view (or fully hidden) has box null and 0 visible pixels: it is not
      // part of this frame's ground truth at all (not even don't care).
      if (!ob.contains("box") || ob.at("box").is_null()) continue;
      GtObstacle x;
      x.id = ob.value("id", 0);
      const auto& b = ob.at("box");
      if (!b.is_array() || b.size() != 4) throw UserError("frame " + s + ": obstacle box is not [x0, y0, x1, y1]");
      x.box = {b[0].get<int>(), b[1].get<int>(), b[2].get<int>(), b[3].get<int>()};
      x.distance_m = ob.at("distance_m").get<double>();
      x.visible = ob.value("visible_pixels", 0);
      x.truncated = ob.value("truncated", false);
      gt.push_back(x);
    }
    const cv::Mat lc = read_image((tr / "image_2" / (s + ".png")).string(), cv::IMREAD_COLOR);
    ImageI16 disp, disp_right;
    StageTimings mt;
    bool frame_matched = false;
    if (o.oracle) {
      disp = read_kitti_disparity_q4((tr / "disp_occ_0" / (s + ".png")).string());
    } else if (use_cache && read_cached_disp(stdfs::path(o.disparity_cache) / (s + ".png"), &disp) &&
               (!need_right || read_cached_disp(stdfs::path(o.disparity_cache) / (s + "_right.png"), &disp_right))) {
      timed = false;
    } else {
      const cv::Mat rc = read_image((tr / "image_3" / (s + ".png")).string(), cv::IMREAD_COLOR);
      if (rc.size() != lc.size()) throw UserError("frame " + s + ": left and right sizes differ");
      const MatchResult mr = matcher->match(to_core_gray(lc), to_core_gray(rc));
      disp = mr.disp_esr;
      disp_right = mr.disp_right_wta;
      mt = mr.timings;
      frame_matched = true;
      if (use_cache) {
        write_cached_disp(stdfs::path(o.disparity_cache) / (s + ".png"), disp);
        if (need_right) write_cached_disp(stdfs::path(o.disparity_cache) / (s + "_right.png"), disp_right);
      }
    }
    if (densify_after) {
      const auto t0 = std::chrono::steady_clock::now();
      disp = densify(disp, cfg.matcher.densify, nullptr, need_right ? &disp_right : nullptr);
      mt.ms[std::size_t(Stage::Densify)] = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      densify_ms += mt.ms[std::size_t(Stage::Densify)];
    }
    if (disp.width != lc.cols || disp.height != lc.rows) throw UserError("frame " + s + ": disparity size differs from the image");
    const DetectResult r = detector.detect(disp, to_core_rgb(lc), calib);
    Tally t = score_frame(gt, r, o);
    mask_iou(r.road_mask, tr / "sim_gt" / (s + "_road.png"), &t.road_i, &t.road_u);
    mask_iou(r.sky_mask, tr / "sim_gt" / (s + "_sky.png"), &t.sky_i, &t.sky_u);
    for (std::size_t k = 0; k < t.match_ms.size(); ++k) t.match_ms[k] = mt.ms[k];
    for (std::size_t k = 0; k < t.detect_ms.size(); ++k) t.detect_ms[k] = r.timings.ms[k];
    per_type[type].add(t);
    all.add(t);
    nlohmann::json fj = tally_json(t, frame_matched);
    fj["frame"] = s;
    fj["type"] = type;
    fj["missed"] = t.missed;
    fj["false_positive_boxes"] = t.false_pos;
    nlohmann::json dets = nlohmann::json::array();
    for (const Obstacle& x : r.obstacles)
      dets.push_back({{"box", {x.x0, x.y0, x.x1, x.y1}}, {"distance_m", x.distance_m}, {"pixels", x.pixel_count}});
    fj["detections"] = dets;
    frames.push_back(fj);
  }
  progress(stems.size(), stems.size(), "done");

  std::printf("detect-eval: %s, %zu frames, disparity from %s; detected = IoU >= %.2f and |dZ|/Z <= %.0f %%, "
              "don't care below %d visible px\n",
              o.dataset.c_str(), stems.size(),
              o.oracle ? "ground truth (oracle)" : (densify_after ? "the matcher, densified" : "the matcher, ESR (sparse)"), o.min_iou,
              o.max_rel_dist * 100, o.min_visible);
  std::printf("%-16s %6s %5s %7s %7s %7s %7s %7s %8s %8s %9s %9s %6s\n", "type", "frames", "GT", "det%", "box%", "FP/fr",
              "roadIoU", "skyIoU", "dZ med%", "dZ p90%", "match ms", "detect ms", "ratio");
  nlohmann::json out;
  out["format"] = "fuzzystereo-detect-eval";
  out["dataset"] = o.dataset;
  out["oracle_disparity"] = o.oracle;
  out["input"] = o.oracle ? "ground truth" : detect_input_name(input);
  out["disparity_cache"] = use_cache ? nlohmann::json(o.disparity_cache) : nlohmann::json(nullptr);
  out["criteria"] = {{"min_iou", o.min_iou}, {"max_rel_distance", o.max_rel_dist}, {"min_visible_pixels", o.min_visible}};
  out["config_toml"] = config_to_toml(cfg.values);
  auto row = [&](const std::string& name, const Tally& t) {
    const nlohmann::json j = tally_json(t, timed);
    auto pct = [](const nlohmann::json& v) { return v.is_null() ? NAN : v.get<double>() * 100.0; };
    auto val = [](const nlohmann::json& v) { return v.is_null() ? NAN : v.get<double>(); };
    std::printf("%-16s %6d %5d %7.1f %7.1f %7.2f %7.3f %7.3f %8.1f %8.1f %9.1f %9.2f %6.3f\n", name.c_str(), t.frames, t.gt,
                pct(j["detection_rate"]), pct(j["detection_rate_box_only"]), val(j["false_positives_per_frame"]),
                val(j["road_iou"]), val(j["sky_iou"]), pct(j["distance_rel_error_median"]), pct(j["distance_rel_error_p90"]),
                val(j["ms_per_frame"]["matcher_total"]), val(j["ms_per_frame"]["detect_total"]),
                val(j["ms_per_frame"]["detect_over_matcher"]));
    return j;
  };
  for (const auto& [name, t] : per_type) out["per_type"][name] = row(name, t);
  out["overall"] = row("overall", all);
  if (densify_after) {
    out["densify_ms_per_frame"] = densify_ms / double(stems.size());
    std::printf("densify (input = dense, run on the ESR map after the matcher or the cache): %.2f ms/frame\n",
                densify_ms / double(stems.size()));
  }
  out["frames"] = frames;
  if (!o.json.empty()) {
    std::ofstream f(o.json);
    f << out.dump(2) << "\n";
    if (!f) throw UserError("cannot write '" + o.json + "'");
    std::printf("wrote %s\n", o.json.c_str());
  }
}

}  // namespace

void add_detect_eval_command(CLI::App& app) {
  auto o = std::make_shared<EvalOptions>();
  CLI::App* c = app.add_subcommand("detect-eval", "Score obstacle detection on a generated dataset (fuzzystereo_sim.json layout)");
  c->add_option("--dataset", o->dataset, "dataset root (holds fuzzystereo_sim.json and training/)")->required();
  c->add_option("--json", o->json, "write the metrics (per type, overall, per frame) as JSON");
  c->add_option("--config", o->config, "TOML config (defaults: common/config/default.toml)");
  c->add_option("--fis", o->fis, "FIS definition TOML (default: built-in common/fis/fis.toml); not with --disparity-cache");
  c->add_option("--limit", o->limit, "first N frames only")->check(CLI::NonNegativeNumber);
  c->add_option("--max-disparity", o->max_disparity, "override cost.max_disparity (default: the dataset's max_disparity)");
  c->add_option("--disparity-cache", o->disparity_cache,
                 "directory caching the matcher's disparity per frame (read when present, else matched and written; "
                 "refused when made with another matcher config); matcher timings are then not reported");
  c->add_flag("--oracle-disparity", o->oracle, "use the ground-truth disparity instead of the matcher (isolates detection)");
  c->add_option("--min-iou", o->min_iou, "box IoU for a detection to match a GT obstacle")->check(CLI::Range(0.0, 1.0));
  c->add_option("--max-rel-distance", o->max_rel_dist, "largest |Z_det - Z_gt| / Z_gt of a match")->check(CLI::Range(0.0, 10.0));
  c->add_option("--min-visible", o->min_visible, "GT obstacles with fewer visible pixels are don't care")->check(CLI::NonNegativeNumber);
  c->callback([o] { run_detect_eval(*o); });
}

}  // namespace fs::app
