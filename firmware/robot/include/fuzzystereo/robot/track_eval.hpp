// Tracking evaluation on generated constant-velocity trajectories with exact ground truth (issue 5:
// "position RMSE lower than the raw per-frame measurements and velocity estimates within 0.1 m/s
// after 10 frames"). One obstacle per trajectory, Gaussian position noise per axis, fed to the
// MultiTracker exactly as the robot loop feeds it (one measurement per frame, always in view).
// Used by `fuzzystereo sim track-eval` and the tracker's unit tests (tests/cpp/robot/test_tracking.cpp).
#pragma once

#include "fuzzystereo/robot/params.hpp"

namespace fs::robot {

struct TrackEvalOptions {
  int trials = 100;              // trajectories
  int frames = 60;               // frames per trajectory
  double dt_s = 0.1;             // frame period [s] (10 Hz)
  double sigma_m = 0.05;         // position noise per axis [m] (stereo at a few metres)
  double max_axis_speed_mps = 0.6;  // each velocity component uniform in [-this, this] [m/s]
  int settle_frames = 10;        // velocity errors count from this frame on ("after 10 frames")
  unsigned seed = 42;
};

struct TrackEvalResult {
  double filt_pos_rmse_m = 0;       // filtered position vs truth, every frame
  double raw_pos_rmse_m = 0;        // raw measurement vs truth, every frame
  double vel_rmse_after_mps = 0;    // |v_est - v| RMS from settle_frames on
  double vel_p95_after_mps = 0;     // ... its 95th percentile
  double vel_max_after_mps = 0;     // ... its maximum
  double max_speed_mps = 0;         // fastest trajectory of the set [m/s]
  long frames_not_one_track = 0;    // frames where the tracker did not hold exactly one track (should be 0)
  long frames_total = 0;
};

// Deterministic for given options and parameters (std::mt19937 seeded with opt.seed). Throws
// std::invalid_argument on trials, frames or settle_frames out of range or a non-positive dt / sigma.
TrackEvalResult evaluate_constant_velocity(const TrackerParams& tp, const TrackEvalOptions& opt);

}  // namespace fs::robot
