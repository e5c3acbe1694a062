// Stereo evaluation datasets: layout detection and ground-truth decoding (KITTI 2012/2015,
// Middlebury 2001-3, 2005-6 ThirdSize/HalfSize/FullSize, 2014 MiddEval3). The layouts and encodings
// are those of the official archives; see /work/shared/datasets/SOURCES.md for the copies we use.
//
// Ground-truth convention (every decoder): CV_32FC1 disparity in px of the left image,
// **0 = no ground truth** (KITTI 0, Middlebury 8-bit 0 and MiddEval3 inf all map to 0).
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace fs::app {

// How the ground-truth file stores disparities.
enum class GtEncoding {
  None,      // no ground truth for this frame (e.g. KITTI testing/)
  Png16,     // KITTI: uint16 PNG, disparity = value / 256, 0 = unknown
  Png8,      // Middlebury 2001-2006: 8-bit PNG/PGM, disparity = value / gt_divisor, 0 = unknown
  Pfm,       // MiddEval3: PFM float32, rows bottom-to-top, inf = unknown
};

// Where the frame's non-occluded pixels are marked (the evaluation area "non-occluded" of the KITTI
// devkit and of MiddEval3): only where the set ships it.
enum class NocEncoding {
  None,          // not shipped (Middlebury 2001-2006, KITTI 2015 copies without disp_noc_0)
  KittiDisp,     // KITTI disp_noc/ (2012) or disp_noc_0/ (2015): a pixel is non-occluded where it is > 0
  MiddEvalMask,  // MiddEval3 mask0nocc.png: 255 = non-occluded, 128 = occluded, 0 = no ground truth
};

struct Calibration {
  bool valid = false;
  double focal_px = 0.0;     // f [px] of the rectified left camera
  double baseline_m = 0.0;   // B [m]
  double doffs_px = 0.0;     // x-offset of the principal points (MiddEval3 only) [px]
};

struct Frame {
  std::string set;           // "kitti2012", "kitti2015", "middlebury2001-3", "middlebury2006-third",
                             // "middlebury2006-half", "middlebury2006-full", "middlebury2014-Q" ...
  std::string name;          // "000046", "tsukuba", "Aloe", "Motorcycle"
  std::string left_path;
  std::string right_path;
  std::string gt_path;       // empty when encoding == None
  GtEncoding gt_encoding = GtEncoding::None;
  double gt_divisor = 1.0;   // Png16: 256; Png8: 16 / 8 / 4 / 3 / 2 / 1; Pfm: 1
  // Disparities searched: 0 .. max_disparity-1. Fixed per layout (not read from the ground truth),
  // a multiple of 16 so OpenCV's BM/SGBM take it unchanged.
  int max_disparity = 64;
  Calibration calib;
  std::string noc_path;      // empty when noc_encoding == None
  NocEncoding noc_encoding = NocEncoding::None;

  bool has_gt() const { return gt_encoding != GtEncoding::None; }
  bool has_noc() const { return noc_encoding != NocEncoding::None; }
};

// Finds every frame of every known layout under `dir` (the datasets root, one set's folder, or one
// scene folder), sorted by (set, name). Throws fs::UserError when `dir` does not exist or contains
// no known layout (the message lists the layouts looked for).
std::vector<Frame> discover_dataset(const std::string& dir);

// Decodes the frame's ground truth (see the convention above). Throws fs::UserError naming the file
// when it is missing or undecodable, or when the frame has no ground truth.
cv::Mat load_ground_truth(const Frame& frame);

// The frame's non-occluded pixels: CV_8UC1, 255 = non-occluded, 0 = occluded or unknown. Throws
// fs::UserError naming the file when it is missing or undecodable, or when the frame has none
// (has_noc() false).
cv::Mat load_nonoccluded_mask(const Frame& frame);

// PFM reader ("Pf" grey or "PF" colour -> first channel; either endianness), top row first.
// Values are returned as stored (inf stays inf). Throws fs::UserError naming the file.
cv::Mat read_pfm(const std::string& path);

// The frame's images in colour (8-bit BGR, via fs::app::read_image). Throws fs::UserError naming the
// file when one is unreadable and naming both when their sizes differ.
struct FrameImages {
  cv::Mat left, right;
};
FrameImages read_frame_images(const Frame& frame);

// Rounds n up to a multiple of 16 (at least 16).
int round_up_16(int n);

// Parsers for the calibration files (exposed for tests). Invalid Calibration when a field is missing.
Calibration parse_kitti2012_calib(const std::string& text, bool colour_cameras);  // P0/P1 or P2/P3
Calibration parse_kitti2015_calib(const std::string& text);                        // P_rect_02/03
Calibration parse_middlebury2014_calib(const std::string& text, int* ndisp);       // cam0, baseline [mm]

}  // namespace fs::app
