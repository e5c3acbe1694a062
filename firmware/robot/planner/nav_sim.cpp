// Seeded 2-D navigation scenarios and the closed loop that runs them (nav_sim.hpp).
#include "fuzzystereo/robot/nav_sim.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "fuzzystereo/robot/clock.hpp"
#include "fuzzystereo/robot/failsafe.hpp"
#include "fuzzystereo/robot/motors.hpp"
#include "fuzzystereo/robot/odometry.hpp"

namespace fs::robot {
namespace {

using Rng = std::mt19937_64;
double uni(Rng& r, double a, double b) { return std::uniform_real_distribution<double>(a, b)(r); }

bool clear_of(const std::vector<CircleObstacle>& obs, Vec2 p, double r) {
  for (const CircleObstacle& o : obs)
    if (norm(p - o.c) < o.r + r) return false;
  return true;
}

// Distance of point p to the infinite line through a with direction d (unit).
double line_dist(Vec2 a, Vec2 d, Vec2 p) {
  const Vec2 ap = p - a;
  return std::abs(ap.x * d.y - ap.y * d.x);
}

void add_ring(std::vector<CircleObstacle>& obs, Vec2 c, double ring_r, double rp_radius) {
  // Circles of radius 0.12 around c with surface gaps of 1.2 * robot radius (< robot diameter).
  const double r = 0.12, gap = 1.2 * rp_radius;
  const int n = static_cast<int>(std::ceil(2 * M_PI * ring_r / (2 * r + gap)));
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    obs.push_back({{c.x + ring_r * std::cos(a), c.y + ring_r * std::sin(a)}, r, {}});
  }
}

}  // namespace

Vec2 NavScenario::at(std::size_t i, double t) const {
  const CircleObstacle& o = obstacles[i];
  if (i >= turns.size() || turns[i].empty()) return o.at(t);
  Vec2 p = o.c, v = o.vel;
  double t0 = 0.0;
  for (const auto& [tk, vk] : turns[i]) {
    if (tk > t) break;
    p = p + (tk - t0) * v;
    t0 = tk;
    v = vk;
  }
  return p + (t - t0) * v;
}

Vec2 NavScenario::vel_at(std::size_t i, double t) const {
  Vec2 v = obstacles[i].vel;
  if (i < turns.size())
    for (const auto& [tk, vk] : turns[i]) {
      if (tk > t) break;
      v = vk;
    }
  return v;
}

void walk_movers(NavScenario& sc, MoverModel model, const std::vector<CircleObstacle>& avoid, double horizon_s,
                 double dt) {
  auto& obs = sc.obstacles;
  sc.turns.assign(obs.size(), {});
  if (model == MoverModel::kPass) return;
  const auto moving = [&](std::size_t i) { return obs[i].vel.x != 0.0 || obs[i].vel.y != 0.0; };
  // A mover whose line starts inside a static obstacle or another mover starts where it comes out
  // (moved forward along its line, at most 30 s of its walk); one that never does is left out.
  const auto inside = [&](std::size_t i) {
    for (std::size_t k = 0; k < obs.size(); ++k)
      if (k != i && norm(obs[i].c - obs[k].c) < obs[i].r + obs[k].r) return true;
    return false;
  };
  for (std::size_t i = 0; i < obs.size();) {
    bool out = true;
    if (moving(i) && inside(i)) {
      out = false;
      for (int k = 0; k < static_cast<int>(30.0 / dt) && !out; ++k) {
        obs[i].c = obs[i].c + dt * obs[i].vel;
        out = !inside(i);
      }
    }
    if (out) ++i;
    else obs.erase(obs.begin() + static_cast<std::ptrdiff_t>(i));
  }
  sc.turns.assign(obs.size(), {});
  std::vector<Vec2> pos(obs.size()), vel(obs.size());
  for (std::size_t i = 0; i < obs.size(); ++i) pos[i] = obs[i].c, vel[i] = obs[i].vel;
  // The first thing (index into obs, or obs.size() + k for avoid[k]) a disc of radius r at p overlaps.
  const auto blocker = [&](std::size_t i, Vec2 p) -> std::ptrdiff_t {
    for (std::size_t j = 0; j < obs.size(); ++j)
      if (j != i && norm(p - pos[j]) < obs[i].r + obs[j].r) return static_cast<std::ptrdiff_t>(j);
    if (model == MoverModel::kSlide)
      for (std::size_t k = 0; k < avoid.size(); ++k)
        if (norm(p - avoid[k].c) < obs[i].r + avoid[k].r) return static_cast<std::ptrdiff_t>(obs.size() + k);
    return -1;
  };
  std::vector<std::size_t> walking;
  for (std::size_t i = 0; i < obs.size(); ++i)
    if (moving(i)) walking.push_back(i);
  const int steps = static_cast<int>(std::ceil(horizon_s / dt));
  for (int k = 0; k < steps && !walking.empty(); ++k) {
    const double t = k * dt;  // every walker moves from its position at t to t + dt
    for (std::size_t w = 0; w < walking.size();) {
      const std::size_t i = walking[w];
      std::ptrdiff_t j = blocker(i, pos[i] + dt * vel[i]);
      if (j >= 0 && model == MoverModel::kSlide) {
        // Deflect: off a start / goal area it bounces (mirrored about the area's tangent, so it
        // walks away from it, as the straight lines keep away from them); along an obstacle it
        // slides (the tangent of its disc at the walker, on the side of its velocity), or along the
        // other tangent when that one is blocked.
        const bool area = static_cast<std::size_t>(j) >= obs.size();
        const Vec2 c = area ? avoid[static_cast<std::size_t>(j) - obs.size()].c : pos[static_cast<std::size_t>(j)];
        const Vec2 d = pos[i] - c;
        const double nn = norm(d), speed = norm(vel[i]);
        bool turned = false;
        if (nn > 1e-9) {
          const Vec2 nrm = (1.0 / nn) * d;
          Vec2 tan{-nrm.y, nrm.x};
          if (tan.x * vel[i].x + tan.y * vel[i].y < 0) tan = -1.0 * tan;
          const double vn = nrm.x * vel[i].x + nrm.y * vel[i].y;
          const Vec2 bounce = vel[i] - (2.0 * std::min(vn, 0.0)) * nrm;
          // An area: the bounce, then either tangent; an obstacle: its forward tangent, then the other.
          const Vec2 tries[3] = {bounce, speed * tan, -speed * tan};
          for (int k2 = area ? 0 : 1; k2 < 3 && !turned; ++k2) {
            const Vec2 v = tries[k2];
            if (norm(v) > 0 && blocker(i, pos[i] + dt * v) < 0) {
              vel[i] = v;
              sc.turns[i].push_back({t, v});
              turned = true;
            }
          }
        }
        if (turned) j = -1;
      }
      if (j >= 0) {  // stands from t on at its last position clear of everything
        vel[i] = {};
        sc.turns[i].push_back({t, Vec2{}});
        walking.erase(walking.begin() + static_cast<std::ptrdiff_t>(w));
        continue;
      }
      pos[i] = pos[i] + dt * vel[i];
      ++w;
    }
  }
}

NavScenario make_nav_scenario(std::uint64_t seed, bool blocked, const RobotParams& rp, MoverModel movers) {
  Rng rng(seed * 0x9E3779B97F4A7C15ull + (blocked ? 7 : 1));
  for (int attempt = 0;; ++attempt) {
    NavScenario sc;
    sc.seed = seed;
    sc.solvable = !blocked;
    const double L = uni(rng, 4.0, 6.0);
    sc.goal = {L, uni(rng, -1.5, 1.5)};
    sc.start = {0, 0, wrap_angle(std::atan2(sc.goal.y, sc.goal.x) + uni(rng, -0.8, 0.8))};
    auto& obs = sc.obstacles;
    const Vec2 s = sc.start.pos();
    const Vec2 dir = (1.0 / norm(sc.goal - s)) * (sc.goal - s);
    const Vec2 nrm{-dir.y, dir.x};
    if (blocked) {
      const bool ring_goal = uni(rng, 0, 1) < 0.5;
      add_ring(obs, ring_goal ? sc.goal : s, uni(rng, 0.7, 1.2), rp.radius_m);
      sc.features = ring_goal ? "ring-goal" : "ring-robot";
    }
    const double feature = uni(rng, 0, 1);
    if (!blocked && feature < 0.3) {  // wall across the direct path with one narrow gap
      const double t = uni(rng, 0.35, 0.65) * norm(sc.goal - s);
      const double gap = uni(rng, 2.0 * (rp.radius_m + 0.08), 2.0 * (rp.radius_m + 0.25));
      const double off = uni(rng, -1.0, 1.0), r = 0.15;
      const Vec2 c0 = s + t * dir;
      for (double y = off + 0.5 * gap + r; y < 3.5; y += 2 * r) obs.push_back({c0 + y * nrm, r, {}});
      for (double y = off - 0.5 * gap - r; y > -3.5; y -= 2 * r) obs.push_back({c0 + y * nrm, r, {}});
      sc.features += "gap ";
    } else if (!blocked && feature < 0.55) {  // U-trap open towards the robot on the direct path
      const Vec2 c0 = s + uni(rng, 0.4, 0.6) * norm(sc.goal - s) * dir;
      const double w = uni(rng, 0.6, 1.0), depth = uni(rng, 0.6, 1.0), r = 0.12;
      for (double y = -w; y <= w + 1e-9; y += 2 * r) obs.push_back({c0 + y * nrm, r, {}});  // bottom
      for (double x = 2 * r; x <= depth; x += 2 * r) {                                      // arms
        obs.push_back({c0 - x * dir + w * nrm, r, {}});
        obs.push_back({c0 - x * dir - w * nrm, r, {}});
      }
      sc.features += "utrap ";
    }
    const int n_static = static_cast<int>(uni(rng, 5, 11));
    for (int i = 0; i < n_static; ++i) {
      const CircleObstacle o{{uni(rng, 0.6, L + 0.5), uni(rng, -2.5, 2.5)}, uni(rng, 0.1, 0.4), {}};
      if (norm(o.c - s) < o.r + rp.radius_m + 0.4 || norm(o.c - sc.goal) < o.r + rp.radius_m + 0.4) continue;
      obs.push_back(o);
    }
    const int n_moving = static_cast<int>(uni(rng, 0, 3.99));
    for (int i = 0; i < n_moving; ++i) {
      // crosses the start-goal line at a random point, roughly perpendicular, at 0.05-0.30 m/s
      // (independent of the robot's speed limit: a slower robot meets the same world)
      const Vec2 cross = s + uni(rng, 0.3, 0.8) * norm(sc.goal - s) * dir;
      const double ang = uni(rng, -0.6, 0.6), speed = 0.5 * uni(rng, 0.1, 0.6);
      const double side = uni(rng, 0, 1) < 0.5 ? -1.0 : 1.0;
      const Vec2 mdir = std::cos(ang) * (side * nrm) + std::sin(ang) * dir;
      const double r = uni(rng, 0.12, 0.3);
      const double t_cross = uni(rng, 2.0, 10.0);  // reaches the line at this time
      CircleObstacle m{cross - (speed * t_cross) * mdir, r, speed * mdir};
      // never through the start or goal areas (the robot stands there)
      if (line_dist(m.c, mdir, s) < r + rp.radius_m + 0.8 || line_dist(m.c, mdir, sc.goal) < r + rp.radius_m + 0.8)
        continue;
      obs.push_back(m);
      if (sc.features.find("moving") == std::string::npos) sc.features += "moving ";
    }
    if (!clear_of(obs, s, rp.radius_m + 0.1) || !clear_of(obs, sc.goal, rp.radius_m + 0.1)) continue;
    // kSlide movers bounce off the start and goal areas (which the lines of all movers keep out of).
    walk_movers(sc, movers, {{s, rp.radius_m + 0.8, {}}, {sc.goal, rp.radius_m + 0.8, {}}});
    if (!blocked) {
      // Solvable: a path among the static obstacles and the movers that end up standing (solid
      // movers), where they stand.
      std::vector<CircleObstacle> st;
      for (std::size_t i = 0; i < obs.size(); ++i)
        if (norm(obs[i].vel) == 0) st.push_back(obs[i]);
        else if (i < sc.turns.size() && !sc.turns[i].empty() && norm(sc.turns[i].back().second) == 0)
          st.push_back({sc.at(i, sc.turns[i].back().first), obs[i].r, {}});
      if (!std::isfinite(shortest_path_length(st, s, sc.goal, rp.radius_m + 0.03, 0.1))) continue;
    }
    (void)attempt;
    return sc;
  }
}

NavResult run_nav_scenario(const NavScenario& sc, const RobotParams& rp, const PlannerParams& pp) {
  NavResult res;
  std::vector<CircleObstacle> statics;
  for (const auto& o : sc.obstacles)
    if (norm(o.vel) == 0) statics.push_back(o);
  if (sc.solvable) res.shortest_m = shortest_path_length(statics, sc.start.pos(), sc.goal, rp.radius_m, 0.05);
  const double straight = norm(sc.goal - sc.start.pos());
  const double max_time = sc.solvable ? 3.0 * std::max(straight, std::isfinite(res.shortest_m) ? res.shortest_m : straight) /
                                                rp.max_speed_mps + 15.0
                                      : 15.0;
  SimClock clock;
  SimMotors motors(rp, sc.start, 0);
  Planner planner(pp, rp);
  DiffDriveMixer mixer(rp);
  const std::int64_t frame_ns = s_to_ns(pp.control_period_s), sub_ns = 10'000'000;
  res.min_gap_m = std::numeric_limits<double>::infinity();
  Pose2D prev = sc.start;
  PlanStatus status = PlanStatus::kMoving;
  double blocked_still_s = 0;
  std::vector<Vec2> last_route;  // route commitment ([planner] route_keep_ratio)
  for (;;) {
    const double t = ns_to_s(clock.now_ns());
    const Pose2D pose = motors.pose();
    std::vector<CircleObstacle> now;
    for (std::size_t i = 0; i < sc.obstacles.size(); ++i) now.push_back({sc.at(i, t), sc.obstacles[i].r, sc.vel_at(i, t)});
    const BodyTwist cur = twist_from_wheels(motors.wheel_left_mps(), motors.wheel_right_mps(), rp.wheel_base_m);
    const PlanOutput plan = planner.plan(pose, cur, sc.goal, now, {&last_route, {}});
    if (pp.route_keep_ratio > 0) last_route = plan.path;
    status = plan.status;
    if (status == PlanStatus::kReached) {
      res.reached = true;
      break;
    }
    const bool ahead = obstacle_in_front(pose, now, rp.radius_m, rp.stop_distance_m);
    const WheelCommand wc = mixer.mix(apply_front_stop(plan.cmd, ahead, rp.stop_allows_turning), pp.control_period_s);
    motors.set(wc.left, wc.right);
    // advance one frame in 10 ms sub-steps, checking contact against the true obstacles
    for (std::int64_t k = 0; k < frame_ns; k += sub_ns) {
      clock.advance(std::min(sub_ns, frame_ns - k));
      motors.advance_to(clock.now_ns());
      const Pose2D p = motors.pose();
      const double ts = ns_to_s(clock.now_ns());
      res.path_m += norm(p.pos() - prev.pos());
      prev = p;
      for (std::size_t i = 0; i < sc.obstacles.size(); ++i) {
        const double gap = norm(p.pos() - sc.at(i, ts)) - sc.obstacles[i].r - rp.radius_m;
        res.min_gap_m = std::min(res.min_gap_m, gap);
        if (gap < 0) res.collided = true;
      }
    }
    if (res.collided) break;
    // unsolvable scenario: done once the robot has stood still, blocked, for 3 s
    const bool standing_now = std::abs(motors.wheel_left_mps()) < 1e-6 && std::abs(motors.wheel_right_mps()) < 1e-6;
    blocked_still_s = (status == PlanStatus::kBlocked && standing_now) ? blocked_still_s + pp.control_period_s : 0.0;
    if (!sc.solvable && blocked_still_s >= 3.0) break;
    if (ns_to_s(clock.now_ns()) > max_time) {
      res.timed_out = true;
      break;
    }
  }
  res.time_s = ns_to_s(clock.now_ns());
  res.final_status = status;
  const bool standing = std::abs(motors.wheel_left_mps()) < 1e-6 && std::abs(motors.wheel_right_mps()) < 1e-6;
  res.safe_stop = !res.collided && status == PlanStatus::kBlocked && standing;
  return res;
}

NavSuiteResult run_nav_suite(int n_solvable, int n_blocked, std::uint64_t seed, const RobotParams& rp,
                             const PlannerParams& pp) {
  NavSuiteResult s;
  double ratio_sum = 0;
  for (int i = 0; i < n_solvable; ++i) {
    const NavScenario sc = make_nav_scenario(seed + static_cast<std::uint64_t>(i), false, rp);
    const NavResult r = run_nav_scenario(sc, rp, pp);
    ++s.solvable;
    if (r.collided) ++s.collisions;
    if (r.timed_out) ++s.timeouts;
    if (r.reached && !r.collided) {
      ++s.reached_clean;
      const double ratio = r.path_m / r.shortest_m;
      ratio_sum += ratio;
      s.max_path_ratio = std::max(s.max_path_ratio, ratio);
    } else {
      s.failed_seeds.push_back(sc.seed);
    }
  }
  if (s.reached_clean) s.mean_path_ratio = ratio_sum / s.reached_clean;
  for (int i = 0; i < n_blocked; ++i) {
    const NavScenario sc = make_nav_scenario(seed + 100000 + static_cast<std::uint64_t>(i), true, rp);
    const NavResult r = run_nav_scenario(sc, rp, pp);
    ++s.blocked;
    if (r.safe_stop) ++s.blocked_safe;
    else s.failed_seeds.push_back(sc.seed);
  }
  return s;
}

}  // namespace fs::robot
