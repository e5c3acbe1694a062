// Multi-target tracker around CvKalman (eq. 26-32). Association is greedy global nearest
// neighbour: all (track, measurement) pairs inside the gate sorted by distance, the closest pair
// taken first. With the handful of obstacles a stereo detector reports per frame (< 20) and gates
// much smaller than the spacing of distinct obstacles, this equals the optimal (Hungarian)
// assignment except in rare crossing cases, costs O(nm log nm), and is deterministic; see
// docs/robot.md.
#include "fuzzystereo/robot/tracker.hpp"

#include <algorithm>
#include <cmath>

namespace fs::robot {
namespace {
// Radius of the speed gate's noise term in standard deviations of the 2-D position difference.
constexpr double kSpeedGateSigmas = 4.0;
}  // namespace

SilhouetteCircle circle_from_silhouette(double bearing_a, double bearing_b, double front_range_m) {
  const double tm = 0.5 * (bearing_a + bearing_b);
  const double s = std::min(0.9, std::sin(0.5 * std::fabs(bearing_a - bearing_b)));
  SilhouetteCircle c;
  c.radius_m = front_range_m * s / (1.0 - s);
  const double rho_c = front_range_m + c.radius_m;
  c.centre = {rho_c * std::cos(tm), rho_c * std::sin(tm)};
  return c;
}

Vec2 ray_centre(Vec2 front, double radius_m) {
  const double b = std::atan2(front.y, front.x);
  const double back = radius_m * std::cos(b);
  return {front.x + back * std::cos(b), front.y + back * std::sin(b)};
}

void MultiTracker::mark_movers(const std::vector<int>& ids) {
  for (Track& tr : tracks_) tr.mover = std::find(ids.begin(), ids.end(), tr.id) != ids.end();
}

void MultiTracker::mark_static(const std::vector<int>& ids) {
  for (Track& tr : tracks_) tr.static_obstacle = std::find(ids.begin(), ids.end(), tr.id) != ids.end();
}

std::vector<std::pair<int, int>> MultiTracker::step(std::int64_t t_ns, const std::vector<ObstacleMeasurement>& meas,
                                                    const VisibilityFn& visible) {
  // 1. predict every track to t (eq. 26).
  double dt_pred = 0.0;
  if (have_t_ && t_ns > last_t_ns_) {
    dt_pred = ns_to_s(t_ns - last_t_ns_);
    for (Track& tr : tracks_) {
      // coast_decay_s (session 47): a track not measured at the previous step is coasting; the velocity it
      // had when it left the view was worse than none for predicting where a mover went (docs/robot.md).
      // coast_decay_unseen_only: only while its estimate is outside the sensor's view (a mover that left it).
      if (p_.coast_decay_s > 0 && tr.last_meas_ns < last_t_ns_ &&
          (!p_.coast_decay_unseen_only || (visible && !visible(tr.pos()))))
        tr.kf.predict_damped(dt_pred, p_.coast_decay_s, q_level(tr));
      else
        tr.kf.predict(dt_pred, q_level(tr));
    }
  }
  if (!have_t_ || t_ns > last_t_ns_) last_t_ns_ = t_ns;
  have_t_ = true;
  for (Track& tr : tracks_) tr.updated_this_frame = false;

  // 2. gated greedy nearest-neighbour association.
  struct Cand {
    double d;
    int ti, mi;
  };
  std::vector<Cand> cands;
  for (int ti = 0; ti < static_cast<int>(tracks_.size()); ++ti) {
    const Track& tr = tracks_[ti];
    const double gate = std::min(p_.gate_max_m, p_.gate_m + p_.gate_sigmas * tr.kf.pos_sigma());
    const double dtm = ns_to_s(t_ns - tr.last_meas_ns);
    for (int mi = 0; mi < static_cast<int>(meas.size()); ++mi) {
      const ObstacleMeasurement& m = meas[mi];
      const double d = norm(m.p - tr.pos());
      if (d > gate) continue;
      // Speed gate: no obstacle moves faster than max_speed_mps, so a measurement further from the
      // track's last one than that speed over the time since, plus the noise of both positions
      // (kSpeedGateSigmas stds of their 2-D difference: a true measurement falls outside with
      // probability exp(-8) = 0.03 %) and the shift of the centre when the measured half-width changes (the
      // centre is placed half the width behind the visible front), belongs to something else. The
      // predicted-position gate alone is up to gate_max_m wide for a young track (its velocity std
      // is init_vel_sigma_mps), so the fragments of a gap wall 0.3 m apart chained into confirmed
      // tracks "travelling" at 0.4-5 m/s (seed-11 suite; docs/robot.md "Association").
      const double sigma = meas_sigma(m);
      const double speed_gate = p_.max_speed_mps * dtm + kSpeedGateSigmas * std::sqrt(sigma * sigma + tr.last_meas_var) +
                                std::abs(m.radius_m - tr.last_meas_radius_m);
      if (p_.max_speed_mps > 0 && norm(m.p - tr.last_meas_p) > speed_gate) continue;
      // Identity gate of static obstacles: a static obstacle does not move, so a measurement
      // further than static_gate_m from its track's last one is something else, and a measurement
      // on old map cells is not a far-off track's. Without it a static obstacle's track that had
      // coasted out of view for seconds (its gate grown to gate_max_m) took over a mover's
      // measurements 1-2 m away, and the loop's moving test, judging the track's whole-life
      // travel, never believed it moved (8 of 23 contacts, seeds 93-104). Off by default: on fresh seeds
      // 105-110 it gave 14 contacts against 11 (docs/robot.md "Session 35").
      if (p_.static_gate_m > 0 && (tr.static_obstacle || m.static_cells) && norm(m.p - tr.last_meas_p) > p_.static_gate_m)
        continue;
      // Appearance gate (session 47): neighbouring obstacles of another colour do not swap identities. A
      // track that took a neighbour's measurement (10 % of confirmed updates, docs/robot.md "Session 26";
      // a static post's track taking a passing mover's keeps its static history, and the mover's track
      // ends) reads a velocity neither has.
      const double cd = std::max(0.0, chroma_distance(tr, m));  // no colour: no gate, no cost
      if (p_.appearance_gate > 0 && cd > p_.appearance_gate) continue;
      // ... and as a cost: where two tracks compete for a measurement (or two measurements for a track), the
      // greedy pairing takes the one of the nearer colour first (appearance_weight_m per unit of distance).
      cands.push_back({d + p_.appearance_weight_m * cd, ti, mi});
    }
  }
  std::vector<int> meas_of(tracks_.size(), -1);
  std::vector<char> used(meas.size(), 0);
  std::vector<std::pair<int, int>> assoc;
  // Greedy: the pairs in increasing d (ties by index, so deterministic), each taken when its track and its
  // measurement are both still free.
  const auto take_nearest_first = [&](std::vector<Cand>& pairs) {
    std::sort(pairs.begin(), pairs.end(), [](const Cand& a, const Cand& b) {
      return a.d != b.d ? a.d < b.d : (a.ti != b.ti ? a.ti < b.ti : a.mi < b.mi);
    });
    for (const Cand& c : pairs) {
      if (meas_of[c.ti] >= 0 || used[c.mi]) continue;
      meas_of[c.ti] = c.mi;
      used[c.mi] = 1;
    }
  };
  take_nearest_first(cands);
  // 2b. re-acquisition of coasting movers (reacquire_speed_mps > 0, docs/robot.md "Session 46"). A mover's
  // coasted prediction drifts at its velocity error (0.1-0.4 m/s on the vision measurements: 1-3 m after
  // seconds out of view), beyond the gate, and its measurements then start a new track that knows no velocity
  // and fails the loop's moving test for 1-2 s, while the old one coasts on as a phantom. What cannot be wrong
  // is where the track was last measured and how fast an obstacle can go: a left-over measurement within that
  // reach of a coasting track's last measurement is its obstacle (the nearest relative to the reach first); the
  // update's finite-difference velocity then spans the whole gap. Not for tracks last measured on old map cells
  // (static obstacles' tracks; the loop's moving test would not trust them anyway) nor for such measurements.
  // Every confirmed track, not only the loop's movers: a young mover's track (3-4 hits) has not passed the moving
  // test yet, and its velocity from 0.2 s differences is the least reliable of all (session 46).
  if (p_.reacquire_speed_mps > 0) {
    std::vector<Cand> re;
    for (int ti = 0; ti < static_cast<int>(tracks_.size()); ++ti) {
      const Track& tr = tracks_[ti];
      const double dtm = ns_to_s(t_ns - tr.last_meas_ns);
      if (meas_of[ti] >= 0 || !tr.confirmed || tr.last_meas_static || dtm < p_.reacquire_min_coast_s) continue;
      for (int mi = 0; mi < static_cast<int>(meas.size()); ++mi) {
        const ObstacleMeasurement& m = meas[mi];
        if (used[mi] || m.static_cells) continue;
        if (p_.appearance_gate > 0 && chroma_distance(tr, m) > p_.appearance_gate) continue;
        const double sigma = meas_sigma(m);
        const double reach = p_.reacquire_speed_mps * dtm + 3.0 * std::sqrt(sigma * sigma + tr.last_meas_var) +
                             std::abs(m.radius_m - tr.last_meas_radius_m);
        const double d = norm(m.p - tr.last_meas_p);
        if (d <= reach) re.push_back({d / reach, ti, mi});
      }
    }
    take_nearest_first(re);
  }

  // 3. update associated tracks (eq. 31-32), count misses of the others.
  for (int ti = 0; ti < static_cast<int>(tracks_.size()); ++ti) {
    Track& tr = tracks_[ti];
    const int mi = meas_of[ti];
    if (mi < 0) {
      if (visible && visible(tr.pos())) {  // out of view: coast, no miss counted
        bool all_in = true;
        if (p_.miss_sigmas > 0 && (tr.mover || !p_.miss_movers_only)) {
          // Only where the whole region the object may be in is in view does seeing nothing mean it
          // is not there; a drifting prediction of an out-of-view mover enters the view first.
          const auto& P = tr.kf.P();
          const double r = p_.miss_sigmas * std::sqrt(std::max(P(0, 0), P(1, 1))) + tr.radius_m;
          for (int k = 0; k < 8 && all_in; ++k) {
            const double a = k * M_PI / 4.0;
            all_in = visible(tr.pos() + Vec2{r * std::cos(a), r * std::sin(a)});
          }
        }
        if (all_in) ++tr.misses;
      }
      continue;
    }
    const ObstacleMeasurement& m = meas[mi];
    const double sigma = meas_sigma(m);
    const double var = sigma * sigma;
    const double dtm = ns_to_s(t_ns - tr.last_meas_ns);
    if (switching()) {
      // Maneuver switch (docs/robot.md "Session 31"): the fading mean of the position NIS, a
      // chi-square variable with mean 2 while the constant-velocity model and R fit. Above
      // maneuver_nis the track turns, starts or stops (or its measurements jump between
      // fragments): it gets the high Q level, raised already for the interval just predicted so
      // this update follows the measurement; back at the steady level once the mean falls again.
      const double nis = tr.kf.position_nis(m.p.x, m.p.y, var);
      tr.nis_mean = p_.maneuver_fade * tr.nis_mean + (1.0 - p_.maneuver_fade) * nis;
      const bool now = tr.nis_mean > p_.maneuver_nis;
      if (now && !tr.maneuvering && dt_pred > 0.0) {
        const double hi = p_.accel_sigma_mps2, lo = p_.accel_sigma_steady_mps2;
        tr.kf.add_process_noise(dt_pred, std::sqrt(std::max(0.0, hi * hi - lo * lo)));
      }
      tr.maneuvering = now;
    }
    if (p_.velocity_measurement && tr.hits >= 1 && dtm > 1e-6) {
      // z = [p; v], v = finite difference to this track's previous measurement. With independent
      // position noise var_k, var_{k-1}: Var(v) = (var_k + var_{k-1}) / dt^2, Cov(p, v) = var_k / dt.
      // R is that covariance (the paper's R is diagonal; the p-v cross term is kept because it is
      // exactly the noise of the vector we feed, see docs/robot.md).
      const Vec2 v = (1.0 / dtm) * (m.p - tr.last_meas_p);
      const double prev_var = tr.last_meas_var;
      Vec4 z(m.p.x, m.p.y, v.x, v.y);
      Mat4 R = Mat4::Zero();
      R(0, 0) = R(1, 1) = var;
      R(2, 2) = R(3, 3) = (var + prev_var) / (dtm * dtm);
      R(0, 2) = R(2, 0) = R(1, 3) = R(3, 1) = var / dtm;
      tr.kf.update(z, R);
    } else {
      tr.kf.update_position(m.p.x, m.p.y, var);
    }
    // A detection can only under-measure an obstacle's width (it is fragmented, partly outside the
    // view or behind another obstacle), so the track keeps the largest radius measured. (An EMA of
    // the measurements, used before, let a cylinder at the edge of the view shrink from 0.17 m to
    // 0.13 m, and the planner then turned the robot into it.)
    tr.radius_m = std::max(tr.radius_m, m.radius_m);
    tr.distance_class = m.distance_class;
    ++tr.hits;
    tr.misses = 0;
    tr.confirmed = tr.confirmed || tr.hits >= p_.confirm_hits;
    tr.last_meas_ns = t_ns;
    tr.last_meas_p = m.p;
    tr.remember_measurement(t_ns, m.p);
    tr.last_meas_var = var;
    tr.last_meas_radius_m = m.radius_m;
    tr.last_meas_static = m.static_cells;
    tr.meas_vel = tr.vel();
    tr.last_chroma_d = chroma_distance(tr, m);
    if (m.has_chroma) {
      tr.chroma = tr.has_chroma ? p_.appearance_fade * tr.chroma + (1.0 - p_.appearance_fade) * m.chroma : m.chroma;
      tr.has_chroma = true;
    }
    tr.updated_this_frame = true;
    assoc.emplace_back(tr.id, mi);
  }

  // 4. delete: confirmed after K consecutive visible misses, tentative after the first one, any
  // track after max_coast_s without a measurement.
  const std::int64_t max_coast_ns = s_to_ns(p_.max_coast_s);
  std::erase_if(tracks_, [&](const Track& tr) {
    if (tr.updated_this_frame) return false;
    if (t_ns - tr.last_meas_ns > max_coast_ns) return true;
    return tr.confirmed ? tr.misses >= p_.max_misses : tr.misses >= 1;
  });

  // 5. new tentative tracks from unassociated measurements (eq. 30: huge velocity variance).
  for (int mi = 0; mi < static_cast<int>(meas.size()); ++mi) {
    if (used[mi]) continue;
    const ObstacleMeasurement& m = meas[mi];
    const double sigma = meas_sigma(m);
    Track tr;
    tr.id = next_id_++;
    tr.kf.init(m.p.x, m.p.y, sigma * sigma, p_.init_vel_sigma_mps * p_.init_vel_sigma_mps);
    tr.radius_m = m.radius_m;
    tr.distance_class = m.distance_class;
    tr.hits = 1;
    tr.confirmed = p_.confirm_hits <= 1;
    tr.last_meas_ns = t_ns;
    tr.last_meas_p = m.p;
    tr.first_meas_ns = t_ns;
    tr.first_meas_p = m.p;
    tr.remember_measurement(t_ns, m.p);
    tr.first_meas_var = sigma * sigma;
    tr.last_meas_var = sigma * sigma;
    tr.last_meas_radius_m = m.radius_m;
    tr.last_meas_static = m.static_cells;
    tr.has_chroma = m.has_chroma;
    tr.chroma = m.chroma;
    tr.updated_this_frame = true;
    assoc.emplace_back(tr.id, mi);
    tracks_.push_back(tr);
  }
  return assoc;
}

std::vector<CircleObstacle> MultiTracker::obstacles(bool include_tentative, double uncertainty_sigmas,
                                                    double uncertainty_max_m) const {
  std::vector<CircleObstacle> out;
  for (const Track& tr : tracks_) {
    if (!tr.confirmed && !include_tentative) continue;
    const double grow = std::min(uncertainty_max_m, uncertainty_sigmas * tr.kf.pos_sigma());
    out.push_back({tr.pos(), tr.radius_m + grow, tr.vel()});
  }
  return out;
}

void LostTracks::update(const std::vector<Track>& tracks, std::int64_t t_ns, double keep_s) {
  for (const Track& old : prev_) {
    const bool alive = std::any_of(tracks.begin(), tracks.end(), [&](const Track& tr) { return tr.id == old.id; });
    if (!alive) lost_.push_back(old);
  }
  const std::int64_t keep_ns = s_to_ns(keep_s);
  std::erase_if(lost_, [&](const Track& tr) { return t_ns - tr.last_meas_ns > keep_ns; });
  prev_.clear();
  for (const Track& tr : tracks)
    if (tr.confirmed) prev_.push_back(tr);
}

}  // namespace fs::robot
