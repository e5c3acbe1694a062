// Stereo rectification from a calibration file (cv::stereoRectify + cv::initUndistortRectifyMap,
// computed once; cv::remap per frame). OpenCV does the geometry: this file only reads, validates
// and names the fields.
#include "fuzzystereo/capture/rectifier.hpp"

#include <cmath>
#include <filesystem>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace fs::capture {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string size_text(cv::Size s) { return std::to_string(s.width) + "x" + std::to_string(s.height); }

[[noreturn]] void bad(const std::string& what, const std::string& field, const std::string& why) {
  throw CaptureError("calibration '" + what + "': field '" + field + "' " + why);
}

bool all_finite(const cv::Mat& m) { return cv::checkRange(m, true, nullptr, -1e12, 1e12); }

// Reads a matrix field as CV_64F; `rows` x `cols` required (0 = any). Throws naming the field.
cv::Mat read_matrix(const cv::FileStorage& fsr, const std::string& what, const std::string& field,
                    const std::string& alias = "") {
  cv::FileNode n = fsr[field];
  std::string used = field;
  if (n.empty() && !alias.empty()) {
    n = fsr[alias];
    used = alias;
  }
  if (n.empty()) bad(what, field, "is missing" + (alias.empty() ? std::string() : " (nor '" + alias + "')"));
  cv::Mat m;
  try {
    n >> m;
  } catch (const cv::Exception&) {
    bad(what, used, "is not a matrix (expected an opencv-matrix)");
  }
  if (m.empty()) bad(what, used, "is not a matrix (expected an opencv-matrix)");
  m.convertTo(m, CV_64F);
  return m;
}

double read_number(const cv::FileStorage& fsr, const std::string& what, const std::string& field, bool required,
                   double fallback = 0.0) {
  const cv::FileNode n = fsr[field];
  if (n.empty()) {
    if (required) bad(what, field, "is missing");
    return fallback;
  }
  if (!n.isReal() && !n.isInt()) bad(what, field, "is not a number");
  const double v = n.real();
  if (!std::isfinite(v)) bad(what, field, "is not finite");
  return v;
}

bool read_flag(const cv::FileStorage& fsr, const std::string& field) {
  const cv::FileNode n = fsr[field];
  if (n.empty()) return false;
  if (n.isInt() || n.isReal()) return n.real() != 0.0;
  if (n.isString()) {
    const std::string s = n.string();
    return s == "true" || s == "True" || s == "TRUE" || s == "1";
  }
  return false;
}

cv::Size read_size(const cv::FileStorage& fsr, const std::string& what, bool required) {
  const bool has_w = !fsr["image_width"].empty(), has_h = !fsr["image_height"].empty();
  if (!has_w && !has_h && !required) return {};
  const double w = read_number(fsr, what, "image_width", true), h = read_number(fsr, what, "image_height", true);
  if (w < 16 || h < 16 || w != std::floor(w) || h != std::floor(h))
    bad(what, w < 16 || w != std::floor(w) ? "image_width" : "image_height", "must be an integer of at least 16 px");
  return {int(w), int(h)};
}

void check_shape(const cv::Mat& m, const std::string& what, const std::string& field, int rows, int cols) {
  if (m.rows != rows || m.cols != cols)
    bad(what, field, "must be " + std::to_string(rows) + "x" + std::to_string(cols) + ", got " + std::to_string(m.rows) +
                         "x" + std::to_string(m.cols));
  if (!all_finite(m)) bad(what, field, "has a non-finite element");
}

void check_camera_matrix(const cv::Mat& K, const std::string& what, const std::string& field, cv::Size size) {
  check_shape(K, what, field, 3, 3);
  const double fx = K.at<double>(0, 0), fy = K.at<double>(1, 1), cx = K.at<double>(0, 2), cy = K.at<double>(1, 2);
  if (!(fx > 0 && fy > 0)) bad(what, field, "must have positive focal lengths fx, fy (got " + std::to_string(fx) + ", " + std::to_string(fy) + ")");
  if (K.at<double>(1, 0) != 0 || K.at<double>(2, 0) != 0 || K.at<double>(2, 1) != 0 || K.at<double>(2, 2) != 1)
    bad(what, field, "must be [fx s cx; 0 fy cy; 0 0 1]");
  if (cx < 0 || cy < 0 || cx > size.width || cy > size.height)
    bad(what, field, "principal point (" + std::to_string(cx) + ", " + std::to_string(cy) + ") lies outside the " +
                         size_text(size) + " image (image_width/image_height of another resolution?)");
}

void check_distortion(cv::Mat& D, const std::string& what, const std::string& field) {
  const int n = int(D.total());
  if ((D.rows != 1 && D.cols != 1) || (n != 4 && n != 5 && n != 8 && n != 12 && n != 14))
    bad(what, field, "must be a 1xN or Nx1 vector with N = 4, 5, 8, 12 or 14, got " + std::to_string(D.rows) + "x" +
                         std::to_string(D.cols));
  if (!all_finite(D)) bad(what, field, "has a non-finite element");
  D = D.reshape(1, 1);
}

}  // namespace

Rectifier Rectifier::from_stereo_calibration(const cv::Mat& K1in, const cv::Mat& D1in, const cv::Mat& K2in,
                                             const cv::Mat& D2in, const cv::Mat& Rin, const cv::Mat& Tin,
                                             cv::Size size, double alpha, const std::string& what) {
  cv::Mat K1, D1, K2, D2, R, T;
  K1in.convertTo(K1, CV_64F);
  D1in.convertTo(D1, CV_64F);
  K2in.convertTo(K2, CV_64F);
  D2in.convertTo(D2, CV_64F);
  Rin.convertTo(R, CV_64F);
  Tin.convertTo(T, CV_64F);
  if (size.width < 16 || size.height < 16) bad(what, "image_width", "must be an integer of at least 16 px");
  check_camera_matrix(K1, what, "K1", size);
  check_camera_matrix(K2, what, "K2", size);
  check_distortion(D1, what, "D1");
  check_distortion(D2, what, "D2");
  if (R.total() == 3) {  // a Rodrigues vector is accepted too
    cv::Mat Rm;
    cv::Rodrigues(R.reshape(1, 3), Rm);
    R = Rm;
  }
  check_shape(R, what, "R", 3, 3);
  if (cv::norm(R * R.t(), cv::Mat::eye(3, 3, CV_64F), cv::NORM_INF) > 1e-3 || cv::determinant(R) < 0)
    bad(what, "R", "is not a rotation matrix (R R^T != I or det R < 0)");
  if (T.total() != 3) bad(what, "T", "must be 3x1, got " + std::to_string(T.rows) + "x" + std::to_string(T.cols));
  T = T.reshape(1, 3);
  if (!all_finite(T)) bad(what, "T", "has a non-finite element");
  const double B = cv::norm(T);
  if (!(B > 0.005 && B < 2.0))
    bad(what, "T", "gives a baseline |T| = " + std::to_string(B) + ", outside 0.005 .. 2 m (T must be in METRES: "
                   "calibrate with the square size in metres, or divide T by 1000 if it is in mm)");
  if (std::abs(T.at<double>(1)) > std::abs(T.at<double>(0)))
    bad(what, "T", "is mostly vertical (|T.y| > |T.x|): fuzzystereo needs the cameras side by side");
  if (T.at<double>(0) > 0)
    bad(what, "T", "has T.x > 0: the right camera is to the LEFT of the left one (left and right swapped?)");

  Rectifier r;
  r.what_ = what;
  r.size_ = size;
  cv::Mat Q;
  cv::stereoRectify(K1, D1, K2, D2, size, R, T, r.R1_, r.R2_, r.P1_, r.P2_, Q, cv::CALIB_ZERO_DISPARITY, alpha, size);
  cv::initUndistortRectifyMap(K1, D1, r.R1_, r.P1_, size, CV_16SC2, r.lmap1_, r.lmap2_);
  cv::initUndistortRectifyMap(K2, D2, r.R2_, r.P2_, size, CV_16SC2, r.rmap1_, r.rmap2_);
  // Rectified pair: P1 = [f 0 cx 0; 0 f cy 0; 0 0 1 0], P2 = [f 0 cx f*Tx'; ...] with Tx' = -B.
  r.calib_.focal_px = r.P1_.at<double>(0, 0);
  r.calib_.cx = r.P1_.at<double>(0, 2);
  r.calib_.cy = r.P1_.at<double>(1, 2);
  r.calib_.baseline_m = -r.P2_.at<double>(0, 3) / r.P2_.at<double>(0, 0);
  if (!r.calib_.valid())
    bad(what, "T", "gives an invalid rectified pair (f = " + std::to_string(r.calib_.focal_px) +
                   " px, B = " + std::to_string(r.calib_.baseline_m) + " m)");
  return r;
}

Rectifier Rectifier::pre_rectified(const StereoCalib& calib, cv::Size size, const std::string& what) {
  if (!(calib.focal_px > 0)) bad(what, "f", "must be > 0 px");
  if (!(calib.baseline_m > 0.005 && calib.baseline_m < 2.0))
    bad(what, "B", "= " + std::to_string(calib.baseline_m) + " is outside 0.005 .. 2 m (B must be in METRES)");
  Rectifier r;
  r.calib_ = calib;
  r.size_ = size;
  r.what_ = what;
  return r;
}

Rectifier Rectifier::from_file(const std::string& path, double alpha) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw CaptureError("calibration '" + path + "': no such file");
  cv::FileStorage fsr;
  try {
    fsr.open(path, cv::FileStorage::READ);
  } catch (const cv::Exception& e) {
    throw CaptureError("calibration '" + path + "': not an OpenCV FileStorage YAML/XML file (" + e.err + ")");
  }
  if (!fsr.isOpened()) throw CaptureError("calibration '" + path + "': not an OpenCV FileStorage YAML/XML file");
  Rectifier r;
  if (read_flag(fsr, "rectified")) {
    StereoCalib c;
    c.focal_px = read_number(fsr, path, "f", true);
    c.baseline_m = read_number(fsr, path, "B", true);
    c.cx = read_number(fsr, path, "cx", true);
    c.cy = read_number(fsr, path, "cy", true);
    r = pre_rectified(c, read_size(fsr, path, false), path);
  } else {
    const cv::Size size = read_size(fsr, path, true);
    // One statement per field: errors report the first missing field in file order.
    const cv::Mat K1 = read_matrix(fsr, path, "K1", "M1");
    const cv::Mat D1 = read_matrix(fsr, path, "D1");
    const cv::Mat K2 = read_matrix(fsr, path, "K2", "M2");
    const cv::Mat D2 = read_matrix(fsr, path, "D2");
    const cv::Mat R = read_matrix(fsr, path, "R");
    const cv::Mat T = read_matrix(fsr, path, "T");
    r = from_stereo_calibration(K1, D1, K2, D2, R, T, size, alpha, path);
  }
  r.calib_.height_m = read_number(fsr, path, "height_m", false, 0.0);
  const double pitch_deg = read_number(fsr, path, "pitch_deg", false, 0.0);
  if (r.calib_.height_m < 0 || r.calib_.height_m > 10) bad(path, "height_m", "must be within 0 .. 10 m");
  if (std::abs(pitch_deg) > 90) bad(path, "pitch_deg", "must be within -90 .. 90 deg");
  r.calib_.pitch_rad = pitch_deg * kPi / 180.0;
  return r;
}

void Rectifier::check_size(cv::Size s, const std::string& source) const {
  if (size_.area() > 0 && s != size_)
    throw CaptureError("frames from '" + source + "' are " + size_text(s) + " but calibration '" + what_ +
                       "' is for image_width x image_height = " + size_text(size_) +
                       " (set camera.width / camera.height to match, or recalibrate at this size)");
}

void Rectifier::apply(StereoFrame& f) const {
  check_size(f.left.size(), f.source);
  check_size(f.right.size(), f.source);
  if (!remaps()) return;
  cv::Mat l, r;
  cv::remap(f.left, l, lmap1_, lmap2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::remap(f.right, r, rmap1_, rmap2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  f.left = l;
  f.right = r;
}

}  // namespace fs::capture
