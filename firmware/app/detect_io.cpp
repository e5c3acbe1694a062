#include "detect_io.hpp"

#include "fuzzystereo/capture/rectifier.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "config.hpp"
#include "detect_config.hpp"
#include "io.hpp"

namespace fs::app {

static_assert(sizeof(Rgb8) == 3, "Rgb8 images are dumped as H x W x 3 bytes");

namespace {

std::string read_text(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw UserError("cannot read calibration '" + path + "': no such file or not readable");
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// "key: v v v" lines (KITTI calibration files).
std::map<std::string, std::vector<double>> colon_lines(const std::string& text) {
  std::map<std::string, std::vector<double>> m;
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    const auto c = line.find(':');
    if (c == std::string::npos) continue;
    std::istringstream vals(line.substr(c + 1));
    std::vector<double> v;
    double x;
    while (vals >> x) v.push_back(x);
    m[line.substr(0, c)] = v;
  }
  return m;
}

}  // namespace

StereoCalib calib_from_json(const nlohmann::json& root, const std::string& source) {
  const nlohmann::json& j = root.contains("calib") && root["calib"].is_object() ? root["calib"] : root;
  auto get = [&](const char* key, bool required) -> double {
    if (!j.contains(key) || !j[key].is_number()) {
      if (required)
        throw UserError("calibration '" + source + "' has no number '" + key +
                        "' (needed: focal_px, baseline_m, cx, cy; optional: height_m, pitch_deg)");
      return 0.0;
    }
    return j[key].get<double>();
  };
  StereoCalib c;
  c.focal_px = get("focal_px", true);
  c.baseline_m = get("baseline_m", true);
  c.cx = get("cx", true);
  c.cy = get("cy", true);
  c.height_m = get("height_m", false);
  c.pitch_rad = get("pitch_deg", false) * M_PI / 180.0;
  if (!c.valid()) throw UserError("calibration '" + source + "': focal_px and baseline_m must be > 0");
  return c;
}

StereoCalib load_stereo_calib(const std::string& path) {
  const std::string text = read_text(path);
  const std::string ext = std::filesystem::path(path).extension().string();
  // The robot's own calibration file (OpenCV FileStorage: `capture`'s calib.yml, `fuzzyctl
  // calibrate`'s stereo.yml; docs/capture.md): the calibration of the rectified pair, read and
  // checked by the Rectifier (the images given to detect must already be rectified).
  if (ext == ".yml" || ext == ".yaml" || ext == ".xml" || text.rfind("%YAML", 0) == 0 || text.rfind("<?xml", 0) == 0) {
    try {
      return capture::Rectifier::from_file(path).calib();
    } catch (const capture::CaptureError& e) {
      throw UserError(e.what());
    }
  }
  if (ext == ".json") {
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
      throw UserError("calibration '" + path + "' is not valid JSON: " + e.what());
    }
    return calib_from_json(j, path);
  }
  if (text.find("P_rect_02") != std::string::npos || text.find("P2:") != std::string::npos) {
    const auto m = colon_lines(text);
    const bool k15 = m.count("P_rect_02") != 0;
    const char* k2 = k15 ? "P_rect_02" : "P2";
    const char* k3 = k15 ? "P_rect_03" : "P3";
    if (!m.count(k2) || m.at(k2).size() != 12 || !m.count(k3) || m.at(k3).size() != 12)
      throw UserError("KITTI calibration '" + path + "' needs 12 numbers on both " + k2 + " and " + k3);
    const auto& p2 = m.at(k2);
    const auto& p3 = m.at(k3);
    StereoCalib c;
    c.focal_px = p2[0];
    c.cx = p2[2];
    c.cy = p2[6];
    c.baseline_m = (p2[3] - p3[3]) / p2[0];  // P[0][3] = -f * t_x of each rectified camera
    if (!c.valid()) throw UserError("KITTI calibration '" + path + "' gives a non-positive focal length or baseline");
    return c;
  }
  try {
    return parse_calib_toml(text, path);
  } catch (const ConfigError& e) {
    throw UserError(e.what());
  }
}

ImageI16 read_kitti_disparity_q4(const std::string& path) {
  cv::Mat m = read_image(path, cv::IMREAD_UNCHANGED);
  if (m.type() != CV_16UC1)
    throw UserError("disparity '" + path + "' must be a 16-bit single-channel KITTI PNG (value = d * 256, 0 = none)");
  ImageI16 d(m.cols, m.rows);
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x) {
      const int v = m.at<std::uint16_t>(y, x);
      // d*256 -> d*16 rounded; 0 = no estimate. Values above int16 Q4 range (d >= 2048) are clipped.
      d.at(x, y) = v == 0 ? kInvalidDisp : std::int16_t(std::min(32767, (v + 8) / 16));
    }
  return d;
}

ImageRgb8 to_core_rgb(const cv::Mat& in) {
  cv::Mat bgr;
  if (in.channels() == 1) cv::cvtColor(in, bgr, cv::COLOR_GRAY2BGR);
  else if (in.channels() == 4) cv::cvtColor(in, bgr, cv::COLOR_BGRA2BGR);
  else bgr = in;
  ImageRgb8 o(bgr.cols, bgr.rows);
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < bgr.cols; ++x) o.at(x, y) = Rgb8{p[x][2], p[x][1], p[x][0]};
  }
  return o;
}

nlohmann::json obstacles_json(const DetectResult& r, const StereoCalib& calib, int width, int height) {
  nlohmann::json j;
  j["format"] = "fuzzystereo-obstacles";
  j["version"] = 1;
  j["width"] = width;
  j["height"] = height;
  j["calib"] = {{"focal_px", calib.focal_px}, {"baseline_m", calib.baseline_m}, {"cx", calib.cx}, {"cy", calib.cy}};
  j["road"] = {{"found", r.road.found}, {"a", r.road.a}, {"b", r.road.b}, {"horizon_row", r.road.horizon_row}};
  j["sky_skipped"] = r.sky_skipped;
  nlohmann::json t;
  for (int i = 0; i < int(DetectStage::Count); ++i) t[detect_stage_name(DetectStage(i))] = r.timings.ms[std::size_t(i)];
  j["detect_ms"] = t;
  j["obstacles"] = nlohmann::json::array();
  for (const Obstacle& o : r.obstacles)
    j["obstacles"].push_back({{"id", o.id},
                              {"box", {o.x0, o.y0, o.x1, o.y1}},
                              {"pixel_count", o.pixel_count},
                              {"disparity_px", double(o.disparity_q4) / kDispScale},
                              {"distance_m", o.distance_m},
                              {"lateral_m", o.lateral_m},
                              {"class", obstacle_class_name(o.cls)}});
  return j;
}

cv::Mat draw_overlay(const cv::Mat& left_bgr, const DetectResult& r) {
  cv::Mat out;
  if (left_bgr.channels() == 1) cv::cvtColor(left_bgr, out, cv::COLOR_GRAY2BGR);
  else out = left_bgr.clone();
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      cv::Vec3b& p = out.at<cv::Vec3b>(y, x);
      const cv::Vec3b tint = r.road_mask.at(x, y) ? cv::Vec3b(200, 0, 200) : r.sky_mask.at(x, y) ? cv::Vec3b(255, 255, 0) : p;
      for (int c = 0; c < 3; ++c) p[c] = std::uint8_t((p[c] + tint[c]) / 2);
    }
  for (const Obstacle& o : r.obstacles) {
    // Paper Fig. 22: nearest red, slightly farther green, farthest blue (BGR here).
    const cv::Scalar col = o.cls == ObstacleClass::Near ? cv::Scalar(0, 0, 255)
                           : o.cls == ObstacleClass::Mid ? cv::Scalar(0, 200, 0) : cv::Scalar(255, 0, 0);
    cv::rectangle(out, cv::Point(o.x0, o.y0), cv::Point(o.x1, o.y1), col, 2);
    char txt[32];
    std::snprintf(txt, sizeof txt, "%.1f m", o.distance_m);
    cv::putText(out, txt, cv::Point(o.x0, std::max(10, o.y0 - 3)), cv::FONT_HERSHEY_SIMPLEX, 0.4, col, 1, cv::LINE_AA);
  }
  return out;
}

void write_detect_dump(const std::string& dir, const ImageI16& disp, const ImageRgb8& rgb, const StereoCalib& calib,
                       const std::string& config_toml, const DetectResult& r) {
  make_output_dir(dir);
  const std::size_t h = std::size_t(disp.height), w = std::size_t(disp.width);
  write_npy(dir + "/disp.npy", disp.data.data(), {h, w});
  if (!rgb.empty()) write_npy(dir + "/left_rgb.npy", reinterpret_cast<const std::uint8_t*>(rgb.data.data()), {h, w, 3});
  write_npy(dir + "/vdisp.npy", r.vdisp.data.data(), {h, std::size_t(r.bins)});
  write_npy(dir + "/road_raw.npy", r.road_raw.data.data(), {h, w});
  write_npy(dir + "/road_mask.npy", r.road_mask.data.data(), {h, w});
  write_npy(dir + "/sky_mask.npy", r.sky_mask.data.data(), {h, w});
  write_npy(dir + "/candidates.npy", r.candidates.data.data(), {h, w});
  write_npy(dir + "/cluster_labels.npy", r.cluster_labels.data.data(), {h, w});
  std::vector<std::uint8_t> cells;
  for (const ImageU8& c : r.udisp_kept) cells.insert(cells.end(), c.data.begin(), c.data.end());
  write_npy(dir + "/udisp_kept.npy", cells.data(), {r.udisp_kept.size(), std::size_t(r.bins), w});
  write_npy(dir + "/kept.npy", r.kept.data.data(), {h, w});
  write_npy(dir + "/components.npy", r.components.data.data(), {h, w});
  write_npy(dir + "/obstacle_labels.npy", r.obstacle_labels.data.data(), {h, w});
  nlohmann::json m = obstacles_json(r, calib, int(w), int(h));
  m["format"] = "fuzzystereo-detect-dump";
  m["firmware_version"] = FS_VERSION;
  m["bins"] = r.bins;
  m["calib"]["height_m"] = calib.height_m;
  m["calib"]["pitch_deg"] = calib.pitch_rad * 180.0 / M_PI;
  m["road"]["support"] = r.road.support;
  m["road_line_q4"] = r.road_line_q4;  // INT32_MIN above the horizon
  m["sky_rows"] = r.sky_rows;
  m["centres_q4"] = r.centres_q4;
  m["cluster_sizes"] = r.cluster_sizes;
  m["kmeans_iterations"] = r.kmeans_iterations;
  m["config_toml"] = config_toml;
  std::ofstream f(dir + "/detect_meta.json");
  f << m.dump(2) << "\n";
  if (!f) throw UserError("cannot write '" + dir + "/detect_meta.json'");
}

}  // namespace fs::app
