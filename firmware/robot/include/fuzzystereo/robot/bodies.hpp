// Hidden sides of mapped obstacles (session 34, `[loop] body_*`; the default since the fresh-seed
// rule of docs/robot.md "Session 34" passed).
//
// The stereo camera sees an obstacle's front surface only, so the map (obstacle_map.hpp) holds the
// arc of it that faced the camera when it was in view. A robot that later drives round the
// obstacle comes close to the side the map never held; with that side out of the camera's view
// (beside the robot) or nearer than the matcher's range, the planner has nothing there and the
// robot turns into it (docs/robot.md "Session 34": 4 of the 5 contacts with static obstacles on
// suite seeds 87-92 were on a side without a single map cell, with 22-101 cells on the other).
//
// A convex body is completed from its visible arc: the occupied cells are grouped (single linkage
// within `link_m`), a circle is fitted to each group (algebraic fit, then Gauss-Newton on the
// geometric distance), and a fit that is round enough — radius in [min_r_m, max_r_m], RMS distance
// of the cells to the circle <= max_rms_m, the cells covering an arc of >= min_arc_deg round the
// centre — becomes a circle for the planner. A straight group (a wall, a box's face) has no
// acceptable circle (its radius diverges) and gets none: the map's cells stay what the planner
// sees of it. The circles are transient (planner.hpp: they never decide "blocked").
#pragma once
#include <vector>

#include "fuzzystereo/robot/geometry.hpp"

namespace fs::robot {

struct BodyFitParams {
  double link_m = 0.08;      // cells nearer than this are one group [m]
  int min_cells = 6;         // smaller groups are not fitted
  double min_r_m = 0.05;     // accepted radii [m]
  double max_r_m = 0.6;
  double max_rms_m = 0.08;   // RMS distance of the group's cells to the fitted circle [m]
  double min_arc_deg = 60;   // arc the group's cells cover round the fitted centre [deg]
};

// A circle fitted to points: centre, radius, RMS of (|p - c| - r) and the arc the points cover
// round c (the complement of the largest angular gap between consecutive points) [deg].
struct CircleFit {
  Vec2 c;
  double r = 0, rms = 0, arc_deg = 0;
  bool ok = false;  // false: fewer than 3 points, collinear points, or no convergence
};

// Least-squares circle through pts: the algebraic (Kasa) fit x^2 + y^2 + D x + E y + F = 0 as the
// start, then Gauss-Newton on sum (|p - c| - r)^2 (the algebraic fit is biased towards small circles
// on short arcs).
CircleFit fit_circle(const std::vector<Vec2>& pts);

// One accepted body: its circle (static, transient) and the fit that gave it.
struct FittedBody {
  CircleObstacle circle;
  CircleFit fit;
  int cells = 0;
};

// The bodies of the occupied cells `cells` (ObstacleMap::obstacles: circles at the mean hit point of
// each cell), in the order of each group's first cell. A group whose circle would hold `robot`
// (an estimate that cannot be right: the robot stands there) gives none.
std::vector<FittedBody> fit_bodies(const std::vector<CircleObstacle>& cells, Vec2 robot, const BodyFitParams& p);

}  // namespace fs::robot
