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
#include <vector>
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

// Texture (our addition, session 8, docs/detection.md "(b) Texture"): the standard deviation of the grey level
// (luma (77 R + 150 G + 29 B + 128) >> 8) over the (2r+1)^2 window around each pixel, clipped at the image
// border (n pixels). The sky is smooth at this scale (its gradient and clouds change slowly); an obstacle face
// in sky colours (grey, white, blue paint) has texture. Integer box sums S1 = sum g, S2 = sum g^2; "textured"
// when n*S2 - S1^2 > (n*t)^2, i.e. variance > t^2 (exact integer left side, one double comparison); then eroded by
// the same window, so the windows reaching r pixels from an obstacle's silhouette into the smooth sky stay sky.
ImageU8 textured_mask(const ImageRgb8& rgb, int rows_limit, int radius, double max_std) {
  const int w = rgb.width, h = rgb.height;
  ImageU8 out(w, h, 0);
  if (max_std <= 0 || radius < 1) return out;
  const int rows = std::clamp(rows_limit, 0, h);
  const int ih = std::min(h, rows + radius);  // rows needed for the windows of rows < rows_limit
  const std::size_t W = std::size_t(w) + 1;
  std::vector<std::int64_t> s1((std::size_t(ih) + 1) * W, 0), s2((std::size_t(ih) + 1) * W, 0);
  for (int y = 0; y < ih; ++y) {
    const Rgb8* c = rgb.row(y);
    std::int64_t r1 = 0, r2 = 0;
    for (int x = 0; x < w; ++x) {
      const std::int64_t g = (77 * c[x].r + 150 * c[x].g + 29 * c[x].b + 128) >> 8;
      r1 += g, r2 += g * g;
      s1[std::size_t(y + 1) * W + std::size_t(x + 1)] = s1[std::size_t(y) * W + std::size_t(x + 1)] + r1;
      s2[std::size_t(y + 1) * W + std::size_t(x + 1)] = s2[std::size_t(y) * W + std::size_t(x + 1)] + r2;
    }
  }
  auto box = [&](const std::vector<std::int64_t>& s, int x0, int y0, int x1, int y1) {  // inclusive, in range
    return s[std::size_t(y1 + 1) * W + std::size_t(x1 + 1)] - s[std::size_t(y0) * W + std::size_t(x1 + 1)] -
           s[std::size_t(y1 + 1) * W + std::size_t(x0)] + s[std::size_t(y0) * W + std::size_t(x0)];
  };
  const double t2 = max_std * max_std;
  for (int y = 0; y < rows; ++y) {
    const int y0 = std::max(0, y - radius), y1 = std::min(ih - 1, y + radius);
    for (int x = 0; x < w; ++x) {
      const int x0 = std::max(0, x - radius), x1 = std::min(w - 1, x + radius);
      const std::int64_t n = std::int64_t(y1 - y0 + 1) * (x1 - x0 + 1);
      const std::int64_t a = box(s1, x0, y0, x1, y1), b = box(s2, x0, y0, x1, y1);
      out.at(x, y) = std::uint8_t(double(n * b - a * a) > t2 * double(n) * double(n));
    }
  }
  // Erosion by the same window: a pixel is textured only when its whole window is, so the halo of textured
  // windows that reach r pixels into the smooth sky beside an obstacle's silhouette stays sky.
  ImageU8 er(w, h, 0);
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < w; ++x) {
      bool all = true;
      for (int dy = -radius; dy <= radius && all; ++dy)
        for (int dx = -radius; dx <= radius && all; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= w || yy >= rows) continue;
          all = out.at(xx, yy) != 0;
        }
      er.at(x, y) = std::uint8_t(all);
    }
  return er;
}

ImageU8 sky_mask(const ImageRgb8& rgb, const ImageI16& disp, int rows_limit, const DetectParams& p) {
  ImageU8 m(rgb.width, rgb.height, 0);
  const int rows = std::clamp(rows_limit, 0, rgb.height);
  const bool check_tex = p.sky_max_texture > 0 && p.sky_texture_radius >= 1;
  const ImageU8 tex = check_tex ? textured_mask(rgb, rows, p.sky_texture_radius, p.sky_max_texture) : ImageU8();
  const std::int32_t dmax = std::int32_t(p.sky_max_disparity_px * kDispScale + 0.5);
  const bool check_disp = p.sky_max_disparity_px > 0.0;
  for (int y = 0; y < rows; ++y) {
    const Rgb8* c = rgb.row(y);
    const std::int16_t* d = disp.row(y);
    std::uint8_t* o = m.row(y);
    for (int x = 0; x < rgb.width; ++x) {
      if (check_disp && d[x] > dmax) continue;  // a near object in sky colours is not sky
      if (check_tex && tex.at(x, y)) continue;  // a textured surface in sky colours is not sky
      const Hsv h = rgb_to_hsv(c[x]);
      bool sky = false;
      for (const HsvRange& r : p.sky_ranges) sky = sky || in_range(h, r);
      o[x] = std::uint8_t(sky);
    }
  }
  return m;
}

}  // namespace fs::detect
