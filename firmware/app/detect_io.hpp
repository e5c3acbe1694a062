// Detection at the edge of the program: calibration files, KITTI disparity input, colour
// conversion, obstacles JSON, overlay drawing and the detect dump (docs/formats.md, "Detect dump").
#pragma once
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "fuzzystereo/calib.hpp"
#include "fuzzystereo/detect.hpp"
#include "fuzzystereo/image.hpp"
#include "fuzzystereo/matcher.hpp"
#include "fuzzystereo/params.hpp"
#include "config.hpp"
#include "io.hpp"

namespace fs::app {

// The disparity map detection reads ([detect] input, docs/detection.md "Input map"): the paper's
// sparse map after ESR (MatchResult::disp_esr) or the map after the densify stage (disp_final).
enum class DetectInput { Esr, Dense };
inline DetectInput detect_input_from(const ConfigValues& v) {
  return v.str("detect.input") == "dense" ? DetectInput::Dense : DetectInput::Esr;
}
inline const char* detect_input_name(DetectInput in) { return in == DetectInput::Dense ? "dense" : "esr"; }

// The matcher settings for a detection consumer (detect, detect-eval, the robot loop): on the sparse
// ESR input the densify stage, which then serves nothing, is switched off and costs nothing per frame;
// on the dense input [densify] runs as configured. [detect] matcher_boundary turns the [boundary]
// refinement on for these consumers, [detect] matcher_subpixel_every_segment the sub-pixel value of every
// segment ([cost] subpixel_every_segment; docs/detection.md "Input map"), [detect] matcher_coarse_iterations and
// matcher_iterations their SLIC rounds (docs/results.md "Session 44").
inline MatcherParams detection_matcher_params(MatcherParams p, const ConfigValues& v) {
  if (detect_input_from(v) == DetectInput::Esr) p.densify.enabled = false;
  if (v.flag("detect.matcher_boundary")) p.boundary.enabled = true;
  if (v.flag("detect.matcher_subpixel_every_segment")) p.cost.subpixel_every_segment = true;
  // [detect] matcher_coarse_iterations / matcher_iterations (-1 = as [segmentation]): the robot keeps the
  // 4-round segmentation it was validated with while match / eval / bench default to the coarse start.
  if (const int c = v.integer("detect.matcher_coarse_iterations"); c >= 0) p.seg.coarse_iterations = c;
  if (const int n = v.integer("detect.matcher_iterations"); n >= 0) {
    if (n == 0)
      throw UserError("config: detect.matcher_iterations = 0 is out of range (valid: -1 = as [segmentation], or 1 to 20)");
    p.seg.iterations = n;
  }
  if (const int k = v.integer("detect.matcher_nmi_candidates"); k >= 0) p.cost.nmi_candidates = k;
  return p;
}
// The map of a match result that detection reads.
inline const ImageI16& detection_disparity(const MatchResult& r, DetectInput in) {
  return in == DetectInput::Dense ? r.disp_final : r.disp_esr;
}

// --calib FILE: JSON ({"focal_px", "baseline_m", "cx", "cy"[, "height_m", "pitch_deg"]}, at the top
// level or under "calib" — a simulator sim_gt/*.json works as is), TOML (same fields), or a KITTI
// calibration (calib_cam_to_cam.txt P_rect_02/P_rect_03, or KITTI 2012 P2/P3). Throws UserError
// naming the file and the missing field.
StereoCalib load_stereo_calib(const std::string& path);
StereoCalib calib_from_json(const nlohmann::json& j, const std::string& source);

// KITTI uint16 disparity PNG (value = d * 256, 0 = none) -> Q4 (kInvalidDisp = none).
ImageI16 read_kitti_disparity_q4(const std::string& path);
// 8-bit BGR/BGRA/grey Mat -> RGB core image.
ImageRgb8 to_core_rgb(const cv::Mat& bgr);

nlohmann::json obstacles_json(const DetectResult& r, const StereoCalib& calib, int width, int height);
// Left image with road (magenta) and sky (cyan) tinted, obstacle boxes in red / green / blue for
// near / mid / far with their distance.
cv::Mat draw_overlay(const cv::Mat& left_bgr, const DetectResult& r);
// Every detect stage's inputs and outputs as .npy + detect_meta.json in `dir`.
void write_detect_dump(const std::string& dir, const ImageI16& disp, const ImageRgb8& rgb, const StereoCalib& calib,
                       const std::string& config_toml, const DetectResult& r);

}  // namespace fs::app
