#include "io.hpp"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace fs::app {

void check_output_file(const std::string& what, const std::string& path) {
  if (path.empty()) return;
  const std::filesystem::path p(path);
  const std::filesystem::path dir = p.has_parent_path() ? p.parent_path() : std::filesystem::path(".");
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec))
    throw UserError(what + " '" + path + "': directory '" + dir.string() + "' does not exist");
  if (std::filesystem::is_directory(p, ec)) throw UserError(what + " '" + path + "' is a directory");
  if (::access(dir.c_str(), W_OK) != 0)
    throw UserError(what + " '" + path + "': directory '" + dir.string() + "' is not writable (" + std::strerror(errno) + ")");
}

void write_text_file(const std::string& what, const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << text;
  f.flush();
  if (!f) throw UserError("cannot write " + what + " '" + path + "'");
}

void make_output_dir(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw UserError("cannot create output directory '" + dir + "': " + ec.message());
}

cv::Mat read_image(const std::string& path, int flags) {
  if (!std::filesystem::exists(path)) throw UserError("image '" + path + "' does not exist");
  cv::Mat m;
  try {
    m = cv::imread(path, flags);
  } catch (const cv::Exception& e) {
    throw UserError("image '" + path + "' could not be decoded: " + e.what());
  }
  if (m.empty()) throw UserError("image '" + path + "' could not be decoded (not an image, or an unsupported format)");
  return m;
}

ImageU8 to_core_gray(const cv::Mat& m) {
  cv::Mat g;
  cv::Mat src = m;
  if (src.depth() == CV_16U) src.convertTo(src, CV_8U, 1.0 / 256.0);
  if (src.depth() != CV_8U) throw UserError("only 8- or 16-bit images are supported");
  if (src.channels() == 3) cv::cvtColor(src, g, cv::COLOR_BGR2GRAY);
  else if (src.channels() == 4) cv::cvtColor(src, g, cv::COLOR_BGRA2GRAY);
  else g = src;
  ImageU8 out(g.cols, g.rows);
  for (int y = 0; y < g.rows; ++y) std::memcpy(out.row(y), g.ptr<std::uint8_t>(y), std::size_t(g.cols));
  return out;
}

cv::Mat to_mat(const ImageU8& img) {
  cv::Mat m(img.height, img.width, CV_8U);
  for (int y = 0; y < img.height; ++y) std::memcpy(m.ptr<std::uint8_t>(y), img.row(y), std::size_t(img.width));
  return m;
}

cv::Mat disp_q4_to_float(const ImageI16& disp) {
  cv::Mat m(disp.height, disp.width, CV_32F);
  for (int y = 0; y < disp.height; ++y) {
    float* o = m.ptr<float>(y);
    const std::int16_t* s = disp.row(y);
    for (int x = 0; x < disp.width; ++x) o[x] = s[x] == kInvalidDisp ? -1.0f : static_cast<float>(s[x]) / kDispScale;
  }
  return m;
}

void write_image(const std::string& path, const cv::Mat& img) {
  bool ok = false;
  try {
    ok = cv::imwrite(path, img);
  } catch (const cv::Exception& e) {
    throw UserError("cannot write '" + path + "': " + e.what());
  }
  if (!ok) throw UserError("cannot write '" + path + "' (directory missing or not writable?)");
}

void write_disp_kitti(const std::string& path, const cv::Mat& disp_float) {
  cv::Mat out(disp_float.size(), CV_16U);
  for (int y = 0; y < disp_float.rows; ++y) {
    const float* s = disp_float.ptr<float>(y);
    std::uint16_t* o = out.ptr<std::uint16_t>(y);
    for (int x = 0; x < disp_float.cols; ++x)
      o[x] = s[x] > 0.0f ? static_cast<std::uint16_t>(std::min(65535.0f, s[x] * 256.0f + 0.5f)) : 0;
  }
  write_image(path, out);
}

cv::Mat colorize_disparity(const cv::Mat& disp_float, double max_disp) {
  cv::Mat u8(disp_float.size(), CV_8U), valid(disp_float.size(), CV_8U);
  for (int y = 0; y < disp_float.rows; ++y) {
    const float* s = disp_float.ptr<float>(y);
    for (int x = 0; x < disp_float.cols; ++x) {
      const bool ok = s[x] >= 0.0f && std::isfinite(s[x]);
      valid.at<std::uint8_t>(y, x) = ok ? 255 : 0;
      u8.at<std::uint8_t>(y, x) = ok ? cv::saturate_cast<std::uint8_t>(s[x] * 255.0 / std::max(1.0, max_disp)) : 0;
    }
  }
  cv::Mat color;
  cv::applyColorMap(u8, color, cv::COLORMAP_TURBO);
  color.setTo(cv::Scalar(0, 0, 0), valid == 0);
  return color;
}

namespace {

template <class T>
void write_npy_impl(const std::string& path, const T* data, const std::vector<std::size_t>& shape, const char* descr) {
  std::string shp = "(";
  std::size_t count = 1;
  for (std::size_t i = 0; i < shape.size(); ++i) {
    shp += std::to_string(shape[i]) + (shape.size() == 1 || i + 1 < shape.size() ? "," : "");
    if (i + 1 < shape.size()) shp += " ";
    count *= shape[i];
  }
  shp += ")";
  std::string header = std::string("{'descr': '") + descr + "', 'fortran_order': False, 'shape': " + shp + ", }";
  // magic(6) + version(2) + len(2) + header + '\n' padded to a multiple of 64.
  const std::size_t total = 10 + header.size() + 1;
  header.append((64 - total % 64) % 64, ' ');
  header += '\n';
  std::ofstream f(path, std::ios::binary);
  if (!f) throw UserError("cannot write '" + path + "'");
  f.write("\x93NUMPY\x01\x00", 8);
  const auto len = static_cast<std::uint16_t>(header.size());
  const char lb[2] = {static_cast<char>(len & 0xFF), static_cast<char>(len >> 8)};
  f.write(lb, 2);
  f.write(header.data(), static_cast<std::streamsize>(header.size()));
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(count * sizeof(T)));
  if (!f) throw UserError("cannot write '" + path + "' (disk full?)");
}

}  // namespace

void write_npy(const std::string& p, const std::int32_t* d, const std::vector<std::size_t>& s) { write_npy_impl(p, d, s, "<i4"); }
void write_npy(const std::string& p, const std::int16_t* d, const std::vector<std::size_t>& s) { write_npy_impl(p, d, s, "<i2"); }
void write_npy(const std::string& p, const std::uint8_t* d, const std::vector<std::size_t>& s) { write_npy_impl(p, d, s, "|u1"); }
void write_npy(const std::string& p, const std::uint32_t* d, const std::vector<std::size_t>& s) { write_npy_impl(p, d, s, "<u4"); }

ImageI32 read_npy_labels(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw UserError("labels file '" + path + "' does not exist or is not readable");
  char magic[10];
  f.read(magic, 10);
  if (!f || std::memcmp(magic, "\x93NUMPY", 6) != 0) throw UserError("'" + path + "' is not a .npy file");
  const std::size_t hlen = std::size_t(std::uint8_t(magic[8])) | (std::size_t(std::uint8_t(magic[9])) << 8);
  std::string header(hlen, '\0');
  f.read(header.data(), static_cast<std::streamsize>(hlen));
  if (header.find("'<i4'") == std::string::npos || header.find("'fortran_order': False") == std::string::npos)
    throw UserError("'" + path + "' must hold int32 labels in C order");
  const auto p0 = header.find('('), p1 = header.find(')');
  int h = 0, w = 0;
  if (p0 == std::string::npos || p1 == std::string::npos || std::sscanf(header.c_str() + p0, "(%d, %d)", &h, &w) != 2 ||
      h <= 0 || w <= 0)
    throw UserError("'" + path + "' must be a 2-D array");
  ImageI32 img(w, h);
  f.read(reinterpret_cast<char*>(img.data.data()), static_cast<std::streamsize>(img.size() * sizeof(std::int32_t)));
  if (!f) throw UserError("'" + path + "' is truncated");
  for (auto v : img.data)
    if (v < 0) throw UserError("'" + path + "' has negative labels");
  return img;
}

}  // namespace fs::app
