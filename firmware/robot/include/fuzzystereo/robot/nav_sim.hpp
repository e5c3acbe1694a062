// Closed-loop 2-D kinematic navigation check of the planner: perfect obstacle knowledge (true
// positions and velocities), circles, some moving, narrow gaps and U-traps, seeded. The loop is the
// robot loop with the perception replaced by ground truth: SimClock -> SimMotors (true pose) ->
// Planner -> front-stop failsafe -> DiffDriveMixer -> SimMotors. Used by the unit tests (targets:
// >= 98 % of solvable scenarios reach the goal without collision, 100 % of unsolvable ones end in a
// safe stop) and callable from the app (e.g. a `fuzzystereo selftest`).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "fuzzystereo/robot/geometry.hpp"
#include "fuzzystereo/robot/params.hpp"
#include "fuzzystereo/robot/planner.hpp"

namespace fs::robot {

struct NavScenario {
  std::uint64_t seed = 0;
  Pose2D start;
  Vec2 goal;
  std::vector<CircleObstacle> obstacles;  // at t = 0; position at t is at(i, t)
  // Per obstacle: its changes of velocity, (t [s], new velocity), in time order; empty = constant
  // velocity (static obstacles, pass-through movers). A stop is a turn to velocity 0.
  std::vector<std::vector<std::pair<double, Vec2>>> turns;
  bool solvable = true;                   // false: goal (or robot) enclosed, gaps narrower than the robot
  std::string features;                   // "gap", "utrap", "moving", "ring-goal", "ring-robot"

  // Position and velocity of obstacle i at time t (c, vel, then each turn in order).
  Vec2 at(std::size_t i, double t) const;
  Vec2 vel_at(std::size_t i, double t) const;
};

// How the movers of a generated scenario meet static obstacles and each other.
enum class MoverModel {
  kPass,   // straight lines through everything (the worlds of every suite file up to session 26)
  kStop,   // walk until the next step would overlap something, then stand there
  kSlide,  // (default) deflect along the obstacle (the tangent at the contact, keeping speed and the forward
           // side); stand only when both tangents are blocked. Off the start and goal areas (which
           // the straight lines never cross either) they bounce: mirrored about the area's tangent.
};

// Deterministic in seed. blocked = true builds an unsolvable one. Same seed, same static obstacles
// and mover lines whatever the mover model; with kStop / kSlide a mover whose line starts inside an
// obstacle starts where its line comes out of it.
NavScenario make_nav_scenario(std::uint64_t seed, bool blocked, const RobotParams& rp, MoverModel movers = MoverModel::kSlide);

// Solid movers (kStop, kSlide): fills sc.turns by stepping every mover in dt steps up to horizon_s
// against the static obstacles, the other movers (at their positions then) and `avoid` (discs only
// kSlide movers keep out of).
void walk_movers(NavScenario& sc, MoverModel model, const std::vector<CircleObstacle>& avoid = {},
                 double horizon_s = 120.0, double dt = 0.05);

struct NavResult {
  bool reached = false;    // within goal tolerance
  bool collided = false;   // robot disc touched an obstacle disc at any 10 ms sub-step
  bool safe_stop = false;  // ended standing still, status blocked, no collision
  bool timed_out = false;
  double time_s = 0;
  double path_m = 0;       // distance driven
  double shortest_m = 0;   // shortest_path_length among the static obstacles (solvable only)
  double min_gap_m = 0;    // smallest surface gap seen
  PlanStatus final_status = PlanStatus::kMoving;
};

NavResult run_nav_scenario(const NavScenario& sc, const RobotParams& rp, const PlannerParams& pp);

struct NavSuiteResult {
  int solvable = 0, reached_clean = 0, collisions = 0, timeouts = 0;
  int blocked = 0, blocked_safe = 0;
  double mean_path_ratio = 0;  // driven / shortest over the clean successes
  double max_path_ratio = 0;
  std::vector<std::uint64_t> failed_seeds;
  double success_rate() const { return solvable ? static_cast<double>(reached_clean) / solvable : 0.0; }
  double safe_stop_rate() const { return blocked ? static_cast<double>(blocked_safe) / blocked : 0.0; }
};

NavSuiteResult run_nav_suite(int n_solvable, int n_blocked, std::uint64_t seed, const RobotParams& rp,
                             const PlannerParams& pp);

}  // namespace fs::robot
