// Plain scalar references of the detection stages (firmware/core/src/detect/), written the
// straightforward way, for the bit-exact tests in test_detect.cpp. Not used by the firmware.
#pragma once
#include <algorithm>
#include <cmath>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::ref {

inline int bin_of(std::int16_t q4) { return int(std::lround(double(q4) / kDispScale + 1e-9)); }  // round half up for q4 >= 0

// eq. (16)-(17) literally: delta(i, j) = [round(disp(i, j)) == d], v(j, d) = sum over the row.
inline ImageI32 v_disparity(const ImageI16& disp, int bins) {
  ImageI32 v(bins, disp.height, 0);
  for (int y = 0; y < disp.height; ++y)
    for (int d = 0; d < bins; ++d) {
      int n = 0;
      for (int x = 0; x < disp.width; ++x) n += disp.at(x, y) != kInvalidDisp && bin_of(disp.at(x, y)) == d;
      v.at(d, y) = n;
    }
  return v;
}

inline ImageU8 road_pixels(const ImageI16& disp, const std::vector<std::int32_t>& line_q4, double tol_px,
                           double tol_rel = 0.0) {
  ImageU8 m(disp.width, disp.height, 0);
  for (int y = 0; y < disp.height; ++y)
    for (int x = 0; x < disp.width; ++x) {
      const int l = line_q4[std::size_t(y)], d = disp.at(x, y);
      if (l == INT32_MIN) continue;
      const int tol = int(std::lround(tol_px * kDispScale + tol_rel * (l > 0 ? l : 0)));
      m.at(x, y) = d != kInvalidDisp && std::abs(d - l) <= tol;
    }
  return m;
}

// Road completion, pixel by pixel: an invalid pixel in a row with a line value becomes road when
// the invalid run through it is <= max_run long and the first valid pixels to its left and right are
// road (a side that reaches the image border counts as road, but not both sides).
inline ImageU8 complete_road(const ImageU8& road, const ImageI16& disp, const std::vector<std::int32_t>& line_q4,
                             int max_run) {
  ImageU8 m = road;
  if (max_run <= 0) return m;
  for (int y = 0; y < disp.height; ++y)
    for (int x = 0; x < disp.width; ++x) {
      if (line_q4[std::size_t(y)] == INT32_MIN || disp.at(x, y) != kInvalidDisp) continue;
      int l = x, r = x;
      while (l >= 0 && disp.at(l, y) == kInvalidDisp) --l;
      while (r < disp.width && disp.at(r, y) == kInvalidDisp) ++r;
      const bool at_l = l < 0, at_r = r >= disp.width;
      if (r - l - 1 > max_run || (at_l && at_r)) continue;
      if ((at_l || road.at(l, y)) && (at_r || road.at(r, y))) m.at(x, y) = 1;
    }
  return m;
}

// Full 2-D window: dilation = any pixel inside the image window; erosion = all pixels inside.
inline ImageU8 close_mask(const ImageU8& m, int r) {
  if (r <= 0) return m;
  auto op = [&](const ImageU8& in, bool dilate) {
    ImageU8 o(in.width, in.height, 0);
    for (int y = 0; y < in.height; ++y)
      for (int x = 0; x < in.width; ++x) {
        bool any = false, all = true;
        for (int yy = y - r; yy <= y + r; ++yy)
          for (int xx = x - r; xx <= x + r; ++xx) {
            if (xx < 0 || yy < 0 || xx >= in.width || yy >= in.height) continue;
            any = any || in.at(xx, yy);
            all = all && in.at(xx, yy);
          }
        o.at(x, y) = dilate ? any : all;
      }
    return o;
  };
  return op(op(m, true), false);
}

// Texture (session 8): per pixel the (2r+1)^2 window clipped at the border, n*S2 - S1^2 > (n*t)^2 on the integer
// luma, then the erosion (every window pixel within the image and rows < rows textured). Direct loops.
inline ImageU8 textured_mask(const ImageRgb8& rgb, int rows, int r, double t) {
  const int w = rgb.width, h = rgb.height;
  ImageU8 tex(w, h, 0), out(w, h, 0);
  if (t <= 0 || r < 1) return out;
  rows = std::clamp(rows, 0, h);
  auto luma = [&](int x, int y) {
    const Rgb8 c = rgb.at(x, y);
    return std::int64_t((77 * c.r + 150 * c.g + 29 * c.b + 128) >> 8);
  };
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < w; ++x) {
      std::int64_t n = 0, s1 = 0, s2 = 0;
      for (int yy = y - r; yy <= y + r; ++yy)
        for (int xx = x - r; xx <= x + r; ++xx) {
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
          const std::int64_t g = luma(xx, yy);
          ++n, s1 += g, s2 += g * g;
        }
      tex.at(x, y) = std::uint8_t(double(n * s2 - s1 * s1) > t * t * double(n) * double(n));
    }
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < w; ++x) {
      bool all = true;
      for (int yy = y - r; yy <= y + r; ++yy)
        for (int xx = x - r; xx <= x + r; ++xx)
          if (xx >= 0 && yy >= 0 && xx < w && yy < rows && !tex.at(xx, yy)) all = false;
      out.at(x, y) = std::uint8_t(all);
    }
  return out;
}

inline ImageU8 sky_mask(const ImageRgb8& rgb, const ImageI16& disp, int rows, const DetectParams& p) {
  ImageU8 m(rgb.width, rgb.height, 0);
  const ImageU8 tex = textured_mask(rgb, rows, p.sky_texture_radius, p.sky_max_texture);
  for (int y = 0; y < rgb.height; ++y)
    for (int x = 0; x < rgb.width; ++x) {
      if (y >= rows) continue;
      if (tex.at(x, y)) continue;
      if (p.sky_max_disparity_px > 0 && disp.at(x, y) != kInvalidDisp && disp.at(x, y) > p.sky_max_disparity_px * kDispScale) continue;
      const detect::Hsv h = detect::rgb_to_hsv(rgb.at(x, y));
      for (const HsvRange& r : p.sky_ranges)
        if (detect::in_range(h, r)) m.at(x, y) = 1;
    }
  return m;
}

// Lloyd's k-means on the list of pixels (eq. 22-23), same init / ties / rounding rules as the core.
inline detect::KMeansResult kmeans(const ImageI16& disp, const ImageU8& cand, int k, int max_it, int merge_q4 = 0) {
  detect::KMeansResult res;
  res.labels = ImageU8(disp.width, disp.height, kNoCluster);
  std::vector<std::int32_t> pts;
  for (std::size_t i = 0; i < disp.size(); ++i)
    if (cand.data[i]) pts.push_back(disp.data[i]);
  if (pts.empty()) return res;
  std::vector<std::int32_t> sorted = pts;
  std::sort(sorted.begin(), sorted.end());
  const std::int64_t n = std::int64_t(pts.size());
  std::vector<std::int32_t> c(static_cast<std::size_t>(k));
  for (int i = 0; i < k; ++i) c[std::size_t(i)] = sorted[std::size_t(n * (2 * i + 1) / (2 * k))];
  auto nearest = [&](std::int32_t q) {
    int bi = 0;
    for (int i = 1; i < k; ++i)
      if (std::abs(q - c[std::size_t(i)]) < std::abs(q - c[std::size_t(bi)])) bi = i;
    return bi;
  };
  int it = 0;
  while (it < max_it) {
    std::vector<std::int64_t> sum(static_cast<std::size_t>(k), 0), cnt(static_cast<std::size_t>(k), 0);
    for (auto q : pts) {
      const int i = nearest(q);
      sum[std::size_t(i)] += q;
      ++cnt[std::size_t(i)];
    }
    bool moved = false;
    for (int i = 0; i < k; ++i)
      if (cnt[std::size_t(i)]) {
        // round half up of the mean
        const auto nc = std::int32_t(std::floor(double(sum[std::size_t(i)]) / double(cnt[std::size_t(i)]) + 0.5));
        moved |= nc != c[std::size_t(i)];
        c[std::size_t(i)] = nc;
      }
    ++it;
    if (!moved) break;
  }
  res.iterations = it;
  std::vector<std::int64_t> cnt(static_cast<std::size_t>(k), 0);
  for (auto q : pts) ++cnt[std::size_t(nearest(q))];
  std::vector<int> order;
  for (int i = 0; i < k; ++i) order.push_back(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return c[std::size_t(a)] > c[std::size_t(b)]; });
  // Merge: walk the clusters nearest first; start a new output cluster when the gap to the previous
  // non-empty centre is >= merge_q4; the output centre is the rounded mean of its pixels' centres.
  std::vector<int> remap(static_cast<std::size_t>(k), -1);
  std::vector<std::vector<int>> groups;
  int prev = 0;
  for (int i : order) {
    if (!cnt[std::size_t(i)]) continue;
    if (groups.empty() || merge_q4 <= 0 || prev - c[std::size_t(i)] >= merge_q4) groups.emplace_back();
    groups.back().push_back(i);
    remap[std::size_t(i)] = int(groups.size()) - 1;
    prev = c[std::size_t(i)];
  }
  for (const auto& g : groups) {
    double sw = 0, sc = 0;
    for (int i : g) sw += double(cnt[std::size_t(i)]), sc += double(cnt[std::size_t(i)]) * c[std::size_t(i)];
    res.centres_q4.push_back(std::int32_t(std::floor(sc / sw + 0.5)));
    res.sizes.push_back(std::int64_t(sw));
  }
  for (std::size_t i = 0; i < disp.size(); ++i)
    if (cand.data[i]) res.labels.data[i] = std::uint8_t(remap[std::size_t(nearest(disp.data[i]))]);
  return res;
}

// eq. (24)-(25) cluster by cluster, cell by cell.
inline detect::UDispResult u_disparity(const ImageI16& disp, const ImageU8& labels, int clusters, int bins,
                                       const DetectParams& p) {
  detect::UDispResult res;
  res.kept = ImageU8(disp.width, disp.height, 0);
  for (int c = 0; c < clusters; ++c) {
    ImageI32 u(disp.width, bins, 0);  // u(x, d)
    for (int y = 0; y < disp.height; ++y)
      for (int x = 0; x < disp.width; ++x)
        if (labels.at(x, y) == c) ++u.at(x, bin_of(disp.at(x, y)));
    ImageU8 ok(disp.width, bins, 0), kept(disp.width, bins, 0);
    for (int d = 0; d < bins; ++d)
      for (int x = 0; x < disp.width; ++x) {
        int s = 0;
        for (int dd = d - p.udisp_d_tolerance_px; dd <= d + p.udisp_d_tolerance_px; ++dd)
          if (dd >= 0 && dd < bins) s += u.at(x, dd);
        ok.at(x, d) = u.at(x, d) > 0 && s >= p.udisp_min_height_px;
      }
    for (int d = 0; d < bins; ++d)
      for (int x = 0; x < disp.width; ++x) {
        if (!ok.at(x, d)) continue;
        int a = x, b = x;
        while (a > 0 && ok.at(a - 1, d)) --a;
        while (b + 1 < disp.width && ok.at(b + 1, d)) ++b;
        kept.at(x, d) = b - a + 1 >= p.udisp_min_run_px;
      }
    res.kept_cells.push_back(kept);
  }
  for (int y = 0; y < disp.height; ++y)
    for (int x = 0; x < disp.width; ++x)
      if (labels.at(x, y) != kNoCluster) res.kept.at(x, y) = res.kept_cells[labels.at(x, y)].at(x, bin_of(disp.at(x, y)));
  return res;
}

// Flood fill (breadth first), components numbered in raster order of their first pixel.
// rel > 0: a step must also be <= max(min_step, rel * the larger disparity).
inline ImageI32 components(const ImageU8& m, const ImageI16& disp, int step, int* count, double rel = 0.0,
                           int min_step = 0) {
  ImageI32 lab(m.width, m.height, 0);
  int n = 0;
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) {
      if (!m.at(x, y) || lab.at(x, y)) continue;
      lab.at(x, y) = ++n;
      std::deque<std::pair<int, int>> q{{x, y}};
      while (!q.empty()) {
        auto [cx, cy] = q.front();
        q.pop_front();
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int nx = cx + dx, ny = cy + dy;
            if (nx < 0 || ny < 0 || nx >= m.width || ny >= m.height || !m.at(nx, ny) || lab.at(nx, ny)) continue;
            const int s = std::abs(disp.at(nx, ny) - disp.at(cx, cy));
            if (s > step) continue;
            if (rel > 0 && s > min_step && s > rel * std::max<int>(disp.at(nx, ny), disp.at(cx, cy))) continue;
            lab.at(nx, ny) = n;
            q.push_back({nx, ny});
          }
      }
    }
  *count = n;
  return lab;
}

// Bimodal split, the straightforward way: per component, sort its Q4 values; for every threshold t
// between the smallest and the largest value, the Otsu term (s0*n1 - s1*n0)^2 / (n0*n1) from
// direct sums (same double expression as the firmware, so the same ties); the lower medians from
// the sorted values; the valley by counting. Then a flood fill over (label, side).
inline int bimodal_threshold(std::vector<int> v, int min_px, double min_rel, double max_valley) {
  std::sort(v.begin(), v.end());
  const std::int64_t n = std::int64_t(v.size());
  if (n < 2 * std::int64_t(min_px) || v.empty() || v.front() == v.back()) return -1;
  int best_t = -1;
  double best = -1.0;
  for (int t = v.front() + 1; t <= v.back(); ++t) {
    std::int64_t n0 = 0, s0 = 0, s1 = 0;
    for (int q : v) (q < t ? (++n0, s0 += q) : (s1 += q));
    const std::int64_t n1 = n - n0;
    if (n0 < min_px || n1 < min_px) continue;
    const double diff = double(s0 * n1 - s1 * n0);
    const double crit = diff * diff / double(n0 * n1);
    if (crit > best) best = crit, best_t = t;
  }
  if (best_t < 0) return -1;
  const auto cut = std::lower_bound(v.begin(), v.end(), best_t);
  const std::int64_t c0 = cut - v.begin(), c1 = n - c0;
  const int m0 = v[std::size_t((c0 - 1) / 2)], m1 = v[std::size_t(c0 + (c1 - 1) / 2)];
  if (double(m1 - m0) < min_rel * double(m1)) return -1;
  const int g = (m1 - m0) / 4;
  std::int64_t valley = 0;
  for (int q : v) valley += q >= m0 + g && q <= m1 - g;
  if (double(valley) > max_valley * double(n)) return -1;
  return best_t;
}

inline ImageI32 split_bimodal(const ImageI32& comp, int count, const ImageI16& disp, int min_px, double min_rel,
                              double max_valley, int rounds, int* out_count) {
  ImageI32 lab = comp;
  int n = count;
  for (int r = 0; r < rounds && min_rel > 0; ++r) {
    std::vector<std::vector<int>> vals(std::size_t(n) + 1);
    for (std::size_t i = 0; i < lab.size(); ++i)
      if (lab.data[i]) vals[std::size_t(lab.data[i])].push_back(disp.data[i]);
    std::vector<int> thr(std::size_t(n) + 1, -1);
    bool any = false;
    for (int c = 1; c <= n; ++c) {
      thr[std::size_t(c)] = bimodal_threshold(vals[std::size_t(c)], min_px, min_rel, max_valley);
      any = any || thr[std::size_t(c)] >= 0;
    }
    if (!any) break;
    auto key = [&](int x, int y) {
      const int c = lab.at(x, y), t = c ? thr[std::size_t(c)] : -1;
      return c == 0 ? 0 : 2 * c + (t >= 0 && disp.at(x, y) >= t);
    };
    ImageI32 out(lab.width, lab.height, 0);
    int m = 0;
    for (int y = 0; y < lab.height; ++y)
      for (int x = 0; x < lab.width; ++x) {
        if (!lab.at(x, y) || out.at(x, y)) continue;
        const int k = key(x, y);
        out.at(x, y) = ++m;
        std::deque<std::pair<int, int>> q{{x, y}};
        while (!q.empty()) {
          auto [cx, cy] = q.front();
          q.pop_front();
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int nx = cx + dx, ny = cy + dy;
              if (nx < 0 || ny < 0 || nx >= lab.width || ny >= lab.height || out.at(nx, ny) || key(nx, ny) != k) continue;
              out.at(nx, ny) = m;
              q.push_back({nx, ny});
            }
        }
      }
    lab = std::move(out);
    n = m;
  }
  *out_count = n;
  return lab;
}

}  // namespace fs::ref
