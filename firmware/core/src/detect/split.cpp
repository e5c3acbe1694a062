// Splitting bimodal components (our addition, docs/detection.md "(e) Splitting"). The paper groups
// the kept pixels into obstacles without saying how; our 8-connected components join neighbours
// whose disparities differ by a small step, so two obstacles at different depths that touch in the
// image still join when the matcher smooths the disparity across their boundary (a ramp of small
// steps), or when a strip of road or background at intermediate disparity links them. Such a
// component's disparity histogram has two modes. Per component: Otsu's threshold on the Q4
// histogram (maximum between-class variance); the component is split
// when both classes hold >= min_px pixels, their lower medians differ by >= min_rel of the larger,
// and the band between the two medians' inner quarters (the valley) holds <= max_valley of the
// component's pixels (a slanted surface has a flat histogram: its valley holds ~25 %). The pixels
// are then relabelled: 8-neighbours join when they had the same label and fall on the same side.
// Repeated `rounds` times (a component spanning three depths splits twice).
//
// Necks (session 30, docs/detection.md "(e) Necks"): an obstacle whose box has a run of thin columns
// between two full parts (two posts joined through a strip of road at their feet that the matcher
// gave their disparity) is cut there; split_necks works on the column pixel counts of each label.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

namespace {
int find(std::vector<int>& parent, int a) {
  while (parent[std::size_t(a)] != a) {
    parent[std::size_t(a)] = parent[std::size_t(parent[std::size_t(a)])];
    a = parent[std::size_t(a)];
  }
  return a;
}

// 8-connected labelling of equal non-zero keys (W, NW, N, NE neighbours, union-find with the
// smaller label as root); labels 1..m in raster order of first appearance.
ImageI32 relabel_keys(const ImageI32& keys, int* out_count) {
  const int w = keys.width, h = keys.height;
  ImageI32 tmp(w, h, 0);
  std::vector<int> parent{0};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int k = keys.at(x, y);
      if (k == 0) continue;
      int cur = 0;
      const int nx[4] = {x - 1, x - 1, x, x + 1}, ny[4] = {y, y - 1, y - 1, y - 1};
      for (int j = 0; j < 4; ++j) {
        if (nx[j] < 0 || nx[j] >= w || ny[j] < 0 || keys.at(nx[j], ny[j]) != k) continue;
        const int nl = tmp.at(nx[j], ny[j]);
        if (cur == 0) {
          cur = nl;
        } else {
          const int a = find(parent, cur), b = find(parent, nl);
          if (a != b) parent[std::size_t(std::max(a, b))] = std::min(a, b);
        }
      }
      if (cur == 0) {
        cur = int(parent.size());
        parent.push_back(cur);
      }
      tmp.at(x, y) = cur;
    }
  std::vector<int> final_label(parent.size(), 0);
  int m = 0;
  for (auto& v : tmp.data) {
    if (v == 0) continue;
    const int r = find(parent, v);
    if (final_label[std::size_t(r)] == 0) final_label[std::size_t(r)] = ++m;
    v = final_label[std::size_t(r)];
  }
  *out_count = m;
  return tmp;
}

// Relabels by keys per (label, column of its box): a pixel of label c in column x gets
// key[off[c] + x - x0[c]] (0 = the pixel is dropped); the keys are renumbered 1.. in raster order of
// their first pixel. Keys lie in [0, nkeys). Shared by split_necks and split_seams.
ImageI32 renumber_column_keys(const ImageI32& labels, int count, const std::vector<std::size_t>& off,
                              const std::vector<int>& x0, const std::vector<std::int32_t>& key, std::size_t nkeys,
                              int* out_count) {
  const int w = labels.width, h = labels.height;
  std::vector<int> renum(nkeys, 0);
  int m = 0;
  ImageI32 out(w, h, 0);
  for (int y = 0; y < h; ++y) {
    const std::int32_t* l = labels.row(y);
    std::int32_t* d = out.row(y);
    for (int x = 0; x < w; ++x) {
      const int c = l[x];
      if (c <= 0 || c > count) continue;
      const std::int32_t k = key[off[std::size_t(c)] + std::size_t(x - x0[std::size_t(c)])];
      if (k == 0) continue;
      int& r = renum[std::size_t(k)];
      if (r == 0) r = ++m;
      d[x] = r;
    }
  }
  if (out_count) *out_count = m;
  return out;
}
}  // namespace

int bimodal_threshold_q4(const std::vector<std::int32_t>& hist, int lo, int min_px, double min_rel, double max_valley) {
  const int nb = int(hist.size());
  std::int64_t n = 0, s = 0;
  for (int i = 0; i < nb; ++i) n += hist[std::size_t(i)], s += std::int64_t(hist[std::size_t(i)]) * (lo + i);
  if (n < 2 * std::int64_t(min_px) || nb < 2) return -1;
  // Otsu: maximise the between-class term (s0*n1 - s1*n0)^2 / (n0*n1) over thresholds t (class 0:
  // q4 < t); ties keep the lowest t. s0*n1 - s1*n0 is exact in int64 (|.| < 2^53 for images up to
  // 2^21 pixels and Q4 < 2^12), so the square and the division are each one IEEE-rounded operation:
  // the same value on every platform (no fused multiply-add applies).
  std::int64_t n0 = 0, s0 = 0;
  int best_t = -1;
  double best = -1.0;
  for (int i = 0; i + 1 < nb; ++i) {
    n0 += hist[std::size_t(i)], s0 += std::int64_t(hist[std::size_t(i)]) * (lo + i);
    const std::int64_t n1 = n - n0, s1 = s - s0;
    if (n0 < min_px || n1 < min_px) continue;
    const double diff = double(s0 * n1 - s1 * n0);
    const double crit = diff * diff / double(n0 * n1);
    if (crit > best) best = crit, best_t = lo + i + 1;
  }
  if (best_t < 0) return -1;
  // Lower medians of the two classes and the valley between them.
  std::int64_t c0 = 0, c1 = 0;
  for (int q = lo; q < best_t; ++q) c0 += hist[std::size_t(q - lo)];
  c1 = n - c0;
  auto lower_median = [&](int from, int to, std::int64_t count) {
    const std::int64_t want = (count - 1) / 2;
    std::int64_t acc = 0;
    for (int q = from; q < to; ++q) {
      acc += hist[std::size_t(q - lo)];
      if (acc > want) return q;
    }
    return to - 1;
  };
  const int m0 = lower_median(lo, best_t, c0), m1 = lower_median(best_t, lo + nb, c1);
  if (double(m1 - m0) < min_rel * double(m1)) return -1;
  const int g = (m1 - m0) / 4;  // valley = [m0 + g, m1 - g]
  std::int64_t valley = 0;
  for (int q = m0 + g; q <= m1 - g; ++q) valley += hist[std::size_t(q - lo)];
  if (double(valley) > max_valley * double(n)) return -1;
  return best_t;
}

ImageI32 split_bimodal_components(const ImageI32& components, int count, const ImageI16& disp, int min_px,
                                  double min_rel, double max_valley, int rounds, int* out_count) {
  ImageI32 lab = components;
  int n = count;
  const int w = lab.width, h = lab.height;
  for (int round = 0; round < rounds && min_rel > 0; ++round) {
    // Per component: Q4 range, then histogram and threshold.
    std::vector<int> lo(std::size_t(n) + 1, 1 << 30), hi(std::size_t(n) + 1, -1);
    for (std::size_t i = 0; i < lab.size(); ++i) {
      const int c = lab.data[i];
      if (c == 0) continue;
      lo[std::size_t(c)] = std::min(lo[std::size_t(c)], int(disp.data[i]));
      hi[std::size_t(c)] = std::max(hi[std::size_t(c)], int(disp.data[i]));
    }
    std::vector<std::size_t> off(std::size_t(n) + 2, 0);
    for (int c = 1; c <= n; ++c) off[std::size_t(c) + 1] = off[std::size_t(c)] + std::size_t(hi[std::size_t(c)] >= lo[std::size_t(c)] ? hi[std::size_t(c)] - lo[std::size_t(c)] + 1 : 0);
    std::vector<std::int32_t> hist(off[std::size_t(n) + 1], 0);
    for (std::size_t i = 0; i < lab.size(); ++i) {
      const int c = lab.data[i];
      if (c) ++hist[off[std::size_t(c)] + std::size_t(disp.data[i] - lo[std::size_t(c)])];
    }
    std::vector<int> thr(std::size_t(n) + 1, -1);
    bool any = false;
    for (int c = 1; c <= n; ++c) {
      if (off[std::size_t(c) + 1] == off[std::size_t(c)]) continue;
      std::vector<std::int32_t> hc(hist.begin() + std::ptrdiff_t(off[std::size_t(c)]),
                                   hist.begin() + std::ptrdiff_t(off[std::size_t(c) + 1]));
      thr[std::size_t(c)] = bimodal_threshold_q4(hc, lo[std::size_t(c)], min_px, min_rel, max_valley);
      any = any || thr[std::size_t(c)] >= 0;
    }
    if (!any) break;
    // Relabel: key = 2 * label + side; 8-neighbours (W, NW, N, NE) join when their keys are equal.
    auto key = [&](int x, int y) {
      const int c = lab.at(x, y);
      if (c == 0) return 0;
      const int t = thr[std::size_t(c)];
      return 2 * c + (t >= 0 && disp.at(x, y) >= t ? 1 : 0);
    };
    ImageI32 keys(w, h, 0);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) keys.at(x, y) = key(x, y);
    int m = 0;
    ImageI32 tmp = relabel_keys(keys, &m);
    lab = std::move(tmp);
    n = m;
  }
  if (out_count) *out_count = n;
  return lab;
}

ImageI32 split_necks(const ImageI32& components, int count, int min_width, double max_share, int min_px,
                     double foot_share, int* out_count) {
  if (min_width <= 0 || count <= 0) {
    if (out_count) *out_count = count;
    return components;
  }
  const int w = components.width, h = components.height;
  // Column counts per component over its box.
  std::vector<int> x0(std::size_t(count) + 1, w), x1(std::size_t(count) + 1, -1);
  std::vector<int> y0(std::size_t(count) + 1, h), y1(std::size_t(count) + 1, -1);
  for (int y = 0; y < h; ++y) {
    const std::int32_t* l = components.row(y);
    for (int x = 0; x < w; ++x)
      if (l[x]) {
        const std::size_t c = std::size_t(l[x]);
        x0[c] = std::min(x0[c], x), x1[c] = std::max(x1[c], x), y0[c] = std::min(y0[c], y), y1[c] = std::max(y1[c], y);
      }
  }
  std::vector<std::size_t> off(std::size_t(count) + 2, 0);
  for (int c = 1; c <= count; ++c)
    off[std::size_t(c) + 1] = off[std::size_t(c)] + std::size_t(x1[std::size_t(c)] >= x0[std::size_t(c)] ? x1[std::size_t(c)] - x0[std::size_t(c)] + 1 : 0);
  std::vector<std::int32_t> cols(off[std::size_t(count) + 1], 0), top(off[std::size_t(count) + 1], h);
  for (int y = 0; y < h; ++y) {
    const std::int32_t* l = components.row(y);
    for (int x = 0; x < w; ++x)
      if (l[x]) {
        const std::size_t k = off[std::size_t(l[x])] + std::size_t(x - x0[std::size_t(l[x])]);
        ++cols[k];
        top[k] = std::min<std::int32_t>(top[k], y);
      }
  }

  // Per component, the columns to drop (cut[] over the whole image width, per component run).
  std::vector<std::uint8_t> cut(cols.size(), 0);
  bool any = false;
  for (int c = 1; c <= count; ++c) {
    const std::size_t o = off[std::size_t(c)], nc = off[std::size_t(c) + 1] - o;
    if (nc < std::size_t(min_width) + 2) continue;
    std::vector<std::int32_t> sorted(cols.begin() + std::ptrdiff_t(o), cols.begin() + std::ptrdiff_t(o + nc));
    const std::size_t q = (3 * (nc - 1)) / 4;  // 75th percentile (lower)
    std::nth_element(sorted.begin(), sorted.begin() + std::ptrdiff_t(q), sorted.end());
    const double thin = max_share * double(sorted[q]);
    std::vector<std::int64_t> prefix(nc + 1, 0);  // pixels left of column i
    for (std::size_t i = 0; i < nc; ++i) prefix[i + 1] = prefix[i] + cols[o + i];
    std::size_t i = 0;
    while (i < nc) {
      if (double(cols[o + i]) > thin) {
        ++i;
        continue;
      }
      std::size_t j = i;
      while (j < nc && double(cols[o + j]) <= thin) ++j;  // thin run [i, j)
      const bool wide = j - i >= std::size_t(min_width), inside = i > 0 && j < nc;
      bool foot = true;  // the thin run lies in the lowest foot_share of the box rows
      if (foot_share > 0) {
        const double limit = y1[std::size_t(c)] - foot_share * double(y1[std::size_t(c)] - y0[std::size_t(c)] + 1);
        for (std::size_t k = i; k < j; ++k) foot = foot && double(top[o + k]) >= limit;
      }
      if (wide && inside && foot && prefix[i] >= min_px && prefix[nc] - prefix[j] >= min_px) {
        for (std::size_t k = i; k < j; ++k) cut[o + k] = 1;
        any = true;
      }
      i = j;
    }
  }
  if (!any) {
    if (out_count) *out_count = count;
    return components;
  }
  // New labels: a cut label's columns between cuts form one piece each (its fragments keep together,
  // connected or not), every other label is kept whole; cut columns drop out. Renumbered in raster
  // order of first appearance.
  std::vector<std::int32_t> piece(cols.size(), 0);  // key per (label, column): 1 + column-run start
  for (int c = 1; c <= count; ++c) {
    const std::size_t o = off[std::size_t(c)], nc = off[std::size_t(c) + 1] - o;
    std::int32_t key = std::int32_t(o) + 1;
    for (std::size_t i = 0; i < nc; ++i) {
      if (cut[o + i]) {
        key = std::int32_t(o + i) + 2;  // the next piece starts after this cut column
        continue;
      }
      piece[o + i] = key;
    }
  }
  return renumber_column_keys(components, count, off, x0, piece, cols.size() + 2, out_count);
}

ImageI32 split_seams(const ImageI32& labels, int count, const ImageRgb8& rgb, double min_step, int window,
                     int min_width, int min_px, int max_cuts, double min_rows, double drop_share, int* out_count) {
  const int w = labels.width, h = labels.height;
  if (min_step <= 0 || count <= 0 || max_cuts <= 0 || window <= 0 || rgb.width != w || rgb.height != h || rgb.empty()) {
    if (out_count) *out_count = count;
    return labels;
  }
  // Column sums per label over its box: pixels and R, G, B (int64: <= 255 * image pixels).
  std::vector<int> x0(std::size_t(count) + 1, w), x1(std::size_t(count) + 1, -1);
  std::vector<int> y0(std::size_t(count) + 1, h), y1(std::size_t(count) + 1, -1);
  for (int y = 0; y < h; ++y) {
    const std::int32_t* l = labels.row(y);
    for (int x = 0; x < w; ++x)
      if (l[x] > 0 && l[x] <= count) {
        const std::size_t c = std::size_t(l[x]);
        x0[c] = std::min(x0[c], x), x1[c] = std::max(x1[c], x), y0[c] = std::min(y0[c], y), y1[c] = std::max(y1[c], y);
      }
  }
  std::vector<std::size_t> off(std::size_t(count) + 2, 0);
  for (int c = 1; c <= count; ++c)
    off[std::size_t(c) + 1] = off[std::size_t(c)] + std::size_t(x1[std::size_t(c)] >= x0[std::size_t(c)] ? x1[std::size_t(c)] - x0[std::size_t(c)] + 1 : 0);
  struct Sums {
    std::int64_t n = 0, r = 0, g = 0, b = 0;
  };
  std::vector<Sums> cols(off[std::size_t(count) + 1]);
  for (int y = 0; y < h; ++y) {
    const std::int32_t* l = labels.row(y);
    const Rgb8* px = rgb.row(y);
    for (int x = 0; x < w; ++x)
      if (l[x] > 0 && l[x] <= count) {
        Sums& s = cols[off[std::size_t(l[x])] + std::size_t(x - x0[std::size_t(l[x])])];
        ++s.n, s.r += px[x].r, s.g += px[x].g, s.b += px[x].b;
      }
  }
  // Regularised chromaticity of pixel sums, Q16 (see the header), and the step between two sums: the
  // largest of the three channel differences.
  auto chroma = [](const Sums& a, std::int64_t q[3]) {
    const std::int64_t d = a.r + a.g + a.b + 30 * a.n;
    q[0] = ((a.r + 10 * a.n) << 16) / d, q[1] = ((a.g + 10 * a.n) << 16) / d, q[2] = ((a.b + 10 * a.n) << 16) / d;
  };
  auto chroma_step = [&](const Sums& a, const Sums& b) {
    std::int64_t qa[3], qb[3];
    chroma(a, qa);
    chroma(b, qb);
    std::int64_t step = 0;
    for (int k = 0; k < 3; ++k) step = std::max(step, qa[k] > qb[k] ? qa[k] - qb[k] : qb[k] - qa[k]);
    return step;
  };
  const auto threshold = static_cast<std::int64_t>(std::llround(min_step * 65536.0));
  auto dist2 = [](const std::int64_t p[3], const std::int64_t q[3]) {
    std::int64_t s2 = 0;
    for (int k = 0; k < 3; ++k) s2 += (p[k] - q[k]) * (p[k] - q[k]);
    return s2;
  };
  // Row test: the share of the label's rows (with pixels within kRowPx columns on both sides of the
  // boundary at box column i) whose left pixels' chromaticity is nearer the left window's than the right
  // window's, and whose right pixels' is nearer the right window's. A seam between two obstacles runs
  // down the whole box; a step of the column means made by blobs of one multi-coloured surface (camouflage)
  // does not hold row by row.
  constexpr int kRowPx = 3;
  auto rows_agree = [&](int c, std::size_t i, const Sums& lw, const Sums& rw) {
    std::int64_t ql[3], qr[3];
    chroma(lw, ql);
    chroma(rw, qr);
    const int xb = x0[std::size_t(c)] + int(i);  // first column right of the boundary
    int rows = 0, agree = 0;
    for (int y = y0[std::size_t(c)]; y <= y1[std::size_t(c)]; ++y) {
      const std::int32_t* l = labels.row(y);
      const Rgb8* px = rgb.row(y);
      Sums sl, sr;
      for (int x = std::max(0, xb - kRowPx); x < xb; ++x)
        if (l[x] == c) ++sl.n, sl.r += px[x].r, sl.g += px[x].g, sl.b += px[x].b;
      for (int x = xb; x < std::min(w, xb + kRowPx); ++x)
        if (l[x] == c) ++sr.n, sr.r += px[x].r, sr.g += px[x].g, sr.b += px[x].b;
      if (sl.n == 0 || sr.n == 0) continue;
      ++rows;
      std::int64_t a[3], b[3];
      chroma(sl, a);
      chroma(sr, b);
      agree += dist2(a, ql) < dist2(a, qr) && dist2(b, qr) < dist2(b, ql);
    }
    return rows > 0 ? double(agree) / double(rows) : 0.0;
  };
  std::vector<std::uint8_t> starts(cols.size(), 0);  // 1: a new piece of its label starts at this column
  bool any = false;
  for (int c = 1; c <= count; ++c) {
    const std::size_t o = off[std::size_t(c)], nc = off[std::size_t(c) + 1] - o;
    if (nc < 2 * std::size_t(std::max(1, min_width))) continue;
    std::vector<Sums> pre(nc + 1);  // sums of columns [0, i)
    for (std::size_t i = 0; i < nc; ++i) {
      const Sums& s = cols[o + i];
      pre[i + 1] = {pre[i].n + s.n, pre[i].r + s.r, pre[i].g + s.g, pre[i].b + s.b};
    }
    auto range = [&](std::size_t a, std::size_t b) {
      return Sums{pre[b].n - pre[a].n, pre[b].r - pre[a].r, pre[b].g - pre[a].g, pre[b].b - pre[a].b};
    };
    // Breadth first over the parts: the whole label, then the two sides of each cut.
    std::vector<std::array<std::size_t, 2>> parts{{0, nc}};
    int cuts = 0;
    for (std::size_t k = 0; k < parts.size() && cuts < max_cuts; ++k) {
      const std::size_t a = parts[k][0], b = parts[k][1];
      const std::size_t mw = std::size_t(std::max(1, min_width));
      if (b - a < 2 * mw) continue;
      // Candidate boundaries at or above the threshold, strongest first (ties: the leftmost); the first
      // that passes the row test is cut.
      std::vector<std::pair<std::int64_t, std::size_t>> cand;
      for (std::size_t i = a + mw; i + mw <= b; ++i) {
        if (range(a, i).n < min_px || range(i, b).n < min_px) continue;
        const Sums left = range(i - std::min(i - a, std::size_t(window)), i);
        const Sums right = range(i, std::min(b, i + std::size_t(window)));
        if (left.n == 0 || right.n == 0) continue;
        const std::int64_t step = chroma_step(left, right);
        if (step >= threshold) cand.push_back({-step, i});
      }
      std::sort(cand.begin(), cand.end());
      std::size_t best_i = 0;
      bool found = false;
      for (const auto& [neg_step, i] : cand) {
        const Sums left = range(i - std::min(i - a, std::size_t(window)), i);
        const Sums right = range(i, std::min(b, i + std::size_t(window)));
        if (min_rows <= 0 || rows_agree(c, i, left, right) >= min_rows) {
          best_i = i;
          found = true;
          break;
        }
      }
      if (!found) continue;
      starts[o + best_i] = 1;
      any = true;
      ++cuts;
      parts.push_back({a, best_i});
      parts.push_back({best_i, b});
    }
  }
  if (!any) {
    if (out_count) *out_count = count;
    return labels;
  }
  // Key per (label, column): 1 + the column index (in cols) where its piece starts.
  std::vector<std::int32_t> key(cols.size(), 0);
  for (int c = 1; c <= count; ++c) {
    const std::size_t o = off[std::size_t(c)], nc = off[std::size_t(c) + 1] - o;
    std::int32_t k = std::int32_t(o) + 1;
    for (std::size_t i = 0; i < nc; ++i) {
      if (starts[o + i]) k = std::int32_t(o + i) + 1;
      key[o + i] = k;
    }
  }
  // Pieces of a cut label with fewer than drop_share of its pixels are dropped: a sliver of background
  // the matcher attached to the obstacle's side (it has the background's colour, not a neighbour's).
  std::vector<std::uint8_t> drop(cols.size() + 2, 0);
  if (drop_share > 0) {
    std::vector<std::int64_t> piece_px(cols.size() + 2, 0);
    for (int c = 1; c <= count; ++c) {
      const std::size_t o = off[std::size_t(c)], nc = off[std::size_t(c) + 1] - o;
      std::int64_t total = 0;
      for (std::size_t i = 0; i < nc; ++i) piece_px[std::size_t(key[o + i])] += cols[o + i].n, total += cols[o + i].n;
      for (std::size_t i = 0; i < nc; ++i)
        drop[std::size_t(key[o + i])] = double(piece_px[std::size_t(key[o + i])]) < drop_share * double(total);
    }
  }
  for (auto& k : key)
    if (drop[std::size_t(k)]) k = 0;
  return renumber_column_keys(labels, count, off, x0, key, cols.size() + 2, out_count);
}

}  // namespace fs::detect
