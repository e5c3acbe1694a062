// Scene files: defaults, every kind of validation error names the file and the field, round trip.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "config.hpp"
#include "fuzzystereo/sim/generator.hpp"
#include "fuzzystereo/sim/scene.hpp"

namespace {

// An example scene of common/sim/scenes (a path, not string concatenation: GCC 12 at -O1 warns
// falsely on operator+ of a temporary std::string, -Warray-bounds, GCC PR 105329).
std::string example_scene(const std::string& name) {
  return (std::filesystem::path(FS_SIM_SCENES_DIR) / name).string();
}

using fs::sim::parse_scene;

// The message parse_scene throws for `text` (fails the test when it does not throw).
std::string error_of(const std::string& text) {
  try {
    parse_scene(text, "scene.toml");
  } catch (const fs::ConfigError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for:\n" << text;
  return {};
}

TEST(SimScene, EmptyFileGivesDocumentedDefaults) {
  const auto s = parse_scene("", "empty.toml");
  EXPECT_EQ(s.camera.width, 640);
  EXPECT_EQ(s.camera.height, 360);
  EXPECT_DOUBLE_EQ(s.camera.focal_px, 420.0);
  EXPECT_DOUBLE_EQ(s.camera.cx, 319.5);
  EXPECT_DOUBLE_EQ(s.camera.cy, 179.5);
  EXPECT_DOUBLE_EQ(s.camera.baseline_m, 0.12);
  EXPECT_DOUBLE_EQ(s.camera.height_m, 0.40);
  EXPECT_DOUBLE_EQ(s.camera.pitch_deg, 5.0);
  EXPECT_EQ(s.render.supersample, 2);
  EXPECT_FALSE(s.mission.has_value());
  EXPECT_TRUE(s.obstacles.empty());
}

TEST(SimScene, ExampleScenesLoad) {
  for (const char* name : {"example.toml", "overcast.toml", "many_obstacles.toml"}) {
    const auto s = fs::sim::load_scene(example_scene(name));
    EXPECT_FALSE(s.obstacles.empty()) << name;
  }
  const auto ex = fs::sim::load_scene(example_scene("example.toml"));
  ASSERT_EQ(ex.obstacles.size(), 4u);
  EXPECT_EQ(ex.obstacles[1].shape, fs::sim::Shape::Post);
  EXPECT_DOUBLE_EQ(ex.obstacles[1].radius_m, 0.25);  // person-sized default
  EXPECT_DOUBLE_EQ(ex.obstacles[1].height_m, 1.7);
  EXPECT_DOUBLE_EQ(ex.obstacles[1].vy_mps, 0.5);
  ASSERT_TRUE(ex.mission.has_value());
  EXPECT_DOUBLE_EQ(ex.mission->goal_x_m, 15.0);
}

TEST(SimScene, NegativeBaselineNamesFieldAndRange) {
  EXPECT_EQ(error_of("[camera]\nbaseline_m = -0.1\n"),
            "scene.toml: camera.baseline_m = -0.1 is out of range: float in (0, 2] m");
}

TEST(SimScene, UnknownTextureListsChoices) {
  const std::string e = error_of(
      "[[obstacles]]\nx_m = 2.0\n[[obstacles]]\nx_m = 3.0\n[[obstacles]]\nx_m = 4.0\ntexture = \"foo\"\n");
  EXPECT_EQ(e, "scene.toml: obstacles[2].texture = \"foo\" is not valid: one of \"bricks\", \"noise\", \"stripes\", "
               "\"checker\", \"wood\", \"camo\"");
}

TEST(SimScene, ObstacleBelowGround) {
  EXPECT_EQ(error_of("[[obstacles]]\nx_m = 2.0\n[[obstacles]]\nx_m = 3.0\nz_m = -0.5\n"),
            "scene.toml: obstacles[1].z_m = -0.5: obstacle below ground (must be >= 0)");
}

TEST(SimScene, UnknownKeysRejectedEverywhere) {
  EXPECT_NE(error_of("colour = 3\n").find("unknown field 'colour'"), std::string::npos);
  const std::string cam = error_of("[camera]\nwidht = 320\n");
  EXPECT_NE(cam.find("unknown field 'camera.widht'"), std::string::npos) << cam;
  EXPECT_NE(cam.find("width"), std::string::npos) << cam;  // lists the valid names
  EXPECT_NE(error_of("[[obstacles]]\nspeed = 1\n").find("unknown field 'obstacles[0].speed'"), std::string::npos);
  EXPECT_NE(error_of("[radiometric.left]\ngian = 1\n").find("radiometric.left.gian"), std::string::npos);
  EXPECT_NE(error_of("[weather]\nrain = true\n").find("unknown field 'weather'"), std::string::npos);
}

TEST(SimScene, WrongTypesNameTheField) {
  const std::string w = error_of("[camera]\nwidth = \"wide\"\n");
  EXPECT_NE(w.find("camera.width = \"wide\" has the wrong type: expected int in [16, 4096] px"), std::string::npos) << w;
  EXPECT_NE(error_of("[camera]\nwidth = 320.5\n").find("camera.width"), std::string::npos);
  EXPECT_NE(error_of("[sky]\nkind = 3\n").find("sky.kind = 3 has the wrong type"), std::string::npos);
  EXPECT_NE(error_of("camera = 3\n").find("camera must be a table"), std::string::npos);
  EXPECT_NE(error_of("obstacles = 3\n").find("obstacles must be an array of tables"), std::string::npos);
  EXPECT_NE(error_of("[[obstacles]]\ncolor = [1, 2]\n").find("obstacles[0].color"), std::string::npos);
  EXPECT_NE(error_of("[[obstacles]]\ncolor = [1, 2, 300]\n").find("obstacles[0].color[2] = 300 is out of range"),
            std::string::npos);
}

TEST(SimScene, OtherRangesAndRules) {
  EXPECT_NE(error_of("[camera]\nwidth = 8\n").find("camera.width = 8 is out of range: int in [16, 4096] px"),
            std::string::npos);
  EXPECT_NE(error_of("[camera]\nwidth = 100\ncx = 150\n").find("camera.cx = 150 is out of range: float in [0, 99] px"),
            std::string::npos);
  EXPECT_NE(error_of("[light]\nambient = 1.5\n").find("light.ambient = 1.5 is out of range: float in [0, 1]"),
            std::string::npos);
  EXPECT_NE(error_of("[render]\nsupersample = 0\n").find("render.supersample = 0"), std::string::npos);
  EXPECT_NE(error_of("[[obstacles]]\nshape = \"box\"\nradius_m = 0.3\n").find("obstacles[0].radius_m is not a field of a box"),
            std::string::npos);
  EXPECT_NE(error_of("[[obstacles]]\nshape = \"post\"\nlength_m = 0.3\n").find("obstacles[0].length_m is not a field of a post"),
            std::string::npos);
  EXPECT_NE(error_of("[[obstacles]]\nid = 4\n[[obstacles]]\nid = 4\n").find("obstacles[1].id = 4 is already used by obstacles[0]"),
            std::string::npos);
  EXPECT_NE(error_of("[[obstacles]]\nshape = \"cube\"\n").find("obstacles[0].shape = \"cube\" is not valid: one of \"box\""),
            std::string::npos);
  EXPECT_NE(error_of("seed = \n").find("scene.toml:1:"), std::string::npos);  // syntax error with line
}

TEST(SimScene, MissingIdsTakeTheSmallestFreeOnes) {
  const auto s = parse_scene("[[obstacles]]\nid = 0\n[[obstacles]]\n[[obstacles]]\nid = 1\n[[obstacles]]\n", "s.toml");
  ASSERT_EQ(s.obstacles.size(), 4u);
  EXPECT_EQ(s.obstacles[0].id, 0);
  EXPECT_EQ(s.obstacles[1].id, 2);
  EXPECT_EQ(s.obstacles[2].id, 1);
  EXPECT_EQ(s.obstacles[3].id, 3);
}

TEST(SimScene, TomlRoundTripIsExact) {
  auto s = fs::sim::load_scene(example_scene("many_obstacles.toml"));
  s.camera.focal_px = 421.123456789012345;  // a value with a long expansion
  s.obstacles[0].x_m = 0.1 + 0.2;
  const std::string text = fs::sim::scene_to_toml(s);
  const auto back = parse_scene(text, "back.toml");
  EXPECT_EQ(fs::sim::scene_to_toml(back), text);
  EXPECT_EQ(back.camera.focal_px, s.camera.focal_px);
  EXPECT_EQ(back.obstacles[0].x_m, s.obstacles[0].x_m);
  EXPECT_EQ(back.obstacles.size(), s.obstacles.size());
  EXPECT_EQ(back.radiometric.right.gamma, 1.2);
}

// Generated scenes use 63-bit seeds; every one of them must load again from its scene file (seed 123,
// scene 56 has 9206339968386896057, which the old range [0, 9.2e18] rejected).
TEST(SimScene, GeneratedSeedsUseTheWholeRangeAndLoad) {
  const auto s = fs::sim::generate_scene(123, 56, fs::sim::GeneratorOptions{});
  EXPECT_GT(s.seed, 9200000000000000000ULL);
  const auto back = parse_scene(fs::sim::scene_to_toml(s), "000056.toml");
  EXPECT_EQ(back.seed, s.seed);
  EXPECT_EQ(parse_scene("seed = 9223372036854775807\n", "max.toml").seed, 9223372036854775807ULL);
  EXPECT_NE(error_of("seed = -1\n").find("seed"), std::string::npos);
}

}  // namespace
