#include <array>
#include <queue>
#include <set>
#include <stdexcept>
#include <utility>

#include <gtest/gtest.h>

#include "fuzzystereo/stages.hpp"
#include "internal.hpp"
#include "slic_reference.hpp"
#include "test_util.hpp"

namespace fs {
namespace {

// Every label must be one 4-connected region.
bool labels_connected(const ImageI32& l, int count) {
  std::vector<int> seen_components(std::size_t(count), 0);
  ImageU8 visited(l.width, l.height, 0);
  for (int y = 0; y < l.height; ++y)
    for (int x = 0; x < l.width; ++x) {
      if (visited.at(x, y)) continue;
      const int lab = l.at(x, y);
      if (++seen_components[std::size_t(lab)] > 1) return false;
      std::queue<std::pair<int, int>> q;
      q.push({x, y});
      visited.at(x, y) = 1;
      while (!q.empty()) {
        auto [cx, cy] = q.front();
        q.pop();
        const int dx[4] = {1, -1, 0, 0}, dy[4] = {0, 0, 1, -1};
        for (int k = 0; k < 4; ++k) {
          const int nx = cx + dx[k], ny = cy + dy[k];
          if (nx < 0 || ny < 0 || nx >= l.width || ny >= l.height) continue;
          if (visited.at(nx, ny) || l.at(nx, ny) != lab) continue;
          visited.at(nx, ny) = 1;
          q.push({nx, ny});
        }
      }
    }
  return true;
}

TEST(Slic, LabelsDenseConnectedAndRunsCoverImage) {
  for (auto [w, h, S] : {std::tuple{97, 61, 8}, {33, 17, 5}, {5, 3, 4}, {150, 41, 12}}) {
    const ImageU8 img = test::texture_image(w, h, 3u);
    SegmentationParams p;
    p.region_size = S;
    const Segmentation seg = slic_segment(img, p);
    ASSERT_GT(seg.count, 0);
    std::set<int> used(seg.labels.data.begin(), seg.labels.data.end());
    EXPECT_EQ(int(used.size()), seg.count);
    EXPECT_EQ(*used.begin(), 0);
    EXPECT_TRUE(labels_connected(seg.labels, seg.count)) << w << "x" << h;
    // Runs: each pixel exactly once, with the right label; pixel counts agree.
    ImageU8 cover(w, h, 0);
    for (int s = 0; s < seg.count; ++s) {
      int n = 0;
      for (int r = seg.run_begin[std::size_t(s)]; r < seg.run_begin[std::size_t(s) + 1]; ++r) {
        const fs::Run& run = seg.runs[std::size_t(r)];
        for (int x = run.x0; x < run.x1; ++x) {
          EXPECT_EQ(seg.labels.at(x, run.y), s);
          ++cover.at(x, run.y);
          ++n;
        }
      }
      EXPECT_EQ(n, seg.pixels[std::size_t(s)]);
    }
    for (auto c : cover.data) ASSERT_EQ(c, 1);
  }
}

TEST(Slic, Deterministic) {
  const ImageU8 img = test::texture_image(64, 48, 9u);
  SegmentationParams p;
  EXPECT_EQ(slic_segment(img, p).labels.data, slic_segment(img, p).labels.data);
}

TEST(Slic, RefusesParametersOutsideTheIntegerFormatsRange) {
  // region_size <= 48 keeps dI * S in int16 and D' below the iteration tag; compactness <= 100 likewise.
  const ImageU8 img = test::texture_image(64, 48, 9u);
  SegmentationParams p;
  p.region_size = 48;
  EXPECT_NO_THROW(slic_segment(img, p));
  for (const auto& [S, m] : {std::pair{49, 20}, {0, 20}, {8, 101}, {8, -1}}) {
    p.region_size = S;
    p.compactness = m;
    EXPECT_THROW(slic_segment(img, p), std::invalid_argument) << S << " " << m;
  }
}

TEST(Slic, SegmentCountFollowsRegionSize) {
  const ImageU8 img = test::texture_image(120, 80, 5u);
  SegmentationParams p;
  p.region_size = 8;
  const int n8 = slic_segment(img, p).count;
  p.region_size = 16;
  const int n16 = slic_segment(img, p).count;
  EXPECT_GT(n8, 2 * n16);
  EXPECT_NEAR(n8, 120 * 80 / 64, 120 * 80 / 64 / 2);
}

TEST(Slic, SegmentsFollowAStepEdge) {
  // Two flat halves: no segment may straddle the edge at x = 30.
  ImageU8 img(61, 40, 40);
  for (int y = 0; y < 40; ++y)
    for (int x = 30; x < 61; ++x) img.at(x, y) = 200;
  SegmentationParams p;
  p.region_size = 8;
  const Segmentation seg = slic_segment(img, p);
  for (int s = 0; s < seg.count; ++s) {
    std::set<bool> side;
    for (int r = seg.run_begin[std::size_t(s)]; r < seg.run_begin[std::size_t(s) + 1]; ++r)
      for (int x = seg.runs[std::size_t(r)].x0; x < seg.runs[std::size_t(r)].x1; ++x) side.insert(x >= 30);
    EXPECT_EQ(side.size(), 1u) << "segment " << s;
  }
}

// The fast SLIC (run-based centre update and connectivity, SIMD assignment) against the plain
// per-pixel reference: identical labels and runs on random and textured images of odd sizes.
TEST(Slic, MatchesScalarReference) {
  struct Case { int w, h, S, m, it, pct; unsigned seed; bool textured; int coarse = 0; };
  const Case cases[] = {{37, 23, 5, 10, 3, 25, 1, false}, {101, 67, 8, 20, 4, 25, 2, true},
                        {129, 41, 6, 40, 2, 50, 3, true}, {63, 95, 11, 5, 4, 10, 4, false},
                        {7, 5, 3, 20, 1, 25, 5, true},    {211, 53, 8, 20, 4, 100, 6, true},
                        // > 16 iterations (the iteration tags run out once) and the largest distances
                        // (S = 48, m = 100: D' just below the tag bits)
                        {61, 59, 4, 1, 20, 25, 7, false}, {131, 97, 48, 100, 17, 25, 8, true},
                        {150, 120, 48, 100, 3, 25, 9, false},
                        // coarse start (`coarse_iterations`) on odd and even sizes, narrow (S/2 < 8) and
                        // wide windows, S = 3 (halved to 1), and 17 + 17 rounds (tags run out in both)
                        {101, 67, 8, 20, 1, 25, 10, true, 2},  {129, 41, 6, 40, 2, 50, 11, true, 3},
                        {37, 23, 5, 10, 2, 25, 12, false, 1},  {64, 48, 8, 20, 1, 25, 13, true, 4},
                        {31, 29, 3, 20, 1, 25, 14, true, 2},   {150, 121, 48, 100, 2, 25, 15, true, 2},
                        {61, 59, 4, 1, 17, 25, 16, false, 17}, {211, 53, 20, 30, 1, 25, 17, true, 2}};
  for (const Case& c : cases) {
    const ImageU8 img = c.textured ? test::texture_image(c.w, c.h, c.seed) : test::random_image(c.w, c.h, c.seed);
    SegmentationParams p;
    p.region_size = c.S;
    p.compactness = c.m;
    p.iterations = c.it;
    p.min_segment_pct = c.pct;
    p.coarse_iterations = c.coarse;
    const Segmentation fast = slic_segment(img, p);
    const Segmentation ref = test::slic_segment_reference(img, p);
    ASSERT_EQ(fast.count, ref.count) << c.w << "x" << c.h << " S=" << c.S << " coarse=" << c.coarse;
    EXPECT_EQ(fast.labels.data, ref.labels.data) << c.w << "x" << c.h << " S=" << c.S << " coarse=" << c.coarse;
    EXPECT_EQ(fast.run_begin, ref.run_begin);
    EXPECT_EQ(fast.pixels, ref.pixels);
    ASSERT_EQ(fast.runs.size(), ref.runs.size());
    for (std::size_t i = 0; i < ref.runs.size(); ++i) {
      ASSERT_EQ(fast.runs[i].y, ref.runs[i].y) << "run " << i;
      ASSERT_EQ(fast.runs[i].x0, ref.runs[i].x0) << "run " << i;
      ASSERT_EQ(fast.runs[i].x1, ref.runs[i].x1) << "run " << i;
    }
  }
}

TEST(Segmentation, FromLabelsBuildsRuns) {
  ImageI32 l(5, 2);
  l.data = {0, 0, 1, 1, 0, 2, 2, 2, 1, 0};
  const Segmentation seg = segmentation_from_labels(l);
  EXPECT_EQ(seg.count, 3);
  EXPECT_EQ(seg.pixels, (std::vector<std::int32_t>{4, 3, 3}));
  EXPECT_EQ(seg.run_begin, (std::vector<std::int32_t>{0, 3, 5, 6}));
}

}  // namespace
}  // namespace fs

// detail::for_each_run (flag bytes read as 64-bit words) against the plain scan it replaced, on
// random rows of every width 1..80 (word boundaries, sentinel) with short and long runs.
TEST(ForEachRun, MatchesScalarScan) {
  std::uint32_t state = 12345;
  auto rnd = [&] { state = state * 1664525u + 1013904223u; return state >> 8; };
  for (int w = 1; w <= 80; ++w) {
    for (int rep = 0; rep < 20; ++rep) {
      std::vector<std::int32_t> row(static_cast<std::size_t>(w));
      const std::uint32_t stay = rep % 4 == 0 ? 0u : 90u;  // % chance a pixel repeats its left neighbour
      for (int x = 0; x < w; ++x)
        row[std::size_t(x)] = x > 0 && rnd() % 100 < stay ? row[std::size_t(x) - 1] : static_cast<std::int32_t>(rnd() % 3) - 1;
      std::vector<std::array<int, 2>> expect, got;
      for (int x = 0; x < w;) {
        int e = x + 1;
        while (e < w && row[std::size_t(e)] == row[std::size_t(x)]) ++e;
        expect.push_back({x, e});
        x = e;
      }
      std::vector<std::uint8_t> flags(std::size_t(w) + 8, 0xAA);
      fs::detail::for_each_run(row.data(), w, flags.data(), [&](int x0, int x1) { got.push_back({x0, x1}); });
      ASSERT_EQ(got, expect) << "w=" << w << " rep=" << rep;
    }
  }
}
