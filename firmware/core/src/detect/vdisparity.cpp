// Road surface from the v-disparity image, paper eq. (16)-(17), Section III-B.
//
// The road is a slanted line d = a*v + b in the v-disparity image. We find it with a weighted
// RANSAC over the non-empty cells (a cell's weight is its pixel count) followed by a weighted
// least-squares refit on the inliers. Why RANSAC and not Hough: the only free parameters are the
// slope range and an inlier band in disparity px, which are physical; a Hough accumulator needs a
// (rho, theta) quantisation whose resolution trades against the 1-px disparity quantisation of the
// cells, and its peak is biased by long vertical obstacle lines (slope 0) unless theta is clipped,
// which is exactly the slope range RANSAC takes directly. The generator is a fixed-seed xorshift, so
// a frame always gives the same line (docs/detection.md).
#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

int disparity_bins(const ImageI16& disp) {
  int mx = 0;
  for (const std::int16_t q : disp.data)
    if (q != kInvalidDisp && q >= 0) mx = std::max(mx, disp_bin(q));
  return mx + 1;
}

// eq. (16)-(17): one histogram over rounded disparity per image row.
ImageI32 v_disparity(const ImageI16& disp, int bins) {
  ImageI32 v(bins, disp.height, 0);
  for (int y = 0; y < disp.height; ++y) {
    const std::int16_t* d = disp.row(y);
    std::int32_t* h = v.row(y);
    for (int x = 0; x < disp.width; ++x)
      if (d[x] >= 0) ++h[disp_bin(d[x])];  // kInvalidDisp (< 0) skipped
  }
  return v;
}

namespace {

struct Cell {
  int v, d;
  std::int64_t w;
};

// xorshift64*: tiny, fixed, identical on every platform (std distributions are not specified
// bit-exactly across standard libraries).
struct Rng {
  std::uint64_t s;
  explicit Rng(int seed) : s(0x9E3779B97F4A7C15ull ^ std::uint64_t(std::uint32_t(seed))) {
    if (s == 0) s = 1;
  }
  std::uint64_t next() {
    s ^= s >> 12;
    s ^= s << 25;
    s ^= s >> 27;
    return s * 0x2545F4914F6CDD1Dull;
  }
};

std::int64_t score(const std::vector<Cell>& cells, double a, double b, double tol) {
  std::int64_t s = 0;
  for (const Cell& c : cells)
    if (std::fabs(double(c.d) - (a * c.v + b)) <= tol) s += c.w;
  return s;
}

}  // namespace

RoadLine fit_road_line(const ImageI32& vdisp, std::int64_t valid_pixels, const DetectParams& p) {
  RoadLine best;
  std::vector<Cell> cells;
  for (int v = 0; v < vdisp.height; ++v)
    for (int d = 1; d < vdisp.width; ++d)  // d = 0 (infinity, sky) carries no slope information
      if (vdisp.at(d, v) >= p.road_min_cell_count) cells.push_back({v, d, vdisp.at(d, v)});
  if (cells.size() < 2) return best;
  std::vector<std::int64_t> cum(cells.size());
  std::int64_t total = 0;
  for (std::size_t i = 0; i < cells.size(); ++i) cum[i] = (total += cells[i].w);
  auto pick = [&](Rng& r) {  // cell drawn with probability proportional to its count
    const std::int64_t t = std::int64_t(r.next() % std::uint64_t(total));
    return std::size_t(std::upper_bound(cum.begin(), cum.end(), t) - cum.begin());
  };
  Rng rng(p.road_ransac_seed);
  double ba = 0, bb = 0;
  std::int64_t bs = -1;
  for (int it = 0; it < p.road_ransac_iterations; ++it) {
    const Cell& c1 = cells[pick(rng)];
    const Cell& c2 = cells[pick(rng)];
    if (c1.v == c2.v) continue;
    const double a = double(c2.d - c1.d) / double(c2.v - c1.v);
    if (a < p.road_slope_min || a > p.road_slope_max) continue;
    const double b = c1.d - a * c1.v;
    const std::int64_t s = score(cells, a, b, p.road_fit_tolerance_px);
    if (s > bs) bs = s, ba = a, bb = b;
  }
  if (bs <= 0) return best;
  // Refit by weighted least squares d = a*v + b on one cell per row: the inlier cell of the row
  // with the most pixels (weight = its count). One cell per row keeps the few obstacle cells that
  // touch the line near an obstacle's foot from pulling the line towards them; the road is the
  // widest surface in its rows.
  long double sw = 0, sv = 0, sd = 0, svv = 0, svd = 0;
  {
    std::vector<const Cell*> row_best(std::size_t(vdisp.height), nullptr);
    for (const Cell& c : cells)
      if (std::fabs(double(c.d) - (ba * c.v + bb)) <= p.road_fit_tolerance_px) {
        const Cell*& r = row_best[std::size_t(c.v)];
        if (!r || c.w > r->w) r = &c;
      }
    for (const Cell* c : row_best)
      if (c) {
        const long double w = (long double)c->w;
        sw += w, sv += w * c->v, sd += w * c->d, svv += w * c->v * c->v, svd += w * c->v * c->d;
      }
  }
  const long double den = sw * svv - sv * sv;
  if (den > 0) {
    const double a = double((sw * svd - sv * sd) / den), b = double((sd - (long double)a * sv) / sw);
    const std::int64_t s = score(cells, a, b, p.road_fit_tolerance_px);
    // Keep the refit unless it loses support (it can, by a cell, when the RANSAC line was lucky).
    if (a >= p.road_slope_min && a <= p.road_slope_max && s * 100 >= bs * 98) bs = s, ba = a, bb = b;
  }
  if (double(bs) < p.road_min_support_pct / 100.0 * double(valid_pixels)) return best;
  best.found = true;
  best.a = ba;
  best.b = bb;
  best.support = bs;
  // a > 0: first row where the line's disparity is positive.
  const double v0 = -bb / ba;
  best.horizon_row = std::clamp(int(std::floor(v0)) + 1, 0, vdisp.height);
  return best;
}

std::vector<std::int32_t> road_line_table(const RoadLine& line, int rows) {
  std::vector<std::int32_t> t(std::size_t(rows), INT32_MIN);
  if (!line.found) return t;
  for (int v = std::max(0, line.horizon_row); v < rows; ++v)
    t[std::size_t(v)] = std::int32_t(std::lround((line.a * v + line.b) * kDispScale));
  return t;
}

// Pixels on the road line: |q4 - line_q4(v)| <= tolerance, rows with a line value only.
// The band grows with the line's disparity when tolerance_rel > 0 (docs/detection.md "(a)"): the
// matcher's road error grows towards the bottom rows, where the road is steep in disparity.
ImageU8 road_pixels(const ImageI16& disp, const std::vector<std::int32_t>& line_q4, double tolerance_px,
                    double tolerance_rel) {
  ImageU8 m(disp.width, disp.height, 0);
  for (int y = 0; y < disp.height; ++y) {
    const std::int32_t l = line_q4[std::size_t(y)];
    if (l == INT32_MIN) continue;
    const std::int32_t tol = std::int32_t(std::lround(tolerance_px * kDispScale + tolerance_rel * std::max(0, l)));
    const std::int16_t* d = disp.row(y);
    std::uint8_t* o = m.row(y);
    // Valid disparities in [l - tol, l + tol]; lo >= 0 keeps kInvalidDisp out.
    const std::int32_t lo = std::max<std::int32_t>(0, l - tol), hi = l + tol;
    for (int x = 0; x < disp.width; ++x) o[x] = std::uint8_t(d[x] >= lo && d[x] <= hi);
  }
  return m;
}

// Road completion: the matcher leaves long invalid runs on the road (the left occlusion strip, whose
// width is the road's own disparity, and low-texture patches longer than fill_max_run_px); they are
// road in the scene but not in road_pixels. Runs bounded by road on both sides (or road and the
// border) become road. Invalid pixels are never obstacle candidates, so detection is unchanged.
ImageU8 complete_road(const ImageU8& road, const ImageI16& disp, const std::vector<std::int32_t>& line_q4, int max_run) {
  ImageU8 m = road;
  if (max_run <= 0) return m;
  const int w = disp.width;
  for (int y = 0; y < disp.height; ++y) {
    if (line_q4[std::size_t(y)] == INT32_MIN) continue;
    const std::int16_t* d = disp.row(y);
    const std::uint8_t* r = road.row(y);
    std::uint8_t* o = m.row(y);
    for (int x = 0; x < w;) {
      if (d[x] >= 0) {
        ++x;
        continue;
      }
      int e = x;  // [x, e) invalid
      while (e < w && d[e] < 0) ++e;
      const bool left_ok = x == 0 || r[x - 1], right_ok = e == w || r[e];
      const bool some_road = (x > 0 && r[x - 1]) || (e < w && r[e]);
      if (e - x <= max_run && left_ok && right_ok && some_road) std::fill(o + x, o + e, std::uint8_t(1));
      x = e;
    }
  }
  return m;
}

// Slope prior (our addition, session 7): the paper fits "the" line; with the camera's mounting known, a flat
// road's line has slope B cos(pitch) / h (calib.hpp: d = f B / Z, ground rows), so a line far from it is not
// the road (a radiometric frame of the tuning set, 000081, fitted a = 0.021 through two obstacles at ~7 px
// instead of the road's 0.3, and every obstacle became road). 0 = off, and off without a mounting (KITTI).
bool road_slope_range(const DetectParams& p, const StereoCalib& calib, double* lo, double* hi) {
  *lo = p.road_slope_min, *hi = p.road_slope_max;
  if (p.road_slope_prior_rel > 0 && calib.height_m > 0 && calib.baseline_m > 0) {
    const double a0 = calib.baseline_m * std::cos(calib.pitch_rad) / calib.height_m;
    *lo = std::max(*lo, a0 / (1.0 + p.road_slope_prior_rel));
    *hi = std::min(*hi, a0 * (1.0 + p.road_slope_prior_rel));
  }
  return *lo <= *hi;
}

}  // namespace fs::detect
