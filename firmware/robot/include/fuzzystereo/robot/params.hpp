// Parameter structs of the robot-side libraries, each filled from its config section by a
// xxx_params_from(const fs::ConfigValues&) function (firmware/robot/params/params.cpp). The config
// loader has already range-checked every field, so these functions only convert units
// (degrees in files -> radians in code, ms -> ns) and never re-validate.
#pragma once
#include <cstdint>
#include <string>

#include "fuzzystereo/robot/perception_health.hpp"

namespace fs {
struct ConfigValues;
}

namespace fs::robot {

// [robot] — body geometry and motion limits.
struct RobotParams {
  double radius_m = 0.15;             // bounding circle of the body [m]
  double wheel_base_m = 0.16;         // distance between the wheel contact points [m]
  double max_speed_mps = 0.5;         // forward speed limit [m/s]
  double max_accel_mps2 = 1.0;        // forward acceleration/deceleration limit [m/s^2]
  double max_yaw_rate_radps = 2.0943951023931953;    // [rad/s] (file: max_yaw_rate_degps = 120)
  double max_yaw_accel_radps2 = 6.283185307179586;  // [rad/s^2] (file: max_yaw_accel_degps2 = 360)
  double max_wheel_speed_mps = 0.6;   // wheel surface speed at motor duty 1.0 [m/s]
  double goal_tolerance_m = 0.15;     // goal reached when the centre is this close [m]
  double arrive_margin_m = 0.03;      // the planner declares arrival this far inside goal_tolerance_m [m]
  double stop_distance_m = 0.05;      // failsafe: free gap in front below which forward motion stops [m]
  double evade_reverse_mps = 0.2;     // reverse speed allowed only to evade a mover coming at the robot
                                      // when no forward arc is safe (0 = never reverses) [m/s]
  double ground_ahead_min_pct = 0.0;  // failsafe: forward motion stops while less than this percent of
                                      // the ground band ahead is road or a detected obstacle (0 = off) [%]
  double ground_ahead_band_m = 1.0;   // the band: ground up to this far forward of the camera [m]
  double ground_ahead_release_pct = 80.0;  // ... and, once stopped, moves on only from this percent [%]
  bool stop_allows_turning = true;    // failsafe stop still lets the robot turn on the spot
  bool odometry_accel_model = true;   // commanded odometry (no wheel encoders) integrates the wheels of
                                      // an acceleration-limited model (max_accel_mps2 per wheel, as the
                                      // simulator's motors) instead of stepping to each command
};

// [tracker] — Kalman filter eq. (26)-(32) and track management.
struct TrackerParams {
  double pos_sigma_m = 0.10;        // std of a position measurement per axis (R) [m]
  double accel_sigma_mps2 = 0.5;    // white-noise acceleration std (Q) [m/s^2]; with the maneuver
                                    // switch below, the level of a manoeuvring track
  double accel_sigma_steady_mps2 = 0.15;  // Q level of a track whose innovations look like noise
                                         // (maneuver switch, docs/robot.md "Session 31"); 0 = off:
                                         // every track always uses accel_sigma_mps2 [m/s^2]
  double maneuver_nis = 4.0;        // a track manoeuvres while its faded mean position NIS
                                    // (chi-square, 2 dof, mean 2 when the model fits) exceeds this
  double maneuver_fade = 0.7;       // weight of the previous mean NIS in the fading average
  double init_vel_sigma_mps = 5.0;  // velocity std of a new track (P0, eq. 30) [m/s]
  double gate_m = 0.5;              // association gate at zero uncertainty [m]
  double gate_sigmas = 3.0;         // gate grows by this many predicted position stds
  double gate_max_m = 2.0;          // upper bound of the gate [m]
  int confirm_hits = 3;             // M: a track is confirmed after this many associated frames
  int max_misses = 5;               // K: deleted after this many consecutive *visible* misses
  double max_coast_s = 10.0;        // deleted after this long without any measurement [s]
  double miss_sigmas = 2.0;         // a miss counts only when the disc of radius miss_sigmas x the
                                    // predicted position std + the track's radius lies in view (all
                                    // 8 points of its rim and its centre); 0 = the centre alone
  bool miss_movers_only = true;     // miss_sigmas applies only to tracks the loop marked as movers
                                    // (MultiTracker::mark_movers: its moving test, no static support)
  bool velocity_measurement = true; // z = [p; v] with v the finite difference (eq. 31-32, H = I)
  double max_speed_mps = 0.0;       // speed gate: fastest obstacle expected; a measurement further
                                    // from the track's last one than this speed (+ noise) allows is
                                    // not its [m/s]; 0 = off (docs/robot.md "Session 8": 0.5 measured
                                    // with the nav8 fields, not the default)
  double static_gate_m = 0.0;       // identity gate of static obstacles: a track the loop marked static
                                    // (MultiTracker::mark_static: static support) or a measurement on
                                    // old map cells (static_cells) pair only within this distance of
                                    // the track's last measurement [m]; 0 = off (docs/robot.md "Session 35")
  double reacquire_speed_mps = 0.0; // re-acquisition of coasting movers (docs/robot.md "Session 46"): a
                                    // measurement left over by the gated association may pair with a confirmed
                                    // track whose last measurement was not on old map cells and that has coasted at
                                    // least reacquire_min_coast_s, when it lies within this speed x the time since the
                                    // track's last measurement (+ 3 stds of both, + the change of half-width) of
                                    // that measurement [m/s]; 0 = off
  double reacquire_min_coast_s = 0.4;  // ... only tracks unmeasured for at least this long [s]
  double appearance_gate = 0.0;     // identity by colour (docs/robot.md "Session 47"): a measurement whose rg
                                    // chromaticity lies further than this from the track's (fading mean) is not
                                    // its obstacle; 0 = off. Needs a colour camera; ignored where either has none
  double coast_decay_s = 0.0;       // a track that missed its last frame predicts with its velocity decaying at
                                    // this time constant (CvKalman::predict_damped; docs/robot.md "Session 47")
                                    // [s]; 0 = constant velocity throughout (the paper's F)
  bool coast_decay_unseen_only = false;  // ... only while the track's estimate is outside the view
  double appearance_weight_m = 0.0; // association cost of colour: the greedy pairing orders candidates by their
                                    // distance + this x their chromaticity distance [m]; 0 = distance alone
  double appearance_fade = 0.7;     // weight of the track's previous chromaticity in its fading mean
};

// [planner] — global grid A* + sampled-arc local planner.
struct PlannerParams {
  double safety_margin_m = 0.10;     // extra clearance wanted around obstacles [m]
  double collision_margin_m = 0.02;  // hard clearance: closer counts as collision [m]
  double horizon_s = 2.5;            // arcs are checked against predicted obstacles this far [s]
  double sim_step_s = 0.1;           // time step of the arc check [s]
  double control_period_s = 0.2;     // expected time between frames (dynamic window) [s]
  double grid_resolution_m = 0.1;    // A* grid cell [m]
  double grid_margin_m = 3.0;        // grid extends this far beyond start/goal [m]
  double lookahead_m = 1.0;          // carrot distance along the global path [m]
  int v_samples = 7;                 // forward-speed samples in the dynamic window
  int w_samples = 15;                // yaw-rate samples in the dynamic window
  double w_heading = 1.0;            // cost weight: heading error to the carrot [1/rad]
  double w_clearance = 0.6;          // cost weight: lack of clearance (soft, within safety margin)
  double w_speed = 0.4;              // cost weight: slowness (1 - v/vmax)
  double w_progress = 1.5;           // cost weight: remaining distance to the carrot [1/m]
  double uncertainty_sigmas = 1.0;   // obstacle radius grows by this many position stds
  double uncertainty_max_m = 0.3;    // ... at most this much [m]
  bool latency_compensation = true;  // plan from the pose and obstacle positions predicted to the
                                     // time the command reaches the motors (docs/robot.md)
  bool escape_inside_margin = true;  // an obstacle already inside the hard margin at t = 0 blocks
                                     // only arcs that bring the robot closer to it (docs/robot.md)
  bool evade_when_blocked = true;    // with no route to the goal, still dodge a mover coming at the
                                     // standing robot (docs/robot.md, session 16)
  bool transient_not_blocking = false;  // transient circles (a tracked obstacle's possible places)
                                       // are left out of the "blocked" (no path) decision
  bool ignore_goal_footprint = false;  // obstacles whose inflated disc covers the goal are left out
                                       // of the global search (the local planner still avoids them)
  double route_keep_ratio = 0.0;     // route commitment: the last frame's global path is kept while it
                                     // is free and at most this times the new one's length (+ extra);
                                     // 0 = off (a new A* route every frame; docs/robot.md)
  double route_keep_extra_m = 0.0;   // ... plus this much [m]
  double shortcut_ratio = 1.5;       // gap shortcut (session 42): when the full-margin route exists but is
                                     // longer than this times the route with radius + shortcut_margin_m,
                                     // the latter is taken (a gap the safety margin closes, against a
                                     // detour round the wall's end); 0 = off (the narrower margin is
                                     // tried only when the full one finds nothing; before session 42)
  double shortcut_margin_m = 0.05;   // the margin of that route [m], between collision and safety margin
  double route_keep_offset_m = 0.3;  // the robot must be within this of the kept path [m]
  double unseen_check_s = 0.0;       // look where you drive: an arc with v > 0 whose leading point
                                     // (radius + safety margin ahead) enters ground the camera has not
                                     // seen recently within this time is not driven; 0 = off [s]
  double w_memory = 0.0;             // cost weight: how deep an arc enters the remembered places of
                                     // movers out of view (PlanContext::memory; docs/robot.md
                                     // "Session 29"); 0 = off
  double max_lateral_accel_mps2 = 0.0;  // arcs with v |omega| above this are not driven: a sharp turn
                                        // at speed sweeps the body into ground the forward camera has
                                        // not seen (docs/robot.md "Session 32"); 0 = off [m/s^2]
  bool speed_follows_heading = false;  // the w_speed term rewards vmax * max(0, cos e) instead of vmax,
                                       // e = heading error to the carrot: facing away from it, the robot
                                       // slows and turns on the spot (docs/robot.md "Session 44")
};

// [watchdog]
struct WatchdogParams {
  std::int64_t timeout_ns = 200'000'000;  // file: timeout_ms
};

// [motors]
enum class MotorBackend { kSim, kGpiod };
enum class MotorDriverChip { kL298N, kTB6612 };
enum class PwmMode { kHardware, kSoftware };
enum class StopMode { kBrake, kCoast };

struct MotorParams {
  MotorBackend backend = MotorBackend::kSim;
  MotorDriverChip driver = MotorDriverChip::kL298N;
  std::string gpio_chip = "gpiochip0";
  int left_in1 = 5, left_in2 = 6, right_in1 = 20, right_in2 = 21;  // BCM line offsets
  int stby = -1;                       // TB6612 STBY line; -1 = tied high / not wired
  PwmMode pwm_mode = PwmMode::kHardware;
  std::string pwm_sysfs_root = "/sys/class/pwm";
  int pwm_chip = 0;
  int left_pwm_channel = 0, right_pwm_channel = 1;  // hardware PWM channels (GPIO12 / GPIO13)
  int left_pwm_line = 12, right_pwm_line = 13;      // software PWM: GPIO line offsets
  double pwm_frequency_hz = 1000.0;
  bool invert_left = false, invert_right = false;
  StopMode stop_mode = StopMode::kBrake;
  double max_duty = 1.0;               // duty at command 1.0 (caps motor voltage)
};

RobotParams robot_params_from(const ConfigValues& v);
TrackerParams tracker_params_from(const ConfigValues& v);
PlannerParams planner_params_from(const ConfigValues& v);
WatchdogParams watchdog_params_from(const ConfigValues& v);
PerceptionHealthParams perception_params_from(const ConfigValues& v);  // [perception]
MotorParams motor_params_from(const ConfigValues& v);

}  // namespace fs::robot
