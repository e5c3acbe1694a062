// Static world memory: a log-odds occupancy grid on the ground plane, filled from the obstacle
// surface points the stereo camera sees and cleared along the camera rays that see free space.
//
// Why a grid next to the tracker (docs/robot.md "Closed loop"): the tracker (eq. 26-32) is made
// for compact objects; walls, rows of posts and large close obstacles arrive as many fragments
// whose positions jitter from frame to frame, which the tracker turns into spurious tracks with
// ghost velocities. The grid remembers what was seen where (also out of the camera's view,
// so the robot does not forget an obstacle beside it when it turns) and forgets it only when the
// camera looks at that place again and sees through it (moving obstacles leave no permanent trail).
// The planner gets the occupied cells as small static circles; moving obstacles come from the tracker.
#pragma once
#include <cstdint>
#include <limits>
#include <vector>

#include "fuzzystereo/robot/geometry.hpp"

namespace fs::robot {

struct ObstacleMapParams {
  double cell_m = 0.05;      // cell size [m]; occupied cells go to the planner as circles of cell/2
  double extent_m = 24.0;    // the grid covers +-extent/2 around the first pose [m]
  double hit = 0.85;         // log-odds added for a frame with a surface point in the cell
  double miss = 0.4;         // log-odds removed for a frame that sees through the cell
  double l_min = -2.0, l_max = 3.5;  // clamp (bounds how long a cell takes to change its mind)
  double l_occupied = 0.4;   // occupied when the log-odds exceed this
  bool remember_seen = false;  // keep last_seen_ns per cell (costs a view test of every cell in
                               // range each scan; the loop sets it for [planner] unseen_check_s)
};

// One camera frame as rays: for each image column the ground distance up to which the camera saw
// free space, and the obstacle surface points it saw (world frame).
struct CameraScan {
  Pose2D pose;                        // robot pose at capture (camera centre at the robot centre)
  double focal_px = 0, cx = 0;        // rectified left camera
  double min_range_m = 0.5;           // nearer than this the camera measures nothing (disparity range)
  std::vector<double> free_range_m;   // per column: forward distance seen free (0 = nothing known)
  std::vector<Vec2> hits;             // obstacle surface points (world) [m]
  std::int64_t t_ns = 0;              // capture time (for ObstacleMap::occupied_before)
};

class ObstacleMap {
 public:
  explicit ObstacleMap(const ObstacleMapParams& p = {}) : p_(p) {}
  // Hits raise their cells (once per frame per cell), then every cell inside the camera's view
  // nearer than its column's free range (and not hit this frame) is lowered.
  void integrate(const CameraScan& scan);
  // Occupied cells within `radius_m` of `centre` as static circles (at the mean of the hit points
  // that fell into the cell, radius cell/2). confirm_range_m > 0: a cell not hit from within that
  // range of the scan pose since it became occupied is marked CircleObstacle::unconfirmed.
  std::vector<CircleObstacle> obstacles(Vec2 centre, double radius_m, double confirm_range_m = 0.0) const;
  // Nearest range (scan pose to hit point) of the hits since the cell at p became occupied; +inf when
  // the cell is not occupied or off the grid.
  double nearest_hit_m(Vec2 p) const;
  int occupied_count() const;
  // Share of the cells whose centres lie inside the disc (c, r) that the camera has seen through
  // (log-odds <= l_free): free space the disc would wrongly claim (bodies.hpp: a circle fitted to the
  // inside of a concave group of cells covers space the camera saw free). 0 for an empty disc.
  double seen_free_share(Vec2 c, double r, double l_free) const;
  // The same over the cells of the disc (c, r) that lie outside the disc (skip_c, skip_r) — where an
  // obstacle was and is no longer, when (c, r) is its earlier place and (skip_c, skip_r) its present one
  // (the "vacated" evidence of motion, docs/robot.md "Session 53"). `cells` receives the number of cells
  // counted; 0 (and a share of 0) when the present disc covers the earlier one.
  double seen_free_share_outside(Vec2 c, double r, Vec2 skip_c, double skip_r, double l_free, int& cells) const;
  // Occupied cells whose mean hit point lies within r of c and that have been occupied without a
  // break since a scan at or before t_ns (a cell that drops below l_occupied starts again).
  // Tells a static obstacle from a mover at the same place: a mover's surface cells become
  // occupied when it arrives, a static obstacle's were there before (docs/robot.md, "Static
  // support of a track").
  // min_frames > 0: only cells hit in at least that many frames since they became occupied (a static
  // surface is hit every frame it is in view; a mover's passing surface only for a frame or two).
  int occupied_before(Vec2 c, double r, std::int64_t t_ns, int min_frames = 0) const;
  // Capture time of the last scan that saw the ground point p: inside the camera's view and nearer
  // than its column's free range (also nearer than min_range_m: a column with a free range has
  // nothing nearer), or a surface point in its cell. INT64_MIN when never seen, off the grid or
  // without ObstacleMapParams::remember_seen.
  std::int64_t last_seen_ns(Vec2 p) const;
  // Capture time of the first scan integrated (the map knows nothing older); 0 before any scan.
  std::int64_t first_scan_ns() const { return first_scan_ns_; }
  const ObstacleMapParams& params() const { return p_; }

 private:
  bool cell_of(Vec2 p, int& ix, int& iy) const;
  // The cells of the square [c - r, c + r]^2, clamped to the grid (inclusive bounds).
  void cell_window(Vec2 c, double r, int& x0, int& y0, int& x1, int& y1) const;
  ObstacleMapParams p_;
  bool init_ = false;
  Vec2 origin_;   // world position of cell (0, 0)'s corner
  int n_ = 0;     // cells per axis
  std::vector<float> logodds_;
  std::vector<float> sx_, sy_;   // running mean of the hit points in the cell
  std::vector<std::uint32_t> nhit_;
  std::vector<std::uint32_t> stamp_;  // frame of the last hit (one hit per frame)
  std::vector<std::int64_t> since_ns_;  // capture time of the scan that made the cell occupied
  std::vector<std::uint16_t> frames_hit_;  // frames with a hit since the cell became occupied
  std::vector<float> nearest_hit_;          // nearest hit range since the cell became occupied [m]
  std::vector<std::int64_t> seen_ns_;   // capture time of the last scan that saw the cell
  std::uint32_t frame_ = 0;
  std::int64_t first_scan_ns_ = 0;
};

}  // namespace fs::robot
