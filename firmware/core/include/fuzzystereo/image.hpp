// Plain image buffers for the algorithm core (no OpenCV here: the core must build for the robot
// with nothing but the standard library). Row-major, tightly packed (stride == width).
#pragma once
#include <cstdint>
#include <cstddef>
#include <vector>

namespace fs {

template <class T>
struct Image {
  int width = 0;
  int height = 0;
  std::vector<T> data;

  Image() = default;
  Image(int w, int h, T fill = T{}) : width(w), height(h), data(std::size_t(w) * std::size_t(h), fill) {}

  T* row(int y) { return data.data() + std::size_t(y) * std::size_t(width); }
  const T* row(int y) const { return data.data() + std::size_t(y) * std::size_t(width); }
  T& at(int x, int y) { return row(y)[x]; }
  const T& at(int x, int y) const { return row(y)[x]; }
  std::size_t size() const { return data.size(); }
  bool empty() const { return data.empty(); }
};

// Colour pixel, R G B order (OpenCV's BGR Mats are converted at the app edge).
struct Rgb8 {
  std::uint8_t r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb8&, const Rgb8&) = default;
};

using ImageU8 = Image<std::uint8_t>;
using ImageRgb8 = Image<Rgb8>;
using ImageU16 = Image<std::uint16_t>;
using ImageI16 = Image<std::int16_t>;
using ImageI32 = Image<std::int32_t>;
using ImageU32 = Image<std::uint32_t>;

// ---- Named fixed-point formats ---------------------------------------------------------------
// Disparity maps: int16, Q11.4 (value = disparity * kDispScale), kInvalidDisp marks "no estimate".
inline constexpr int kDispShift = 4;
inline constexpr int kDispScale = 1 << kDispShift;
inline constexpr std::int16_t kInvalidDisp = -1;

// Largest supported width/height: int16 Q4 disparities and the int32 cost lanes (docs/algorithm.md).
inline constexpr int kMaxImageWidth = 32767;

// Scores and normalised costs in [0, 1]: uint32/int32 in Q16 (1.0 == kQ16One).
inline constexpr int kQ16Shift = 16;
inline constexpr std::int32_t kQ16One = 1 << kQ16Shift;

// Gradient magnitude image, eq. (5): uint16, integer Sobel units (|grad| <= 1443 for 8-bit input).

// Segment label images: int32, labels 0 .. n-1, dense.

}  // namespace fs
