// Densification after ESR (not in the paper; choice and measurements in docs/algorithm.md):
// speckle removal, then an 8-direction median fill of every pixel without an estimate.
// All disparities are Q4 (kDispShift); integer arithmetic only, so every platform and the test's
// brute-force reference produce identical maps.
#include <algorithm>
#include <array>
#include <cstdlib>
#include <vector>

#include "fuzzystereo/stages.hpp"

namespace fs {

int remove_speckles(ImageI16& disp, int max_size, int max_diff_q4, ImageU8* removed) {
  const int w = disp.width, h = disp.height;
  if (max_size <= 0 || disp.empty()) return 0;
  // 4-connected components of valid pixels whose neighbours differ by <= max_diff_q4 (the rule of
  // OpenCV's filterSpeckles, which fs_core cannot call); components of <= max_size pixels go.
  std::vector<std::int32_t> label(static_cast<std::size_t>(w) * h, -1);
  std::vector<std::int32_t> stack, members;
  stack.reserve(1024);
  members.reserve(1024);
  int count = 0;
  for (int start = 0; start < w * h; ++start) {
    if (label[start] >= 0 || disp.data[start] == kInvalidDisp) continue;
    label[start] = start;
    stack.assign(1, start);
    members.clear();
    while (!stack.empty()) {
      const int p = stack.back();
      stack.pop_back();
      members.push_back(p);
      const int x = p % w, y = p / w;
      const int d = disp.data[p];
      auto visit = [&](int q) {
        if (label[q] >= 0) return;
        const int dq = disp.data[q];
        if (dq == kInvalidDisp || std::abs(dq - d) > max_diff_q4) return;
        label[q] = start;
        stack.push_back(q);
      };
      if (x > 0) visit(p - 1);
      if (x + 1 < w) visit(p + 1);
      if (y > 0) visit(p - w);
      if (y + 1 < h) visit(p + w);
    }
    if (static_cast<int>(members.size()) <= max_size) {
      for (int p : members) {
        disp.data[p] = kInvalidDisp;
        if (removed) removed->data[p] = 1;
        ++count;
      }
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

// One ray plane: nearest valid value met walking against (dy, dx), kNone if none.
void scan_ray(const ImageI16& d, int dy, int dx, std::int16_t* out) {
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
  for (int y = y0; y != y_end; y += dy) {
    const std::int16_t* s = d.row(y);
    std::int16_t* o = out + static_cast<std::size_t>(y) * w;
    if (!prev_row) {
      for (int x = 0; x < w; ++x) o[x] = s[x] != kInvalidDisp ? s[x] : kNone;
    } else {
      // interior: o[x] = s[x] valid ? s[x] : prev_row[x - dx]; the column whose source lies
      // outside the image has none.
      const int x_lo = std::max(0, dx), x_hi = std::min(w, w + dx);
      for (int x = 0; x < x_lo; ++x) o[x] = s[x] != kInvalidDisp ? s[x] : kNone;
      for (int x = x_lo; x < x_hi; ++x) o[x] = s[x] != kInvalidDisp ? s[x] : prev_row[x - dx];
      for (int x = x_hi; x < w; ++x) o[x] = s[x] != kInvalidDisp ? s[x] : kNone;
    }
    prev_row = o;
  }
}

}  // namespace

ImageI16 median_fill(const ImageI16& disp, ImageU8* filled) {
  const int w = disp.width, h = disp.height;
  ImageI16 out = disp;
  if (filled) *filled = ImageU8(w, h, 0);
  if (disp.empty()) return out;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  std::vector<std::int16_t> rays(8 * n);
  for (int k = 0; k < 8; ++k) scan_ray(disp, kDirs[k][0], kDirs[k][1], rays.data() + k * n);
  std::vector<std::int16_t> sorted(8 * static_cast<std::size_t>(w));
  for (int y = 0; y < h; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * w;
    std::int16_t* c[8];
    for (int k = 0; k < 8; ++k) {
      c[k] = sorted.data() + static_cast<std::size_t>(k) * w;
      std::copy_n(rays.data() + k * n + row, w, c[k]);
    }
    for (const auto& e : kSort8) {
      std::int16_t* a = c[e[0]];
      std::int16_t* b = c[e[1]];
      for (int x = 0; x < w; ++x) {
        const std::int16_t lo = std::min(a[x], b[x]), hi = std::max(a[x], b[x]);
        a[x] = lo;
        b[x] = hi;
      }
    }
    const std::int16_t* from_left = rays.data() + row;
    const std::int16_t* from_right = rays.data() + n + row;
    const std::int16_t* src = disp.row(y);
    std::int16_t* o = out.row(y);
    for (int x = 0; x < w; ++x) {
      if (src[x] != kInvalidDisp) continue;
      std::int16_t v = kInvalidDisp;
      if (from_left[x] == kNone && from_right[x] != kNone) {
        // Left image border band (x < d): nothing to the left can match; extend the row's first
        // estimate, as the rays from above/below there cross unrelated, farther structure.
        v = from_right[x];
      } else {
        int m = 0;
        while (m < 8 && c[m][x] != kNone) ++m;
        if (m > 0)  // median; for an even count the mean of the two middle values, rounded half up (Q4)
          v = (m & 1) ? c[m / 2][x] : static_cast<std::int16_t>((c[m / 2 - 1][x] + c[m / 2][x] + 1) >> 1);
      }
      o[x] = v;
      if (filled && v != kInvalidDisp) filled->at(x, y) = 1;
    }
  }
  return out;
}

ImageI16 densify(const ImageI16& disp, const DensifyParams& p, ImageU8* changed) {
  ImageI16 d = disp;
  ImageU8 removed(disp.width, disp.height, 0);
  // Disparity 0 (a point at infinity) is where the segment WTA found no match inside the range
  // (sky, textureless or left-border segments); it is treated as "no estimate" and filled.
  for (std::size_t i = 0; i < d.data.size(); ++i)
    if (d.data[i] == 0) {
      d.data[i] = kInvalidDisp;
      removed.data[i] = 1;
    }
  remove_speckles(d, p.speckle_max_size, p.speckle_max_diff * kDispScale, &removed);
  ImageU8 filled;
  ImageI16 out = p.fill ? median_fill(d, &filled) : d;
  if (changed) {
    *changed = ImageU8(disp.width, disp.height, 0);
    for (std::size_t i = 0; i < out.data.size(); ++i)
      changed->data[i] = removed.data[i] ? 2 : (p.fill && filled.data[i] ? 1 : 0);
  }
  return out;
}

}  // namespace fs
