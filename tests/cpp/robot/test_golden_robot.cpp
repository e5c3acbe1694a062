// Cross-platform golden hashes of the robot layer (the companion of tests/cpp/sim/test_golden.cpp):
// the planner driving five seeded navigation scenarios in the kinematic simulator (nav_sim: planner,
// front stop, mixer, motor model, moving obstacles; four solvable, one without a path) and the
// constant-velocity Kalman filter's track evaluation (eq. 26-32 on noisy trajectories), all with the
// config defaults. Each result's doubles are hashed bit for bit and compared with
// tests/golden/robot_hashes.txt natively and under qemu-aarch64 (`make test`): the robot's arm64 build
// must drive the same paths as the desktop. It held only after fs_same_float_everywhere
// (cmake/FuzzyHelpers.cmake): with AArch64's default contraction and Eigen's fused NEON pmadd, 2 of the
// 5 runs ended at other times (scenario 13: 25.4 s and 6.67 m against 24.2 s and 6.45 m), the rest
// differed in the last bits. Not checked
// on x86-64 CPUs without FMA (qemu -cpu Nehalem): glibc's libm takes other code for sin, cos, atan2, ...
// there, and scenario 12 ends 0.2 s earlier (docs/algorithm.md 7).
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "../golden.hpp"
#include "config.hpp"
#include "fuzzystereo/robot/nav_sim.hpp"
#include "fuzzystereo/robot/params.hpp"
#include "fuzzystereo/robot/track_eval.hpp"

namespace {

using fs::golden::Fnv;

// The hashes, and the values behind them as text (shown when a hash differs).
fs::golden::Hashes robot_hashes(std::string& values) {
  fs::golden::Hashes out;
  char line[256];
  const fs::Config cfg = fs::parse_config("", "default.toml");
  const fs::robot::RobotParams rp = fs::robot::robot_params_from(cfg.values);
  const fs::robot::PlannerParams pp = fs::robot::planner_params_from(cfg.values);
  const fs::robot::TrackerParams tp = fs::robot::tracker_params_from(cfg.values);
  for (const auto& [seed, blocked] : {std::pair{11ull, false}, {12ull, false}, {13ull, false}, {14ull, false},
                                      {15ull, true}}) {
    const fs::robot::NavScenario sc = fs::robot::make_nav_scenario(seed, blocked, rp);
    const fs::robot::NavResult r = fs::robot::run_nav_scenario(sc, rp, pp);
    Fnv f;
    f.add(sc.start.x).add(sc.start.y).add(sc.goal.x).add(sc.goal.y).add(sc.obstacles.size());
    f.add(r.reached).add(r.collided).add(r.safe_stop).add(r.timed_out).add(r.time_s).add(r.path_m)
        .add(r.shortest_m).add(r.min_gap_m).add(static_cast<int>(r.final_status));
    out["nav." + std::to_string(seed) + (blocked ? ".blocked" : "")] = f.h;
    std::snprintf(line, sizeof line, "nav %llu: reached %d collided %d safe_stop %d time %.17g s path %.17g m gap %.17g m\n",
                  seed, r.reached, r.collided, r.safe_stop, r.time_s, r.path_m, r.min_gap_m);
    values += line;
  }
  fs::robot::TrackEvalOptions opt;
  opt.trials = 20;
  const fs::robot::TrackEvalResult t = fs::robot::evaluate_constant_velocity(tp, opt);
  out["track_eval"] = fs::golden::hash_of(t.filt_pos_rmse_m, t.raw_pos_rmse_m, t.vel_rmse_after_mps,
                                          t.vel_p95_after_mps, t.vel_max_after_mps, t.frames_not_one_track);
  std::snprintf(line, sizeof line, "track_eval: filtered %.17g raw %.17g vel rms %.17g p95 %.17g max %.17g not-one %ld\n",
                t.filt_pos_rmse_m, t.raw_pos_rmse_m, t.vel_rmse_after_mps, t.vel_p95_after_mps, t.vel_max_after_mps,
                t.frames_not_one_track);
  values += line;
  return out;
}

TEST(GoldenRobot, NavigationAndTrackingHashesMatchTheCommittedFile) {
  std::string values;
  const fs::golden::Hashes got = robot_hashes(values);
  SCOPED_TRACE("values:\n" + values);
  fs::golden::check(got, FS_GOLDEN_ROBOT_FILE, "the robot layer (tests/cpp/robot/test_golden_robot.cpp)");
}

}  // namespace
