#include "fuzzystereo/robot/static_support.hpp"

#include "fuzzystereo/robot/clock.hpp"

#include <algorithm>
#include <vector>

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
  std::vector<char> old(n);
  for (std::size_t k = 0; k < n; ++k) old[k] = map.occupied_before(hits[k], r, before_ns, min_frames) > 0;
  const auto share_of = [&](std::size_t b, std::size_t e) {
    std::size_t c = 0;
    for (std::size_t k = b; k < e; ++k) c += static_cast<std::size_t>(old[k]);
    return static_cast<double>(c) >= share * static_cast<double>(e - b);
  };
  // The whole surface, and each silhouette end (the first and last fifth of the points, which come
  // in image-column order): a mover sliding along its own front surface keeps hitting the same
  // cells there, but its leading edge reaches fresh ones.
  const std::size_t edge = std::max<std::size_t>(1, n / 5);
  return share_of(0, n) && share_of(0, edge) && share_of(n - edge, n);
}

}  // namespace fs::robot
