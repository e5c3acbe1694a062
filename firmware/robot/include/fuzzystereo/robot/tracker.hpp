// Multi-target tracker: one CvKalman (eq. 26-32) per obstacle, gated greedy nearest-neighbour
// association, confirmation after M hits, deletion after K consecutive misses counted only while
// the predicted position is inside the sensor's view (so obstacles that left the camera view coast
// and stay available to the planner). See docs/robot.md "Tracking".
#pragma once
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include "fuzzystereo/robot/clock.hpp"
#include "fuzzystereo/robot/geometry.hpp"
#include "fuzzystereo/robot/kalman.hpp"
#include "fuzzystereo/robot/params.hpp"

namespace fs::robot {

// One detected obstacle of the current frame, already in the world frame.
struct ObstacleMeasurement {
  Vec2 p;                  // ground-plane centre [m]
  double radius_m = 0.1;   // half the measured width [m]
  int distance_class = 0;  // detector's near/mid/far class (passed through)
  double sigma_m = 0;      // position std of this measurement [m]; 0 = TrackerParams::pos_sigma_m
  bool static_cells = false;  // its surface lies on old, stable map cells (robot::measurement_is_static)
  // Appearance (session 47): the mean rg chromaticity r / (r + g + b), g / (r + g + b) of the detection's
  // pixels in the left colour image; has_chroma false for grey cameras or too dark / too few pixels.
  bool has_chroma = false;
  Vec2 chroma{1.0 / 3.0, 1.0 / 3.0};
};

// Mean rg chromaticity of a set of RGB pixels: (sum r, sum g) / sum (r + g + b). has_chroma needs at least
// min_pixels pixels of mean r + g + b >= min_sum (dark pixels carry no colour). Brightness-invariant: the
// same surface under the sides' different shading keeps its chromaticity.
struct ChromaSum {
  std::uint64_t r = 0, g = 0, b = 0, n = 0;
  void add(std::uint8_t R, std::uint8_t G, std::uint8_t B) { r += R; g += G; b += B; ++n; }
  bool valid(std::uint64_t min_pixels = 20, std::uint64_t min_sum = 60) const {
    return n >= min_pixels && r + g + b >= min_sum * n;
  }
  Vec2 chroma() const {
    const double s = static_cast<double>(r + g + b);
    return s > 0 ? Vec2{static_cast<double>(r) / s, static_cast<double>(g) / s} : Vec2{1.0 / 3.0, 1.0 / 3.0};
  }
};

// Measurement model of a round obstacle seen by the camera (at the origin of the frame): the two
// silhouette rays through its box edges, at bearings bearing_a and bearing_b [rad], and the range of
// its front surface between them, front_range_m. The circle tangent to both rays whose nearest point
// on their bisector lies at front_range_m has its centre on the bisector at front_range_m + r, with
// r = front_range_m * s / (1 - s), s = sin(half the angle between the rays). (Placing the centre at
// the front's forward distance + half the box width along the camera's forward axis, as before
// session 12, leaves out r sin(bearing) of its lateral offset and over-measures r by 1 / cos(bearing);
// docs/robot.md "Session 12".) The half-angle is capped at asin(0.9) (r <= 9 x front range).
struct SilhouetteCircle {
  Vec2 centre;  // in the camera's ground-plane frame (x forward, y left) [m]
  double radius_m = 0;
};
SilhouetteCircle circle_from_silhouette(double bearing_a, double bearing_b, double front_range_m);

// Ray model ([loop] ray_centres): the centre of a round obstacle whose visible front, on the ray
// through its box centre, lies at `front` (camera ground-plane frame, x forward, y left) and whose
// box is 2 x radius_m wide at the front's depth: behind the front *along that ray* by
// radius_m x cos(bearing) (at bearing b the box of a circle is ~1 / cos(b) wider than its diameter at
// that depth). The camera-axis model (the default) steps radius_m along the forward axis instead,
// which leaves out ~r sin(b) of the lateral offset (docs/robot.md "Session 12", "Session 26").
Vec2 ray_centre(Vec2 front, double radius_m);

struct Track {
  int id = 0;
  CvKalman kf;
  double radius_m = 0;
  int distance_class = 0;
  int hits = 0;                 // frames with an associated measurement
  int misses = 0;               // consecutive visible misses
  bool confirmed = false;
  std::int64_t last_meas_ns = 0;
  Vec2 last_meas_p;             // for the finite-difference velocity measurement
  std::int64_t first_meas_ns = 0;  // the measurement that started the track
  Vec2 first_meas_p;
  double first_meas_var = 0;    // the first measurement's position variance [m^2]
  double last_meas_var = 0;     // its position variance [m^2]
  double last_meas_radius_m = 0;  // its half-width [m] (speed gate)
  bool last_meas_static = false;  // its ObstacleMeasurement::static_cells
  Vec2 meas_vel;                // the filtered velocity right after the last update (with coast_decay_s the
                                // state's velocity decays while coasting; the loop's moving test judges this one)
  // Appearance (TrackerParams::appearance_gate): a fading mean of its measurements' chromaticity, and the
  // distance of the last measurement's from that mean before the update (-1: one of them had none).
  bool has_chroma = false;
  Vec2 chroma{1.0 / 3.0, 1.0 / 3.0};
  double last_chroma_d = -1.0;
  bool updated_this_frame = false;
  double nis_mean = 2.0;        // faded mean of the position NIS (maneuver switch; 2 = the chi-square mean)
  bool maneuvering = false;     // Q level: accel_sigma_mps2 (true) or accel_sigma_steady_mps2
  bool mover = false;           // the loop's moving test passed at its last planning step (mark_movers)
  bool static_obstacle = false; // the loop found it static (static support) at its last step (mark_static)
  // The last kRecentMeas measured positions with their times, oldest first (the loop's moving test
  // over a recent window, [loop] moving_window_s).
  static constexpr std::size_t kRecentMeas = 32;
  std::vector<std::pair<std::int64_t, Vec2>> recent_meas;
  // The oldest recent measurement at most window_ns before the last one (the last one itself when
  // none is older).
  Vec2 meas_since(std::int64_t window_ns) const {
    for (const auto& [t, p] : recent_meas)
      if (t >= last_meas_ns - window_ns) return p;
    return last_meas_p;
  }
  void remember_measurement(std::int64_t t_ns, Vec2 p) {
    if (recent_meas.size() >= kRecentMeas) recent_meas.erase(recent_meas.begin());
    recent_meas.emplace_back(t_ns, p);
  }

  Vec2 pos() const { return {kf.px(), kf.py()}; }
  Vec2 vel() const { return {kf.vx(), kf.vy()}; }
};

// Is a world point inside the sensor's field of view and range right now?
using VisibilityFn = std::function<bool(Vec2)>;

class MultiTracker {
 public:
  explicit MultiTracker(const TrackerParams& p) : p_(p) {}

  // One frame at time t_ns: predict every track to t_ns, associate, update, manage tracks.
  // Returns the index pairs (track id, measurement index) that were associated.
  std::vector<std::pair<int, int>> step(std::int64_t t_ns, const std::vector<ObstacleMeasurement>& meas,
                                        const VisibilityFn& visible);

  const std::vector<Track>& tracks() const { return tracks_; }
  // Planner input: tracks (confirmed only unless include_tentative) as moving circles; the radius
  // grows by uncertainty_sigmas * position std, capped at uncertainty_max_m.
  std::vector<CircleObstacle> obstacles(bool include_tentative, double uncertainty_sigmas,
                                        double uncertainty_max_m) const;

  const TrackerParams& params() const { return p_; }

  // The robot loop's verdict for the next step: the tracks with these ids are movers, every other
  // one is not (TrackerParams::miss_movers_only).
  void mark_movers(const std::vector<int>& ids);
  // The robot loop's verdict for the next step: the tracks with these ids are static obstacles'
  // (TrackerParams::static_gate_m), every other one is not.
  void mark_static(const std::vector<int>& ids);

 private:
  // Chromaticity distance between a measurement and a track's fading mean; -1 when either has no colour.
  static double chroma_distance(const Track& tr, const ObstacleMeasurement& m) {
    return tr.has_chroma && m.has_chroma ? norm(m.chroma - tr.chroma) : -1.0;
  }
  // A measurement's position std: its own, or pos_sigma_m when it has none.
  double meas_sigma(const ObstacleMeasurement& m) const { return m.sigma_m > 0 ? m.sigma_m : p_.pos_sigma_m; }
  // The maneuver switch is on (accel_sigma_steady_mps2 > 0), and a track's Q level.
  bool switching() const { return p_.accel_sigma_steady_mps2 > 0.0; }
  double q_level(const Track& tr) const {
    return switching() && !tr.maneuvering ? p_.accel_sigma_steady_mps2 : p_.accel_sigma_mps2;
  }
  TrackerParams p_;
  std::vector<Track> tracks_;
  int next_id_ = 1;
  std::int64_t last_t_ns_ = 0;
  bool have_t_ = false;
};

// Memory of deleted confirmed tracks. The tracker deletes a confirmed track after max_misses
// visible misses of its PREDICTED position; a mover whose velocity was over-estimated is predicted
// into the view, missed there, and deleted while it stands beside the robot outside the view
// (seed 11, scenario 92: filtered 0.32 m/s against a true 0.13 m/s, deleted 3.2 s after its last
// measurement, 0.7 m from the robot, which then turned into it). update() keeps a copy of every
// confirmed track that disappeared since the previous call (as it was at its last update) for
// keep_s after its last measurement, so the loop can still plan with where it may be.
class LostTracks {
 public:
  void update(const std::vector<Track>& tracks, std::int64_t t_ns, double keep_s);
  const std::vector<Track>& lost() const { return lost_; }

 private:
  std::vector<Track> prev_;  // confirmed tracks at the previous call
  std::vector<Track> lost_;
};

}  // namespace fs::robot
