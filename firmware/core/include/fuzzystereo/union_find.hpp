// Union-find over the dense indices 0..n-1, path halving. unite() keeps the smaller index as the
// root, so when indices follow scan order a component's root is its first element. Used by the
// run-based connected components of SLIC (segmentation/) and densify/, and by the robot's grouping
// of map cells (robot/mapping/bodies.cpp).
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace fs {

class MinRootUnionFind {
 public:
  explicit MinRootUnionFind(std::size_t n) : parent_(n) {
    for (std::size_t i = 0; i < n; ++i) parent_[i] = static_cast<std::int32_t>(i);
  }
  std::int32_t find(std::int32_t a) {
    while (parent_[std::size_t(a)] != a) {
      parent_[std::size_t(a)] = parent_[std::size_t(parent_[std::size_t(a)])];
      a = parent_[std::size_t(a)];
    }
    return a;
  }
  // unite(b, a) for a root a whose new root is b's, known to be smaller than a (b < a in scan order):
  // one find instead of two.
  void attach(std::int32_t a, std::int32_t b) { parent_[std::size_t(a)] = find(b); }
  void unite(std::int32_t a, std::int32_t b) {
    const std::int32_t ra = find(a), rb = find(b);
    if (ra != rb) parent_[std::size_t(std::max(ra, rb))] = std::min(ra, rb);
  }

 private:
  std::vector<std::int32_t> parent_;
};

}  // namespace fs
