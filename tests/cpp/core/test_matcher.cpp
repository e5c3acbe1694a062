// The whole pipeline on synthetic pairs with a known disparity.
#include <gtest/gtest.h>

#include "config.hpp"
#include "fuzzystereo/matcher.hpp"
#include "test_util.hpp"

namespace fs {
namespace {

const FisDefinition& def() {
  static const FisDefinition d = load_fis_definition("");
  return d;
}

TEST(Matcher, RecoversAConstantDisparity) {
  MatcherParams p = load_matcher_config("");
  p.cost.max_disparity = 16;
  const Matcher m(p, def());
  const ImageU8 l = test::texture_image(121, 47, 31u);
  const ImageU8 r = test::shifted_right(l, 7);
  const MatchResult res = m.match(l, r);
  int good = 0, total = 0;
  for (int y = 0; y < l.height; ++y)
    for (int x = 20; x < l.width; ++x) {
      ++total;
      good += std::abs(res.disp_final.at(x, y) - 7 * kDispScale) <= kDispScale / 4;  // sub-pixel: within 1/4 px
    }
  EXPECT_GT(good, total * 95 / 100);
}

TEST(Matcher, TwoLayerSceneAndThreadCountInvariance) {
  // Foreground square at disparity 9 over a background at disparity 3.
  const int w = 131, h = 61;
  const ImageU8 bg = test::texture_image(w + 20, h, 41u), fg = test::texture_image(w + 20, h, 42u);
  ImageU8 l(w, h), r(w, h);
  auto in_fg = [](int x, int y) { return x >= 60 && x < 100 && y >= 15 && y < 45; };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) l.at(x, y) = in_fg(x, y) ? fg.at(x, y) : bg.at(x, y);
  // Distinct brightness per surface (as real objects have), so segments can follow the boundary.
  auto fgv = [&](int x, int y) { return static_cast<std::uint8_t>(128 + fg.at(x, y) / 2); };
  auto bgv = [&](int x, int y) { return static_cast<std::uint8_t>(bg.at(x, y) / 2); };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) l.at(x, y) = in_fg(x, y) ? fgv(x, y) : bgv(x, y);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      // right(x) shows the left pixel xl = x + d of whichever surface is in front there.
      r.at(x, y) = in_fg(x + 9, y) ? fgv(x + 9, y) : bgv(x + 3, y);
    }
  MatcherParams p = load_matcher_config("");
  p.cost.max_disparity = 16;
  p.runtime.threads = 1;
  const MatchResult a = Matcher(p, def()).match(l, r);
  p.runtime.threads = 2;
  const MatchResult b = Matcher(p, def()).match(l, r);
  EXPECT_EQ(a.disp_final.data, b.disp_final.data);
  int fg_ok = 0, fg_n = 0, bg_ok = 0, bg_n = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 20; x < w; ++x) {
      const int d = a.disp_final.at(x, y);
      if (in_fg(x, y)) { ++fg_n; fg_ok += std::abs(d - 9 * kDispScale) <= kDispScale; }
      else { ++bg_n; bg_ok += std::abs(d - 3 * kDispScale) <= kDispScale; }
    }
  EXPECT_GT(fg_ok, fg_n * 85 / 100);
  EXPECT_GT(bg_ok, bg_n * 85 / 100);
}

TEST(Matcher, RejectsSizeMismatch) {
  const Matcher m(load_matcher_config(""), def());
  EXPECT_THROW(m.match(ImageU8(10, 10), ImageU8(11, 10)), std::invalid_argument);
}

TEST(Matcher, GivenLabelsAreUsed) {
  MatcherParams p = load_matcher_config("");
  p.cost.max_disparity = 8;
  const Matcher m(p, def());
  const ImageU8 l = test::texture_image(40, 20, 1u), r = test::shifted_right(l, 2);
  ImageI32 labels(40, 20);
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 40; ++x) labels.at(x, y) = (x / 10) + 4 * (y / 10);
  const MatchResult res = m.match_with_labels(l, r, &labels, &labels);
  EXPECT_EQ(res.seg_left.count, 8);
  EXPECT_EQ(res.seg_left.labels.data, labels.data);
}

}  // namespace
}  // namespace fs
