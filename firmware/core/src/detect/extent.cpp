// Box extent (our addition, session 5 round 3, docs/detection.md "(e) Box extent"). The road stage
// removes every pixel whose disparity lies within the road band of the line (eq. 16-17) — including
// the lowest rows of each obstacle standing on the road, whose foot has the road's disparity there.
// The box then ends tol/a rows (3-7 px here) above the obstacle's true bottom, which alone costs a
// small obstacle the IoU >= 0.5 of a detection. Ground contact: the obstacle of median disparity d
// stands on the road where the line reaches d, so a box whose bottom row lies in the band of d (or
// up to foot_slack_px more above it) is extended down to the last row above it (the image's last row when the
// line stays below d there: the foot is outside the image). Integer: Q4 line table and Q4 band, as in
// road_pixels.
#include <algorithm>
#include <climits>
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

}  // namespace fs::detect
