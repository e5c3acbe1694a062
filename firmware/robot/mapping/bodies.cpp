// Hidden sides of mapped obstacles: circles fitted to groups of occupied map cells (bodies.hpp).
// Why hand-written: the fits are 3x3 least-squares problems solved with Eigen; the grouping is a
// bucket hash with the core's union-find (a few hundred cells per frame).
#include "fuzzystereo/robot/bodies.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include <Eigen/Dense>

#include "fuzzystereo/union_find.hpp"

namespace fs::robot {

namespace {

// Arc covered by pts round c [deg]: 360 minus the largest gap between consecutive bearings.
double arc_covered_deg(const std::vector<Vec2>& pts, Vec2 c) {
  std::vector<double> a;
  a.reserve(pts.size());
  for (const Vec2& p : pts) a.push_back(std::atan2(p.y - c.y, p.x - c.x));
  std::sort(a.begin(), a.end());
  double gap = a.front() + 2.0 * M_PI - a.back();
  for (std::size_t i = 1; i < a.size(); ++i) gap = std::max(gap, a[i] - a[i - 1]);
  return (2.0 * M_PI - gap) * 180.0 / M_PI;
}

}  // namespace

CircleFit fit_circle(const std::vector<Vec2>& pts) {
  CircleFit f;
  const std::size_t n = pts.size();
  if (n < 3) return f;
  // Centred coordinates keep the normal equations well conditioned far from the origin.
  Vec2 m;
  for (const Vec2& p : pts) m = m + p;
  m = (1.0 / double(n)) * m;
  // Kasa: minimise sum (x^2 + y^2 + D x + E y + F)^2 -> 3x3 linear least squares.
  Eigen::MatrixXd A(n, 3);
  Eigen::VectorXd b(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = pts[i].x - m.x, y = pts[i].y - m.y;
    A(Eigen::Index(i), 0) = x;
    A(Eigen::Index(i), 1) = y;
    A(Eigen::Index(i), 2) = 1.0;
    b(Eigen::Index(i)) = -(x * x + y * y);
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() < 3) return f;  // collinear points (a straight group): no circle
  const Eigen::Vector3d s = qr.solve(b);
  double cx = -0.5 * s(0), cy = -0.5 * s(1);
  const double r2 = cx * cx + cy * cy - s(2);
  if (!std::isfinite(r2) || r2 <= 0.0) return f;
  double r = std::sqrt(r2);
  // Gauss-Newton on the geometric residuals e_i = |p_i - c| - r (parameters cx, cy, r).
  for (int it = 0; it < 10; ++it) {
    Eigen::Matrix3d JtJ = Eigen::Matrix3d::Zero();
    Eigen::Vector3d Jte = Eigen::Vector3d::Zero();
    for (const Vec2& p : pts) {
      const double dx = p.x - m.x - cx, dy = p.y - m.y - cy, d = std::sqrt(dx * dx + dy * dy);
      if (d < 1e-12) return f;
      const Eigen::Vector3d J(-dx / d, -dy / d, -1.0);
      JtJ += J * J.transpose();
      Jte += J * (d - r);
    }
    const Eigen::Vector3d step = JtJ.ldlt().solve(-Jte);
    if (!step.allFinite()) return f;
    cx += step(0);
    cy += step(1);
    r += step(2);
    if (step.norm() < 1e-7) break;
  }
  if (!std::isfinite(r) || r <= 0.0) return f;
  f.c = {cx + m.x, cy + m.y};
  f.r = r;
  double ss = 0.0;
  for (const Vec2& p : pts) {
    const double e = norm(p - f.c) - r;
    ss += e * e;
  }
  f.rms = std::sqrt(ss / double(n));
  f.arc_deg = arc_covered_deg(pts, f.c);
  f.ok = true;
  return f;
}

std::vector<FittedBody> fit_bodies(const std::vector<CircleObstacle>& cells, Vec2 robot, const BodyFitParams& p) {
  std::vector<FittedBody> out;
  const std::size_t n = cells.size();
  if (n == 0 || p.min_cells < 3 || !(p.link_m > 0.0)) return out;  // the config keeps link_m >= 0.01
  // Single linkage within link_m: cells hashed into square buckets of side link_m, each cell checked
  // against the cells of its own and the 8 neighbouring buckets (linear in the number of cells whatever
  // their layout; a sweep over x degenerates to all pairs along a wall parallel to the y axis).
  const double inv = 1.0 / p.link_m;
  std::unordered_map<std::int64_t, std::vector<int>> buckets;
  const auto key = [](std::int64_t bx, std::int64_t by) { return (bx << 32) ^ (by & 0xffffffff); };
  std::vector<std::int64_t> bx(n), by(n);
  for (std::size_t i = 0; i < n; ++i) {
    bx[i] = static_cast<std::int64_t>(std::floor(cells[i].c.x * inv));
    by[i] = static_cast<std::int64_t>(std::floor(cells[i].c.y * inv));
    buckets[key(bx[i], by[i])].push_back(int(i));
  }
  MinRootUnionFind uf(n);
  const double l2 = p.link_m * p.link_m;
  for (std::size_t i = 0; i < n; ++i)
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const auto it = buckets.find(key(bx[i] + dx, by[i] + dy));
        if (it == buckets.end()) continue;
        for (const int j : it->second)
          if (j > int(i) && norm2(cells[std::size_t(j)].c - cells[i].c) <= l2) uf.unite(int(i), j);
      }
  // Groups in the order of their first cell (the root is the smallest index).
  std::vector<std::vector<Vec2>> groups;
  std::vector<int> group_of(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    const int root = uf.find(int(i));
    int& g = group_of[std::size_t(root)];
    if (g < 0) {
      g = static_cast<int>(groups.size());
      groups.emplace_back();
    }
    groups[std::size_t(g)].push_back(cells[i].c);
  }
  for (const auto& g : groups) {
    if (static_cast<int>(g.size()) < p.min_cells) continue;
    const CircleFit f = fit_circle(g);
    if (!f.ok || f.r < p.min_r_m || f.r > p.max_r_m || f.rms > p.max_rms_m || f.arc_deg < p.min_arc_deg) continue;
    if (norm(robot - f.c) <= f.r) continue;  // the robot stands inside it: not a body
    FittedBody b;
    b.circle.c = f.c;
    b.circle.r = f.r;
    b.circle.transient = true;
    b.fit = f;
    b.cells = static_cast<int>(g.size());
    out.push_back(b);
  }
  return out;
}

}  // namespace fs::robot
