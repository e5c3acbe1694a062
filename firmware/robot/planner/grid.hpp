// Occupancy grid and A* / Theta* searches used by the planner (private to fs_robot).
#pragma once
#include <cmath>
#include <cstdint>
#include <functional>
#include <vector>

#include "fuzzystereo/robot/geometry.hpp"

namespace fs::robot::detail {

struct Grid {
  Vec2 origin;       // world position of cell (0, 0)'s centre
  double res = 0.1;  // cell size [m]
  int nx = 0, ny = 0;
  std::vector<std::uint8_t> blocked;  // row-major, 1 = blocked

  void init(Vec2 lo, Vec2 hi, double resolution, int max_cells_per_axis);
  int idx(int ix, int iy) const { return iy * nx + ix; }
  bool inside(int ix, int iy) const { return ix >= 0 && iy >= 0 && ix < nx && iy < ny; }
  Vec2 center(int ix, int iy) const { return {origin.x + ix * res, origin.y + iy * res}; }
  void cell_of(Vec2 p, int& ix, int& iy) const {
    ix = static_cast<int>(std::lround((p.x - origin.x) / res));
    iy = static_cast<int>(std::lround((p.y - origin.y) / res));
  }
  bool blocked_at(Vec2 p) const {
    int ix, iy;
    cell_of(p, ix, iy);
    return !inside(ix, iy) || blocked[idx(ix, iy)];
  }
  // Marks every cell whose centre lies within r of c.
  void fill_disc(Vec2 c, double r);
  void clear_disc(Vec2 c, double r);
  // Straight segment free of blocked cells (sampled every res / 2).
  bool segment_free(Vec2 a, Vec2 b) const;
};

// Is p's free region smaller than `budget` cells (a pocket, e.g. an enclosed goal)? 8-connected
// flood fill that stops after `budget` cells. Makes "blocked" cheap to detect when the goal or the
// robot is enclosed, where A* would otherwise search the whole grid.
bool in_small_pocket(const Grid& g, Vec2 p, int budget);

// 8-connected A* (octile heuristic) from start to goal cell; returns the path of cell centres with
// the exact start and goal positions at its ends, or empty when none exists.
std::vector<Vec2> astar(const Grid& g, Vec2 start, Vec2 goal);

// Theta* (any-angle A*) over free cells; line of sight is decided by `los` (exact geometry).
// Returns the path length or +inf.
double theta_star_length(const Grid& g, Vec2 start, Vec2 goal, const std::function<bool(Vec2, Vec2)>& los);

}  // namespace fs::robot::detail
