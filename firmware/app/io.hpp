// Image I/O and conversions at the edge of the program (OpenCV lives here, not in the core).
#pragma once
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "fuzzystereo/image.hpp"

namespace fs {

// Bad user input (missing/unreadable file, size mismatch ...). what() is one line for the user.
class UserError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace app {

// Fails fast, before a long run, when `path` cannot be written later: its directory must exist and be
// writable (UserError naming `what`, the path and the reason). Empty path: nothing to check.
void check_output_file(const std::string& what, const std::string& path);
// Writes `text` to `path`; UserError naming `what` and the path when the file cannot be written completely.
void write_text_file(const std::string& what, const std::string& path, const std::string& text);

// Creates an output directory and its parents; throws UserError naming it (and the reason) when it cannot.
void make_output_dir(const std::string& dir);

// Reads an image; throws UserError naming the file when it is missing or undecodable.
cv::Mat read_image(const std::string& path, int flags);
// Any 8-bit 1/3/4-channel Mat -> 8-bit grey core image.
ImageU8 to_core_gray(const cv::Mat& m);
cv::Mat to_mat(const ImageU8& img);
// Q4 disparity (kInvalidDisp = no estimate) -> float disparity in px, invalid = -1.
cv::Mat disp_q4_to_float(const ImageI16& disp);
// KITTI 16-bit PNG: value = disparity * 256, 0 = invalid.
void write_disp_kitti(const std::string& path, const cv::Mat& disp_float);
// Colour-mapped preview (TURBO), invalid pixels black; max_disp scales the colours.
cv::Mat colorize_disparity(const cv::Mat& disp_float, double max_disp);
void write_image(const std::string& path, const cv::Mat& img);

// NumPy .npy (format 1.0, little-endian, C order) — the dump format the host reads.
void write_npy(const std::string& path, const std::int32_t* data, const std::vector<std::size_t>& shape);
void write_npy(const std::string& path, const std::int16_t* data, const std::vector<std::size_t>& shape);
void write_npy(const std::string& path, const std::uint8_t* data, const std::vector<std::size_t>& shape);
void write_npy(const std::string& path, const std::uint32_t* data, const std::vector<std::size_t>& shape);
// Reads an int32 .npy written by write_npy (labels for --labels-from). Throws UserError.
ImageI32 read_npy_labels(const std::string& path);

}  // namespace app
}  // namespace fs
