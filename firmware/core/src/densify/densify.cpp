// Densification after ESR (not in the paper; choice and measurements in docs/algorithm.md):
// speckle removal, then an 8-direction median fill of every pixel without an estimate.
// All disparities are Q4 (kDispShift); integer arithmetic only, so every platform and the test's
// brute-force reference produce identical maps.
#include <algorithm>
#include <array>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <vector>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"

namespace fs {

int remove_speckles(ImageI16& disp, int max_size, int max_diff_q4, ImageU8* removed) {
  const int w = disp.width, h = disp.height;
  if (max_size <= 0 || disp.empty()) return 0;
  // 4-connected components of valid pixels whose neighbours differ by <= max_diff_q4 (the rule of
  // OpenCV's filterSpeckles, which fs_core cannot call); components of <= max_size pixels go.
  // Three passes on runs: a run is a maximal stretch of a row whose consecutive pixels connect.
  //   1. per row, in parallel: the runs;
  //   2. serial: runs numbered row by row, runs of consecutive rows joined (union-find) where a
  //      pixel connects to the one above it;
  //   3. per row, in parallel: the runs of small components set invalid.
  struct SRun {
    std::int32_t x0, x1;
  };
  std::vector<std::vector<SRun>> row_runs(static_cast<std::size_t>(h));
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < h; ++y) {
    const std::int16_t* d = disp.row(y);
    std::vector<SRun>& rr = row_runs[std::size_t(y)];
    int x = 0;
    while (x < w) {
      if (d[x] == kInvalidDisp) { ++x; continue; }
      int e = x + 1;
      while (e < w && d[e] != kInvalidDisp && std::abs(d[e] - d[e - 1]) <= max_diff_q4) ++e;
      rr.push_back({x, e});
      x = e;
    }
  }
  std::vector<std::int32_t> row_begin(std::size_t(h) + 1, 0);  // global index of a row's first run
  for (int y = 0; y < h; ++y)
    row_begin[std::size_t(y) + 1] = row_begin[std::size_t(y)] + static_cast<std::int32_t>(row_runs[std::size_t(y)].size());
  const auto nruns = static_cast<std::size_t>(row_begin.back());
  detail::MinRootUnionFind uf(nruns);
  // Runs of consecutive rows join where they overlap and one pixel of the overlap connects to the
  // one above it: the overlapping pairs are walked in order (two pointers) and each pair's overlap
  // is scanned only up to its first connecting pixel. The components, and so their roots (the
  // smallest run index), do not depend on the order of the unions.
  for (int y = 1; y < h; ++y) {
    const std::int16_t* d = disp.row(y);
    const std::int16_t* u = disp.row(y - 1);
    const std::vector<SRun>& cur = row_runs[std::size_t(y)];
    const std::vector<SRun>& above = row_runs[std::size_t(y) - 1];
    const std::int32_t base = row_begin[std::size_t(y)], base_u = row_begin[std::size_t(y) - 1];
    std::size_t j = 0;
    for (std::size_t i = 0; i < cur.size(); ++i) {
      const SRun& a = cur[i];
      while (j < above.size() && above[j].x1 <= a.x0) ++j;  // runs above ending before a
      for (std::size_t k = j; k < above.size() && above[k].x0 < a.x1; ++k) {
        const int x0 = std::max(a.x0, above[k].x0), x1 = std::min(a.x1, above[k].x1);
        for (int x = x0; x < x1; ++x)
          if (std::abs(d[x] - u[x]) <= max_diff_q4) {
            uf.unite(base + static_cast<std::int32_t>(i), base_u + static_cast<std::int32_t>(k));
            break;
          }
      }
    }
  }
  std::vector<std::int32_t> parent(nruns);  // each run's root
  std::vector<std::int32_t> size(nruns, 0);
  for (int y = 0; y < h; ++y) {
    const std::vector<SRun>& rr = row_runs[std::size_t(y)];
    for (std::size_t k = 0; k < rr.size(); ++k) {
      const std::size_t i = std::size_t(row_begin[std::size_t(y)]) + k;
      parent[i] = uf.find(static_cast<std::int32_t>(i));
      size[std::size_t(parent[i])] += rr[k].x1 - rr[k].x0;
    }
  }
  int count = 0;
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static) reduction(+ : count)
#endif
  for (int y = 0; y < h; ++y) {
    std::int16_t* d = disp.row(y);
    const std::vector<SRun>& rr = row_runs[std::size_t(y)];
    for (std::size_t k = 0; k < rr.size(); ++k) {
      const std::size_t i = std::size_t(row_begin[std::size_t(y)]) + k;
      if (size[std::size_t(parent[i])] > max_size) continue;
      const SRun& r = rr[k];
      std::fill(d + r.x0, d + r.x1, kInvalidDisp);
      if (removed) std::fill(removed->row(y) + r.x0, removed->row(y) + r.x1, std::uint8_t(1));
      count += r.x1 - r.x0;
    }
  }
  return count;
}

namespace {

// Directions (dy, dx) of the 8 rays; ray k of pixel p holds the first valid disparity met walking
// from p against (dy, dx), p itself included. Index 0 = from the left, 1 = from the right.
constexpr std::array<std::array<int, 2>, 8> kDirs{{{0, 1}, {0, -1}, {1, 0}, {-1, 0}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}}};
// "No estimate" inside the ray planes: larger than any Q4 disparity, so it sorts last.
constexpr std::int16_t kNone = 32767;
// An optimal sorting network for 8 values (19 compare-exchanges, Knuth TAOCP 5.3.4); branch-free,
// so the compiler vectorises it across a row.
constexpr std::array<std::array<int, 2>, 19> kSort8{{{0, 2}, {1, 3}, {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7},
                                                     {0, 1}, {2, 3}, {4, 5}, {6, 7}, {2, 4}, {3, 5}, {1, 4}, {3, 6},
                                                     {1, 2}, {3, 4}, {5, 6}}};

// One interior row of a ray plane with a vertical step: o[x] = s[x] valid ? s[x] : prev[x - dx] (and its
// step count t[x] = 0 : tprev[x - dx] + 1) for x in [x_lo, x_hi). Restrict-qualified so it vectorises.
void ray_row(const std::int16_t* __restrict s, const std::int16_t* __restrict prev, std::int16_t* __restrict o,
             int x_lo, int x_hi, int dx) {
  for (int x = x_lo; x < x_hi; ++x) {
    const std::int16_t v = s[x], p = prev[x - dx];  // both loaded: a select, not a branch
    o[x] = v != kInvalidDisp ? v : p;
  }
}
void step_row(const std::int16_t* __restrict s, const std::int16_t* __restrict tprev, std::int16_t* __restrict t,
              int x_lo, int x_hi, int dx) {
  for (int x = x_lo; x < x_hi; ++x) {
    const std::int16_t v = s[x], p = static_cast<std::int16_t>(tprev[x - dx] + 1);
    t[x] = v != kInvalidDisp ? std::int16_t(0) : p;
  }
}

// One ray plane: nearest valid value met walking against (dy, dx), kNone if none. dist (optional,
// rays with a vertical step; median_fill keeps the two horizontal rays in row buffers): the number
// of steps to that value (0 on a valid pixel; undefined where the value is kNone).
void scan_ray(const ImageI16& d, int dy, int dx, std::int16_t* out, std::int16_t* dist) {
  const int w = d.width, h = d.height;
  if (dy == 0) {
    for (int y = 0; y < h; ++y) {
      const std::int16_t* s = d.row(y);
      std::int16_t* o = out + static_cast<std::size_t>(y) * w;
      std::int16_t prev = kNone;
      if (dx > 0) {
        for (int x = 0; x < w; ++x) o[x] = prev = (s[x] != kInvalidDisp ? s[x] : prev);
      } else {
        for (int x = w - 1; x >= 0; --x) o[x] = prev = (s[x] != kInvalidDisp ? s[x] : prev);
      }
    }
    return;
  }
  const int y0 = dy > 0 ? 0 : h - 1, y_end = dy > 0 ? h : -1;
  const std::int16_t* prev_row = nullptr;
  const std::int16_t* prev_dist = nullptr;
  for (int y = y0; y != y_end; y += dy) {
    const std::int16_t* s = d.row(y);
    std::int16_t* o = out + static_cast<std::size_t>(y) * w;
    std::int16_t* t = dist ? dist + static_cast<std::size_t>(y) * w : nullptr;
    if (!prev_row) {
      for (int x = 0; x < w; ++x) o[x] = s[x] != kInvalidDisp ? s[x] : kNone;
      if (t) std::fill(t, t + w, std::int16_t(0));
    } else {
      // interior: o[x] = s[x] valid ? s[x] : prev_row[x - dx]; the column whose source lies
      // outside the image has none.
      const int x_lo = std::max(0, dx), x_hi = std::min(w, w + dx);
      for (int x = 0; x < x_lo; ++x) o[x] = s[x] != kInvalidDisp ? s[x] : kNone;
      ray_row(s, prev_row, o, x_lo, x_hi, dx);
      for (int x = x_hi; x < w; ++x) o[x] = s[x] != kInvalidDisp ? s[x] : kNone;
      if (t) {
        for (int x = 0; x < x_lo; ++x) t[x] = 0;
        step_row(s, prev_dist, t, x_lo, x_hi, dx);
        for (int x = x_hi; x < w; ++x) t[x] = 0;
      }
    }
    prev_row = o;
    prev_dist = t;
  }
}

// Slant-aware fill, one pair of opposite rays over the m gathered pixels: where the two values are
// on one surface (within max_diff_q4) both take the linear interpolation at the pixel,
// (a*tb + b*ta) / (ta + tb) rounded half up (Q4): q = floor(M / d), M = 2 (a*tb + b*ta) + s,
// d = 2 s, s = ta + tb. Bounds: a, b < 2^12 (Q4 of a disparity < 256), ta, tb < 2^15, so M < 2^31
// (int32). No integer division (it was most of the fill's cost): q0 = trunc(M / d) in float has
// a relative error <= 2^-23 (M rounded, then one correctly rounded division), so for q < 2^12 it
// is off by at most 1, and one correction step each way makes it exact. Every load is
// unconditional and the test uses & (not &&), so the loop vectorises (AVX2 clone on x86-64: SSE2
// has no 32-bit multiply).
FS_TARGET_CLONES_V4
void interpolate_pair(std::int16_t* __restrict a, std::int16_t* __restrict b, const std::int16_t* __restrict ta,
                      const std::int16_t* __restrict tb, int m, int max_diff_q4) {
  for (int i = 0; i < m; ++i) {
    const std::int32_t va = a[i], vb = b[i], ra = ta[i], rb = tb[i];
    const std::int32_t diff = va - vb;
    const bool ok = (va != kNone) & (vb != kNone) & (diff <= max_diff_q4) & (-diff <= max_diff_q4);
    const std::int32_t wa = ok ? ra : 0, wb = ok ? rb : 0, sum = ok ? wa + wb : 1, d = 2 * sum;
    const std::int32_t M = 2 * ((ok ? va : 0) * wb + (ok ? vb : 0) * wa) + sum;
    std::int32_t q = static_cast<std::int32_t>(static_cast<float>(M) / static_cast<float>(d));
    q = (q + 1) * d <= M ? q + 1 : q;
    q = q * d > M ? q - 1 : q;
    a[i] = static_cast<std::int16_t>(ok ? q : va);
    b[i] = static_cast<std::int16_t>(ok ? q : vb);
  }
}

// Slant-aware fill: the pairs of opposite rays in median_fill's slot order (left/right, above/below,
// upper-left/lower-right, upper-right/lower-left; kDirs indices).
constexpr std::array<std::array<int, 2>, 4> kOpposite{{{0, 1}, {2, 3}, {4, 7}, {5, 6}}};

}  // namespace

// The six rays with a vertical step are stored as planes (independent scans, run in parallel); the
// two horizontal rays are row buffers. Per row, the 8 ray values of the pixels without an estimate
// are gathered into 8 short arrays and sorted there by the network (vectorised across pixels), so
// valid pixels cost nothing. Rows are then independent and filled in parallel.
ImageI16 median_fill(const ImageI16& disp, ImageU8* filled, int interp_max_diff_q4) {
  const int w = disp.width, h = disp.height;
  ImageI16 out = disp;
  if (filled) *filled = ImageU8(w, h, 0);
  if (disp.empty()) return out;
  const std::size_t n = static_cast<std::size_t>(w) * h, uw = static_cast<std::size_t>(w);
  // Planes j = 0..5 hold the rays kDirs[j + 2] (dy = +1 for kDirs 2, 4, 5; dy = -1 for 3, 6, 7).
  const bool interp = interp_max_diff_q4 > 0;
  // Every element is written by scan_ray, so the planes are not zero-filled first (std::vector
  // would: ~1 ms per KITTI frame). steps: int16, w and h < 32768.
  const std::unique_ptr<std::int16_t[]> rays_buf(new std::int16_t[6 * n]);
  const std::unique_ptr<std::int16_t[]> steps_buf(interp ? new std::int16_t[6 * n] : nullptr);
  std::int16_t* const rays = rays_buf.get();
  std::int16_t* const steps = steps_buf.get();
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int j = 0; j < 6; ++j)
    scan_ray(disp, kDirs[std::size_t(j) + 2][0], kDirs[std::size_t(j) + 2][1], rays + std::size_t(j) * n,
             interp ? steps + std::size_t(j) * n : nullptr);
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel
#endif
  {
    std::vector<std::int16_t> horiz(2 * uw), c(8 * uw), hsteps(interp ? 2 * uw : 0), tg(interp ? 8 * uw : 0);
    std::vector<std::int32_t> idx(uw);
    std::vector<std::array<int, 2>> hole_runs(uw);  // [x0, x1) of each run of holes in the row
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(static)
#endif
    for (int y = 0; y < h; ++y) {
      const std::int16_t* src = disp.row(y);
      std::int16_t* from_left = horiz.data();
      std::int16_t* from_right = horiz.data() + uw;
      std::int16_t prev = kNone;
      // The two horizontal rays (and, for the slant-aware fill, their step counts).
      std::int16_t* left_steps = hsteps.data();
      std::int16_t* right_steps = hsteps.data() + (interp ? uw : 0);
      std::int16_t pt = 0;
      for (int x = 0; x < w; ++x) {
        const bool ok = src[x] != kInvalidDisp;
        from_left[x] = prev = ok ? src[x] : prev;
        if (interp) left_steps[x] = pt = ok ? std::int16_t(0) : static_cast<std::int16_t>(pt + 1);
      }
      prev = kNone;
      pt = 0;
      for (int x = w - 1; x >= 0; --x) {
        const bool ok = src[x] != kInvalidDisp;
        from_right[x] = prev = ok ? src[x] : prev;
        if (interp) right_steps[x] = pt = ok ? std::int16_t(0) : static_cast<std::int16_t>(pt + 1);
      }
      // Gather the pixels without an estimate (the left border band takes its own rule).
      const std::size_t row = static_cast<std::size_t>(y) * uw;
      std::int16_t* o = out.row(y);
      // Holes come in runs along the row (those of the left border band are a prefix: the invalid
      // pixels before the row's first estimate), so the ray values are gathered run by run, one
      // contiguous copy per run and plane, in the order of idx.
      int m = 0, nh = 0;
      for (int x = 0; x < w;) {
        if (src[x] != kInvalidDisp) { ++x; continue; }
        if (from_left[x] == kNone && from_right[x] != kNone) {
          // Left image border band (x < d): nothing to the left can match; extend the row's first
          // estimate, as the rays from above/below there cross unrelated, farther structure.
          o[x] = from_right[x];
          if (filled) filled->at(x, y) = 1;
          ++x;
          continue;
        }
        int e = x + 1;  // a run of holes (none of them in the border band: that ends at x)
        while (e < w && src[e] == kInvalidDisp) ++e;
        hole_runs[std::size_t(nh++)] = {x, e};
        for (; x < e; ++x) idx[std::size_t(m++)] = x;
      }
      if (m == 0) continue;
      auto gather = [&](const std::int16_t* plane, std::int16_t* dst) {
        for (int r = 0; r < nh; ++r) {
          const auto [x0, x1] = hole_runs[std::size_t(r)];
          dst = std::copy(plane + x0, plane + x1, dst);
        }
      };
      const std::int16_t* planes[8] = {from_left,         from_right,        rays + row,
                                       rays + n + row, rays + 2 * n + row, rays + 3 * n + row,
                                       rays + 4 * n + row, rays + 5 * n + row};
      std::int16_t* cc[8];
      for (int k = 0; k < 8; ++k) {
        cc[k] = c.data() + std::size_t(k) * uw;
        gather(planes[k], cc[k]);
      }
      if (interp) {
        // Opposite rays on one surface: both slots take their interpolation (interpolate_pair).
        const std::int16_t* tplanes[8] = {left_steps, right_steps, steps + row, steps + n + row,
                                          steps + 2 * n + row, steps + 3 * n + row,
                                          steps + 4 * n + row, steps + 5 * n + row};
        for (int k = 0; k < 8; ++k) gather(tplanes[k], tg.data() + std::size_t(k) * uw);
        for (const auto& pr : kOpposite) {
          std::int16_t* __restrict a = cc[pr[0]];
          std::int16_t* __restrict b = cc[pr[1]];
          const std::int16_t* __restrict ta = tg.data() + std::size_t(pr[0]) * uw;
          const std::int16_t* __restrict tb = tg.data() + std::size_t(pr[1]) * uw;
          interpolate_pair(a, b, ta, tb, m, interp_max_diff_q4);
        }
      }
      for (const auto& e : kSort8) {
        std::int16_t* a = cc[e[0]];
        std::int16_t* b = cc[e[1]];
        for (int i = 0; i < m; ++i) {
          const std::int16_t lo = std::min(a[i], b[i]), hi = std::max(a[i], b[i]);
          a[i] = lo;
          b[i] = hi;
        }
      }
      for (int i = 0; i < m; ++i) {
        int cnt = 0;
        while (cnt < 8 && cc[cnt][i] != kNone) ++cnt;
        std::int16_t v = kInvalidDisp;
        if (cnt > 0)  // median; for an even count the mean of the two middle values, rounded half up (Q4)
          v = (cnt & 1) ? cc[cnt / 2][i] : static_cast<std::int16_t>((cc[cnt / 2 - 1][i] + cc[cnt / 2][i] + 1) >> 1);
        const int x = idx[std::size_t(i)];
        o[x] = v;
        if (filled && v != kInvalidDisp) filled->at(x, y) = 1;
      }
    }
  }
  return out;
}

// The right map is the right-reference WTA map (dense but for segments without a candidate); a
// left pixel is "seen" when some right pixel's disparity lands on it, within `dilate` px.
// Rows are independent.
int occlusion_fill(ImageI16& disp, const ImageI16& disp_right, int dilate, int max_gap, ImageU8* filled) {
  const int w = disp.width, h = disp.height;
  if (disp_right.width != w || disp_right.height != h)
    throw std::invalid_argument("occlusion_fill: the right map must have the size of the left map");
  if (filled && (filled->width != w || filled->height != h))
    throw std::invalid_argument("occlusion_fill: the filled mask must have the size of the map");
  int count = 0;
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel reduction(+ : count)
#endif
  {
    // cover[x]: number of right pixels landing within `dilate` px of left pixel x (a difference
    // array: +1 where a landing's window starts, -1 past its end; the prefix sum is the count).
    std::vector<std::int32_t> cover(std::size_t(w) + 1);
#if defined(FS_HAVE_OPENMP)
#pragma omp for schedule(static)
#endif
    for (int y = 0; y < h; ++y) {
      std::fill(cover.begin(), cover.end(), 0);
      const std::int16_t* r = disp_right.row(y);
      for (int xr = 0; xr < w; ++xr) {  // right pixel xr sees left pixel xr + round(d_r)
        if (r[xr] == kInvalidDisp) continue;
        const int x = xr + ((r[xr] + kDispScale / 2) >> kDispShift);
        if (x < 0 || x >= w) continue;  // lands outside the image
        const int lo = std::max(0, x - dilate), hi = std::min(w - 1, x + dilate);
        ++cover[std::size_t(lo)];
        --cover[std::size_t(hi) + 1];
      }
      for (int x = 1; x < w; ++x) cover[std::size_t(x)] += cover[std::size_t(x) - 1];
      std::int16_t* d = disp.row(y);
      std::uint8_t* f = filled ? filled->row(y) : nullptr;
      // Holes come in runs between estimates; a run is filled (its seen pixels excepted) from the
      // estimates that bound it, read before anything in the row is written.
      int x = 0;
      while (x < w) {
        if (d[x] != kInvalidDisp) { ++x; continue; }
        int e = x + 1;
        while (e < w && d[e] == kInvalidDisp) ++e;  // holes [x, e)
        const std::int16_t left = x > 0 ? d[x - 1] : kInvalidDisp;
        const std::int16_t right = e < w ? d[e] : kInvalidDisp;
        if (e - x <= max_gap && (left != kInvalidDisp || right != kInvalidDisp)) {
          const std::int16_t bg = left == kInvalidDisp ? right : (right == kInvalidDisp ? left : std::min(left, right));
          for (int k = x; k < e; ++k) {
            if (cover[std::size_t(k)] > 0) continue;
            d[k] = bg;
            if (f) f[k] = 1;
            ++count;
          }
        }
        x = e;
      }
    }
  }
  return count;
}

// Left border band, docs/algorithm.md 6f. Columns count from x0 (u = x - x0; images up to 8192 wide)
// and the window holds at most 256 columns, so int64 is exact throughout: S_d < 2^23 (Q4 d < 2^15),
// den = n^2 var(u) <= 2^16 * 255^2 / 4 < 2^30, |bnum| = n^2 |cov(u, d)| <= sqrt(den) n 2^14 < 2^38
// (Cauchy-Schwarz, std(d) < 2^14) and |n u - S_u| < 2^22, so the numerator S_d den + bnum (n u - S_u)
// < 2^61 and 2 num + n den < 2^63; the rounding is exact and the same on every platform.
int extrapolate_left_border(ImageI16& out, const ImageI16& before, int window_px, int cap_q4, double min_slope_q4) {
  if (window_px <= 0) return 0;
  if (window_px > 256) throw std::invalid_argument("extrapolate_left_border: window above 256 columns");
  if (before.width != out.width || before.height != out.height)
    throw std::invalid_argument("extrapolate_left_border: maps of different sizes");
  const int w = before.width, h = before.height;
  const int min_n = std::max(3, window_px / 4);
  int rows = 0;
  for (int y = 0; y < h; ++y) {
    const std::int16_t* b = before.row(y);
    int x0 = 0;
    while (x0 < w && b[x0] == kInvalidDisp) ++x0;
    if (x0 == 0 || x0 == w) continue;
    std::int64_t n = 0, su = 0, sd = 0, suu = 0, sud = 0;
    for (int x = x0; x < std::min(w, x0 + window_px); ++x) {
      if (b[x] == kInvalidDisp) continue;
      const std::int64_t u = x - x0;
      ++n;
      su += u;
      sd += b[x];
      suu += u * u;
      sud += u * b[x];
    }
    if (n < min_n) continue;
    const std::int64_t den = n * suu - su * su;   // n^2 var(u) > 0 (>= 3 distinct columns)
    const std::int64_t bnum = n * sud - su * sd;  // slope b = bnum / den [Q4 per column]
    if (den <= 0 || bnum >= 0) continue;          // flat or falling towards the border: keep the fill
    if (min_slope_q4 > 0 && -static_cast<double>(bnum) < min_slope_q4 * static_cast<double>(den)) continue;
    std::int16_t* o = out.row(y);
    const std::int64_t dd = n * den, q2 = 2 * dd;  // > 0
    for (int x = 0; x < x0; ++x) {
      // d(u) = S_d / n + b (u - S_u / n) = (S_d den + bnum (n u - S_u)) / (n den), rounded half up (floor of
      // (2 num + dd) / (2 dd); num > 0 here: b < 0 and u < 0 <= S_u / n)
      const std::int64_t u = x - x0;
      const std::int64_t num = sd * den + bnum * (n * u - su);
      const std::int64_t t = 2 * num + dd;
      std::int64_t q = t >= 0 ? t / q2 : -((-t + q2 - 1) / q2);
      if (cap_q4 > 0) q = std::min<std::int64_t>(q, cap_q4);
      o[x] = static_cast<std::int16_t>(std::clamp<std::int64_t>(q, 0, 32767));
    }
    ++rows;
  }
  return rows;
}

ImageI16 densify(const ImageI16& disp, const DensifyParams& p, ImageU8* changed, const ImageI16* disp_right,
                 int max_disparity) {
  const auto n = static_cast<std::ptrdiff_t>(disp.data.size());
  ImageI16 d(disp.width, disp.height);
  ImageU8 removed(disp.width, disp.height);
  // Disparity 0 (a point at infinity) is where the segment WTA found no match inside the range
  // (sky, textureless or left-border segments); it is treated as "no estimate" and filled.
  // Element-wise, branch-free passes (vectorised, split between threads).
  {
    const std::int16_t* __restrict src = disp.data.data();
    std::int16_t* __restrict dst = d.data.data();
    std::uint8_t* __restrict rm = removed.data.data();
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for simd schedule(static)
#endif
    for (std::ptrdiff_t i = 0; i < n; ++i) {
      const bool zero = src[i] == 0;
      dst[i] = zero ? kInvalidDisp : src[i];
      rm[i] = zero ? 1 : 0;
    }
  }
  if (p.occlusion_fill && !disp_right)
    throw std::invalid_argument("densify: occlusion_fill needs the right-reference map (disp_right)");
  remove_speckles(d, p.speckle_max_size, p.speckle_max_diff * kDispScale, &removed);
  ImageU8 occ_filled;  // only for `changed`
  if (p.occlusion_fill) {
    if (changed) occ_filled = ImageU8(disp.width, disp.height, 0);
    occlusion_fill(d, *disp_right, p.occlusion_dilate, p.occlusion_max_gap, changed ? &occ_filled : nullptr);
  }
  ImageU8 filled;
  ImageI16 out = p.fill ? median_fill(d, &filled, p.interpolate_max_diff * kDispScale) : d;
  if (p.fill && p.border_fit_px > 0)
    extrapolate_left_border(out, d, p.border_fit_px, max_disparity > 0 ? (max_disparity - 1) * kDispScale : 0,
                            p.border_fit_min_slope * kDispScale);
  if (p.smooth) out = smooth_disparity(out, p.smoothing);
  if (changed) {
    *changed = ImageU8(disp.width, disp.height);
    const std::uint8_t* __restrict rm = removed.data.data();
    const std::uint8_t* __restrict fl = p.fill ? filled.data.data() : rm;  // not read unless p.fill
    std::uint8_t* __restrict ch = changed->data.data();
    const bool fill = p.fill;
    const bool occ = !occ_filled.empty();
    const std::uint8_t* __restrict oc = occ ? occ_filled.data.data() : rm;  // not read unless occ
#if defined(FS_HAVE_OPENMP)
#pragma omp parallel for simd schedule(static)
#endif
    for (std::ptrdiff_t i = 0; i < n; ++i) ch[i] = (occ && oc[i]) ? 1 : (rm[i] ? 2 : ((fill && fl[i]) ? 1 : 0));
  }
  return out;
}

}  // namespace fs
