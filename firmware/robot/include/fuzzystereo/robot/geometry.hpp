// Small 2-D ground-plane types shared by odometry, tracking and planning. World frame: x forward
// (east), y left, z up; yaw counter-clockwise from +x [rad].
#pragma once

#include <algorithm>
#include <cmath>

namespace fs::robot {

struct Vec2 {
  double x = 0, y = 0;
};
inline Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
inline Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
inline Vec2 operator*(double s, Vec2 a) { return {s * a.x, s * a.y}; }
inline double dot(Vec2 a, Vec2 b) { return a.x * b.x + a.y * b.y; }
// sqrt of the sum of squares (std::hypot's overflow care is not needed for metres and costs 5x).
inline double norm(Vec2 a) { return std::sqrt(a.x * a.x + a.y * a.y); }
inline double norm2(Vec2 a) { return a.x * a.x + a.y * a.y; }

struct Pose2D {
  double x = 0, y = 0, yaw = 0;  // [m], [m], [rad]
  Vec2 pos() const { return {x, y}; }
};

// Wrap an angle to (-pi, pi].
inline double wrap_angle(double a) {
  a = std::remainder(a, 2.0 * M_PI);
  return a <= -M_PI ? a + 2.0 * M_PI : a;
}

// Bearing of point q from the robot at p, relative to its heading, in (-pi, pi] [rad].
inline double bearing_of(const Pose2D& p, Vec2 q) { return wrap_angle(std::atan2(q.y - p.y, q.x - p.x) - p.yaw); }

// Obstacle for planning: a circle at time 0 moving with constant velocity (predicted position at
// time t is c + t * vel). Oriented boxes are given to the planner as their bounding circle
// (conservative; see docs/robot.md).
struct CircleObstacle {
  Vec2 c;           // centre [m]
  double r = 0;     // radius [m]
  Vec2 vel;         // [m/s]; zero for static obstacles
  bool transient = false;  // a place a tracked obstacle may be (near-track circle, reachable set),
                           // not a known surface: never decides "blocked" (planner.hpp)
  bool unconfirmed = false;  // a map cell hit only from farther than the confirmation range (depth
                             // error grows with Z^2): left out of the global search where it covers
                             // the goal, so it never decides "blocked" there (planner.cpp)
  double grow = 0;      // [m/s] radius growth: where a tracked obstacle of unknown heading can be
  double grow_max = 0;  // [m] at most this much growth (r_at(t) = r + min(grow t, grow_max))
  Vec2 at(double t) const { return c + t * vel; }
  double r_at(double t) const { return grow > 0.0 ? r + std::min(grow * t, grow_max) : r; }
  bool moves() const { return vel.x != 0.0 || vel.y != 0.0 || grow > 0.0; }
};

// Oriented box: centre, half extents along its own axes, heading [rad].
struct BoxObstacle {
  Vec2 c;
  double half_len = 0, half_wid = 0, yaw = 0;
  Vec2 vel;
  CircleObstacle bounding_circle() const { return {c, std::hypot(half_len, half_wid), vel}; }
};

}  // namespace fs::robot
