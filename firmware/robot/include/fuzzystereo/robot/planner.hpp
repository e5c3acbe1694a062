// Path planner for a differential-drive disc robot among moving circular obstacles.
//   1. global: 8-connected A* on an occupancy grid of the obstacles' current (predicted) positions,
//      inflated by robot radius + safety margin (retried with the bare collision margin, so gaps the
//      margin closes are still found); gives guidance through narrow gaps and out of U-traps;
//   2. local: sampled constant-(v, omega) arcs inside the dynamic window, each checked over
//      horizon_s against every obstacle's PREDICTED position c + t * vel; admissible only when
//      collision-free and the robot can still brake to a stop before the first contact; scored by
//      heading to a carrot on the global path, progress, clearance and speed.
// Runs every frame; no state (the caller may pass the last frame's path back: route commitment).
// No global path -> status kBlocked and a braking command; no admissible arc -> kWaiting and a
// braking command. docs/robot.md "Planner".
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "fuzzystereo/robot/geometry.hpp"
#include "fuzzystereo/robot/odometry.hpp"
#include "fuzzystereo/robot/params.hpp"

namespace fs::robot {

enum class PlanStatus {
  kMoving,   // following an admissible arc
  kReached,  // within goal tolerance: stop
  kWaiting,  // a global path exists but no arc is safe now (e.g. a crossing obstacle): braking
  kBlocked,  // no collision-free path to the goal exists: safe stop
};
const char* to_string(PlanStatus s);

struct PlanOutput {
  BodyTwist cmd;                 // requested (v, omega); the mixer applies acceleration limits
  PlanStatus status = PlanStatus::kBlocked;
  std::vector<Vec2> path;        // global path (world), start .. goal; empty when blocked
  Vec2 carrot;                   // lookahead point the local planner steered to
  bool reduced_margin = false;   // the path needed the bare collision margin (a tight gap)
  double clearance_m = 0;        // smallest predicted surface gap along the chosen arc [m]
  bool route_kept = false;       // the global path is the last frame's route (route commitment)
  bool evading = false;          // every arc was unsafe and a moving obstacle would hit the standing
                                 // robot: cmd is the arc whose first contact comes latest
};

// What the caller remembers between frames, all optional.
struct PlanContext {
  // The previous frame's PlanOutput::path (world), for route commitment ([planner] route_keep_ratio
  // > 0); nullptr = none.
  const std::vector<Vec2>* last_route = nullptr;
  // Whether the camera saw the ground point recently (the loop: ObstacleMap::last_seen_ns within
  // [loop] seen_max_age_s), for "look where you drive" ([planner] unseen_check_s > 0); empty = no check.
  std::function<bool(Vec2)> recently_seen;
  // Soft circles where a mover that left the view may be now ([planner] w_memory > 0): they cost,
  // never block; nullptr = none.
  const std::vector<CircleObstacle>* memory = nullptr;
  // [planner] speed_follows_heading for this call even when the parameter is off (the loop: while
  // stuck, with [loop] stuck_speed_follows_heading).
  bool speed_follows_heading = false;
};

class Planner {
 public:
  Planner(const PlannerParams& pp, const RobotParams& rp) : pp_(pp), rp_(rp) {}
  // pose: current pose; current: current body twist (for the dynamic window); obstacles at the
  // current time with velocities (planning uses c + t * vel for t in [0, horizon]).
  PlanOutput plan(const Pose2D& pose, const BodyTwist& current, Vec2 goal,
                  const std::vector<CircleObstacle>& obstacles, const PlanContext& ctx = {}) const;

  const PlannerParams& params() const { return pp_; }
  const RobotParams& robot() const { return rp_; }

 private:
  struct DynamicWindow {
    double vmin = 0, vmax = 0, wmin = 0, wmax = 0;
    int nv = 2, nw = 3;
    BodyTwist at(int iv, int iw) const;  // sample (iv, iw) of the nv x nw grid
  };
  std::vector<CircleObstacle> reachable_obstacles(const std::vector<CircleObstacle>& obstacles, Vec2 pos) const;
  DynamicWindow dynamic_window(const BodyTwist& current, double dist_goal) const;
  bool evade_instead_of_standing(const Pose2D& pose, const std::vector<CircleObstacle>& near, double escape_gap) const;
  void reverse_escape(const Pose2D& pose, const BodyTwist& current, const DynamicWindow& dw,
                      const std::vector<CircleObstacle>& near, double& escape_gap, BodyTwist& escape) const;

  PlannerParams pp_;
  RobotParams rp_;
};

// Latency compensation: a command computed from a frame reaches the motors latency_s later; until
// then the robot keeps driving `current` and obstacles keep moving. Returns the pose predicted for
// that moment (exact arc) and moves every obstacle centre along its velocity by latency_s, so the
// planner's t = 0 is the moment its command takes effect. latency_s <= 0 changes nothing.
Pose2D predict_to_command_time(const Pose2D& pose, const BodyTwist& current, double latency_s,
                               std::vector<CircleObstacle>& obstacles);

// Where a tracked obstacle of doubtful heading can go ([loop] near_track_moving = "fan", session 28):
// `count` transient circles at c with radius r, each leaving at the track's speed |vel|, the first
// along vel and the others evenly spaced round the circle. A track whose velocity is 60-140 deg off
// its mover's (a mover that turned) is still covered where it goes. Appended to `out`.
void fan_circles(Vec2 c, double r, Vec2 vel, int count, std::vector<CircleObstacle>& out);

// Reachable set of an obstacle last measured at `last_p` (radius r) moving at `speed`, `age_s` ago:
// a circle at last_p grown by speed * age_s, at most cap_m. Returned (true) only when it lies within
// reach of the robot (centre distance <= near_m + grown) and does not already hold the
// robot (centre distance > grown + robot_radius: a set that holds the robot leaves no arc).
// keep_holding = true also returns a set that holds the robot (the planner's escape rule,
// escape_inside_margin, then only forbids arcs that bring the robot nearer its centre).
bool reachable_set(Vec2 last_p, double r, double speed, double age_s, double cap_m, Vec2 robot_pos,
                   double robot_radius, double near_m, CircleObstacle& out, bool keep_holding = false);

// Sensing action before a turn ([loop] look_before_turn_m; docs/robot.md "Look before turning").
// The camera sees +-half_fov_rad about the heading; a mover whose track was last measured at
// `last_p` outside that view may stand beside the robot, where nothing of it is in the map. When
// `cmd` drives forward (v > 0.02 m/s) on an arc that turns towards that side (|omega| > 0.1 rad/s,
// omega of the sign of last_p's bearing) and last_p lies within near_m of the robot and outside
// the view, the robot should first turn on the spot to look there: returns true and sets `look` =
// (0, +-yaw_rate) towards last_p. Otherwise false (`look` untouched). The loop ends the action
// when last_p's bearing is inside the view. (Seed 11, scenario 92: a mover's track deleted 0.7 m
// beside the robot at 60-95 deg; the robot drove a left arc into it.)
bool look_before_turn(const Pose2D& pose, const BodyTwist& cmd, Vec2 last_p, double half_fov_rad, double near_m,
                      double yaw_rate, BodyTwist& look);

// Speed to grow a reachable set with [m/s]: the filtered speed, at most (when use_travel_rate) the
// track's measured travel rate max(0, |last_p - first_p| - noise_m) / life_s. A track whose velocity
// was filtered from mis-associated fragments or depth noise reads 0.1-0.3 m/s while its measurements
// stay in place (noise_m: the travel that measurement noise alone explains, e.g. 2 position std);
// a mover's travel rate is its speed. life_s <= 0 (one measurement): the filtered speed.
double reach_speed(double filtered_speed, Vec2 first_p, Vec2 last_p, double life_s, bool use_travel_rate,
                   double noise_m = 0.0);

// Length of the shortest path for a disc of radius `radius` from start to goal among static
// circles (their velocities are ignored), or +infinity when none exists. Any-angle search
// (Theta*) on a grid of `resolution_m` whose line-of-sight test is exact geometry (segment-to-circle
// distance), so the result is within about 1-2 % of the exact Euclidean shortest path (checked
// against the analytic tangent-arc-tangent length in the tests); docs/robot.md.
double shortest_path_length(const std::vector<CircleObstacle>& obstacles, Vec2 start, Vec2 goal,
                            double radius, double resolution_m = 0.05);

// Left/right wheel command from (v, omega) with speed and acceleration limits.
struct WheelCommand {
  double left = 0, right = 0;  // normalised motor command in [-1, 1] (1 = max_wheel_speed_mps)
  BodyTwist twist;             // the twist actually commanded after all limits
};

class DiffDriveMixer {
 public:
  explicit DiffDriveMixer(const RobotParams& rp) : rp_(rp) {}
  // Limits v to [-evade_reverse_mps, max_speed] (the planner reverses only to evade), omega to
  // +-max_yaw_rate, their changes to the acceleration limits over dt, then scales both wheels
  // down together (keeping the curvature) when one exceeds max_wheel_speed_mps.
  WheelCommand mix(const BodyTwist& want, double dt);
  void reset() { last_ = {}; }
  const BodyTwist& last() const { return last_; }

 private:
  RobotParams rp_;
  BodyTwist last_;
};

}  // namespace fs::robot
