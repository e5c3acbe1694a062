// Global grid A* + sampled-arc local planner (docs/robot.md "Planner").
#include "fuzzystereo/robot/planner.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "fuzzystereo/robot/odometry.hpp"
#include "grid.hpp"

namespace fs::robot {

const char* to_string(PlanStatus s) {
  switch (s) {
    case PlanStatus::kMoving: return "moving";
    case PlanStatus::kReached: return "reached";
    case PlanStatus::kWaiting: return "waiting";
    case PlanStatus::kBlocked: return "blocked";
  }
  return "?";
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Obstacles slower than this count as static when deciding "blocked" (a path closed only by a
// moving obstacle means wait, not blocked) [m/s].
constexpr double kStaticSpeed = 0.05;
// Grid size cap per axis (bounds the per-frame cost when obstacles are far apart).
constexpr int kMaxCellsPerAxis = 300;  // (doubled for the fine retry)

struct GlobalPlan {
  std::vector<Vec2> path;
  detail::Grid grid;
  bool reduced_margin = false;
  bool only_static = false;
};

bool build_and_search(const std::vector<CircleObstacle>& obs, bool static_only, double inflate, Vec2 start, Vec2 goal,
                      double margin, double res, bool check_pockets, const PlannerParams& pp, GlobalPlan& out) {
  Vec2 lo{std::min(start.x, goal.x) - margin, std::min(start.y, goal.y) - margin};
  Vec2 hi{std::max(start.x, goal.x) + margin, std::max(start.y, goal.y) + margin};
  detail::Grid& g = out.grid;
  g.init(lo, hi, res, 2 * kMaxCellsPerAxis);
  for (const CircleObstacle& o : obs) {
    if (static_only && norm(o.vel) > kStaticSpeed) continue;
    // "Blocked" (the static-only tries) is a final verdict, the safe stop: only known surfaces may
    // give it, not the circles that mark where a tracked obstacle may be (zero velocity, but no
    // surface: seed-11 suite, scenarios 23 and 74 stopped "blocked" beside a mover's near-track
    // circle and a ghost track's reachable set).
    if (static_only && pp.transient_not_blocking && o.transient) continue;
    // An obstacle that covers the goal point itself (inflated) is left to the local planner: the
    // global search then asks whether the goal's surroundings can be reached; a ring round the goal
    // is still found, its obstacles do not cover the goal point. Which obstacles:
    // - map cells seen only from afar ([loop] blocked_confirm_range_m, the default): at 4-5.5 m a
    //   quarter-pixel disparity error is 0.25-0.5 m, and single false detections there left cells
    //   on the goal that the camera could not clear from where the robot stood (suites 13-35, 15-4,
    //   15-45: "blocked" stops 4-5.6 m from an empty goal); the robot drives on and sees them nearer.
    //   Left out of every try: out of the static-only ones only, the first tries fail every frame
    //   and the robot follows the static-only route, which ignores movers (15-4);
    // - with [planner] ignore_goal_footprint (off), every obstacle there (seed 11, scenario 74:
    //   cells 0.03-0.2 m from the goal stopped the robot 4.5 m from it; confirmed surfaces too).
    if ((o.unconfirmed || pp.ignore_goal_footprint) && norm(o.c - goal) < o.r + inflate) continue;
    g.fill_disc(o.c, o.r + inflate);
  }
  // The robot may already be inside an inflated disc (margin violated): free its own cell
  // neighbourhood so the search can lead it out; the local planner enforces the hard margin.
  int sx, sy;
  g.cell_of(start, sx, sy);
  if (g.inside(sx, sy) && g.blocked[g.idx(sx, sy)]) g.clear_disc(start, 1.5 * g.res);
  // An enclosed goal or robot: the pocket is found in a few hundred cells, while A* would expand
  // the whole (large) grid on every one of the retries below.
  const int pocket = static_cast<int>(std::ceil(M_PI * 4.0 / (res * res)));  // ~ a 2 m disc
  if (check_pockets && (detail::in_small_pocket(g, goal, pocket) || detail::in_small_pocket(g, start, pocket))) {
    out.path.clear();
    return false;
  }
  out.path = detail::astar(g, start, goal);
  return !out.path.empty();
}

double path_length(const std::vector<Vec2>& path) {
  double len = 0;
  for (std::size_t i = 1; i < path.size(); ++i) len += norm(path[i] - path[i - 1]);
  return len;
}

GlobalPlan global_plan(const std::vector<CircleObstacle>& obs, Vec2 start, Vec2 goal, const PlannerParams& pp,
                       const RobotParams& rp) {
  const double full = rp.radius_m + pp.safety_margin_m, bare = rp.radius_m + pp.collision_margin_m;
  // Tries, cheapest first: all obstacles with the full margin; with the bare collision margin
  // (a gap the safety margin closes); the same on a grid twice as fine (a gap narrower than a few
  // cells can vanish in the rasterisation); on a grid twice as large (a detour around a long wall).
  // Then the same with static obstacles only: a path closed only by moving obstacles means "wait",
  // not "blocked".
  GlobalPlan gp;
  const double res = pp.grid_resolution_m;
  for (const bool only_static : {false, true}) {
    gp.only_static = only_static;
    gp.reduced_margin = false;
    const double m = pp.grid_margin_m;
    // (the pocket test is skipped on the first try, which usually succeeds)
    if (build_and_search(obs, only_static, full, start, goal, m, res, only_static, pp, gp)) {
      // Gap shortcut ([planner] shortcut_ratio, session 42): a gap the safety margin closes in some
      // frames and not in others (depth noise, the 0.1 m raster) makes the route flip between it and
      // a detour round the wall's end, and the robot loops in front of the wall (suite seed 146,
      // scenario 38). A much shorter route with the narrower margin wins.
      // A route from start to goal is at least their distance apart, so a full-margin route within
      // ratio x that distance cannot lose to the shortcut: the second search runs only where it can win
      // (not on the open-field frames, most of them).
      const double full_len = path_length(gp.path);
      if (pp.shortcut_ratio > 0 && !only_static && full_len > pp.shortcut_ratio * norm(goal - start)) {
        GlobalPlan sc;
        const double narrow = rp.radius_m + std::clamp(pp.shortcut_margin_m, pp.collision_margin_m, pp.safety_margin_m);
        if (narrow < full && build_and_search(obs, false, narrow, start, goal, m, res, true, pp, sc) &&
            full_len > pp.shortcut_ratio * path_length(sc.path)) {
          sc.only_static = false;
          sc.reduced_margin = true;
          return sc;
        }
      }
      return gp;
    }
    gp.reduced_margin = true;
    if (build_and_search(obs, only_static, bare, start, goal, m, res, true, pp, gp)) return gp;
    if (build_and_search(obs, only_static, bare, start, goal, m, 0.5 * res, true, pp, gp)) return gp;
    if (build_and_search(obs, only_static, bare, start, goal, 2.0 * m, res, true, pp, gp)) return gp;
  }
  return gp;
}

// Furthest point along the path within lookahead whose straight segment from the robot is free.
Vec2 pick_carrot(const GlobalPlan& gp, Vec2 pos, double lookahead) {
  const auto& path = gp.path;
  Vec2 best = path.size() > 1 ? path[1] : path.back();
  double along = 0;
  for (std::size_t i = 1; i < path.size(); ++i) {
    along += norm(path[i] - path[i - 1]);
    if (along > lookahead && i > 1) break;
    if (gp.grid.segment_free(pos, path[i])) best = path[i];
  }
  return best;
}

double point_segment_distance(Vec2 p, Vec2 a, Vec2 b) {
  const Vec2 ab = b - a;
  const double l2 = norm2(ab);
  const double t = l2 > 0 ? std::clamp(dot(p - a, ab) / l2, 0.0, 1.0) : 0.0;
  return norm(p - (a + t * ab));
}

// Route commitment ([planner] route_keep_*): the last frame's route, from the robot's nearest point
// on it, when it still ends at the goal, passes within route_keep_offset_m of the robot and is free
// on this frame's grid (the one the new route was found on, same obstacles and inflation).
bool last_route_from(const std::vector<Vec2>& last, Vec2 pos, Vec2 goal, const GlobalPlan& gp,
                     const PlannerParams& pp, std::vector<Vec2>& kept) {
  if (last.size() < 2 || norm(last.back() - goal) > 1e-9) return false;
  double best = kInf;
  std::size_t seg = 0;
  for (std::size_t i = 0; i + 1 < last.size(); ++i) {
    const double d = point_segment_distance(pos, last[i], last[i + 1]);
    if (d < best) {
      best = d;
      seg = i;
    }
  }
  if (best > pp.route_keep_offset_m) return false;
  kept.assign(1, pos);
  kept.insert(kept.end(), last.begin() + static_cast<std::ptrdiff_t>(seg) + 1, last.end());
  for (std::size_t i = 1; i < kept.size(); ++i)
    if (!gp.grid.segment_free(kept[i - 1], kept[i])) return false;
  return true;
}

// Look where you drive ([planner] unseen_check_s): the arc's leading point (lead ahead of the centre,
// along the heading) at every sim step up to unseen_check_s, on ground the camera has not seen
// recently. The camera sees +-50 deg; a mover beside the robot is in no map and, once its track is
// lost, in no plan: every collision of the closed-loop suites since session 3 was with a mover that
// came from outside the view (seed 11, scenario 58: a left arc at 2 rad/s into a 0.11 m/s mover at
// 63 deg bearing). Such an arc is not driven; turning on the spot (v = 0) still is, and shows the
// camera the way first.
bool drives_into_unseen(const Pose2D& p0, double v, double w, double lead, const PlannerParams& pp,
                        const std::function<bool(Vec2)>& seen) {
  for (double t = pp.sim_step_s; t <= pp.unseen_check_s + 1e-9; t += pp.sim_step_s) {
    const Pose2D p = integrate_pose(p0, {v, w}, t);
    if (!seen({p.x + lead * std::cos(p.yaw), p.y + lead * std::sin(p.yaw)})) return true;
  }
  return false;
}

// Soft memory cost: the deepest the robot's disc enters any memory circle along the arc, over the
// horizon — 0 outside every circle, 1 with the robot's centre on a circle's centre. An arc that leads
// out of a circle the robot is already in scores its depth at the first step, less than one that goes
// deeper.
double memory_depth(const Pose2D& p0, double v, double w, const std::vector<CircleObstacle>& mem,
                    const PlannerParams& pp, const RobotParams& rp) {
  double depth = 0.0;
  for (double t = pp.sim_step_s; t <= pp.horizon_s + 1e-9; t += pp.sim_step_s) {
    const Pose2D p = integrate_pose(p0, {v, w}, t);
    for (const auto& m : mem) {
      const double reach = m.r_at(t) + rp.radius_m;  // a memory circle may grow over the horizon
      const Vec2 c = m.at(t);
      const double d = std::hypot(p.x - c.x, p.y - c.y);
      if (d < reach) depth = std::max(depth, 1.0 - d / reach);
    }
  }
  return depth;
}

struct ArcEval {
  double t_collide = kInf;  // first time the hard margin is violated
  double min_gap = kInf;    // smallest surface gap before that [m]
  double best_d = kInf;     // closest approach to the carrot before that [m]
  double heading_at_best = -1;   // cos of the heading error to the carrot at the closest approach
  double heading_after_T = -1;   // ... after one control period (what the command does now)
};

// Squared centre distance below which the robot touches obstacle i (its hard margin): robot radius
// + o.r + collision_margin_m. With escape_inside_margin, a static obstacle (zero velocity: map
// cells, near-track and reachable-set circles) the robot is already closer to than that at t = 0
// gets its current distance instead: an arc then "touches" it only when it brings the robot closer
// still. Moving obstacles keep the hard margin (no arc admissible -> the evasion below): on seed-11
// scenario 92 the rule for movers let the robot drive on beside a track 0.2 m off the true mover,
// into it. Without this every arc, standing included, is in contact from the
// first step, no arc is admissible, and a robot that came too close to a static obstacle (or
// stands in a map cell left by a passing mover) waits there for ever — the evasion below is only
// for moving obstacles (seed-11 suite scenarios 18, 97, 99: 145-168 frames standing, timeout).
std::vector<double> contact_d2(const Pose2D& p0, const std::vector<CircleObstacle>& obs, const PlannerParams& pp,
                               const RobotParams& rp) {
  std::vector<double> d2(obs.size());
  for (std::size_t i = 0; i < obs.size(); ++i) {
    const CircleObstacle& o = obs[i];
    const double hard = o.r + rp.radius_m + pp.collision_margin_m;
    const double dx = o.c.x - p0.x, dy = o.c.y - p0.y, now2 = dx * dx + dy * dy;
    const bool is_static = !o.moves();
    d2[i] = pp.escape_inside_margin && is_static ? std::min(hard * hard, now2) : hard * hard;
  }
  return d2;
}

// Robot along a constant (v, omega) arc; with brake = true, v and omega decay at the acceleration
// limits after the first control period (the stop the robot can always still make). Positions use
// the exact arc (integrate_pose) with the heading rotated incrementally (no trig per step).
// hard2[i]: squared contact distance of obs[i] (contact_d2).
ArcEval eval_arc(const Pose2D& p0, double v, double w, bool brake, const std::vector<CircleObstacle>& obs,
                 const std::vector<double>& hard2, Vec2 carrot, const PlannerParams& pp, const RobotParams& rp) {
  ArcEval e;
  const int steps = std::max(1, static_cast<int>(std::lround(pp.horizon_s / pp.sim_step_s)));
  const double dt = pp.horizon_s / steps;
  double x = p0.x, y = p0.y, c = std::cos(p0.yaw), s = std::sin(p0.yaw);
  double cv = v, cw = w;
  double rc = std::cos(cw * dt), rs = std::sin(cw * dt);
  // cosine of the heading error; acos is taken once per arc at the end
  auto heading_err = [&](double px, double py) {
    const double dx = carrot.x - px, dy = carrot.y - py, d = std::sqrt(dx * dx + dy * dy);
    return d > 1e-6 ? std::clamp((c * dx + s * dy) / d, -1.0, 1.0) : 1.0;
  };
  auto look = [&](double px, double py) {
    const double dx = carrot.x - px, dy = carrot.y - py, d = std::sqrt(dx * dx + dy * dy);
    if (d < e.best_d) {
      e.best_d = d;
      e.heading_at_best = heading_err(px, py);
    }
  };
  look(x, y);
  e.heading_after_T = heading_err(x, y);
  bool after_T_set = false;
  for (int k = 1; k <= steps; ++k) {
    const double t = k * dt;
    if (brake && t > pp.control_period_s) {
      cv = std::max(0.0, cv - rp.max_accel_mps2 * dt);
      const double dw = rp.max_yaw_accel_radps2 * dt;
      cw = std::abs(cw) <= dw ? 0.0 : cw - std::copysign(dw, cw);
      rc = std::cos(cw * dt);
      rs = std::sin(cw * dt);
    }
    const double c1 = c * rc - s * rs, s1 = s * rc + c * rs;
    if (std::abs(cw * dt) < 1e-9) {
      x += cv * dt * c;
      y += cv * dt * s;
    } else {
      const double r = cv / cw;
      x += r * (s1 - s);
      y -= r * (c1 - c);
    }
    c = c1;
    s = s1;
    double gap_min = kInf;
    bool hit = false;
    for (std::size_t i = 0; i < obs.size(); ++i) {
      const CircleObstacle& o = obs[i];
      const double ox = o.c.x + t * o.vel.x - x, oy = o.c.y + t * o.vel.y - y;
      const double d2 = ox * ox + oy * oy;
      // A growing obstacle (grow > 0): its hard distance grows with it (hard2 holds it at t = 0).
      const double g = o.grow > 0.0 ? o.r_at(t) - o.r : 0.0;
      if (g > 0.0 ? std::sqrt(d2) < std::sqrt(hard2[i]) + g : d2 < hard2[i]) hit = true;
      // only gaps below the soft range (robot radius + safety margin) enter the clearance cost
      const double rt = o.r + g;
      const double soft = rt + 2.0 * rp.radius_m + pp.safety_margin_m;
      if (d2 < soft * soft) gap_min = std::min(gap_min, std::sqrt(d2) - rt - rp.radius_m);
    }
    if (hit) {
      e.t_collide = t;
      break;
    }
    e.min_gap = std::min(e.min_gap, gap_min);
    look(x, y);
    if (!after_T_set && t >= pp.control_period_s - 1e-9) {
      e.heading_after_T = heading_err(x, y);
      after_T_set = true;
    }
  }
  return e;
}

// Escape score of driving (v, w): the smallest signed surface gap to the obstacles (moving ones at
// c + t vel) from one control period on to the horizon, sampled every sim_step (negative =
// overlap). Starting at one period, not at 0: every arc starts from the same pose.
double worst_gap(const Pose2D& pose, double v, double w, const std::vector<CircleObstacle>& obs,
                 const PlannerParams& pp, const RobotParams& rp, bool moving_only = false) {
  double worst = std::numeric_limits<double>::infinity();
  for (double t = pp.control_period_s; t <= pp.horizon_s + 1e-9; t += pp.sim_step_s) {
    const Pose2D p = integrate_pose(pose, {v, w}, t);
    for (const CircleObstacle& o : obs) {
      if (moving_only && !o.moves()) continue;
      worst = std::min(worst, norm(o.c + t * o.vel - p.pos()) - o.r_at(t) - rp.radius_m);
    }
  }
  return worst;
}

}  // namespace

// Only obstacles the robot can reach within the horizon matter for the arcs.
std::vector<CircleObstacle> Planner::reachable_obstacles(const std::vector<CircleObstacle>& obstacles, Vec2 pos) const {
  const double reach = rp_.max_speed_mps * pp_.horizon_s + rp_.radius_m + pp_.safety_margin_m;
  std::vector<CircleObstacle> near;
  for (const CircleObstacle& o : obstacles)
    if (norm(o.c - pos) - o.r_at(pp_.horizon_s) - norm(o.vel) * pp_.horizon_s <= reach) near.push_back(o);
  return near;
}

// The (v, omega) samples reachable within one control period from the current twist.
Planner::DynamicWindow Planner::dynamic_window(const BodyTwist& current, double dist_goal) const {
  const double T = pp_.control_period_s;
  DynamicWindow dw;
  dw.vmax = std::min(rp_.max_speed_mps, current.v + rp_.max_accel_mps2 * T);
  // slow down towards the goal so the robot can stop inside the tolerance
  dw.vmax = std::min(dw.vmax, std::sqrt(2.0 * rp_.max_accel_mps2 * std::max(0.0, dist_goal - 0.5 * rp_.goal_tolerance_m)));
  dw.vmin = std::max(0.0, current.v - rp_.max_accel_mps2 * T);
  dw.wmax = std::min(rp_.max_yaw_rate_radps, current.omega + rp_.max_yaw_accel_radps2 * T);
  dw.wmin = std::max(-rp_.max_yaw_rate_radps, current.omega - rp_.max_yaw_accel_radps2 * T);
  dw.nv = std::max(2, pp_.v_samples);
  dw.nw = std::max(3, pp_.w_samples);
  return dw;
}

BodyTwist Planner::DynamicWindow::at(int iv, int iw) const {
  const double v = vmin > vmax ? vmin : vmin + (vmax - vmin) * iv / (nv - 1);
  return {v, wmin + (wmax - wmin) * iw / (nw - 1)};
}

// Evade rather than brake: something moving comes within the collision margin of the standing
// robot (a static obstacle never reaches a robot that stands; the obstacles are grown by their
// uncertainty, so the robot may already be "inside" one) and gets nearer than it is now, and the
// best escape arc keeps a larger worst-case gap over the horizon than standing.
bool Planner::evade_instead_of_standing(const Pose2D& pose, const std::vector<CircleObstacle>& near,
                                        double escape_gap) const {
  double now_moving = kInf;
  for (const CircleObstacle& o : near)
    if (o.moves()) now_moving = std::min(now_moving, norm(o.c - pose.pos()) - o.r - rp_.radius_m);
  const double stand_moving = worst_gap(pose, 0.0, 0.0, near, pp_, rp_, true);
  const double stand_gap = worst_gap(pose, 0.0, 0.0, near, pp_, rp_);
  return stand_moving < pp_.collision_margin_m && stand_moving < now_moving - 0.02 && escape_gap > stand_gap + 0.03;
}

// Reverse escape ([robot] evade_reverse_mps > 0, session 30): the arcs backwards at the reverse speed
// and half of it (as far as the acceleration limit allows within one control period), over the
// window's yaw rates; the one with the largest worst-case gap replaces `escape` when it beats it.
// The cameras look forward, so the arcs behind are checked against what the map and the tracks hold
// (the trail the robot came along, static cells seen before, tracked movers).
void Planner::reverse_escape(const Pose2D& pose, const BodyTwist& current, const DynamicWindow& dw,
                             const std::vector<CircleObstacle>& near, double& escape_gap, BodyTwist& escape) const {
  if (!(rp_.evade_reverse_mps > 0)) return;
  const double vlow = std::max(-rp_.evade_reverse_mps, current.v - rp_.max_accel_mps2 * pp_.control_period_s);
  if (!(vlow < -1e-3)) return;
  for (const double v : {vlow, 0.5 * vlow})
    for (int iw = 0; iw < dw.nw; ++iw) {
      const double w = dw.at(0, iw).omega;
      const double g = worst_gap(pose, v, w, near, pp_, rp_);
      if (g > escape_gap) {
        escape_gap = g;
        escape = {v, w};
      }
    }
}

PlanOutput Planner::plan(const Pose2D& pose, const BodyTwist& current, Vec2 goal,
                         const std::vector<CircleObstacle>& obstacles, const PlanContext& ctx) const {
  PlanOutput out;
  const Vec2 pos = pose.pos();
  const double dist_goal = norm(goal - pos);
  // Arrival is declared arrive_margin_m inside the tolerance: the pose is the robot's own estimate,
  // and a robot that stops on the boundary by its odometry can stand a few millimetres outside it in
  // truth, for good (suite seed 11, scenario 59: 0.149 m by odometry, 0.154 m true, 20 s standing).
  if (dist_goal <= std::max(0.0, rp_.goal_tolerance_m - rp_.arrive_margin_m)) {
    out.status = PlanStatus::kReached;
    out.carrot = goal;
    return out;
  }

  // 1. global guidance.
  GlobalPlan gp = global_plan(obstacles, pos, goal, pp_, rp_);
  if (gp.path.empty()) {
    out.status = PlanStatus::kBlocked;  // safe stop: the mixer ramps v, omega down to 0
    // No route, but a mover coming at the standing robot is still dodged (evade_when_blocked):
    // seed-12 suite scenario 37, a tracked 0.18 m/s mover walked into the robot from behind while
    // it stood "blocked" (no route through the mover's predicted disc) turning on the spot.
    if (pp_.evade_when_blocked) {
      const std::vector<CircleObstacle> near = reachable_obstacles(obstacles, pos);
      const DynamicWindow dw = dynamic_window(current, dist_goal);
      double escape_gap = -kInf;
      BodyTwist escape{};
      for (int iv = 0; iv < dw.nv; ++iv)
        for (int iw = 0; iw < dw.nw; ++iw) {
          const BodyTwist tw = dw.at(iv, iw);
          const double g = worst_gap(pose, tw.v, tw.omega, near, pp_, rp_);
          if (g > escape_gap) {
            escape_gap = g;
            escape = tw;
          }
        }
      reverse_escape(pose, current, dw, near, escape_gap, escape);
      if (evade_instead_of_standing(pose, near, escape_gap)) {
        out.status = PlanStatus::kMoving;
        out.evading = true;
        out.cmd = escape;
      }
    }
    return out;
  }
  // Route commitment: A* on a grid rebuilt every frame may switch between two routes of about the
  // same length (round either side of an obstacle, through a gap or round the wall's end) as depth
  // noise and ghost circles come and go; the robot then turns back and forth and times out (suite
  // seed 11, scenario 5: 40 s within 1.3 m of the start). Keep the last route while it is free and
  // not much longer than the new one. Not while only static obstacles leave a path (waiting).
  if (pp_.route_keep_ratio > 0 && ctx.last_route != nullptr && !gp.only_static) {
    std::vector<Vec2> kept;
    if (last_route_from(*ctx.last_route, pos, goal, gp, pp_, kept) &&
        path_length(kept) <= pp_.route_keep_ratio * path_length(gp.path) + pp_.route_keep_extra_m) {
      gp.path = std::move(kept);
      out.route_kept = true;
    }
  }
  out.path = gp.path;
  out.reduced_margin = gp.reduced_margin;
  out.carrot = pick_carrot(gp, pos, pp_.lookahead_m);

  const std::vector<CircleObstacle> near = reachable_obstacles(obstacles, pos);
  const std::vector<double> hard2 = contact_d2(pose, near, pp_, rp_);

  // 2. dynamic window around the current twist.
  const DynamicWindow dw = dynamic_window(current, dist_goal);
  double best_cost = kInf;
  BodyTwist best{};
  double best_gap = 0;
  // The arc that keeps the largest worst-case gap: the way out when every arc is unsafe.
  double escape_gap = -std::numeric_limits<double>::infinity();
  BodyTwist escape{};
  const double carrot_dist0 = norm(out.carrot - pos);
  // The speed the w_speed term rewards: full speed, or with [planner] speed_follows_heading full speed times the
  // cosine of the heading error to the carrot (0 from 90 deg on: slow down and turn on the spot when facing away).
  const double vmax_ref = std::max(1e-6, rp_.max_speed_mps);
  const bool follows_heading = pp_.speed_follows_heading || ctx.speed_follows_heading;
  const double v_ref = follows_heading && carrot_dist0 > 1e-3
                           ? vmax_ref * std::max(0.0, std::cos(bearing_of(pose, out.carrot)))
                           : vmax_ref;
  const bool check_seen = pp_.unseen_check_s > 0 && static_cast<bool>(ctx.recently_seen);
  const double lead = rp_.radius_m + pp_.safety_margin_m;
  const bool use_memory = pp_.w_memory > 0 && ctx.memory != nullptr && !ctx.memory->empty();
  for (int iv = 0; iv < dw.nv; ++iv) {
    for (int iw = 0; iw < dw.nw; ++iw) {
      const auto [v, w] = dw.at(iv, iw);
      // [planner] max_lateral_accel_mps2: no sharp turns at speed (turning on the spot stays free).
      if (pp_.max_lateral_accel_mps2 > 0 && v * std::abs(w) > pp_.max_lateral_accel_mps2) continue;
      if (check_seen && v > 0.02 && drives_into_unseen(pose, v, w, lead, pp_, ctx.recently_seen)) continue;
      const ArcEval a = eval_arc(pose, v, w, false, near, hard2, out.carrot, pp_, rp_);
      double collide_pen = 0;
      if (a.t_collide != kInf) {
        // admissible only if braking from (v, w) after one control period stays clear
        const ArcEval b = eval_arc(pose, v, w, true, near, hard2, out.carrot, pp_, rp_);
        if (b.t_collide != kInf) {
          const double g = worst_gap(pose, v, w, near, pp_, rp_);
          if (g > escape_gap) {
            escape_gap = g;
            escape = {v, w};
          }
          continue;
        }
        collide_pen = 1.0 - a.t_collide / pp_.horizon_s;  // prefer arcs that stay clear longer
      }
      // Progress: how much closer the arc (before any contact) gets to the carrot; heading: the
      // alignment with the carrot at that closest approach, or after one control period when the arc
      // makes no progress (turning on the spot). Judged along the arc, not at its end, so fast arcs
      // that pass the carrot are not punished for overshooting it.
      const double progress = (a.best_d - carrot_dist0) / std::max(1e-3, rp_.max_speed_mps * pp_.horizon_s);
      const double heading = std::acos(a.best_d < carrot_dist0 - 0.05 ? a.heading_at_best : a.heading_after_T);
      const double soft = pp_.safety_margin_m + rp_.radius_m;
      const double clear_pen = std::clamp((soft - a.min_gap) / soft, 0.0, 1.0);
      const double cost = pp_.w_heading * heading / M_PI + pp_.w_progress * progress +
                          pp_.w_clearance * clear_pen + pp_.w_speed * (follows_heading ? std::abs(v_ref - v) / vmax_ref : 1.0 - v / vmax_ref) +
                          2.0 * collide_pen +
                          (use_memory ? pp_.w_memory * memory_depth(pose, v, w, *ctx.memory, pp_, rp_) : 0.0);
      if (cost < best_cost) {
        best_cost = cost;
        best = {v, w};
        best_gap = a.min_gap;
      }
    }
  }
  if (best_cost == kInf) {
    // Nothing is safe to drive right now. Braking is right unless something is coming at the
    // standing robot (a moving obstacle: a static one never reaches a robot that stands; the
    // obstacles are grown by their uncertainty, so the robot may already be "inside" one): then
    // take the arc that keeps the largest worst-case gap over the horizon, if it beats standing
    // (every frame re-plans, and the dynamic window widens as the robot speeds up). With
    // evade_reverse_mps the arcs backwards are candidates too.
    reverse_escape(pose, current, dw, near, escape_gap, escape);
    if (evade_instead_of_standing(pose, near, escape_gap)) {
      out.status = PlanStatus::kMoving;
      out.evading = true;
      out.cmd = escape;
      return out;
    }
    out.status = PlanStatus::kWaiting;  // brake
    out.cmd = {0.0, 0.0};
    return out;
  }
  out.cmd = best;
  out.clearance_m = best_gap;
  out.status = gp.only_static ? PlanStatus::kWaiting : PlanStatus::kMoving;
  return out;
}

Pose2D predict_to_command_time(const Pose2D& pose, const BodyTwist& current, double latency_s,
                               std::vector<CircleObstacle>& obstacles) {
  if (!(latency_s > 0.0)) return pose;
  for (CircleObstacle& o : obstacles) {
    o.c = o.c + latency_s * o.vel;
    if (o.grow > 0.0) {  // grown by the latency; what is left of the cap stays
      const double g = o.r_at(latency_s) - o.r;
      o.r += g;
      o.grow_max -= g;
    }
  }
  return integrate_pose(pose, current, latency_s);
}

void fan_circles(Vec2 c, double r, Vec2 vel, int count, std::vector<CircleObstacle>& out) {
  const double sp = norm(vel), a0 = std::atan2(vel.y, vel.x);
  for (int k = 0; k < count; ++k) {
    const double a = a0 + 2.0 * M_PI * k / count;
    out.push_back({c, r, {sp * std::cos(a), sp * std::sin(a)}, true});
  }
}

bool reachable_set(Vec2 last_p, double r, double speed, double age_s, double cap_m, Vec2 robot_pos,
                   double robot_radius, double near_m, CircleObstacle& out, bool keep_holding) {
  const double grown = r + std::min(std::max(0.0, speed * age_s), std::max(0.0, cap_m));
  const double dl = norm(last_p - robot_pos);
  if (dl > near_m + grown || (!keep_holding && dl <= grown + robot_radius)) return false;
  out = {last_p, grown, {}};
  return true;
}

bool look_before_turn(const Pose2D& pose, const BodyTwist& cmd, Vec2 last_p, double half_fov_rad, double near_m,
                      double yaw_rate, BodyTwist& look) {
  if (cmd.v <= 0.02 || std::fabs(cmd.omega) <= 0.1) return false;
  if (norm(last_p - pose.pos()) > near_m) return false;
  const double bearing = bearing_of(pose, last_p);
  if (std::fabs(bearing) < half_fov_rad || bearing * cmd.omega <= 0.0) return false;
  look = {0.0, bearing > 0.0 ? yaw_rate : -yaw_rate};
  return true;
}

double reach_speed(double filtered_speed, Vec2 first_p, Vec2 last_p, double life_s, bool use_travel_rate,
                   double noise_m) {
  if (!use_travel_rate || !(life_s > 0.0)) return filtered_speed;
  return std::min(filtered_speed, std::max(0.0, norm(last_p - first_p) - std::max(0.0, noise_m)) / life_s);
}

double shortest_path_length(const std::vector<CircleObstacle>& obstacles, Vec2 start, Vec2 goal, double radius,
                            double resolution_m) {
  // Free space: centre farther than r_i + radius from every circle centre.
  auto free_pt = [&](Vec2 p) {
    for (const CircleObstacle& o : obstacles)
      if (norm(p - o.c) < o.r + radius) return false;
    return true;
  };
  if (!free_pt(start) || !free_pt(goal)) return kInf;
  auto los = [&](Vec2 a, Vec2 b) {  // exact segment-to-circle distance
    for (const CircleObstacle& o : obstacles)
      if (point_segment_distance(o.c, a, b) < o.r + radius) return false;
    return true;
  };
  double margin = 1.0;
  for (const CircleObstacle& o : obstacles) margin = std::max(margin, 2.0 * (o.r + radius));
  Vec2 lo{std::min(start.x, goal.x), std::min(start.y, goal.y)}, hi{std::max(start.x, goal.x), std::max(start.y, goal.y)};
  for (const CircleObstacle& o : obstacles) {
    lo = {std::min(lo.x, o.c.x - o.r), std::min(lo.y, o.c.y - o.r)};
    hi = {std::max(hi.x, o.c.x + o.r), std::max(hi.y, o.c.y + o.r)};
  }
  lo = lo - Vec2{margin, margin};
  hi = hi + Vec2{margin, margin};
  detail::Grid g;
  g.init(lo, hi, resolution_m, 2000);
  for (int iy = 0; iy < g.ny; ++iy)
    for (int ix = 0; ix < g.nx; ++ix) g.blocked[g.idx(ix, iy)] = free_pt(g.center(ix, iy)) ? 0 : 1;
  return detail::theta_star_length(g, start, goal, los);
}

WheelCommand DiffDriveMixer::mix(const BodyTwist& want, double dt) {
  BodyTwist t = want;
  if (!std::isfinite(t.v) || !std::isfinite(t.omega)) t = {0.0, 0.0};
  t.v = std::clamp(t.v, -rp_.evade_reverse_mps, rp_.max_speed_mps);
  t.omega = std::clamp(t.omega, -rp_.max_yaw_rate_radps, rp_.max_yaw_rate_radps);
  const double dv = rp_.max_accel_mps2 * dt, dw = rp_.max_yaw_accel_radps2 * dt;
  t.v = std::clamp(t.v, last_.v - dv, last_.v + dv);
  t.omega = std::clamp(t.omega, last_.omega - dw, last_.omega + dw);
  double vl, vr;
  wheels_from_twist(t, rp_.wheel_base_m, vl, vr);
  const double m = std::max(std::abs(vl), std::abs(vr));
  if (m > rp_.max_wheel_speed_mps) {  // scale both: same curvature, lower speed
    const double s = rp_.max_wheel_speed_mps / m;
    vl *= s;
    vr *= s;
    t = twist_from_wheels(vl, vr, rp_.wheel_base_m);
  }
  last_ = t;
  return {vl / rp_.max_wheel_speed_mps, vr / rp_.max_wheel_speed_mps, t};
}

}  // namespace fs::robot
