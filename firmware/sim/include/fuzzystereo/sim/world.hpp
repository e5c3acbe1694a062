// The synthetic stereo world: renders a rectified stereo pair of a Scene from any robot pose and
// time, with exact ground truth from the left camera's pixel-centre rays, and answers the
// collision questions of the robot simulator. Deterministic: the same scene, pose and time give
// bit-identical images on the same build, whatever the thread count (every pixel is computed
// independently; the sensor noise is a hash of (seed, camera, pixel, channel)).
//
// Conventions (docs/simulator.md): world x forward, y left, z up; camera frame X right, Y down,
// Z forward; left optical centre at the robot position, height camera.height_m, pitched down by
// camera.pitch_deg; right camera at +baseline along camera X. Pixel centres at integer
// coordinates; disparity d = f * B / Z [px], Z = depth along the optical axis [m].
#pragma once
#include <cstdint>
#include <vector>

#include "fuzzystereo/calib.hpp"
#include "fuzzystereo/image.hpp"
#include "fuzzystereo/sim/scene.hpp"

namespace fs::sim {

struct Pose2 {
  double x_m = 0.0, y_m = 0.0;  // [m]
  double yaw_rad = 0.0;         // counter-clockwise from +x [rad]
};

// Ground truth of one obstacle in one rendered frame (left camera).
struct ObstacleTruth {
  int id = 0;
  Shape shape = Shape::Box;
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // box of its visible pixels, inclusive (empty when pixels == 0)
  double world[3] = {0, 0, 0};           // centre of the solid at time t (x, y, z_m + height/2) [m]
  double cam[3] = {0, 0, 0};             // the same point in the left camera frame [m]
  double distance_m = 0.0;               // median depth Z over its visible pixels (0 when none) [m]
  int visible_pixels = 0;
  bool truncated = false;                // its box touches the image border
  double velocity[2] = {0, 0};           // world vx, vy [m/s]
};

// Road mask / sky mask / obstacle id images partition the image: each pixel is exactly one of
// ground (road_mask 255), sky or beyond camera.far_m (sky_mask 255), or an obstacle (id >= 0).
struct RenderResult {
  ImageRgb8 left, right;
  Image<float> disparity;  // left disparity [px] = f*B/Z; 0 = sky / no hit
  ImageU8 road_mask;       // 255 = ground plane hit, 0 otherwise
  ImageU8 sky_mask;        // 255 = sky (no hit within far_m), 0 otherwise
  ImageI32 obstacle_ids;   // obstacle id, -1 = none
  std::vector<ObstacleTruth> obstacles;  // every obstacle of the scene, in scene order
  StereoCalib calib;
};

// World footprint of an obstacle at some time: a circle or an oriented box, with its height span.
struct Footprint {
  int id = 0;
  bool circle = false;
  double x_m = 0.0, y_m = 0.0;          // centre [m]
  double yaw_rad = 0.0;                 // box orientation [rad]
  double half_length_m = 0.0, half_width_m = 0.0;  // box [m]
  double radius_m = 0.0;                // circle [m]
  double z0_m = 0.0, z1_m = 0.0;        // vertical span [m]
};

class World {
 public:
  explicit World(Scene scene);

  const Scene& scene() const { return scene_; }
  StereoCalib calib() const;
  // The pose of [robot] in the scene file.
  Pose2 scene_pose() const;

  // Renders the stereo pair seen from `pose` at time `t` [s]. threads <= 0: OpenMP default.
  RenderResult render(const Pose2& pose, double t, int threads = 0) const;
  RenderResult render(int threads = 0) const { return render(scene_pose(), 0.0, threads); }
  // Plain reference of render(): every sample ray against every obstacle whose screen box holds
  // it, full hit records. render() must give bit-identical results (tests/cpp/sim); several times
  // slower, kept only as that test's oracle.
  RenderResult render_reference(const Pose2& pose, double t, int threads = 0) const;

  std::vector<Footprint> obstacles_at(double t) const;
  // Signed distance [m] from (pose.x, pose.y) to the nearest footprint edge at time t (negative
  // inside one); +infinity without obstacles. Every obstacle counts, whatever its height.
  double clearance(const Pose2& pose, double t) const;
  // True when a disc of `radius_m` at the pose overlaps a footprint at time t.
  bool collides(const Pose2& pose, double radius_m, double t) const { return clearance(pose, t) < radius_m; }

 private:
  Scene scene_;
};

// Signed distance [m] from a point to a footprint edge (negative inside).
double footprint_distance(const Footprint& f, double x_m, double y_m);

}  // namespace fs::sim
