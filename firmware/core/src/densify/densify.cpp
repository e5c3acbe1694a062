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

// One ray plane: nearest valid value met walking against (dy, dx), kInvalidDisp if none.
void scan_ray(const ImageI16& d, int dy, int dx, std::int16_t* out) {
  const int w = d.width, h = d.height;
  if (dy == 0) {
    for (int y = 0; y < h; ++y) {
      const std::int16_t* s = d.row(y);
      std::int16_t* o = out + static_cast<std::size_t>(y) * w;
      std::int16_t prev = kInvalidDisp;
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
    for (int x = 0; x < w; ++x) {
      if (s[x] != kInvalidDisp) {
        o[x] = s[x];
      } else {
        const int xs = x - dx;
        o[x] = (prev_row && xs >= 0 && xs < w) ? prev_row[xs] : kInvalidDisp;
      }
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
  for (std::size_t p = 0; p < n; ++p) {
    if (disp.data[p] != kInvalidDisp) continue;
    const std::int16_t from_left = rays[p], from_right = rays[n + p];
    std::int16_t v = kInvalidDisp;
    if (from_left == kInvalidDisp && from_right != kInvalidDisp) {
      // Left image border band (x < d): nothing to the left can match; extend the row's first
      // estimate, as the rays from above/below there cross unrelated, farther structure.
      v = from_right;
    } else {
      std::array<std::int16_t, 8> c{};
      int m = 0;
      for (int k = 0; k < 8; ++k) {
        const std::int16_t r = rays[k * n + p];
        if (r != kInvalidDisp) c[m++] = r;
      }
      if (m > 0) {
        for (int i = 1; i < m; ++i)  // insertion sort: at most 8 values
          for (int j = i; j > 0 && c[j - 1] > c[j]; --j) std::swap(c[j - 1], c[j]);
        // Median; for an even count the mean of the two middle values, rounded half up (Q4).
        v = (m & 1) ? c[m / 2] : static_cast<std::int16_t>((c[m / 2 - 1] + c[m / 2] + 1) >> 1);
      }
    }
    out.data[p] = v;
    if (filled && v != kInvalidDisp) filled->data[p] = 1;
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
