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
  std::vector<CircleObstacle> obstacles;  // at t = 0; position at t is c + t * vel
  bool solvable = true;                   // false: goal (or robot) enclosed, gaps narrower than the robot
  std::string features;                   // "gap", "utrap", "moving", "ring-goal", "ring-robot"
};

// Deterministic in seed. blocked = true builds an unsolvable one.
NavScenario make_nav_scenario(std::uint64_t seed, bool blocked, const RobotParams& rp);

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
