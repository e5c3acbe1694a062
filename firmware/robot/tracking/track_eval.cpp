// Constant-velocity tracking evaluation (header: fuzzystereo/robot/track_eval.hpp).
#include "fuzzystereo/robot/track_eval.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "fuzzystereo/robot/clock.hpp"
#include "fuzzystereo/robot/tracker.hpp"

namespace fs::robot {

TrackEvalResult evaluate_constant_velocity(const TrackerParams& tp, const TrackEvalOptions& opt) {
  if (opt.trials < 1 || opt.trials > 100000)
    throw std::invalid_argument("track-eval: trials = " + std::to_string(opt.trials) + " is outside [1, 100000]");
  if (opt.frames < 2 || opt.frames > 100000)
    throw std::invalid_argument("track-eval: frames = " + std::to_string(opt.frames) + " is outside [2, 100000]");
  if (opt.settle_frames < 0 || opt.settle_frames >= opt.frames)
    throw std::invalid_argument("track-eval: settle_frames = " + std::to_string(opt.settle_frames) +
                                " must be in [0, frames - 1]");
  if (!(opt.dt_s > 0) || !(opt.sigma_m > 0) || !(opt.max_axis_speed_mps >= 0))
    throw std::invalid_argument("track-eval: dt_s and sigma_m must be > 0 and max_axis_speed_mps >= 0");
  std::mt19937 rng(opt.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double se_f = 0, se_r = 0, se_v = 0;
  long np = 0, nv = 0;
  std::vector<double> verr;
  TrackEvalResult r;
  for (int k = 0; k < opt.trials; ++k) {
    MultiTracker mt(tp);
    // Draw order (start x, start y, vx, vy, then per frame noise x, y) fixed: the figures in
    // docs/robot.md were measured with it.
    const Vec2 p0{3.0 + u(rng), 2.0 * u(rng)};
    const Vec2 v{opt.max_axis_speed_mps * u(rng), opt.max_axis_speed_mps * u(rng)};
    r.max_speed_mps = std::max(r.max_speed_mps, norm(v));
    for (int f = 0; f < opt.frames; ++f) {
      const double t = f * opt.dt_s;
      const Vec2 truth = p0 + t * v;
      const Vec2 z{truth.x + opt.sigma_m * n01(rng), truth.y + opt.sigma_m * n01(rng)};
      mt.step(s_to_ns(t), {{z, 0.2, 1, opt.sigma_m}}, [](Vec2) { return true; });
      ++r.frames_total;
      if (mt.tracks().size() != 1) {
        ++r.frames_not_one_track;
        continue;
      }
      const Track& tr = mt.tracks()[0];
      se_f += std::pow(norm(tr.pos() - truth), 2);
      se_r += std::pow(norm(z - truth), 2);
      ++np;
      if (f >= opt.settle_frames) {
        const double e = norm(tr.vel() - v);
        se_v += e * e;
        ++nv;
        verr.push_back(e);
      }
    }
  }
  if (np > 0) {
    r.filt_pos_rmse_m = std::sqrt(se_f / static_cast<double>(np));
    r.raw_pos_rmse_m = std::sqrt(se_r / static_cast<double>(np));
  }
  if (nv > 0) {
    std::sort(verr.begin(), verr.end());
    r.vel_rmse_after_mps = std::sqrt(se_v / static_cast<double>(nv));
    r.vel_p95_after_mps = verr[verr.size() * 95 / 100];
    r.vel_max_after_mps = verr.back();
  }
  return r;
}

}  // namespace fs::robot
