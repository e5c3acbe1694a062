// World::render (the fast path: tile lists, depth-sorted early stop, clipped and octagon screen
// bounds, per-row ground/sky classes, lazy surface coordinates, cached noise lattice) against
// World::render_reference (the plain renderer it replaced): every output must be bit-identical,
// on scenes built to hit the fast path's special cases.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "fuzzystereo/sim/world.hpp"

namespace {

using namespace fs::sim;

// Scene variant v: small camera (fast also under qemu), obstacles of every shape and texture, a
// ring of posts around the robot (some straddle the camera plane, one nearly touches the camera),
// boxes turned and lifted off the ground, moving obstacles, every sky and ground kind, all
// supersampling factors, non-trivial radiometry, a near far_m (ground rows that end in sky).
Scene variant(int v) {
  Scene s;
  s.seed = 100 + static_cast<std::uint64_t>(v);
  s.camera.width = 72;
  s.camera.height = 44;
  s.camera.focal_px = 48.0 + 6.0 * v;
  s.camera.cx = 35.5 + 0.25 * v;
  s.camera.cy = 21.5 - 0.5 * v;
  s.camera.pitch_deg = v % 3 == 0 ? 0.0 : 4.0 + 3.0 * v;
  s.robot.yaw_deg = 17.0 * v;
  s.sky.kind = static_cast<SkyKind>(v % 3);
  s.ground.texture = static_cast<GroundTexture>(v % 4);
  s.ground.scale_m = 0.7 + 0.2 * v;
  s.light.sun_azimuth_deg = 40.0 * v;
  s.render.supersample = 1 + v % 4;
  s.render.far_m = v == 2 ? 12.0 : 80.0;
  s.radiometric.left.noise_sigma = v % 2 == 0 ? 1.0 : 0.0;
  s.radiometric.right.noise_sigma = 2.5;
  s.radiometric.right.gamma = v == 1 ? 0.8 : 1.0;
  s.radiometric.right.gain = v == 3 ? 1.3 : 1.0;
  s.radiometric.right.bias = v == 3 ? -20.0 : 0.0;
  const double yaw = s.robot.yaw_deg * M_PI / 180.0;
  const double c = std::cos(yaw), sn = std::sin(yaw);
  int id = 0;
  auto add = [&](ObstacleSpec o, double fwd, double left) {
    o.id = id++;
    o.x_m = fwd * c - left * sn;
    o.y_m = fwd * sn + left * c;
    o.texture = static_cast<Texture>(o.id % 6);
    o.color = {60 + 17 * o.id % 170, 200 - 13 * o.id % 140, 90 + 29 * o.id % 150};
    s.obstacles.push_back(o);
  };
  // Ring of posts around the robot (radius 0.9 m): in front, beside (straddling) and behind.
  for (int i = 0; i < 12; ++i) {
    ObstacleSpec o;
    o.shape = i % 2 ? Shape::Post : Shape::Cylinder;
    o.radius_m = 0.12;
    o.height_m = 0.5 + 0.1 * (i % 5);
    const double a = 2.0 * M_PI * i / 12.0 + 0.1 * v;
    add(o, 0.9 * std::cos(a), 0.9 * std::sin(a));
  }
  ObstacleSpec near_post;  // almost touching the camera, at the left image border
  near_post.shape = Shape::Cylinder;
  near_post.radius_m = 0.03;
  near_post.height_m = 1.0;
  add(near_post, 0.12, 0.1 + 0.01 * v);
  for (int i = 0; i < 4; ++i) {  // boxes, turned, some lifted, one moving
    ObstacleSpec b;
    b.shape = Shape::Box;
    b.length_m = 0.4 + 0.3 * i;
    b.width_m = 0.3 + 0.1 * i;
    b.height_m = 0.4 + 0.2 * i;
    b.yaw_deg = 25.0 * i + 10.0 * v;
    b.z_m = i % 2 ? 0.3 : 0.0;
    b.vy_mps = i == 3 ? -1.5 : 0.0;
    add(b, 2.0 + 1.1 * i, -1.5 + 0.9 * i);
  }
  ObstacleSpec far_cyl;  // tall, lifted, moving across
  far_cyl.shape = Shape::Cylinder;
  far_cyl.radius_m = 0.5;
  far_cyl.height_m = 2.0;
  far_cyl.z_m = 0.2;
  far_cyl.vy_mps = 0.3;
  add(far_cyl, 7.0, -0.5);
  return s;
}

template <class T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

void expect_identical(const RenderResult& a, const RenderResult& b, const std::string& what) {
  EXPECT_TRUE(same_bytes(a.left.data, b.left.data)) << what << ": left image";
  EXPECT_TRUE(same_bytes(a.right.data, b.right.data)) << what << ": right image";
  EXPECT_TRUE(same_bytes(a.disparity.data, b.disparity.data)) << what << ": disparity";
  EXPECT_TRUE(same_bytes(a.road_mask.data, b.road_mask.data)) << what << ": road mask";
  EXPECT_TRUE(same_bytes(a.sky_mask.data, b.sky_mask.data)) << what << ": sky mask";
  EXPECT_TRUE(same_bytes(a.obstacle_ids.data, b.obstacle_ids.data)) << what << ": obstacle ids";
  ASSERT_EQ(a.obstacles.size(), b.obstacles.size()) << what;
  for (std::size_t i = 0; i < a.obstacles.size(); ++i) {
    const ObstacleTruth &p = a.obstacles[i], &q = b.obstacles[i];
    EXPECT_TRUE(p.x0 == q.x0 && p.y0 == q.y0 && p.x1 == q.x1 && p.y1 == q.y1) << what << ": box of obstacle " << i;
    EXPECT_EQ(p.visible_pixels, q.visible_pixels) << what << ": obstacle " << i;
    EXPECT_EQ(std::memcmp(&p.distance_m, &q.distance_m, sizeof(double)), 0) << what << ": distance of obstacle " << i;
  }
}

TEST(SimRenderFast, BitIdenticalToTheReferenceRenderer) {
  int obstacle_pixels = 0, sky_pixels = 0, edge_variants = 0;
  for (int v = 0; v < 6; ++v) {
    const World w(variant(v));
    const Pose2 p0 = w.scene_pose();
    for (int step = 0; step < 2; ++step) {
      Pose2 p = p0;
      p.x_m += 0.3 * step * std::cos(p.yaw_rad);
      p.y_m += 0.3 * step * std::sin(p.yaw_rad);
      p.yaw_rad += 0.4 * step;
      const double t = 1.5 * step;
      const std::string what = "variant " + std::to_string(v) + " step " + std::to_string(step);
      const RenderResult ref = w.render_reference(p, t, 1);
      expect_identical(w.render(p, t, 1), ref, what + " (1 thread)");
      expect_identical(w.render(p, t, 2), ref, what + " (2 threads)");
      for (int id : ref.obstacle_ids.data) obstacle_pixels += id >= 0;
      for (auto m : ref.sky_mask.data) sky_pixels += m != 0;
      edge_variants += w.scene().render.supersample > 1;
    }
  }
  // The comparison covered obstacles and sky, not an empty world.
  EXPECT_GT(obstacle_pixels, 2000);
  EXPECT_GT(sky_pixels, 1000);
  EXPECT_GT(edge_variants, 6);
}

// The comparison can fail: half a second later the moving obstacles have moved.
TEST(SimRenderFast, ComparisonDetectsADifferentFrame) {
  const World w(variant(0));
  const RenderResult a = w.render(w.scene_pose(), 0.0, 1), b = w.render_reference(w.scene_pose(), 0.5, 1);
  EXPECT_FALSE(same_bytes(a.left.data, b.left.data));
  EXPECT_FALSE(same_bytes(a.obstacle_ids.data, b.obstacle_ids.data));
}

}  // namespace
