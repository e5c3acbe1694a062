// Progress towards the goal: is the robot stuck? ([loop] stuck_after_s, docs/robot.md "Session 23").
// The suites' gap timeouts are robots held 35-50 s in front of a gap by the circles that say where a
// track that is not a trusted mover may be (near-track circles, reachable sets). When the robot has
// not got `progress_m` closer to the goal (straight line) for `after_s`, the loop plans without
// them; the mode holds until the robot is `exit_m` closer than its best distance before the mode
// began, so approaching the gap alone does not bring the circles back and turn the route away again.
#pragma once
#include <cstdint>
#include <limits>

#include "fuzzystereo/robot/geometry.hpp"

namespace fs::robot {

struct ProgressParams {
  double after_s = 0.0;     // [loop] stuck_after_s (0 = never stuck)
  double progress_m = 0.3;  // [loop] stuck_progress_m
  double exit_m = 1.0;      // [loop] stuck_exit_m
};

class ProgressMonitor {
 public:
  explicit ProgressMonitor(const ProgressParams& p) : p_(p) {}
  // One planning step at time t_ns with the robot's straight-line distance to the goal; true while
  // the robot is stuck.
  bool update(std::int64_t t_ns, double goal_dist_m);
  double best_m() const { return best_m_; }

 private:
  ProgressParams p_;
  double best_m_ = std::numeric_limits<double>::infinity();
  std::int64_t best_ns_ = 0;
  bool stuck_ = false;
  double entry_m_ = 0.0;  // best distance when the mode began
};

// Giving up ([loop] give_up_after_s, docs/robot.md "Session 44"): the robot has not got `progress_m`
// closer to the goal (straight line, the same test as ProgressMonitor) for `after_s`, and since its last
// progress the planner has at least once found no path at all (PlanStatus::kBlocked). It then stops for
// good, a safe stop: the goal looks unreachable and the robot has stopped getting closer to it. The
// blocked scan alone needs 3 s of "blocked" in a row after its turn; a robot circling a ring of obstacles
// round the goal sees a new opening every few frames, so its plan flickers between blocked and moving
// and the run ended at the time limit (seeds 160-163: 4 of 6 missed safe stops).
struct GiveUpParams {
  double after_s = 0.0;     // [loop] give_up_after_s (0 = never)
  double progress_m = 0.3;  // [loop] stuck_progress_m
};

class GiveUpMonitor {
 public:
  explicit GiveUpMonitor(const GiveUpParams& p) : p_(p) {}
  // One planning step at time t_ns: the robot's straight-line distance to the goal and whether this
  // step's plan found no path. True from the step the rule holds on (it latches).
  bool update(std::int64_t t_ns, double goal_dist_m, bool blocked);
  bool given_up() const { return given_up_; }

 private:
  GiveUpParams p_;
  double best_m_ = std::numeric_limits<double>::infinity();
  std::int64_t best_ns_ = 0;
  bool blocked_since_best_ = false;
  bool given_up_ = false;
};

// While stuck, does a track that fails the moving test lose its near-track circle and reachable set?
// Without keep_unseen ([loop] stuck_keep_unseen = false, session 23) every such track does. With it
// (session 25) only a track whose estimated position is inside the camera's horizontal view
// (|bearing from the robot's heading| < half_fov_rad): the gap-closing circles of session 23 belong
// to the posts the robot is looking at, while a track beside or behind the robot may be a slow mover
// walking towards it that the camera cannot check (held-out suites: 12 of 15 collisions were stuck
// robots turning into such movers).
bool stuck_drops_track_circle(bool stuck, bool keep_unseen, const Pose2D& robot, Vec2 track_pos, double half_fov_rad);

// The near-track safety net (docs/robot.md "Closed-loop suite", "Session 41"): a confirmed track that
// fails the loop's moving test goes to the planner as a static circle where it is predicted now when it
// was measured within max_age_s ([loop] near_track_max_age_s), lies within near_m of the robot
// (near_track_m) and moves at least min_speed_mps (moving_speed_mps: a static obstacle's track coincides
// with its map cells). A circle that overlaps the robot's disc (centre distance <= track + robot radius)
// is dropped with kDrop (an estimate inside the robot taken to be wrong), kept with kKeep, and kept only
// for a track without static support with kKeepUnsupported (a static obstacle's ghost track beside a
// gap, kept, holds the robot off the gap; a mover's track beside the robot has none). A kept overlapping
// circle leaves the robot only the arcs that move away from it ([planner] escape_inside_margin).
enum class NearTrackOverlap { kDrop, kKeep, kKeepUnsupported };
struct NearTrackRule {
  double max_age_s = 1.0, near_m = 1.5, min_speed_mps = 0.04;
  NearTrackOverlap overlap = NearTrackOverlap::kDrop;
};
bool near_track_circle(const NearTrackRule& rule, double age_s, double dist_m, double speed_mps, double track_r,
                       double robot_r, bool static_support);

// The loop's moving test (docs/robot.md "Closed-loop suite", sessions 9, 27, 41): does a confirmed track
// go to the planner as a mover (predicted with its velocity)? Returns "mover", or the first condition that
// failed — logged per track in the run record (`tracks[].moving_test`):
//   "static measurement"   its last measurement's surface points lay on map cells that were occupied before
//                          ([loop] static_meas_age_s; the track's last_meas_static, session 42 split it out);
//   "static support"       the map held its place before the track (a static obstacle's track);
//   "few hits", "slow", "old"   fewer than min_hits measurements, speed below min_speed_mps, last measured
//                          more than max_age_s ago;
//   "short travel"         its measurements moved less than min_travel_m from the first one, or less than
//                          min_speed_mps x its life;
//   "travel within noise"  (travel_sigmas > 0) less than travel_sigmas x the two end measurements' std;
//   "direction"            its velocity is more than ~45 deg (cos < 0.7) off its travel — the whole-life
//                          travel, or with window_s > 0 the travel over the last window_s when that is at
//                          least window_travel_m; skipped within direction_near_m of the robot (session 41).
// With vacated_share > 0 (session 53, off by default) a track within vacated_near_m of the robot that fails only
// one of the travel conditions ("short travel", "travel within noise", "direction") is a mover all the same when
// the place it left is seen empty: of the cells of its disc at its measured position [loop] moving_vacated_window_s
// earlier that lie outside its disc now (at least vacated_min_cells of them), at least vacated_share are cells the
// map has seen through since (ObstacleMap::seen_free_share_outside). A static obstacle's place stays occupied (or
// hidden behind it); a mover's is free once the camera looks through it.
struct MovingTestParams {
  int min_hits = 4;
  double min_speed_mps = 0.04, max_age_s = 8.0, min_travel_m = 0.3, travel_sigmas = 0.0, window_s = 0.0,
         window_travel_m = 0.1, direction_near_m = 0.0;
  double vacated_share = 0.0, vacated_near_m = 3.0;
  int vacated_min_cells = 8;
};
struct MovingTestInput {
  bool static_measurement = false;  // the last measurement was found static (Track::last_meas_static)
  bool static_support = false;      // robot::has_static_support (or static_measurement)
  int hits = 0;
  Vec2 vel{};                  // filtered velocity
  double age_s = 0.0;          // since the last measurement
  Vec2 travel{};               // last measured position - first
  double life_s = 0.0;         // last measurement's time - first's
  double end_var_m2 = 0.0;     // first + last measurement's position variance
  Vec2 recent_travel{};        // last measured position - the one window_s before (used with window_s > 0)
  double robot_dist_m = 0.0;   // from the track's estimate to the robot
  double vacated = 0.0;        // the "vacated" share (MovingTestParams::vacated_share) ...
  int vacated_cells = 0;       // ... over this many cells
};
const char* moving_test(const MovingTestParams& p, const MovingTestInput& in);

}  // namespace fs::robot
