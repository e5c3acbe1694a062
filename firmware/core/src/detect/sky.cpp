// Sky removal by HSV colour, paper eq. (18)-(21), Section III-B.
//
// eq. (18) normalises R, G, B by 255; every ratio below is a ratio of two 8-bit quantities, so the
// normalisation cancels and the conversion runs in integers on the 0..255 values:
//   Cmax, Cmin, Delta = Cmax - Cmin                                        eq. (18)
//   H = 60 * ((G-B)/Delta mod 6) | 60 * ((B-R)/Delta + 2) | 60 * ((R-G)/Delta + 4)   eq. (19)
//   S = Delta / Cmax * 100                                                   eq. (20)
//   V = Cmax (reported in 0..100 like S: V = Cmax * 100 / 255)               eq. (21)
// each rounded to the nearest integer (ties away from zero), H taken mod 360 into 0..359.
#include <algorithm>
#include <cstdint>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

namespace {
// round(n / d) for d > 0, ties away from zero.
inline int div_round(int n, int d) { return n >= 0 ? (2 * n + d) / (2 * d) : -((-2 * n + d) / (2 * d)); }
}  // namespace

Hsv rgb_to_hsv(Rgb8 c) {
  const int r = c.r, g = c.g, b = c.b;
  const int cmax = std::max({r, g, b}), cmin = std::min({r, g, b}), delta = cmax - cmin;
  Hsv o;
  if (delta == 0) o.h = 0;
  else if (cmax == r) o.h = div_round(60 * (g - b), delta);        // in [-60, 60]
  else if (cmax == g) o.h = div_round(60 * (b - r), delta) + 120;  // in [60, 180]
  else o.h = div_round(60 * (r - g), delta) + 240;                 // in [180, 300]
  o.h = (o.h % 360 + 360) % 360;                                   // the "mod 6" of eq. (19)
  o.s = cmax == 0 ? 0 : div_round(100 * delta, cmax);
  o.v = div_round(100 * cmax, 255);
  return o;
}

bool in_range(const Hsv& c, const HsvRange& r) {
  if (!r.enabled) return false;
  const bool h_ok = r.h_min <= r.h_max ? (c.h >= r.h_min && c.h <= r.h_max) : (c.h >= r.h_min || c.h <= r.h_max);
  return h_ok && c.s >= r.s_min && c.s <= r.s_max && c.v >= r.v_min && c.v <= r.v_max;
}

ImageU8 sky_mask(const ImageRgb8& rgb, const ImageI16& disp, int rows_limit, const DetectParams& p) {
  ImageU8 m(rgb.width, rgb.height, 0);
  const int rows = std::clamp(rows_limit, 0, rgb.height);
  const std::int32_t dmax = std::int32_t(p.sky_max_disparity_px * kDispScale + 0.5);
  const bool check_disp = p.sky_max_disparity_px > 0.0;
  for (int y = 0; y < rows; ++y) {
    const Rgb8* c = rgb.row(y);
    const std::int16_t* d = disp.row(y);
    std::uint8_t* o = m.row(y);
    for (int x = 0; x < rgb.width; ++x) {
      if (check_disp && d[x] > dmax) continue;  // a near object in sky colours is not sky
      const Hsv h = rgb_to_hsv(c[x]);
      bool sky = false;
      for (const HsvRange& r : p.sky_ranges) sky = sky || in_range(h, r);
      o[x] = std::uint8_t(sky);
    }
  }
  return m;
}

}  // namespace fs::detect
