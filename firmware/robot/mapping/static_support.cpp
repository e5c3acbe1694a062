#include "fuzzystereo/robot/static_support.hpp"

#include "fuzzystereo/robot/clock.hpp"

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

}  // namespace fs::robot
