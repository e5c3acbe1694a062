#include "fuzzystereo/robot/progress.hpp"

#include <cmath>

namespace fs::robot {

bool ProgressMonitor::update(std::int64_t t_ns, double goal_dist_m) {
  if (stuck_ && goal_dist_m < entry_m_ - p_.exit_m) stuck_ = false;
  if (goal_dist_m < best_m_ - p_.progress_m) {  // best_m_ starts at +inf
    best_m_ = goal_dist_m;
    best_ns_ = t_ns;
  }
  if (!stuck_ && p_.after_s > 0 && static_cast<double>(t_ns - best_ns_) * 1e-9 > p_.after_s) {
    stuck_ = true;
    entry_m_ = best_m_;
  }
  return stuck_;
}

bool GiveUpMonitor::update(std::int64_t t_ns, double goal_dist_m, bool blocked) {
  if (given_up_) return true;
  if (goal_dist_m < best_m_ - p_.progress_m) {  // best_m_ starts at +inf
    best_m_ = goal_dist_m;
    best_ns_ = t_ns;
    blocked_since_best_ = false;
  }
  blocked_since_best_ = blocked_since_best_ || blocked;
  given_up_ = p_.after_s > 0 && blocked_since_best_ && static_cast<double>(t_ns - best_ns_) * 1e-9 >= p_.after_s;
  return given_up_;
}

bool stuck_drops_track_circle(bool stuck, bool keep_unseen, const Pose2D& robot, Vec2 track_pos, double half_fov_rad) {
  if (!stuck) return false;
  if (!keep_unseen) return true;
  return std::fabs(bearing_of(robot, track_pos)) < half_fov_rad;
}

bool near_track_circle(const NearTrackRule& rule, double age_s, double dist_m, double speed_mps, double track_r,
                       double robot_r, bool static_support) {
  if (age_s > rule.max_age_s || dist_m > rule.near_m || speed_mps < rule.min_speed_mps) return false;
  if (dist_m > track_r + robot_r) return true;  // clear of the robot's disc
  return rule.overlap == NearTrackOverlap::kKeep ||
         (rule.overlap == NearTrackOverlap::kKeepUnsupported && !static_support);
}

namespace {
// The travel conditions of the test ("short travel", "travel within noise", "direction"); "mover" when all pass.
const char* travel_verdict(const MovingTestParams& p, const MovingTestInput& in, double speed) {
  const double dist = norm(in.travel);
  if (dist < p.min_travel_m || dist < p.min_speed_mps * in.life_s) return "short travel";
  if (p.travel_sigmas > 0 && dist < p.travel_sigmas * std::sqrt(in.end_var_m2)) return "travel within noise";
  if (p.direction_near_m > 0 && in.robot_dist_m <= p.direction_near_m) return "mover";
  if (p.window_s > 0) {
    const double rd = norm(in.recent_travel);
    if (rd >= p.window_travel_m)
      return in.recent_travel.x * in.vel.x + in.recent_travel.y * in.vel.y >= 0.7 * rd * speed ? "mover" : "direction";
  }
  return in.travel.x * in.vel.x + in.travel.y * in.vel.y >= 0.7 * dist * speed ? "mover" : "direction";
}
}  // namespace

const char* moving_test(const MovingTestParams& p, const MovingTestInput& in) {
  if (in.static_measurement) return "static measurement";
  if (in.static_support) return "static support";
  if (in.hits < p.min_hits) return "few hits";
  const double speed = norm(in.vel);
  if (speed < p.min_speed_mps) return "slow";
  if (in.age_s > p.max_age_s) return "old";
  const char* verdict = travel_verdict(p, in, speed);
  const bool vacated = p.vacated_share > 0 && in.robot_dist_m <= p.vacated_near_m &&
                       in.vacated_cells >= p.vacated_min_cells && in.vacated >= p.vacated_share;
  return vacated ? "mover" : verdict;
}

}  // namespace fs::robot
