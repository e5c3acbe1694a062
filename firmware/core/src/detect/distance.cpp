// Obstacle boxes, distance and class (paper Section III-B, Fig. 22: nearest obstacles in red,
// slightly farther in green, farthest in blue). Distance from the disparity: Z = f*B/d with d the
// median Q4 disparity of the component (robust to the few pixels of road or background the
// component may have picked up at its edges); lateral X = (u_c - cx) * Z / f with u_c the centre
// column of the box. The class limits near_m / far_m are configurable (the paper gives none).
#include <algorithm>
#include <cstdlib>
#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

ObstacleClass classify_distance(double z_m, const DetectParams& p) {
  if (z_m < p.near_m) return ObstacleClass::Near;
  if (z_m >= p.far_m) return ObstacleClass::Far;
  return ObstacleClass::Mid;
}

std::vector<Obstacle> measure_obstacles(const ImageI32& components, int count, const ImageI16& disp,
                                        const StereoCalib& calib, const DetectParams& p, ImageI32* labels) {
  struct Acc {
    int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1, n = 0, first = 0;
    std::vector<std::int16_t> d;
  };
  std::vector<Acc> acc(std::size_t(count) + 1);
  for (int y = 0; y < components.height; ++y) {
    const std::int32_t* l = components.row(y);
    const std::int16_t* d = disp.row(y);
    for (int x = 0; x < components.width; ++x) {
      if (l[x] == 0) continue;
      Acc& a = acc[std::size_t(l[x])];
      a.x0 = std::min(a.x0, x), a.y0 = std::min(a.y0, y), a.x1 = std::max(a.x1, x), a.y1 = std::max(a.y1, y);
      ++a.n;
      a.d.push_back(d[x]);
    }
  }
  // Fragment merging (our addition, docs/detection.md "(e)"): components whose boxes, grown by
  // merge_gap_px, overlap and whose median disparities differ by <= merge_max_rel_disparity of the
  // larger one are parts of one obstacle (holes and dark texture split a surface). Single linkage
  // over the components' own boxes and medians, union-find with the smaller label as root.
  std::vector<int> med(std::size_t(count) + 1, 0);
  for (int c = 1; c <= count; ++c) {
    Acc& a = acc[std::size_t(c)];
    if (a.n == 0) continue;
    const std::size_t mid = (a.d.size() - 1) / 2;  // lower median
    std::nth_element(a.d.begin(), a.d.begin() + std::ptrdiff_t(mid), a.d.end());
    med[std::size_t(c)] = a.d[mid];
  }
  std::vector<int> parent(std::size_t(count) + 1);
  for (int c = 0; c <= count; ++c) parent[std::size_t(c)] = c;
  auto find = [&](int c) {
    while (parent[std::size_t(c)] != c) c = parent[std::size_t(c)] = parent[std::size_t(parent[std::size_t(c)])];
    return c;
  };
  auto unite = [&](int c1, int c2) {  // the smaller root stays the root
    const int r1 = find(c1), r2 = find(c2);
    if (r1 != r2) parent[std::size_t(std::max(r1, r2))] = std::min(r1, r2);
  };
  if (p.merge_gap_px >= 0 && p.merge_max_rel_disparity > 0) {
    const int g = p.merge_gap_px, gv = std::max(p.merge_gap_px, p.merge_gap_vertical_px);
    struct Pair {
      std::int64_t num, den;  // |m1 - m2| / max(m1, m2) as an exact fraction (order of the complete linkage)
      int c1, c2;
    };
    std::vector<Pair> pairs;
    for (int c1 = 1; c1 <= count; ++c1) {
      const Acc& a = acc[std::size_t(c1)];
      if (a.n == 0) continue;
      for (int c2 = c1 + 1; c2 <= count; ++c2) {
        const Acc& b = acc[std::size_t(c2)];
        if (b.n == 0 || b.x0 > a.x1 + g || a.x0 > b.x1 + g || b.y0 > a.y1 + gv || a.y0 > b.y1 + gv) continue;
        const int m1 = med[std::size_t(c1)], m2 = med[std::size_t(c2)];
        if (std::abs(m1 - m2) > p.merge_max_rel_disparity * std::max(m1, m2)) continue;
        if (p.merge_group_max_rel <= 0 && p.merge_bridge_max_px <= 0) {  // single linkage (order-free)
          unite(c1, c2);
        } else {
          pairs.push_back({std::abs(m1 - m2), std::max<std::int64_t>(1, std::max(m1, m2)), c1, c2});
        }
      }
    }
    // No depth bridges (session 10, docs/detection.md "(e) Fragment merging"): single linkage, but a
    // component with fewer than merge_bridge_max_px pixels ("small") may close a gap in the image between
    // larger components, not a gap in depth. The large components link among themselves and the small ones
    // among themselves, as before; then each group of small ones joins its anchor, the large component it
    // has the closest pair with (|m1 - m2| / max, exact fractions; ties: the smaller label), and every other
    // large component it has a pair with whose median is within merge_max_rel_disparity of the anchor's.
    // So small fragments at intermediate depths (the matcher's ramp between two obstacles 15-25 % apart,
    // each piece within 10 % of the next) no longer chain the two obstacles into one box. Component
    // medians only: the joins do not depend on their order.
    if (p.merge_group_max_rel <= 0 && p.merge_bridge_max_px > 0) {
      auto big = [&](int c) { return acc[std::size_t(c)].n >= p.merge_bridge_max_px; };
      for (const Pair& q : pairs)
        if (big(q.c1) == big(q.c2)) unite(q.c1, q.c2);
      // Per small group (its root after the small-small joins): the anchor.
      std::vector<int> anchor(std::size_t(count) + 1, 0);
      std::vector<std::int64_t> anum(std::size_t(count) + 1, 0), aden(std::size_t(count) + 1, 1);
      for (const Pair& q : pairs) {
        if (big(q.c1) == big(q.c2)) continue;
        const int rs = find(big(q.c1) ? q.c2 : q.c1), cb = big(q.c1) ? q.c1 : q.c2;
        const std::int64_t l = q.num * aden[std::size_t(rs)], r = anum[std::size_t(rs)] * q.den;
        const int t = anchor[std::size_t(rs)];
        if (t == 0 || l < r || (l == r && cb < t))
          anchor[std::size_t(rs)] = cb, anum[std::size_t(rs)] = q.num, aden[std::size_t(rs)] = q.den;
      }
      std::vector<std::pair<int, int>> joins;  // (small group root, large component), decided before joining
      for (const Pair& q : pairs) {
        if (big(q.c1) == big(q.c2)) continue;
        const int rs = find(big(q.c1) ? q.c2 : q.c1), cb = big(q.c1) ? q.c1 : q.c2;
        const int ca = anchor[std::size_t(rs)], ma = med[std::size_t(ca)], mb = med[std::size_t(cb)];
        // Side by side: the two boxes share at most merge_bridge_max_overlap of the narrower one's columns.
        const Acc& a = acc[std::size_t(ca)];
        const Acc& b = acc[std::size_t(cb)];
        const int ov = std::min(a.x1, b.x1) - std::max(a.x0, b.x0) + 1;
        const int narrow = std::min(a.x1 - a.x0, b.x1 - b.x0) + 1;
        const bool side = double(ov) <= p.merge_bridge_max_overlap * double(narrow);
        if (!side || std::abs(ma - mb) <= p.merge_max_rel_disparity * std::max(ma, mb)) joins.emplace_back(rs, cb);
      }
      for (const auto& [rs, cb] : joins) unite(rs, cb);
      pairs.clear();
    }
    // Complete linkage on the members' medians (session 8, docs/detection.md "(e) Fragment merging"): the
    // closest pairs first (ties by label), two groups join only when all their members' medians together
    // span <= merge_group_max_rel of the largest, so small fragments at an intermediate depth (the
    // matcher's ramp between two obstacles) no longer chain two obstacles 10-25 % apart into one.
    std::sort(pairs.begin(), pairs.end(), [](const Pair& x, const Pair& y) {
      const std::int64_t l = x.num * y.den, r = y.num * x.den;
      if (l != r) return l < r;
      return x.c1 != y.c1 ? x.c1 < y.c1 : x.c2 < y.c2;
    });
    std::vector<int> gmin(med), gmax(med);
    for (const Pair& q : pairs) {
      const int r1 = find(q.c1), r2 = find(q.c2);
      if (r1 == r2) continue;
      const int lo = std::min(gmin[std::size_t(r1)], gmin[std::size_t(r2)]);
      const int hi = std::max(gmax[std::size_t(r1)], gmax[std::size_t(r2)]);
      if (double(hi - lo) > p.merge_group_max_rel * double(hi)) continue;
      const int r = std::min(r1, r2);
      parent[std::size_t(std::max(r1, r2))] = r;
      gmin[std::size_t(r)] = lo, gmax[std::size_t(r)] = hi;
    }
  }
  // Each group's box, count and pixels go to its root (the other members keep n = 0).
  std::vector<int> root(std::size_t(count) + 1, 0);
  auto absorb = [&] {
    for (int c = 1; c <= count; ++c) root[std::size_t(c)] = find(c);
    for (int c = 1; c <= count; ++c) {
      const int r = root[std::size_t(c)];
      if (r == c || acc[std::size_t(c)].n == 0) continue;
      Acc& a = acc[std::size_t(r)];
      Acc& b = acc[std::size_t(c)];
      a.x0 = std::min(a.x0, b.x0), a.y0 = std::min(a.y0, b.y0), a.x1 = std::max(a.x1, b.x1), a.y1 = std::max(a.y1, b.y1);
      a.n += b.n;
      a.d.insert(a.d.end(), b.d.begin(), b.d.end());
      b.n = 0;
      std::vector<std::int16_t>().swap(b.d);
    }
  };
  absorb();
  // Attaching groups (session 8, with complete linkage): a group whose box grown by merge_gap_px overlaps the
  // box of a larger group (more pixels) whose own lower median lies within merge_max_rel_disparity of its
  // lower median joins the one of those with the nearest median (ties: more pixels, then the smaller label).
  // Decided on the groups before the pass, and a group that attaches is no target, so there are no chains:
  // a fragment joins one obstacle, never two obstacles to each other.
  if (p.merge_group_max_rel > 0 && p.merge_attach && p.merge_gap_px >= 0 && p.merge_max_rel_disparity > 0) {
    const int g = p.merge_gap_px;
    std::vector<int> gmed(std::size_t(count) + 1, 0), target(std::size_t(count) + 1, 0);
    for (int c = 1; c <= count; ++c) {
      Acc& a = acc[std::size_t(c)];
      if (a.n == 0) continue;
      const std::size_t mid = (a.d.size() - 1) / 2;
      std::vector<std::int16_t> v(a.d);
      std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(mid), v.end());
      gmed[std::size_t(c)] = v[mid];
    }
    for (int c1 = 1; c1 <= count; ++c1) {
      const Acc& a = acc[std::size_t(c1)];
      if (a.n == 0) continue;
      int best = 0;
      for (int c2 = 1; c2 <= count; ++c2) {
        const Acc& b = acc[std::size_t(c2)];
        if (c2 == c1 || b.n <= a.n || b.x0 > a.x1 + g || a.x0 > b.x1 + g || b.y0 > a.y1 + g || a.y0 > b.y1 + g) continue;
        const int m1 = gmed[std::size_t(c1)], m2 = gmed[std::size_t(c2)];
        if (std::abs(m1 - m2) > p.merge_max_rel_disparity * std::max(m1, m2)) continue;
        if (best == 0) { best = c2; continue; }
        const int db = std::abs(gmed[std::size_t(best)] - m1), dc = std::abs(m2 - m1);
        if (dc < db || (dc == db && b.n > acc[std::size_t(best)].n)) best = c2;
      }
      target[std::size_t(c1)] = best;
    }
    for (int c = 1; c <= count; ++c) {
      const int t = target[std::size_t(c)];
      if (t && target[std::size_t(t)] == 0) parent[std::size_t(c)] = t;  // c is a root: its group moves to t
    }
    absorb();
  }
  // Edge continuity (our addition, session 5, docs/detection.md "(e) Edge continuity"): two groups side
  // by side (horizontal gap <= max(merge_gap_px, 0), boxes may overlap by up to merge_edge_columns
  // columns, rows overlapping by >= half the lower box) whose facing edges have the same disparity (lower
  // medians of the pixels in the merge_edge_columns outermost columns of each, within
  // merge_edge_rel_disparity of the larger) are one slanted surface cut where two k-means clusters meet
  // (the u-disparity filter of each cluster loses the columns at the boundary); their overall medians
  // differ by more than fragment merging allows.
  if (p.merge_edge_rel_disparity > 0 && p.merge_edge_columns > 0) {
    const int k = p.merge_edge_columns;
    std::vector<std::vector<std::int16_t>> left(std::size_t(count) + 1), right(std::size_t(count) + 1);
    for (int y = 0; y < components.height; ++y) {
      const std::int32_t* l = components.row(y);
      const std::int16_t* d = disp.row(y);
      for (int x = 0; x < components.width; ++x) {
        if (l[x] == 0) continue;
        const int g = root[std::size_t(l[x])];
        const Acc& a = acc[std::size_t(g)];
        if (x < a.x0 + k) left[std::size_t(g)].push_back(d[x]);
        if (x > a.x1 - k) right[std::size_t(g)].push_back(d[x]);
      }
    }
    auto lower_median = [](std::vector<std::int16_t>& v) {
      const std::size_t mid = (v.size() - 1) / 2;
      std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(mid), v.end());
      return int(v[mid]);
    };
    std::vector<int> lm(std::size_t(count) + 1, 0), rm(std::size_t(count) + 1, 0);
    for (int c = 1; c <= count; ++c)
      if (acc[std::size_t(c)].n > 0) lm[std::size_t(c)] = lower_median(left[std::size_t(c)]), rm[std::size_t(c)] = lower_median(right[std::size_t(c)]);
    const int g = std::max(p.merge_gap_px, 0);
    for (int c1 = 1; c1 <= count; ++c1) {
      const Acc& a = acc[std::size_t(c1)];
      if (a.n == 0) continue;
      for (int c2 = 1; c2 <= count; ++c2) {
        const Acc& b = acc[std::size_t(c2)];
        if (c2 == c1 || b.n == 0 || b.x1 <= a.x1) continue;  // b ends right of a
        const int gap = b.x0 - a.x1 - 1;
        if (gap > g || gap < -k) continue;
        const int ov = std::min(a.y1, b.y1) - std::max(a.y0, b.y0) + 1;
        if (2 * ov < std::min(a.y1 - a.y0 + 1, b.y1 - b.y0 + 1)) continue;
        const int e1 = rm[std::size_t(c1)], e2 = lm[std::size_t(c2)];
        if (std::abs(e1 - e2) > p.merge_edge_rel_disparity * std::max(e1, e2)) continue;
        unite(c1, c2);
      }
    }
    absorb();
  }
  // Occlusion merging (our addition, docs/detection.md "(e)"): two merged groups at the same depth
  // (medians within merge_max_rel_disparity), with the same top and bottom rows (within 1/20 of the
  // taller height + 2 px), whose horizontal gap (more than merge_gap_px, at most
  // merge_occluded_max_gap_px) is covered column by column (up to merge_gap_px columns may stay open)
  // by the boxes of nearer groups (median > the larger median * (1 + merge_max_rel_disparity), >=
  // min_area_px pixels, overlapping the two's common rows) are one obstacle seen on both sides of a
  // nearer one. Runs on the merged groups, not on fragments, so pieces of two different obstacles
  // are not compared.
  if (p.merge_occluded_max_gap_px > 0 && p.merge_max_rel_disparity > 0) {
    for (int c = 1; c <= count; ++c) {
      Acc& a = acc[std::size_t(c)];
      if (a.n == 0) continue;
      const std::size_t mid = (a.d.size() - 1) / 2;  // lower median
      std::nth_element(a.d.begin(), a.d.begin() + std::ptrdiff_t(mid), a.d.end());
      med[std::size_t(c)] = a.d[mid];
    }
    std::vector<int> cover;
    for (int c1 = 1; c1 <= count; ++c1) {
      const Acc& a0 = acc[std::size_t(c1)];
      if (a0.n == 0) continue;
      for (int c2 = 1; c2 <= count; ++c2) {
        const Acc& b0 = acc[std::size_t(c2)];
        if (c2 == c1 || b0.n == 0 || b0.x0 <= a0.x1) continue;  // b strictly right of a
        const int gap = b0.x0 - a0.x1 - 1;
        if (gap <= std::max(p.merge_gap_px, 0) || gap > p.merge_occluded_max_gap_px) continue;
        const int m1 = med[std::size_t(c1)], m2 = med[std::size_t(c2)];
        if (std::abs(m1 - m2) > p.merge_max_rel_disparity * std::max(m1, m2)) continue;
        const int ry0 = std::max(a0.y0, b0.y0), ry1 = std::min(a0.y1, b0.y1);
        // Same top and bottom rows: the two sides of one surface; two obstacles at one depth rarely
        // share both.
        const int tol = std::max(a0.y1 - a0.y0 + 1, b0.y1 - b0.y0 + 1) / 20 + 2;
        if (std::abs(a0.y0 - b0.y0) > tol || std::abs(a0.y1 - b0.y1) > tol) continue;
        if (find(c1) == find(c2)) continue;
        cover.assign(std::size_t(gap), 0);
        const double near_q4 = double(std::max(m1, m2)) * (1.0 + p.merge_max_rel_disparity);
        for (int c3 = 1; c3 <= count; ++c3) {
          const Acc& o = acc[std::size_t(c3)];
          if (o.n < p.min_area_px || double(med[std::size_t(c3)]) <= near_q4 || o.y1 < ry0 || o.y0 > ry1) continue;
          for (int x = std::max(o.x0, a0.x1 + 1); x <= std::min(o.x1, b0.x0 - 1); ++x) cover[std::size_t(x - a0.x1 - 1)] = 1;
        }
        // Up to merge_gap_px uncovered columns are allowed (box edges of neighbours need not meet).
        if (std::count(cover.begin(), cover.end(), 0) > std::max(p.merge_gap_px, 0)) continue;
        unite(c1, c2);
      }
    }
    absorb();
  }
  // Contained groups (our addition, session 5, docs/detection.md "(e) Contained groups"): a group
  // whose box lies >= contain_min_inside inside the box of a larger group (more pixels, >= min_area_px)
  // is either a leftover piece of that obstacle (medians within contain_merge_rel_disparity of the
  // larger: absorbed) or, when it has fewer than contain_drop_max_px pixels, a wrong-depth blob of the
  // matcher inside it (dropped; with contain_drop_nearer_only only when it is nearer than the host).
  // The host is the containing group with the most pixels (ties: lowest label). All decisions are
  // taken on the groups as they are before this pass (no chains of decisions within the pass).
  if (p.contain_min_inside > 0) {
    for (int c = 1; c <= count; ++c) {
      Acc& a = acc[std::size_t(c)];
      if (a.n == 0) continue;
      const std::size_t mid = (a.d.size() - 1) / 2;  // lower median
      std::nth_element(a.d.begin(), a.d.begin() + std::ptrdiff_t(mid), a.d.end());
      med[std::size_t(c)] = a.d[mid];
    }
    std::vector<int> host(std::size_t(count) + 1, 0);
    for (int c1 = 1; c1 <= count; ++c1) {
      const Acc& a = acc[std::size_t(c1)];
      if (a.n == 0) continue;
      const std::int64_t area = std::int64_t(a.x1 - a.x0 + 1) * (a.y1 - a.y0 + 1);
      int best = 0;
      for (int c2 = 1; c2 <= count; ++c2) {
        const Acc& b = acc[std::size_t(c2)];
        if (c2 == c1 || b.n <= a.n || b.n < p.min_area_px) continue;
        if (best != 0 && b.n <= acc[std::size_t(best)].n) continue;
        const std::int64_t iw = std::min(a.x1, b.x1) - std::max(a.x0, b.x0) + 1;
        const std::int64_t ih = std::min(a.y1, b.y1) - std::max(a.y0, b.y0) + 1;
        if (iw <= 0 || ih <= 0 || double(iw * ih) < p.contain_min_inside * double(area)) continue;
        best = c2;
      }
      host[std::size_t(c1)] = best;
    }
    // Surrounded: the host has pixels on both sides of the group's box, left and right within its rows
    // or above and below within its columns (a hole filled by the piece), not only on one side (an
    // obstacle beside or in front of the host's edge, inside its box only because boxes are rectangles).
    std::vector<std::int32_t> group;
    if (p.contain_surround != ContainSurround::Off) {
      group.assign(components.size(), 0);
      for (std::size_t i = 0; i < components.size(); ++i)
        if (components.data[i] > 0) group[i] = root[std::size_t(components.data[i])];
    }
    auto any_of = [&](int g, int x0, int y0, int x1, int y1) {
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x)
          if (group[std::size_t(y) * std::size_t(components.width) + std::size_t(x)] == g) return true;
      return false;
    };
    std::vector<int> drop;
    for (int c1 = 1; c1 <= count; ++c1) {
      const int c2 = host[std::size_t(c1)];
      if (c2 == 0) continue;
      if (p.contain_surround != ContainSurround::Off) {
        const Acc& a = acc[std::size_t(c1)];
        const Acc& b = acc[std::size_t(c2)];
        const bool lr = any_of(c2, b.x0, a.y0, a.x0 - 1, a.y1) && any_of(c2, a.x1 + 1, a.y0, b.x1, a.y1);
        const bool ud = any_of(c2, a.x0, b.y0, a.x1, a.y0 - 1) && any_of(c2, a.x0, a.y1 + 1, a.x1, b.y1);
        if (p.contain_surround == ContainSurround::All ? !(lr && ud) : !(lr || ud)) continue;
      }
      const int m1 = med[std::size_t(c1)], m2 = med[std::size_t(c2)];
      if (std::abs(m1 - m2) <= p.contain_merge_rel_disparity * std::max(m1, m2)) {
        unite(c1, c2);
      } else if (acc[std::size_t(c1)].n < p.contain_drop_max_px && (!p.contain_drop_nearer_only || m1 > m2)) {
        drop.push_back(c1);
      }
    }
    absorb();
    for (int c : drop) acc[std::size_t(find(c))].n = 0;  // root of its group (it may host absorbed pieces)
  }

  std::vector<Obstacle> obs;
  std::vector<int> comp_of;  // component label (group root) of each obstacle
  for (int c = 1; c <= count; ++c) {
    Acc& a = acc[std::size_t(c)];
    if (a.n == 0 || a.n < p.min_area_px) continue;
    const std::size_t mid = (a.d.size() - 1) / 2;  // lower median
    std::nth_element(a.d.begin(), a.d.begin() + std::ptrdiff_t(mid), a.d.end());
    Obstacle o;
    o.x0 = a.x0, o.y0 = a.y0, o.x1 = a.x1, o.y1 = a.y1, o.pixel_count = a.n;
    o.disparity_q4 = std::max<int>(1, a.d[mid]);  // d = 0 would be at infinity; clamp to 1/16 px
    o.distance_m = calib.depth_of(double(o.disparity_q4) / kDispScale);
    // Range (our addition, session 5): farther than max_distance_m is background, not an obstacle.
    if (p.max_distance_m > 0 && o.distance_m > p.max_distance_m) continue;
    // Physical size: an obstacle lower than min_height_m (box rows * Z / f) is road or matcher noise.
    if (double(o.y1 - o.y0 + 1) * o.distance_m / calib.focal_px < p.min_height_m) continue;
    // Physical area (our addition, docs/detection.md "(e)"): the pixels cover n * (Z/f)^2 m^2.
    // Matcher speckle at a wrong depth is a few hundred pixels at any Z; a real surface that small
    // in m^2 is below what the matcher resolves reliably.
    const double zf = o.distance_m / calib.focal_px;
    if (p.min_area_m2 > 0 && double(a.n) * zf * zf < p.min_area_m2) continue;
    o.lateral_m = (0.5 * (o.x0 + o.x1) - calib.cx) * o.distance_m / calib.focal_px;
    o.cls = classify_distance(o.distance_m, p);
    obs.push_back(o);
    comp_of.push_back(c);
  }
  // Nearest first; equal disparity keeps raster order of the components (stable).
  std::vector<std::size_t> order(obs.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return obs[a].disparity_q4 > obs[b].disparity_q4; });
  std::vector<Obstacle> sorted;
  std::vector<int> id_of_comp(std::size_t(count) + 1, -1);
  for (std::size_t i = 0; i < order.size(); ++i) {
    Obstacle o = obs[order[i]];
    o.id = int(i);
    id_of_comp[std::size_t(comp_of[order[i]])] = int(i);
    sorted.push_back(o);
  }
  if (labels) {
    *labels = ImageI32(components.width, components.height, 0);
    for (std::size_t i = 0; i < components.size(); ++i) {
      const int c = components.data[i] > 0 ? root[std::size_t(components.data[i])] : 0;
      if (c > 0 && id_of_comp[std::size_t(c)] >= 0) labels->data[i] = id_of_comp[std::size_t(c)] + 1;
    }
  }
  return sorted;
}

}  // namespace fs::detect
