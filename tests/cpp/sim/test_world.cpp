// The synthetic world: determinism, exact geometry of the ground truth, stereo consistency of the
// rendered pair, mask partition, obstacle truth, footprints and the generator.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "fuzzystereo/sim/generator.hpp"
#include "fuzzystereo/sim/world.hpp"

namespace {

using namespace fs::sim;

// Small pitch-0 camera so the pinhole expectations are simple and the tests fast (also under qemu).
Scene small_scene() {
  Scene s = parse_scene(
      "seed = 5\n[camera]\nwidth = 200\nheight = 150\nfocal_px = 150\npitch_deg = 0\n"
      "[radiometric.left]\nnoise_sigma = 0\n[radiometric.right]\nnoise_sigma = 0\n",
      "small.toml");
  return s;
}

double grey(const fs::Rgb8& p) { return 0.299 * p.r + 0.587 * p.g + 0.114 * p.b; }

// Right-image grey at real column x (linear interpolation), NaN outside.
double right_grey(const fs::ImageRgb8& r, double x, int y) {
  const int x0 = static_cast<int>(std::floor(x));
  if (x0 < 0 || x0 + 1 >= r.width) return NAN;
  const double f = x - x0;
  return (1 - f) * grey(r.at(x0, y)) + f * grey(r.at(x0 + 1, y));
}

// Mean |left(x,y) - right(x - d(x,y) - extra, y)| over pixels where `use` holds.
template <class Pred>
double stereo_mad(const RenderResult& res, double extra, Pred use) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < res.left.height; ++y)
    for (int x = 0; x < res.left.width; ++x) {
      const float d = res.disparity.at(x, y);
      if (d <= 0.f || !use(x, y)) continue;
      const double r = right_grey(res.right, static_cast<double>(x) - d - extra, y);
      if (std::isnan(r)) continue;
      sum += std::fabs(grey(res.left.at(x, y)) - r);
      ++n;
    }
  EXPECT_GT(n, 500);
  return sum / std::max(n, 1);
}

TEST(SimWorld, SameSceneGivesIdenticalBytesAtAnyThreadCount) {
  Scene s = parse_scene(
      "seed = 9\n[camera]\nwidth = 160\nheight = 90\nfocal_px = 105\n[radiometric.right]\nnoise_sigma = 3\n"
      "[[obstacles]]\nx_m = 3\ntexture = \"bricks\"\n[[obstacles]]\nshape = \"post\"\nx_m = 5\ny_m = 1\n",
      "d.toml");
  const World w(s);
  const RenderResult a = w.render(1), b = w.render(2), c = World(s).render(2);
  EXPECT_TRUE(a.left.data == b.left.data && a.right.data == b.right.data);
  EXPECT_TRUE(a.disparity.data == b.disparity.data && a.obstacle_ids.data == b.obstacle_ids.data);
  EXPECT_TRUE(a.left.data == c.left.data && a.right.data == c.right.data);
  s.seed = 10;  // different seed: different textures and noise, same geometry
  const RenderResult d = World(s).render(2);
  EXPECT_FALSE(a.left.data == d.left.data);
  EXPECT_FALSE(a.right.data == d.right.data);
  EXPECT_TRUE(a.disparity.data == d.disparity.data);
}

TEST(SimWorld, FrontoParallelBoxHasExactDisparityAndPinholeBox) {
  Scene s = small_scene();
  const double Z = 3.0, Wd = 0.8, L = 0.4, Hb = 1.0;
  ObstacleSpec o;
  o.id = 7;
  o.shape = Shape::Box;
  o.x_m = Z + L / 2;  // front face at depth Z (pitch 0, robot at the origin looking along +x)
  o.y_m = 0.0;
  o.length_m = L;
  o.width_m = Wd;
  o.height_m = Hb;
  s.obstacles.push_back(o);
  const World w(s);
  const RenderResult r = w.render(2);
  const auto& c = s.camera;
  const double f = c.focal_px, B = c.baseline_m, h = c.height_m;
  // Pinhole projection of the front face; pixel centres at integer coordinates.
  const int x0 = static_cast<int>(std::ceil(c.cx - f * (Wd / 2) / Z));
  const int x1 = static_cast<int>(std::floor(c.cx + f * (Wd / 2) / Z));
  const int y0 = static_cast<int>(std::ceil(c.cy + f * (h - Hb) / Z));
  const int y1 = static_cast<int>(std::floor(c.cy + f * h / Z));
  ASSERT_EQ(r.obstacles.size(), 1u);
  const ObstacleTruth& t = r.obstacles[0];
  EXPECT_EQ(t.id, 7);
  EXPECT_EQ(t.x0, x0);
  EXPECT_EQ(t.x1, x1);
  EXPECT_EQ(t.y0, y0);
  EXPECT_EQ(t.y1, y1);
  EXPECT_EQ(t.visible_pixels, (x1 - x0 + 1) * (y1 - y0 + 1));
  EXPECT_NEAR(t.distance_m, Z, 1e-5);
  EXPECT_FALSE(t.truncated);
  EXPECT_NEAR(t.cam[0], 0.0, 1e-9);
  EXPECT_NEAR(t.cam[1], h - Hb / 2, 1e-9);
  EXPECT_NEAR(t.cam[2], Z + L / 2, 1e-9);
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      ASSERT_EQ(r.obstacle_ids.at(x, y), 7) << x << "," << y;
      ASSERT_NEAR(r.disparity.at(x, y), f * B / Z, 1e-4) << x << "," << y;
    }
  EXPECT_EQ(r.obstacle_ids.at(x0 - 1, (y0 + y1) / 2), -1);
  EXPECT_EQ(r.obstacle_ids.at(x1 + 1, (y0 + y1) / 2), -1);
  // Ground below the horizon (pitch 0): Z = f*h/(v - cy), so d = B*(v - cy)/h.
  for (int y : {100, 120, 149})
    EXPECT_NEAR(r.disparity.at(5, y), B * (y - c.cy) / h, 1e-4) << y;
  // Rows above the horizon and not on the box are sky.
  EXPECT_EQ(r.sky_mask.at(5, 10), 255);
  EXPECT_EQ(r.disparity.at(5, 10), 0.0f);
}

TEST(SimWorld, RightImageMatchesLeftShiftedByTheGroundTruth) {
  for (const char* tex : {"asphalt", "gravel", "grass", "tiles"}) {
    Scene s = small_scene();
    s.ground.texture = static_cast<GroundTexture>(
        std::find(ground_texture_names().begin(), ground_texture_names().end(), tex) - ground_texture_names().begin());
    ObstacleSpec o;
    o.x_m = 2.5;
    o.y_m = 0.3;
    o.yaw_deg = 25;
    o.height_m = 1.2;
    o.texture = Texture::Bricks;
    s.obstacles.push_back(o);
    const RenderResult r = World(s).render(2);
    auto ground = [&](int x, int y) { return r.road_mask.at(x, y) == 255; };
    auto object = [&](int x, int y) { return r.obstacle_ids.at(x, y) >= 0; };
    const double good = stereo_mad(r, 0.0, ground), bad = stereo_mad(r, 2.0, ground);
    EXPECT_LT(good, 4.0) << tex;
    EXPECT_LT(good * 2.5, bad) << tex << " good " << good << " bad " << bad;
    const double ogood = stereo_mad(r, 0.0, object), obad = stereo_mad(r, 2.0, object);
    EXPECT_LT(ogood, 6.0) << tex;
    EXPECT_LT(ogood * 2.5, obad) << tex << " good " << ogood << " bad " << obad;
  }
}

TEST(SimWorld, MasksPartitionTheImageAndTruthMatchesTheIdImage) {
  const Scene s = load_scene(std::string(FS_SIM_SCENES_DIR) + "/many_obstacles.toml");
  Scene small = s;
  small.camera.width = 192;
  small.camera.height = 108;
  small.camera.focal_px = 126;
  small.camera.cx = 95.5;
  small.camera.cy = 53.5;
  const RenderResult r = World(small).render(2);
  int road = 0, sky = 0, obj = 0;
  for (int y = 0; y < r.left.height; ++y)
    for (int x = 0; x < r.left.width; ++x) {
      const int kinds = (r.road_mask.at(x, y) == 255) + (r.sky_mask.at(x, y) == 255) + (r.obstacle_ids.at(x, y) >= 0);
      ASSERT_EQ(kinds, 1) << x << "," << y;
      ASSERT_TRUE(r.road_mask.at(x, y) == 0 || r.road_mask.at(x, y) == 255);
      ASSERT_EQ(r.sky_mask.at(x, y) == 255, r.disparity.at(x, y) == 0.0f);
      road += r.road_mask.at(x, y) == 255;
      sky += r.sky_mask.at(x, y) == 255;
      obj += r.obstacle_ids.at(x, y) >= 0;
    }
  EXPECT_GT(road, 0);
  EXPECT_GT(sky, 0);
  EXPECT_GT(obj, 0);
  ASSERT_EQ(r.obstacles.size(), s.obstacles.size());
  int visible = 0;
  for (const auto& t : r.obstacles) {
    int n = 0, x0 = 1 << 30, x1 = -1, y0 = 1 << 30, y1 = -1;
    std::vector<double> z;
    for (int y = 0; y < r.left.height; ++y)
      for (int x = 0; x < r.left.width; ++x)
        if (r.obstacle_ids.at(x, y) == t.id) {
          ++n;
          x0 = std::min(x0, x); x1 = std::max(x1, x); y0 = std::min(y0, y); y1 = std::max(y1, y);
          z.push_back(r.calib.depth_of(r.disparity.at(x, y)));
        }
    EXPECT_EQ(t.visible_pixels, n);
    if (n == 0) continue;
    ++visible;
    EXPECT_EQ(t.x0, x0); EXPECT_EQ(t.x1, x1); EXPECT_EQ(t.y0, y0); EXPECT_EQ(t.y1, y1);
    std::sort(z.begin(), z.end());
    EXPECT_GE(t.distance_m, z.front() - 1e-3);
    EXPECT_LE(t.distance_m, z.back() + 1e-3);
    EXPECT_NEAR(t.distance_m, z[z.size() / 2], 0.05 * z[z.size() / 2] + 0.05);
    EXPECT_EQ(t.truncated, x0 == 0 || y0 == 0 || x1 == r.left.width - 1 || y1 == r.left.height - 1);
  }
  EXPECT_GE(visible, 6);
}

TEST(SimWorld, MovingObstacleIsRenderedWhereItIsAtTimeT) {
  Scene s = small_scene();
  ObstacleSpec o;
  o.shape = Shape::Post;
  o.radius_m = 0.25;
  o.height_m = 1.7;
  o.x_m = 4.0;
  o.y_m = 1.0;
  o.vy_mps = -0.5;  // crosses from left to the middle in 2 s
  s.obstacles.push_back(o);
  const World w(s);
  const auto t0 = w.render(w.scene_pose(), 0.0, 2).obstacles[0];
  const auto t2 = w.render(w.scene_pose(), 2.0, 2).obstacles[0];
  EXPECT_NEAR(t2.world[1], 0.0, 1e-12);
  const double mid0 = 0.5 * (t0.x0 + t0.x1), mid2 = 0.5 * (t2.x0 + t2.x1);
  EXPECT_NEAR(mid0, s.camera.cx - s.camera.focal_px * 1.0 / 4.0, 2.0);
  EXPECT_NEAR(mid2, s.camera.cx, 2.0);
  // A rotated robot: the obstacle straight ahead of the new heading is centred.
  const auto tr = w.render(Pose2{0.0, 0.0, std::atan2(1.0, 4.0)}, 0.0, 2).obstacles[0];
  EXPECT_NEAR(0.5 * (tr.x0 + tr.x1), s.camera.cx, 2.0);
}

TEST(SimWorld, FootprintsClearanceAndCollisions) {
  Scene s = parse_scene(
      "[[obstacles]]\nx_m = 5\ny_m = 0\nyaw_deg = 90\nlength_m = 2\nwidth_m = 1\n"
      "[[obstacles]]\nshape = \"cylinder\"\nx_m = 0\ny_m = 3\nradius_m = 0.5\nvx_mps = 1\n",
      "f.toml");
  const World w(s);
  const auto fp = w.obstacles_at(2.0);
  ASSERT_EQ(fp.size(), 2u);
  EXPECT_FALSE(fp[0].circle);
  EXPECT_TRUE(fp[1].circle);
  EXPECT_DOUBLE_EQ(fp[1].x_m, 2.0);
  // Box rotated 90 deg: spans x in [4.5, 5.5], y in [-1, 1].
  EXPECT_NEAR(footprint_distance(fp[0], 4.0, 0.0), 0.5, 1e-12);
  EXPECT_NEAR(footprint_distance(fp[0], 5.0, 1.5), 0.5, 1e-12);
  EXPECT_NEAR(footprint_distance(fp[0], 5.0, 0.0), -0.5, 1e-12);
  EXPECT_NEAR(footprint_distance(fp[0], 6.5, 2.0), std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(w.clearance(Pose2{3.0, 0.0, 0.0}, 0.0), 1.5, 1e-12);
  EXPECT_TRUE(w.collides(Pose2{4.2, 0.0, 0.0}, 0.35, 0.0));
  EXPECT_FALSE(w.collides(Pose2{4.0, 0.0, 0.0}, 0.45, 0.0));
  // The cylinder moves along +x at 1 m/s.
  EXPECT_FALSE(w.collides(Pose2{2.0, 2.3, 0.0}, 0.3, 0.0));
  EXPECT_TRUE(w.collides(Pose2{2.0, 2.3, 0.0}, 0.3, 2.0));
  EXPECT_NEAR(w.clearance(Pose2{2.0, 2.3, 0.0}, 2.0), 0.2, 1e-12);
}

TEST(SimWorld, AMoverTurnsAndStopsAtItsTurnTimes) {
  // Walks +x at 1 m/s, turns to +y at 1.5 s, stands from 2.5 s on.
  Scene s = parse_scene("[[obstacles]]\nshape = \"cylinder\"\nx_m = 0\ny_m = 3\nradius_m = 0.5\nvx_mps = 1\n"
                        "turns = [[1.5, 0, 1], [2.5, 0, 0]]\n",
                        "turns.toml");
  ASSERT_EQ(s.obstacles.size(), 1u);
  ASSERT_EQ(s.obstacles[0].turns.size(), 2u);
  const World w(s);
  EXPECT_DOUBLE_EQ(w.obstacles_at(1.0)[0].x_m, 1.0);
  EXPECT_DOUBLE_EQ(w.obstacles_at(2.0)[0].x_m, 1.5);
  EXPECT_DOUBLE_EQ(w.obstacles_at(2.0)[0].y_m, 3.5);
  EXPECT_DOUBLE_EQ(w.obstacles_at(9.0)[0].y_m, 4.0);
  EXPECT_EQ(s.obstacles[0].velocity_at(9.0)[1], 0.0);
  EXPECT_EQ(s.obstacles[0].velocity_at(2.0)[1], 1.0);
  // written and read back (scene_to_toml); bad turns name the field
  const Scene back = parse_scene(scene_to_toml(s), "back.toml");
  EXPECT_EQ(back.obstacles[0].turns, s.obstacles[0].turns);
  EXPECT_TRUE(parse_scene("[[obstacles]]\nx_m = 3\n", "n.toml").obstacles[0].turns.empty());
  for (const char* bad : {"turns = [[2, 0, 1], [1, 0, 0]]", "turns = [[1, 0]]", "turns = [[-1, 0, 0]]", "turns = 3"}) {
    try {
      parse_scene(std::string("[[obstacles]]\nx_m = 3\nvx_mps = 1\n") + bad + "\n", "bad.toml");
      ADD_FAILURE() << bad << " accepted";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("obstacles[0].turns"), std::string::npos) << e.what();
    }
  }
}

TEST(SimGenerator, TypesSpreadEvenlyObstaclesInViewAndApart) {
  GeneratorOptions opt;
  opt.width = 160;
  opt.height = 90;
  const auto& types = scenario_types();
  for (int i = 0; i < 12; ++i) {
    const Scene s = generate_scene(77, i, opt);
    EXPECT_EQ(s.type, types[static_cast<std::size_t>(i) % types.size()]);
    // Written and read back: the same scene.
    const Scene back = parse_scene(scene_to_toml(s), "gen.toml");
    EXPECT_EQ(scene_to_toml(back), scene_to_toml(s));
    const int n = static_cast<int>(s.obstacles.size());
    if (s.type == "many_obstacles") {
      EXPECT_GE(n, 8) << i;
      EXPECT_LE(n, 15) << i;
    }
    if (s.type == "few_obstacles") {
      EXPECT_LE(n, 2) << i;
    }
    EXPECT_GE(n, 1) << i;
    const auto fps = World(s).obstacles_at(0.0);
    const double yaw = s.robot.yaw_deg * 3.14159265358979323846 / 180.0;
    for (std::size_t a = 0; a < fps.size(); ++a) {
      const double dx = fps[a].x_m - s.robot.x_m, dy = fps[a].y_m - s.robot.y_m;
      const double fwd = dx * std::cos(yaw) + dy * std::sin(yaw);
      EXPECT_GE(fwd, 1.5 - 1e-3) << i;
      EXPECT_LE(fwd, 10.0 + 1e-3) << i;
      for (std::size_t b = a + 1; b < fps.size(); ++b) {
        // No overlap: the centre of one is outside the other's footprint by its own extent.
        const double gap = std::hypot(fps[a].x_m - fps[b].x_m, fps[a].y_m - fps[b].y_m);
        const auto rb = [](const Footprint& f) { return f.circle ? f.radius_m : std::hypot(f.half_length_m, f.half_width_m); };
        EXPECT_GT(gap, rb(fps[a]) + rb(fps[b])) << i << " " << a << " " << b;
      }
    }
    if (s.type == "radiometric") {
      EXPECT_NE(s.radiometric.right.gamma, 1.0);
    }
  }
  EXPECT_EQ(scene_to_toml(generate_scene(77, 3, opt)), scene_to_toml(generate_scene(77, 3, opt)));
  EXPECT_NE(scene_to_toml(generate_scene(77, 3, opt)), scene_to_toml(generate_scene(78, 3, opt)));
}

TEST(SimGenerator, GeneratedObstaclesAreVisible) {
  GeneratorOptions opt;
  opt.width = 160;
  opt.height = 90;
  int total = 0, visible = 0;
  for (int i = 0; i < 6; ++i) {
    const Scene s = generate_scene(3, i, opt);
    for (const auto& t : World(s).render(2).obstacles) {
      ++total;
      visible += t.visible_pixels > 0;
    }
  }
  EXPECT_GT(total, 10);
  EXPECT_GE(visible, total * 8 / 10);  // a few may hide entirely behind nearer ones
}

}  // namespace
