#include <gtest/gtest.h>

#include "config.hpp"

namespace fs {
namespace {

std::string error_of(const std::string& toml) {
  try {
    parse_matcher_config(toml, "test.toml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(Config, DefaultsLoadAndMatchTheStruct) {
  const MatcherParams p = load_matcher_config("");
  EXPECT_EQ(p.seg.region_size, 8);
  EXPECT_EQ(p.seg.coarse_iterations, 1);  // session 44: the coarse start for match / eval / bench
  EXPECT_EQ(p.seg.iterations, 1);
  EXPECT_EQ(p.cost.max_disparity, 64);
  EXPECT_DOUBLE_EQ(p.cost.alpha, 0.2);
  EXPECT_TRUE(p.esr.enabled);
  EXPECT_EQ(p.cost.inject_shift, 0);
}

TEST(Config, OverridesAreApplied) {
  const MatcherParams p = parse_matcher_config("[cost]\nmax_disparity = 128\nalpha = 0.25\n[esr]\nenabled = false\n", "t");
  EXPECT_EQ(p.cost.max_disparity, 128);
  EXPECT_DOUBLE_EQ(p.cost.alpha, 0.25);
  EXPECT_FALSE(p.esr.enabled);
  EXPECT_EQ(p.seg.region_size, 8);  // untouched default
}

TEST(Config, ErrorsNameTheFieldAndRange) {
  std::string e = error_of("[cost]\nmax_disparity = 300\n");
  EXPECT_NE(e.find("cost.max_disparity"), std::string::npos) << e;
  EXPECT_NE(e.find("[2, 256]"), std::string::npos) << e;
  e = error_of("[esr]\nwindow = 8\n");
  EXPECT_NE(e.find("esr.window"), std::string::npos) << e;
  EXPECT_NE(e.find("odd"), std::string::npos) << e;
  e = error_of("[cost]\nalpha = \"half\"\n");
  EXPECT_NE(e.find("cost.alpha"), std::string::npos) << e;
  e = error_of("[cost]\nmax_disparty = 64\n");
  EXPECT_NE(e.find("unknown field 'cost.max_disparty'"), std::string::npos) << e;
  e = error_of("[segmentation]\nregion_size = 8.5\n");
  EXPECT_NE(e.find("integer"), std::string::npos) << e;
  e = error_of("[boundary]\nwindow = 4\n");
  EXPECT_NE(e.find("boundary.window"), std::string::npos) << e;
  EXPECT_NE(e.find("odd"), std::string::npos) << e;
  e = error_of("[boundary]\ncensus_radius = 3\n");
  EXPECT_NE(e.find("boundary.census_radius"), std::string::npos) << e;
  EXPECT_NE(e.find("[1, 2]"), std::string::npos) << e;
  e = error_of("[segmentation]\ncoarse_iterations = 21\n");
  EXPECT_NE(e.find("segmentation.coarse_iterations"), std::string::npos) << e;
  EXPECT_NE(e.find("[0, 20]"), std::string::npos) << e;
  e = error_of("[cost\n");
  EXPECT_NE(e.find("test.toml:1"), std::string::npos) << e;
  EXPECT_THROW(load_matcher_config("/nonexistent/cfg.toml"), ConfigError);
}

TEST(Config, RoundTripThroughToml) {
  MatcherParams p = parse_matcher_config(
      "[segmentation]\ncoarse_iterations = 2\n[cost]\nalpha = 0.3\nnmi_candidates = 0\n[esr]\ntau = 1.25\n[boundary]\nenabled = "
      "true\nmargin = 1.5\nwindow = 5\n",
      "t");
  const MatcherParams q = parse_matcher_config(config_to_toml(p), "roundtrip");
  EXPECT_EQ(q.seg.coarse_iterations, 2);
  EXPECT_TRUE(q.boundary.enabled);
  EXPECT_DOUBLE_EQ(q.boundary.margin, 1.5);
  EXPECT_EQ(q.boundary.window, 5);
  EXPECT_EQ(q.boundary.step, 4);
  EXPECT_DOUBLE_EQ(q.cost.alpha, 0.3);
  EXPECT_EQ(q.cost.nmi_candidates, 0);
  EXPECT_DOUBLE_EQ(q.esr.tau, 1.25);
}

TEST(FisConfig, BadDefinitionsAreRejectedWithTheCulprit) {
  const std::string good = embedded_fis_definition();
  auto error_for = [](const std::string& text) {
    try {
      parse_fis_definition(text, "fis.toml");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string bad = good;
  bad.replace(bad.find("\"very_good\", \"best\""), 19, "\"very_good\", \"bestest\"");
  EXPECT_NE(error_for(bad).find("bestest"), std::string::npos);
  bad = good;
  bad.replace(bad.find("mf = \"trimf\""), 12, "mf = \"gaussmf\"");
  EXPECT_NE(error_for(bad).find("gaussmf"), std::string::npos);
}

}  // namespace
}  // namespace fs
