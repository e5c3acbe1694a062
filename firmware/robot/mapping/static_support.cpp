#include "fuzzystereo/robot/static_support.hpp"

#include "fuzzystereo/robot/clock.hpp"

namespace fs::robot {

int static_support_cells(const ObstacleMap& map, const Track& tr, double lag_s) {
  return map.occupied_before(tr.last_meas_p, tr.radius_m + 0.05, tr.first_meas_ns - s_to_ns(lag_s));
}

bool has_static_support(const ObstacleMap& map, const Track& tr, const StaticSupportParams& p) {
  if (p.cells <= 0) return false;
  if (static_support_cells(map, tr, p.lag_s) >= p.cells) return true;
  return p.dwell_s > 0 &&
         map.occupied_before(tr.last_meas_p, tr.radius_m + 0.05, tr.last_meas_ns - s_to_ns(p.dwell_s)) >= p.cells;
}

}  // namespace fs::robot
