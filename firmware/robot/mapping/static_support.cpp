#include "fuzzystereo/robot/static_support.hpp"

#include "fuzzystereo/robot/clock.hpp"

#include <algorithm>

namespace fs::robot {

namespace {
// The cells a track sits on: within its radius plus this margin of a measured position [m].
constexpr double kCellMargin_m = 0.05;
}  // namespace

int static_support_cells(const ObstacleMap& map, const Track& tr, double lag_s) {
  return map.occupied_before(tr.last_meas_p, tr.radius_m + kCellMargin_m, tr.first_meas_ns - s_to_ns(lag_s));
}

bool has_static_support(const ObstacleMap& map, const Track& tr, const StaticSupportParams& p) {
  if (p.cells <= 0) return false;
  if (static_support_cells(map, tr, p.lag_s) >= p.cells) return true;
  const double r = tr.radius_m + kCellMargin_m;
  if (p.dwell_s > 0 && map.occupied_before(tr.last_meas_p, r, tr.last_meas_ns - s_to_ns(p.dwell_s)) >= p.cells)
    return true;
  return p.born_s > 0 && tr.first_meas_ns <= map.first_scan_ns() + s_to_ns(p.born_s) &&
         norm(tr.last_meas_p - tr.first_meas_p) <= p.born_max_travel_m &&
         map.occupied_before(tr.first_meas_p, r, tr.first_meas_ns) >= p.cells &&
         map.occupied_before(tr.last_meas_p, r, tr.last_meas_ns) >= p.cells;
}

bool measurement_is_static(const ObstacleMap& map, const Vec2* hits, std::size_t n, std::int64_t before_ns, double share,
                           int min_frames) {
  if (n == 0) return false;
  const double r = map.params().cell_m;
  // The whole surface, and each silhouette end (the first and last fifth of the points, which come
  // in image-column order): a mover sliding along its own front surface keeps hitting the same
  // cells there, but its leading edge reaches fresh ones. One pass, counted per part (the ends may
  // overlap for n < 10).
  const std::size_t edge = std::max<std::size_t>(1, n / 5);
  std::size_t all = 0, head = 0, tail = 0;
  for (std::size_t k = 0; k < n; ++k) {
    if (map.occupied_before(hits[k], r, before_ns, min_frames) == 0) continue;
    ++all;
    head += k < edge;
    tail += k >= n - edge;
  }
  const auto enough = [&](std::size_t count, std::size_t of) { return static_cast<double>(count) >= share * static_cast<double>(of); };
  return enough(all, n) && enough(head, edge) && enough(tail, edge);
}

}  // namespace fs::robot
