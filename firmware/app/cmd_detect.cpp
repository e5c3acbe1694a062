// `fuzzystereo detect`: one stereo pair (or a given disparity) -> obstacles (Section III-B).
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "commands.hpp"
#include "config.hpp"
#include "detect_config.hpp"
#include "detect_io.hpp"
#include "fuzzystereo/detect.hpp"
#include "fuzzystereo/matcher.hpp"
#include "io.hpp"

namespace fs::app {

namespace {

struct DetectOptions {
  std::string left, right, calib, config, out, disparity;
  int max_disparity = 0;
  bool dump = false;
};

cv::Mat mask_png(const ImageU8& m) {
  cv::Mat o(m.height, m.width, CV_8U);
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) o.at<std::uint8_t>(y, x) = m.at(x, y) ? 255 : 0;
  return o;
}

void run_detect(const DetectOptions& o) {
  if (o.calib.empty())
    throw UserError("detect needs the camera calibration to turn disparity into distance: pass --calib FILE "
                    "(JSON/TOML with focal_px, baseline_m, cx, cy, or a KITTI calib_cam_to_cam.txt)");
  if (o.disparity.empty() && o.right.empty())
    throw UserError("detect needs --right (to run the matcher) or --disparity (a KITTI 16-bit disparity PNG)");
  const StereoCalib calib = load_stereo_calib(o.calib);
  Config cfg = load_config(o.config);
  if (o.max_disparity > 0) cfg.matcher.cost.max_disparity = o.max_disparity;
  const DetectParams dp = detect_params_from(cfg.values);

  // A single-channel left image is a mono camera: no colour, so the sky stage is skipped.
  const cv::Mat raw = read_image(o.left, cv::IMREAD_UNCHANGED);
  const bool mono = raw.channels() == 1;
  const cv::Mat lc = read_image(o.left, cv::IMREAD_COLOR);
  ImageI16 disp;
  StageTimings mt;
  bool matched = false;
  if (!o.disparity.empty()) {
    disp = read_kitti_disparity_q4(o.disparity);
    if (disp.width != lc.cols || disp.height != lc.rows)
      throw UserError("disparity '" + o.disparity + "' is " + std::to_string(disp.width) + "x" + std::to_string(disp.height) +
                      " but left '" + o.left + "' is " + std::to_string(lc.cols) + "x" + std::to_string(lc.rows));
  } else {
    const cv::Mat rc = read_image(o.right, cv::IMREAD_COLOR);
    if (lc.size() != rc.size())
      throw UserError("left '" + o.left + "' is " + std::to_string(lc.cols) + "x" + std::to_string(lc.rows) + " but right '" +
                      o.right + "' is " + std::to_string(rc.cols) + "x" + std::to_string(rc.rows) + "; a rectified pair must match");
    const DetectInput in = detect_input_from(cfg.values);
    const Matcher matcher(detection_matcher_params(cfg.matcher, cfg.values), load_fis_definition(""));
    const MatchResult mr = matcher.match(to_core_gray(lc), to_core_gray(rc));
    disp = detection_disparity(mr, in);  // [detect] input: disp_esr or the densified disp_final
    mt = mr.timings;
    matched = true;
  }
  const ImageRgb8 rgb = mono ? ImageRgb8{} : to_core_rgb(lc);
  const Detector detector(dp);
  const DetectResult r = detector.detect(disp, rgb, calib);

  make_output_dir(o.out);
  nlohmann::json j = obstacles_json(r, calib, disp.width, disp.height);
  j["left"] = o.left;
  j["disparity_source"] = matched ? "matcher" : o.disparity;
  if (matched) {
    nlohmann::json t;
    for (int i = 0; i < int(Stage::Count); ++i) t[stage_name(Stage(i))] = mt.ms[std::size_t(i)];
    j["matcher_ms"] = t;
  }
  {
    std::ofstream f(o.out + "/obstacles.json");
    f << j.dump(2) << "\n";
    if (!f) throw UserError("cannot write '" + o.out + "/obstacles.json'");
  }
  write_image(o.out + "/overlay.png", draw_overlay(lc, r));
  write_image(o.out + "/road_mask.png", mask_png(r.road_mask));
  write_image(o.out + "/sky_mask.png", mask_png(r.sky_mask));
  const cv::Mat df = disp_q4_to_float(disp);
  write_image(o.out + "/disp_color.png", colorize_disparity(df, std::max(16, r.bins)));
  if (matched) write_disp_kitti(o.out + "/disp_left.png", df);
  if (o.dump) write_detect_dump(o.out + "/dump", disp, rgb, calib, config_to_toml(cfg.values), r);

  std::printf("fuzzystereo detect: %dx%d, disparity from %s, road %s (d = %.3f v %+.2f, horizon row %d), sky %s\n",
              disp.width, disp.height, matched ? "the matcher" : "file", r.road.found ? "found" : "not found", r.road.a,
              r.road.b, r.road.horizon_row, r.sky_skipped ? "skipped" : "removed");
  std::printf("  %zu obstacles:\n", r.obstacles.size());
  for (const Obstacle& ob : r.obstacles)
    std::printf("    #%d %-4s Z %.2f m  X %+.2f m  box (%d,%d)-(%d,%d)  %d px\n", ob.id, obstacle_class_name(ob.cls),
                ob.distance_m, ob.lateral_m, ob.x0, ob.y0, ob.x1, ob.y1, ob.pixel_count);
  std::printf("  stage ms:");
  if (matched) std::printf(" matcher %.1f |", mt.total_ms());
  for (int i = 0; i < int(DetectStage::Count); ++i) std::printf(" %s %.2f", detect_stage_name(DetectStage(i)), r.timings.ms[std::size_t(i)]);
  std::printf(" | detect %.2f\n", r.timings.total_ms());
  std::printf("  wrote %s/obstacles.json, overlay.png, road_mask.png, sky_mask.png, disp_color.png%s\n", o.out.c_str(),
              o.dump ? ", dump/" : "");
}

}  // namespace

void add_detect_command(CLI::App& app) {
  auto o = std::make_shared<DetectOptions>();
  CLI::App* c = app.add_subcommand("detect", "Detect obstacles in one rectified stereo pair (matcher + Section III-B)");
  c->add_option("--left", o->left, "left colour image")->required();
  c->add_option("--right", o->right, "right image (not needed with --disparity)");
  c->add_option("--calib", o->calib, "calibration: JSON/TOML (focal_px, baseline_m, cx, cy), KITTI calib_cam_to_cam.txt, or the robot's OpenCV YAML (capture's calib.yml, docs/capture.md; images already rectified)");
  c->add_option("--config", o->config, "TOML config (defaults: common/config/default.toml)");
  c->add_option("--out", o->out, "output directory")->required();
  c->add_option("--disparity", o->disparity, "KITTI 16-bit disparity PNG to use instead of the matcher (oracle mode)");
  c->add_option("--max-disparity", o->max_disparity, "override cost.max_disparity");
  c->add_flag("--dump", o->dump, "write every detect stage to OUT/dump (docs/formats.md)");
  c->callback([o] { run_detect(*o); });
}

}  // namespace fs::app
