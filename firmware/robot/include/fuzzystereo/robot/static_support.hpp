// Static support of a track: does the static map already hold the obstacle a track sits on?
// (docs/robot.md, "Static support of a track"). A mover's surface cells become occupied when it
// arrives; a static obstacle's were there before. The robot loop uses it to keep static obstacles'
// tracks (fragments of walls and large cylinders read as 0.1-1 m/s "movers") from acting as movers.
#pragma once
#include <cstddef>
#include <cstdint>

#include "fuzzystereo/robot/obstacle_map.hpp"
#include "fuzzystereo/robot/tracker.hpp"

namespace fs::robot {

struct StaticSupportParams {
  int cells = 2;         // [loop] static_track_cells: map cells needed (0 = the test is off)
  double lag_s = 1.0;    // [loop] static_track_lag_s
  double dwell_s = 0.0;  // [loop] static_track_dwell_s (0 = off)
  double born_s = 0.0;   // [loop] static_track_born_s (0 = off)
  double born_max_travel_m = 1.0;  // [loop] static_track_born_max_travel_m
};

// Map cells within the track's radius + 5 cm of its last measured position, occupied without a
// break since lag_s before its first measurement (the count the run record logs as "support").
int static_support_cells(const ObstacleMap& map, const Track& tr, double lag_s);

// The track has static support when at least `cells` such cells exist, or (dwell_s > 0) when at
// least `cells` cells there have been occupied since dwell_s before its last measurement: the
// obstacle stood where it is now for that long. The first test cannot hold for tracks born
// together with their map cells (the start of a run, a newly seen area), which would otherwise
// stay unsupported for life; a mover that keeps moving has fresh cells at its last position.
//
// (born_s > 0) A track born within born_s of the map's first scan — before the map could hold any
// history of that place — also has support when the cells at its *first* measured position have
// stayed occupied without a break since that measurement, the cells at its last measured position
// are occupied, and it has travelled at most born_max_travel_m between the two. A static
// obstacle's cells stay; a mover that leaves its birthplace in view is seen through there and
// loses them (docs/robot.md, "Session 11").
bool has_static_support(const ObstacleMap& map, const Track& tr, const StaticSupportParams& p);

// A detection is static ([loop] static_meas_age_s, static_meas_share) when at least `share` of its
// surface points `hits` (world frame, before this frame is integrated) lie within one map cell of a
// cell occupied without a break since `before_ns`, and so do both silhouette ends (the first and
// last fifth of the points): the map already holds that surface. The loop then makes its track a
// static obstacle's, or with [loop] static_meas_drop keeps it from the tracker. A mover's surface
// reaches fresh cells (faster than about one cell per age). No points: not static.
// min_frames: only cells hit in at least that many frames count (ObstacleMap::occupied_before).
bool measurement_is_static(const ObstacleMap& map, const Vec2* hits, std::size_t n, std::int64_t before_ns, double share,
                           int min_frames = 0);

}  // namespace fs::robot
