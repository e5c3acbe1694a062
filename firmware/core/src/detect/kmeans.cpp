// k-means on the disparities of the obstacle candidates, paper eq. (22)-(23), Section III-B.
//
// The data are 1-D (one Q4 disparity per pixel), so eq. (22)'s Euclidean distance is |q4 - c| and
// eq. (23)'s centroid is the mean. Everything is integer: the pixels are first reduced to a histogram
// over Q4 values (at most 32768 bins, typically D*16), and Lloyd iterations run on the histogram
// with int64 sums -- O(bins * k) per iteration instead of O(pixels * k), bit-identical to running on
// the pixels (tests/cpp/core/test_detect.cpp checks it against the per-pixel reference).
//   init:   centre i = the candidate disparity at quantile (2i+1)/(2k)  (deterministic, spread
//           over the data; no random restarts);
//   assign: nearest centre, ties to the lower index;
//   update: centre = round(sum / count) (ties up); an empty cluster keeps its centre;
//   stop:   when no centre moves, or after max_iterations.
// Output clusters are ordered nearest first (largest disparity) and empty ones are dropped.
// Merge (our addition, docs/detection.md): k = 6 is an upper bound, not a count of objects. With
// fewer depth layers than k, Lloyd splits one obstacle's sub-pixel noise into several clusters of
// a fraction of its pixels each, and the per-cluster u-disparity then sees too few pixels per column
// to keep any of them. Neighbouring centres closer than merge_q4 are therefore merged.
#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

#include "fuzzystereo/detect.hpp"

namespace fs::detect {

namespace {

// eq. (22) in 1-D: index of the centre nearest to q; ties go to the lower index.
int nearest_centre(std::int64_t q, const std::vector<std::int32_t>& c, int k) {
  int bi = 0;
  std::int64_t bd = std::abs(q - c[0]);
  for (int i = 1; i < k; ++i) {
    const std::int64_t dd = std::abs(q - c[std::size_t(i)]);
    if (dd < bd) bd = dd, bi = i;
  }
  return bi;
}

}  // namespace

KMeansResult kmeans_disparity(const ImageI16& disp, const ImageU8& candidates, int k, int max_iterations,
                              int merge_q4) {
  KMeansResult res;
  res.labels = ImageU8(disp.width, disp.height, kNoCluster);
  int maxq = -1;
  for (std::size_t i = 0; i < disp.size(); ++i)
    if (candidates.data[i]) maxq = std::max<int>(maxq, disp.data[i]);
  if (maxq < 0 || k <= 0) return res;
  std::vector<std::int64_t> hist(std::size_t(maxq) + 1, 0);
  std::int64_t n = 0;
  for (std::size_t i = 0; i < disp.size(); ++i)
    if (candidates.data[i]) ++hist[std::size_t(disp.data[i])], ++n;

  // Quantile initialisation: the value whose cumulative count first exceeds floor(n*(2i+1)/(2k)).
  std::vector<std::int32_t> c(static_cast<std::size_t>(k));
  {
    std::int64_t cum = 0;
    int q = 0;
    for (int i = 0; i < k; ++i) {
      const std::int64_t rank = n * (2 * i + 1) / (2 * k);  // 0-based rank in the sorted data
      while (cum + hist[std::size_t(q)] <= rank) cum += hist[std::size_t(q)], ++q;
      c[std::size_t(i)] = q;
    }
  }
  // Lloyd iterations on the histogram. With sorted centres and ties to the lower index, value q
  // goes to the first centre i with |q - c_i| <= |q - c_j| for all j.
  std::vector<std::int64_t> sum(static_cast<std::size_t>(k)), cnt(static_cast<std::size_t>(k));
  std::vector<std::uint8_t> assign(hist.size());
  int it = 0;
  for (; it < max_iterations; ++it) {
    std::fill(sum.begin(), sum.end(), 0);
    std::fill(cnt.begin(), cnt.end(), 0);
    for (std::size_t q = 0; q < hist.size(); ++q) {
      const int bi = nearest_centre(std::int64_t(q), c, k);
      assign[q] = std::uint8_t(bi);
      sum[std::size_t(bi)] += hist[q] * std::int64_t(q);
      cnt[std::size_t(bi)] += hist[q];
    }
    bool moved = false;
    for (int i = 0; i < k; ++i) {
      if (cnt[std::size_t(i)] == 0) continue;
      const std::int32_t nc = std::int32_t((2 * sum[std::size_t(i)] + cnt[std::size_t(i)]) / (2 * cnt[std::size_t(i)]));
      moved = moved || nc != c[std::size_t(i)];
      c[std::size_t(i)] = nc;
    }
    if (!moved) {
      ++it;
      break;
    }
  }
  res.iterations = it;
  // Final assignment with the final centres (the loop's last assignment used the previous ones).
  std::fill(cnt.begin(), cnt.end(), 0);
  for (std::size_t q = 0; q < hist.size(); ++q) {
    const int bi = nearest_centre(std::int64_t(q), c, k);
    assign[q] = std::uint8_t(bi);
    cnt[std::size_t(bi)] += hist[q];
  }
  // Order: largest centre first (nearest); drop empty clusters. Stable on ties (lower index first).
  std::vector<int> order(static_cast<std::size_t>(k));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return c[std::size_t(a)] > c[std::size_t(b)]; });
  std::vector<std::uint8_t> remap(static_cast<std::size_t>(k), kNoCluster);
  std::vector<std::int64_t> msum;  // per output cluster: sum of its centres weighted by size
  std::int32_t prev = 0;           // centre of the previous non-empty cluster (single linkage)
  for (int i : order) {
    const std::size_t u = std::size_t(i);
    if (cnt[u] == 0) continue;
    if (res.centres_q4.empty() || prev - c[u] >= merge_q4 || merge_q4 <= 0) {
      res.centres_q4.push_back(c[u]);
      res.sizes.push_back(0);
      msum.push_back(0);
    }
    const std::size_t o = res.centres_q4.size() - 1;
    remap[u] = std::uint8_t(o);
    res.sizes[o] += cnt[u];
    msum[o] += cnt[u] * std::int64_t(c[u]);
    res.centres_q4[o] = std::int32_t((2 * msum[o] + res.sizes[o]) / (2 * res.sizes[o]));
    prev = c[u];
  }
  for (std::size_t i = 0; i < disp.size(); ++i)
    if (candidates.data[i]) res.labels.data[i] = remap[assign[std::size_t(disp.data[i])]];
  return res;
}

}  // namespace fs::detect
