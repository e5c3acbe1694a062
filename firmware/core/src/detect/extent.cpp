// Box extent (our addition, session 5 round 3, docs/detection.md "(e) Box extent"). The road stage
// removes every pixel whose disparity lies within the road band of the line (eq. 16-17) — including
// the lowest rows of each obstacle standing on the road, whose foot has the road's disparity there.
// The box then ends tol/a rows (3-7 px here) above the obstacle's true bottom, which alone costs a
// small obstacle the IoU >= 0.5 of a detection. Ground contact: the obstacle of median disparity d
// stands on the road where the line reaches d, so a box whose bottom row lies in the band of d (or
// up to foot_slack_px more above it) is extended down to the last row above the one where the line
// reaches d (the image's last row when the line stays below d there: the foot is outside the
// image). Integer: Q4 line table and Q4 band, as in road_pixels.
#include <algorithm>
#include <climits>
#include <cstdlib>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

void extend_to_ground(std::vector<Obstacle>& obstacles, const std::vector<std::int32_t>& line_q4,
                      const DetectParams& p) {
  if (!p.foot_extend || line_q4.empty()) return;
  const int h = int(line_q4.size());
  const std::int32_t slack = std::int32_t(std::lround(p.foot_slack_px * kDispScale));
  for (Obstacle& o : obstacles) {
    const int below = o.y1 + 1;
    if (below >= h || line_q4[std::size_t(below)] == INT32_MIN) continue;
    const std::int32_t d = o.disparity_q4;
    if (line_q4[std::size_t(o.y1)] != INT32_MIN && line_q4[std::size_t(o.y1)] >= d) continue;  // at the foot already
    const std::int32_t l = line_q4[std::size_t(below)];
    // The band of road_pixels at that row: |q4 - l| <= tol; the obstacle's lowest kept row sits just
    // above the rows the band took when l >= d - tol (- slack).
    const std::int32_t tol =
        std::int32_t(std::lround(p.road_tolerance_px * kDispScale + p.road_tolerance_rel * std::max(0, l)));
    if (l < d - tol - slack) continue;  // the road below is farther than the band: no ground contact
    int foot = o.y1;  // the last row where the line is still below d: the obstacle's lowest row
    while (foot + 1 < h && line_q4[std::size_t(foot + 1)] < d) ++foot;
    o.y1 = std::max(o.y1, foot);
  }
}

// Ground contact over a gap (session 14, docs/detection.md "(e) Box extent"). The matcher often measures only
// the upper part of a plain or dark obstacle (the lower part has no disparity, or pieces of it fail the
// u-disparity filter), so its box ends tens of rows above where it stands: 15 of the 206 misses on the 300
// generated frames (session 12 defaults) had a box at their depth ending 15-150 rows above their bottom. An obstacle of median disparity d standing on the
// road fills its columns down to its foot row (where the road line reaches d), unless something nearer hides
// that part — then the part is not visible and the ground truth's box ends above it as well. So the box is
// extended to the foot row when few pixels of the gap between belong to obstacles nearer by more than fragment
// merging's tolerance. Integer: the Q4 line table, pixel counts; one double product for the share.
void extend_over_gap(std::vector<Obstacle>& obstacles, const ImageI32& labels, const std::vector<std::int32_t>& line_q4,
                     const DetectParams& p) {
  if (!p.foot_gap_extend || line_q4.empty() || obstacles.empty()) return;
  const int h = std::min(int(line_q4.size()), labels.height);
  bool any = false;
  for (const std::int32_t l : line_q4) any = any || l != INT32_MIN;
  if (!any) return;
  const std::size_t n = obstacles.size();
  std::vector<std::uint8_t> nearer(n + 1, 0);
  for (Obstacle& o : obstacles) {
    const std::int32_t d = o.disparity_q4;
    int foot = o.y1;  // the last row from the box bottom on whose line value is still below d
    while (foot + 1 < h && line_q4[std::size_t(foot + 1)] < d) ++foot;
    if (foot <= o.y1) continue;
    for (std::size_t k = 0; k < n; ++k)
      nearer[k + 1] = double(obstacles[k].disparity_q4) > double(d) * (1.0 + p.merge_max_rel_disparity);
    std::int64_t occluded = 0;
    for (int y = o.y1 + 1; y <= foot; ++y) {
      const std::int32_t* l = labels.row(y);
      for (int x = o.x0; x <= o.x1; ++x)
        occluded += l[x] > 0 && std::size_t(l[x]) <= n && nearer[std::size_t(l[x])];
    }
    const std::int64_t area = std::int64_t(foot - o.y1) * (o.x1 - o.x0 + 1);
    if (double(occluded) <= p.foot_gap_max_occluded * double(area)) o.y1 = foot;
  }
}

// Sparse and low sides: the columns at a box's left and right ends holding fewer of the obstacle's pixels
// than trim_col_min_share of its fullest column, or whose highest pixel lies lower than
// trim_col_top_share of the box height below its top, are cut off, one column at a time from each side, and
// the box, pixel count, labels and lateral X follow (the distance keeps the median of all pixels). The
// matcher smooths the road's disparity towards an obstacle's at its foot, and fattens it into plain
// background, so a low skirt of a few rows at the obstacle's depth joins the component and widens the
// box by 10-50 px; a real obstacle's side columns are about as tall as its middle ones (vertical sides:
// boxes, cylinders, posts; a cone or a person narrowing upwards loses its outer columns' low part).
void trim_sparse_columns(std::vector<Obstacle>& obstacles, ImageI32& labels, const StereoCalib& calib,
                         const DetectParams& p, const ImageU8* sky, const ImageI16* disp) {
  if ((p.trim_col_min_share <= 0 && p.trim_col_top_share <= 0) || obstacles.empty()) return;
  std::vector<std::int32_t> cols;
  for (Obstacle& o : obstacles) {
    const std::int32_t id = o.id + 1;
    const int bw = o.x1 - o.x0 + 1;
    cols.assign(std::size_t(bw), 0);
    for (int y = o.y0; y <= o.y1; ++y) {
      const std::int32_t* l = labels.row(y);
      for (int x = o.x0; x <= o.x1; ++x) cols[std::size_t(x - o.x0)] += l[x] == id;
    }
    const double need = p.trim_col_min_share * double(*std::max_element(cols.begin(), cols.end()));
    int a = 0, b = bw - 1;
    while (a < b && double(cols[std::size_t(a)]) < need) ++a;
    while (b > a && double(cols[std::size_t(b)]) < need) --b;
    if (p.trim_col_top_share > 0) {
      // Low sides: a column's top = its highest pixel of the obstacle, or of the sky mask at the obstacle's
      // depth (|q4 - d| <= the components' step: max(cc_min_step_px, cc_max_rel_step * d)) — the colour
      // rule (b) also takes bright or grey obstacle pixels above the horizon, and such a column is not low.
      std::vector<int> tops(std::size_t(bw), o.y1 + 1);
      const int tol = std::max(int(std::lround(p.cc_min_step_px * kDispScale)), int(p.cc_max_rel_step * o.disparity_q4));
      for (int y = o.y1; y >= o.y0; --y) {
        const std::int32_t* l = labels.row(y);
        const std::uint8_t* sk = sky ? sky->row(y) : nullptr;
        const std::int16_t* dq = disp ? disp->row(y) : nullptr;
        for (int x = o.x0; x <= o.x1; ++x) {
          const bool on = l[x] == id || (sk && dq && sk[x] && dq[x] >= 0 && std::abs(int(dq[x]) - o.disparity_q4) <= tol);
          if (on) tops[std::size_t(x - o.x0)] = y;
        }
      }
      const double low = double(o.y0) + p.trim_col_top_share * double(o.y1 - o.y0 + 1);
      while (a < b && double(tops[std::size_t(a)]) > low) ++a;
      while (b > a && double(tops[std::size_t(b)]) > low) --b;
    }
    if (a == 0 && b == bw - 1) continue;
    const int nx0 = o.x0 + a, nx1 = o.x0 + b;
    int ny0 = o.y1, ny1 = o.y0, n = 0;
    for (int y = o.y0; y <= o.y1; ++y) {
      std::int32_t* l = labels.row(y);
      for (int x = o.x0; x <= o.x1; ++x) {
        if (l[x] != id) continue;
        if (x < nx0 || x > nx1) {
          l[x] = 0;  // cut off: no longer part of the obstacle
        } else {
          ny0 = std::min(ny0, y), ny1 = std::max(ny1, y), ++n;
        }
      }
    }
    o.x0 = nx0, o.x1 = nx1, o.y0 = ny0, o.y1 = ny1, o.pixel_count = n;
    o.lateral_m = (0.5 * (o.x0 + o.x1) - calib.cx) * o.distance_m / calib.focal_px;
  }
}

}  // namespace fs::detect
