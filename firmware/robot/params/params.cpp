// [robot] [tracker] [planner] [watchdog] [perception] [motors] -> parameter structs. Ranges and choices were
// checked by the config loader (common/config/schema.toml); here only units change.
#include <cmath>

#include "config.hpp"
#include "fuzzystereo/robot/params.hpp"

namespace fs::robot {
namespace {
constexpr double kDegToRad = M_PI / 180.0;
}

RobotParams robot_params_from(const ConfigValues& v) {
  RobotParams p;
  p.radius_m = v.num("robot.radius_m");
  p.wheel_base_m = v.num("robot.wheel_base_m");
  p.max_speed_mps = v.num("robot.max_speed_mps");
  p.max_accel_mps2 = v.num("robot.max_accel_mps2");
  p.max_yaw_rate_radps = v.num("robot.max_yaw_rate_degps") * kDegToRad;
  p.max_yaw_accel_radps2 = v.num("robot.max_yaw_accel_degps2") * kDegToRad;
  p.max_wheel_speed_mps = v.num("robot.max_wheel_speed_mps");
  p.goal_tolerance_m = v.num("robot.goal_tolerance_m");
  p.arrive_margin_m = v.num("robot.arrive_margin_m");
  p.stop_distance_m = v.num("robot.stop_distance_m");
  p.evade_reverse_mps = v.num("robot.evade_reverse_mps");
  p.ground_ahead_min_pct = v.num("robot.ground_ahead_min_pct");
  p.ground_ahead_band_m = v.num("robot.ground_ahead_band_m");
  p.ground_ahead_release_pct = v.num("robot.ground_ahead_release_pct");
  if (p.ground_ahead_min_pct > 0 && p.ground_ahead_release_pct < p.ground_ahead_min_pct)
    throw ConfigError(v.source + ": field 'robot.ground_ahead_release_pct' = " + std::to_string(p.ground_ahead_release_pct) +
                      " must be >= 'robot.ground_ahead_min_pct' = " + std::to_string(p.ground_ahead_min_pct) +
                      " (the stop is released at or above the level that engages it)");
  p.stop_allows_turning = v.flag("robot.stop_allows_turning");
  p.odometry_accel_model = v.flag("robot.odometry_accel_model");
  return p;
}

TrackerParams tracker_params_from(const ConfigValues& v) {
  TrackerParams p;
  p.pos_sigma_m = v.num("tracker.pos_sigma_m");
  p.accel_sigma_mps2 = v.num("tracker.accel_sigma_mps2");
  p.accel_sigma_steady_mps2 = v.num("tracker.accel_sigma_steady_mps2");
  p.maneuver_nis = v.num("tracker.maneuver_nis");
  p.maneuver_fade = v.num("tracker.maneuver_fade");
  if (p.accel_sigma_steady_mps2 > p.accel_sigma_mps2)
    throw ConfigError(v.source + ": field 'tracker.accel_sigma_steady_mps2' = " + std::to_string(p.accel_sigma_steady_mps2) +
                      " must be <= 'tracker.accel_sigma_mps2' = " + std::to_string(p.accel_sigma_mps2) +
                      " (the maneuver switch raises Q from the steady level to accel_sigma_mps2; 0 = off)");
  p.init_vel_sigma_mps = v.num("tracker.init_vel_sigma_mps");
  p.gate_m = v.num("tracker.gate_m");
  p.gate_sigmas = v.num("tracker.gate_sigmas");
  p.gate_max_m = v.num("tracker.gate_max_m");
  p.confirm_hits = v.integer("tracker.confirm_hits");
  p.max_misses = v.integer("tracker.max_misses");
  p.max_coast_s = v.num("tracker.max_coast_s");
  p.miss_sigmas = v.num("tracker.miss_sigmas");
  p.miss_movers_only = v.flag("tracker.miss_movers_only");
  p.velocity_measurement = v.flag("tracker.velocity_measurement");
  p.max_speed_mps = v.num("tracker.max_speed_mps");
  p.static_gate_m = v.num("tracker.static_gate_m");
  p.reacquire_speed_mps = v.num("tracker.reacquire_speed_mps");
  p.reacquire_min_coast_s = v.num("tracker.reacquire_min_coast_s");
  p.appearance_gate = v.num("tracker.appearance_gate");
  p.coast_decay_s = v.num("tracker.coast_decay_s");
  p.coast_decay_unseen_only = v.flag("tracker.coast_decay_unseen_only");
  p.appearance_weight_m = v.num("tracker.appearance_weight_m");
  p.appearance_fade = v.num("tracker.appearance_fade");
  return p;
}

PlannerParams planner_params_from(const ConfigValues& v) {
  PlannerParams p;
  p.safety_margin_m = v.num("planner.safety_margin_m");
  p.collision_margin_m = v.num("planner.collision_margin_m");
  p.horizon_s = v.num("planner.horizon_s");
  p.sim_step_s = v.num("planner.sim_step_s");
  p.control_period_s = v.num("planner.control_period_s");
  p.grid_resolution_m = v.num("planner.grid_resolution_m");
  p.grid_margin_m = v.num("planner.grid_margin_m");
  p.lookahead_m = v.num("planner.lookahead_m");
  p.v_samples = v.integer("planner.v_samples");
  p.w_samples = v.integer("planner.w_samples");
  p.w_heading = v.num("planner.w_heading");
  p.w_clearance = v.num("planner.w_clearance");
  p.w_speed = v.num("planner.w_speed");
  p.w_progress = v.num("planner.w_progress");
  p.uncertainty_sigmas = v.num("planner.uncertainty_sigmas");
  p.uncertainty_max_m = v.num("planner.uncertainty_max_m");
  p.latency_compensation = v.flag("planner.latency_compensation");
  p.escape_inside_margin = v.flag("planner.escape_inside_margin");
  p.evade_when_blocked = v.flag("planner.evade_when_blocked");
  p.transient_not_blocking = v.flag("planner.transient_not_blocking");
  p.ignore_goal_footprint = v.flag("planner.ignore_goal_footprint");
  p.route_keep_ratio = v.num("planner.route_keep_ratio");
  p.route_keep_extra_m = v.num("planner.route_keep_extra_m");
  p.shortcut_ratio = v.num("planner.shortcut_ratio");
  p.shortcut_margin_m = v.num("planner.shortcut_margin_m");
  p.route_keep_offset_m = v.num("planner.route_keep_offset_m");
  p.unseen_check_s = v.num("planner.unseen_check_s");
  p.w_memory = v.num("planner.w_memory");
  p.max_lateral_accel_mps2 = v.num("planner.max_lateral_accel_mps2");
  p.speed_follows_heading = v.flag("planner.speed_follows_heading");
  return p;
}

PerceptionHealthParams perception_params_from(const ConfigValues& v) {
  PerceptionHealthParams p;
  p.enabled = v.flag("perception.health_check");
  p.min_contrast = v.num("perception.min_contrast");
  p.min_valid_pct = v.num("perception.min_valid_pct");
  p.noise_only_valid_pct = v.num("perception.noise_only_valid_pct");
  p.frozen_frames = v.integer("perception.frozen_frames");
  p.trip_frames = v.integer("perception.trip_frames");
  p.clear_frames = v.integer("perception.clear_frames");
  p.startup_frames = v.integer("perception.startup_frames");
  return p;
}

WatchdogParams watchdog_params_from(const ConfigValues& v) {
  return {static_cast<std::int64_t>(v.integer("watchdog.timeout_ms")) * 1'000'000};
}

MotorParams motor_params_from(const ConfigValues& v) {
  MotorParams p;
  p.backend = v.str("motors.backend") == "gpiod" ? MotorBackend::kGpiod : MotorBackend::kSim;
  p.driver = v.str("motors.driver") == "tb6612" ? MotorDriverChip::kTB6612 : MotorDriverChip::kL298N;
  p.gpio_chip = v.str("motors.gpio_chip");
  p.left_in1 = v.integer("motors.left_in1");
  p.left_in2 = v.integer("motors.left_in2");
  p.right_in1 = v.integer("motors.right_in1");
  p.right_in2 = v.integer("motors.right_in2");
  p.stby = v.integer("motors.stby");
  p.pwm_mode = v.str("motors.pwm_mode") == "software" ? PwmMode::kSoftware : PwmMode::kHardware;
  p.pwm_sysfs_root = v.str("motors.pwm_sysfs_root");
  p.pwm_chip = v.integer("motors.pwm_chip");
  p.left_pwm_channel = v.integer("motors.left_pwm_channel");
  p.right_pwm_channel = v.integer("motors.right_pwm_channel");
  p.left_pwm_line = v.integer("motors.left_pwm_line");
  p.right_pwm_line = v.integer("motors.right_pwm_line");
  p.pwm_frequency_hz = v.num("motors.pwm_frequency_hz");
  p.invert_left = v.flag("motors.invert_left");
  p.invert_right = v.flag("motors.invert_right");
  p.stop_mode = v.str("motors.stop_mode") == "coast" ? StopMode::kCoast : StopMode::kBrake;
  p.max_duty = v.num("motors.max_duty");
  return p;
}

}  // namespace fs::robot
