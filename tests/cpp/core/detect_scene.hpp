// Synthetic disparity scenes for the detection tests: a flat road seen by a level camera, boxes
// standing on it at known depth, far background above the horizon, optional noise and holes.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "fuzzystereo/calib.hpp"
#include "fuzzystereo/image.hpp"

namespace fs::test {

struct SceneBox {
  int x0, x1;          // columns (inclusive)
  double z_m;          // depth
  double height_m;     // height above the ground
};

struct Scene {
  StereoCalib calib;
  ImageI16 disp;
  ImageRgb8 rgb;
  std::vector<std::array<int, 4>> boxes;  // x0, y0, x1, y1 inclusive, of each SceneBox
};

// Level camera at height h: road row v > cy has depth Z = f*h/(v - cy), so d = B*(v - cy)/h.
inline Scene make_scene(int w, int h, const std::vector<SceneBox>& boxes, unsigned seed, double noise_px,
                        double hole_frac, double focal_px = 100.0) {
  Scene s;
  s.calib.focal_px = focal_px;
  s.calib.cx = w / 2.0;
  s.calib.cy = h / 2.0;
  s.calib.baseline_m = 0.1;
  s.calib.height_m = 0.5;
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise_px);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> d(std::size_t(w) * std::size_t(h), 0.25);  // above the horizon: far background
  const double f = s.calib.focal_px, B = s.calib.baseline_m, H = s.calib.height_m, cy = s.calib.cy;
  for (int y = 0; y < h; ++y)
    if (y > cy)
      for (int x = 0; x < w; ++x) d[std::size_t(y) * std::size_t(w) + std::size_t(x)] = B * (y - cy) / H;
  // Farther boxes first so nearer ones occlude them.
  std::vector<SceneBox> order = boxes;
  std::sort(order.begin(), order.end(), [](const SceneBox& a, const SceneBox& b) { return a.z_m > b.z_m; });
  for (const SceneBox& b : order) {
    const int ybase = int(std::floor(cy + f * H / b.z_m));
    const int ytop = int(std::ceil(cy + f * (H - b.height_m) / b.z_m));
    for (int y = std::max(0, ytop); y <= std::min(h - 1, ybase); ++y)
      for (int x = b.x0; x <= b.x1; ++x) d[std::size_t(y) * std::size_t(w) + std::size_t(x)] = B * f / b.z_m;
  }
  for (const SceneBox& b : boxes) {
    const int ybase = int(std::floor(cy + f * H / b.z_m));
    const int ytop = int(std::ceil(cy + f * (H - b.height_m) / b.z_m));
    s.boxes.push_back({b.x0, std::max(0, ytop), b.x1, std::min(h - 1, ybase)});
  }
  s.disp = ImageI16(w, h);
  s.rgb = ImageRgb8(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = std::size_t(y) * std::size_t(w) + std::size_t(x);
      double v = d[i] + (noise_px > 0 ? n(rng) : 0.0);
      s.disp.data[i] = (u(rng) < hole_frac || v < 0) ? kInvalidDisp : std::int16_t(std::lround(v * kDispScale));
      // Colours: blue sky above the horizon, grey road, brown boxes below.
      s.rgb.data[i] = y <= cy ? Rgb8{100, 150, 230} : Rgb8{110, 105, 100};
    }
  for (const auto& bx : s.boxes)
    for (int y = bx[1]; y <= bx[3]; ++y)
      for (int x = bx[0]; x <= bx[2]; ++x)
        if (y > cy) s.rgb.at(x, y) = Rgb8{150, 90, 40};
  return s;
}

}  // namespace fs::test
