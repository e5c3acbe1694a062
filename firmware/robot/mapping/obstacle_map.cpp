// Log-odds occupancy grid of the static world (obstacle_map.hpp, docs/robot.md "Closed loop").
#include "fuzzystereo/robot/obstacle_map.hpp"

#include <algorithm>
#include <cmath>

namespace fs::robot {

void ObstacleMap::cell_window(Vec2 c, double r, int& x0, int& y0, int& x1, int& y1) const {
  cell_of({c.x - r, c.y - r}, x0, y0);
  cell_of({c.x + r, c.y + r}, x1, y1);
  x0 = std::max(0, x0);
  y0 = std::max(0, y0);
  x1 = std::min(n_ - 1, x1);
  y1 = std::min(n_ - 1, y1);
}

bool ObstacleMap::cell_of(Vec2 p, int& ix, int& iy) const {
  ix = static_cast<int>(std::floor((p.x - origin_.x) / p_.cell_m));
  iy = static_cast<int>(std::floor((p.y - origin_.y) / p_.cell_m));
  return ix >= 0 && iy >= 0 && ix < n_ && iy < n_;
}

void ObstacleMap::integrate(const CameraScan& scan) {
  if (!init_) {
    n_ = std::max(1, static_cast<int>(std::ceil(p_.extent_m / p_.cell_m)));
    origin_ = {scan.pose.x - 0.5 * n_ * p_.cell_m, scan.pose.y - 0.5 * n_ * p_.cell_m};
    const std::size_t nn = static_cast<std::size_t>(n_) * static_cast<std::size_t>(n_);
    logodds_.assign(nn, 0.f);
    sx_.assign(nn, 0.f);
    sy_.assign(nn, 0.f);
    nhit_.assign(nn, 0);
    stamp_.assign(nn, 0);
    since_ns_.assign(nn, std::numeric_limits<std::int64_t>::max());
    frames_hit_.assign(nn, 0);
    nearest_hit_.assign(nn, std::numeric_limits<float>::infinity());
    if (p_.remember_seen) seen_ns_.assign(nn, std::numeric_limits<std::int64_t>::min());
    first_scan_ns_ = scan.t_ns;
    init_ = true;
  }
  ++frame_;
  // 1. hits
  for (const Vec2& h : scan.hits) {
    int ix, iy;
    if (!cell_of(h, ix, iy)) continue;
    const std::size_t i = static_cast<std::size_t>(iy) * n_ + ix;
    // running mean of the points (a window of ~20 keeps it following slow drift of the odometry)
    const std::uint32_t k = std::min<std::uint32_t>(nhit_[i] + 1, 20);
    sx_[i] += static_cast<float>((h.x - sx_[i]) / k);
    sy_[i] += static_cast<float>((h.y - sy_[i]) / k);
    nhit_[i] = k;
    if (p_.remember_seen) seen_ns_[i] = scan.t_ns;
    const float range = static_cast<float>(norm(h - scan.pose.pos()));
    if (stamp_[i] == frame_) {
      nearest_hit_[i] = std::min(nearest_hit_[i], range);
      continue;
    }
    stamp_[i] = frame_;
    const bool was_occupied = logodds_[i] > static_cast<float>(p_.l_occupied);
    logodds_[i] = std::min(static_cast<float>(p_.l_max), logodds_[i] + static_cast<float>(p_.hit));
    if (!was_occupied && logodds_[i] > static_cast<float>(p_.l_occupied)) {
      since_ns_[i] = scan.t_ns;
      frames_hit_[i] = 0;
      nearest_hit_[i] = std::numeric_limits<float>::infinity();
    }
    nearest_hit_[i] = std::min(nearest_hit_[i], range);
    if (frames_hit_[i] < 0xffff) ++frames_hit_[i];
  }
  // 2. free space along the rays: cells in the view, nearer than their column's free range
  const int w = static_cast<int>(scan.free_range_m.size());
  if (w == 0) return;
  double rmax = 0;
  for (double r : scan.free_range_m) rmax = std::max(rmax, r);
  if (rmax <= scan.min_range_m) return;
  const double c = std::cos(scan.pose.yaw), s = std::sin(scan.pose.yaw);
  // Without remember_seen, cells at the log-odds floor and nearer than min_range_m cannot change:
  // skipped before the view test.
  const bool seen = p_.remember_seen;
  const double near = seen ? p_.cell_m : scan.min_range_m;
  int x0, y0, x1, y1;
  cell_window(scan.pose.pos(), rmax, x0, y0, x1, y1);
  for (int iy = y0; iy <= y1; ++iy)
    for (int ix = x0; ix <= x1; ++ix) {
      const std::size_t i = static_cast<std::size_t>(iy) * n_ + ix;
      if (stamp_[i] == frame_ || (!seen && logodds_[i] <= static_cast<float>(p_.l_min))) continue;
      // cell centre in the robot frame
      const double wx = origin_.x + (ix + 0.5) * p_.cell_m - scan.pose.x;
      const double wy = origin_.y + (iy + 0.5) * p_.cell_m - scan.pose.y;
      const double fwd = c * wx + s * wy, left = -s * wx + c * wy;
      if (fwd < near || fwd > rmax) continue;
      // the whole cell must lie inside the column's free range: test its near and far columns
      const double half = 0.5 * p_.cell_m;
      const double u = scan.cx - scan.focal_px * left / fwd;
      const double du = scan.focal_px * half * 1.5 / fwd;
      const int u0 = static_cast<int>(std::floor(u - du)), u1 = static_cast<int>(std::ceil(u + du));
      if (u0 < 0 || u1 >= w) continue;
      bool free = true;
      for (int uu = u0; uu <= u1 && free; ++uu) free = fwd + half < scan.free_range_m[uu];
      if (!free) continue;
      if (seen) seen_ns_[i] = scan.t_ns;
      // nearer than min_range_m the camera measures nothing: seen (the column's free range says
      // nothing nearer stands there), but no evidence for the occupancy
      if (fwd < scan.min_range_m || logodds_[i] <= static_cast<float>(p_.l_min)) continue;
      logodds_[i] = std::max(static_cast<float>(p_.l_min), logodds_[i] - static_cast<float>(p_.miss));
    }
}

std::int64_t ObstacleMap::last_seen_ns(Vec2 p) const {
  int ix, iy;
  if (!init_ || !p_.remember_seen || !cell_of(p, ix, iy)) return std::numeric_limits<std::int64_t>::min();
  return seen_ns_[static_cast<std::size_t>(iy) * n_ + ix];
}

double ObstacleMap::nearest_hit_m(Vec2 p) const {
  int ix, iy;
  if (!init_ || !cell_of(p, ix, iy)) return std::numeric_limits<double>::infinity();
  const std::size_t i = static_cast<std::size_t>(iy) * n_ + ix;
  if (logodds_[i] <= static_cast<float>(p_.l_occupied)) return std::numeric_limits<double>::infinity();
  return nearest_hit_[i];
}

std::vector<CircleObstacle> ObstacleMap::obstacles(Vec2 centre, double radius_m, double confirm_range_m) const {
  std::vector<CircleObstacle> out;
  if (!init_) return out;
  int x0, y0, x1, y1;
  cell_window(centre, radius_m, x0, y0, x1, y1);
  for (int iy = y0; iy <= y1; ++iy)
    for (int ix = x0; ix <= x1; ++ix) {
      const std::size_t i = static_cast<std::size_t>(iy) * n_ + ix;
      if (logodds_[i] <= static_cast<float>(p_.l_occupied)) continue;
      const Vec2 p{sx_[i], sy_[i]};
      if (norm(p - centre) > radius_m) continue;
      CircleObstacle o{p, 0.5 * p_.cell_m, {}};
      o.unconfirmed = confirm_range_m > 0 && nearest_hit_[i] > confirm_range_m;
      out.push_back(o);
    }
  return out;
}

double ObstacleMap::seen_free_share(Vec2 c, double r, double l_free) const {
  int cells = 0;
  return seen_free_share_outside(c, r, c, -1.0, l_free, cells);  // a negative radius skips no cell
}

double ObstacleMap::seen_free_share_outside(Vec2 c, double r, Vec2 skip_c, double skip_r, double l_free,
                                            int& cells) const {
  cells = 0;
  if (!init_) return 0.0;
  int x0, y0, x1, y1;
  cell_window(c, r, x0, y0, x1, y1);
  int free = 0;
  for (int iy = y0; iy <= y1; ++iy)
    for (int ix = x0; ix <= x1; ++ix) {
      const Vec2 centre{origin_.x + (ix + 0.5) * p_.cell_m, origin_.y + (iy + 0.5) * p_.cell_m};
      if (norm(centre - c) > r || norm(centre - skip_c) <= skip_r) continue;
      ++cells;
      if (logodds_[static_cast<std::size_t>(iy) * n_ + ix] <= static_cast<float>(l_free)) ++free;
    }
  return cells > 0 ? double(free) / cells : 0.0;
}

int ObstacleMap::occupied_before(Vec2 c, double r, std::int64_t t_ns, int min_frames) const {
  if (!init_) return 0;
  int x0, y0, x1, y1;
  cell_window(c, r, x0, y0, x1, y1);
  int n = 0;
  for (int iy = y0; iy <= y1; ++iy)
    for (int ix = x0; ix <= x1; ++ix) {
      const std::size_t i = static_cast<std::size_t>(iy) * n_ + ix;
      if (logodds_[i] <= static_cast<float>(p_.l_occupied) || since_ns_[i] > t_ns || frames_hit_[i] < min_frames) continue;
      if (norm(Vec2{sx_[i], sy_[i]} - c) <= r) ++n;
    }
  return n;
}

int ObstacleMap::occupied_count() const {
  int n = 0;
  for (float l : logodds_) n += l > static_cast<float>(p_.l_occupied);
  return n;
}

}  // namespace fs::robot
