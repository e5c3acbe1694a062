// Ray-cast renderer and ground truth of the synthetic stereo world (docs/simulator.md).
//
// Per pixel and camera: n x n supersampled rays (colour), plus for the left camera one ray through
// the pixel centre that gives the exact ground truth (disparity f*B/Z, masks, obstacle id). Rays
// are not normalised: dir = Xc*(u-cx)/f + Yc*(v-cy)/f + Zc, so the ray parameter at a hit IS the
// depth Z along the optical axis. Surfaces: the ground plane z = 0 up to render.far_m horizontal
// range, oriented boxes and vertical cylinders; Lambert shading with sun + ambient, a haze that
// fades the ground into the horizon colour at far_m (so the cut-off is invisible), sky beyond.
#include "fuzzystereo/sim/world.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "sim_internal.hpp"

#if defined(FS_HAVE_OPENMP)
#include <omp.h>
#endif

namespace fs::sim {
namespace {

using detail::Color;
using detail::Vec3;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
constexpr double kEps = 1e-9;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kMaxSub = 4;  // largest render.supersample (scene.cpp)

struct CameraFrame {
  Vec3 origin, xc, yc, zc;  // optical centre and axes (X right, Y down, Z forward) in world
};

// Camera frames of the left (0) and right (1) camera for a robot pose.
CameraFrame camera_frame(const CameraSpec& c, const Pose2& pose, int cam) {
  const double p = c.pitch_deg * kDeg;
  const Vec3 f{std::cos(pose.yaw_rad), std::sin(pose.yaw_rad), 0.0};
  const Vec3 up{0.0, 0.0, 1.0};
  CameraFrame cf;
  cf.xc = {std::sin(pose.yaw_rad), -std::cos(pose.yaw_rad), 0.0};
  cf.zc = std::cos(p) * f - std::sin(p) * up;
  cf.yc = (-std::sin(p)) * f - std::cos(p) * up;
  cf.origin = Vec3{pose.x_m, pose.y_m, c.height_m} + (cam == 1 ? c.baseline_m : 0.0) * cf.xc;
  return cf;
}

// An obstacle placed at render time t, with its screen bounds per camera.
struct Placed {
  int index = 0;
  const ObstacleSpec* spec = nullptr;
  Vec3 base;          // centre of the footprint at height z_m
  double c = 1, s = 0;  // cos/sin of yaw
  double hx = 0, hy = 0, h = 0, r = 0;
  bool cyl = false;
  detail::Color tint;
  std::uint64_t seed = 0;
  double u0[2], u1[2], v0[2], v1[2];  // sample-space bounds per camera (empty when u0 > u1)
};

struct Hit {
  double t = kInf;  // depth Z [m]
  int what = -2;    // -2 sky, -1 ground, >= 0 index into placed
  Vec3 n;           // world normal
  double s = 0, tt = 0;  // surface coordinates [m] (obstacles)
  int face = 0;
};

Vec3 to_local(const Placed& o, Vec3 v) { return {o.c * v.x + o.s * v.y, -o.s * v.x + o.c * v.y, v.z}; }
Vec3 to_world(const Placed& o, Vec3 v) { return {o.c * v.x - o.s * v.y, o.s * v.x + o.c * v.y, v.z}; }

// Ray / oriented box (slab test in the box frame, origin at the box centre).
void intersect_box(const Placed& o, int idx, Vec3 org, Vec3 dir, Hit& best) {
  const Vec3 lo = to_local(o, org - o.base) - Vec3{0, 0, o.h * 0.5};
  const Vec3 ld = to_local(o, dir);
  const double half[3] = {o.hx, o.hy, o.h * 0.5};
  const double po[3] = {lo.x, lo.y, lo.z}, pd[3] = {ld.x, ld.y, ld.z};
  double tnear = -kInf, tfar = kInf;
  int axis = 0;
  for (int i = 0; i < 3; ++i) {
    if (std::fabs(pd[i]) < kEps) {
      if (std::fabs(po[i]) > half[i]) return;
      continue;
    }
    double t1 = (-half[i] - po[i]) / pd[i], t2 = (half[i] - po[i]) / pd[i];
    if (t1 > t2) std::swap(t1, t2);
    if (t1 > tnear) { tnear = t1; axis = i; }
    tfar = std::min(tfar, t2);
  }
  if (tnear > tfar || tnear <= 1e-6 || tnear >= best.t) return;  // camera inside the box: not drawn
  const double sign = pd[axis] > 0 ? -1.0 : 1.0;
  const Vec3 p = lo + tnear * ld;
  Vec3 ln{0, 0, 0};
  best.t = tnear;
  best.what = idx;
  best.face = axis * 2 + (sign > 0 ? 1 : 0);
  const double z_from_base = p.z + o.h * 0.5;
  if (axis == 0) { ln.x = sign; best.s = p.y; best.tt = z_from_base; }
  else if (axis == 1) { ln.y = sign; best.s = p.x; best.tt = z_from_base; }
  else { ln.z = sign; best.s = p.x; best.tt = p.y; }
  best.n = to_world(o, ln);
}

// Ray / vertical capped cylinder (side, top and bottom discs), in the obstacle frame.
void intersect_cylinder(const Placed& o, int idx, Vec3 org, Vec3 dir, Hit& best) {
  const Vec3 lo = to_local(o, org - o.base);
  const Vec3 ld = to_local(o, dir);
  const double a = ld.x * ld.x + ld.y * ld.y;
  const double b = 2.0 * (lo.x * ld.x + lo.y * ld.y);
  const double cc = lo.x * lo.x + lo.y * lo.y - o.r * o.r;
  if (a > kEps) {
    const double disc = b * b - 4.0 * a * cc;
    if (disc >= 0.0) {
      const double t0 = (-b - std::sqrt(disc)) / (2.0 * a);
      if (t0 > 1e-6 && t0 < best.t) {
        const Vec3 p = lo + t0 * ld;
        if (p.z >= 0.0 && p.z <= o.h) {
          best.t = t0;
          best.what = idx;
          best.face = 0;
          best.n = to_world(o, Vec3{p.x / o.r, p.y / o.r, 0.0});
          best.s = std::atan2(p.y, p.x) * o.r;
          best.tt = p.z;
        }
      }
    }
  }
  if (std::fabs(ld.z) > kEps) {
    for (int cap = 0; cap < 2; ++cap) {
      const double zc = cap == 0 ? o.h : 0.0;
      const double t = (zc - lo.z) / ld.z;
      if (t <= 1e-6 || t >= best.t) continue;
      const Vec3 p = lo + t * ld;
      if (p.x * p.x + p.y * p.y > o.r * o.r) continue;
      best.t = t;
      best.what = idx;
      best.face = 1 + cap;
      best.n = Vec3{0, 0, cap == 0 ? 1.0 : -1.0};
      best.s = p.x;
      best.tt = p.y;
    }
  }
}

struct Tracer {
  const Scene& sc;
  const std::vector<Placed>& placed;
  double far_m;

  Hit trace(const CameraFrame& cf, int cam, double u, double v) const {
    const CameraSpec& c = sc.camera;
    const double a = (u - c.cx) / c.focal_px, b = (v - c.cy) / c.focal_px;
    const Vec3 dir = a * cf.xc + b * cf.yc + cf.zc;
    Hit h;
    if (dir.z < -kEps) {
      const double t = -cf.origin.z / dir.z;
      const double range = t * std::sqrt(dir.x * dir.x + dir.y * dir.y);
      if (range <= far_m) {
        h.t = t;
        h.what = -1;
        h.n = {0, 0, 1};
      }
    }
    for (std::size_t i = 0; i < placed.size(); ++i) {
      const Placed& o = placed[i];
      if (u < o.u0[cam] || u > o.u1[cam] || v < o.v0[cam] || v > o.v1[cam]) continue;
      if (o.cyl) intersect_cylinder(o, static_cast<int>(i), cf.origin, dir, h);
      else intersect_box(o, static_cast<int>(i), cf.origin, dir, h);
    }
    return h;
  }

  Color shade(const CameraFrame& cf, double u, double v, const Hit& h, Vec3 sun, Color sun_c, Color amb_c,
              Color horizon) const {
    const CameraSpec& c = sc.camera;
    const Vec3 dir = ((u - c.cx) / c.focal_px) * cf.xc + ((v - c.cy) / c.focal_px) * cf.yc + cf.zc;
    return shade_dir(cf, dir, h, sun, sun_c, amb_c, horizon);
  }

  // Colour of a hit along the (unnormalised) ray `dir`; h.n, h.s, h.tt must be set.
  Color shade_dir(const CameraFrame& cf, Vec3 dir, const Hit& h, Vec3 sun, Color sun_c, Color amb_c,
                  Color horizon) const {
    const CameraSpec& c = sc.camera;
    const double len = detail::norm(dir);
    const Vec3 d = (1.0 / len) * dir;
    if (h.what == -2) return detail::sky_color(sc.sky.kind, d, sun, sc.seed);
    const double dist = h.t * len;
    // Pixel footprint [m]: distance / f, stretched on surfaces seen at a grazing angle. The true
    // footprint is stretched along the view direction only; the geometric mean (1/sqrt(cos)) keeps
    // the horizontal detail stereo matching needs while still fading what would alias.
    const double cosi = std::max(0.02, std::fabs(detail::dot(d, h.n)));
    const double fp = dist / c.focal_px / std::sqrt(cosi);
    const Vec3 p = cf.origin + h.t * dir;
    Color albedo;
    if (h.what == -1) {
      albedo = detail::ground_albedo(sc.ground.texture, p.x, p.y, sc.ground.scale_m, fp, sc.seed * 31u + 7u);
    } else {
      const Placed& o = placed[static_cast<std::size_t>(h.what)];
      albedo = detail::obstacle_albedo(o.spec->texture, o.tint, h.s, h.tt, fp,
                                       o.seed + static_cast<std::uint64_t>(h.face) * 101u);
    }
    const double amb = sc.light.ambient;
    const double lambert = std::max(0.0, detail::dot(h.n, sun));
    Color col = albedo * ((amb * amb_c) + ((1.0 - amb) * lambert) * sun_c);
    // Haze: the ground (and anything far) fades into the horizon colour at far_m.
    const double horiz = dist * std::sqrt(std::max(0.0, 1.0 - d.z * d.z));
    const double haze = detail::smoothstep(0.3 * far_m, far_m, horiz);
    return detail::mix(col, horizon, haze);
  }
};

// ---- Fast path of render() ------------------------------------------------------------------------
// The reference above (Tracer, used by World::render_reference) tests every sample ray against every
// obstacle whose screen box contains it and computes normal and surface coordinates (an atan2 for a
// cylinder) for every closer hit on the way. The fast path gives bit-identical results (tested
// against the reference) by doing the same floating-point operations in the same order, only fewer
// of them:
//  - per camera, the image is cut into kTile x kTile pixel tiles and each tile lists the obstacles
//    whose screen box overlaps it, nearest first; a ray stops at the first obstacle that cannot
//    beat its current hit (zskip) and resolves exact depth ties by scene order (closer()), as the
//    reference does; a sample still applies the reference's own box test to each listed obstacle;
//  - per image row: the ray constant (v - cy) / f, and whether every ray of the row hits the ground
//    within far_m or the sky (row_info); per column (u - cx) / f. Pixels whose rows agree and that
//    no obstacle box reaches are not supersampled (all their rays see the same surface);
//  - obstacles straddling the camera plane (the reference draws them over the whole image) get the
//    screen box of the part of their bounding box in front of the camera (clipped_bounds), which
//    still contains every sample that can hit them;
//  - the ray parameter, obstacle and face of the first hit are found first; the normal and surface
//    coordinates only for the hit that is shaded (the reference's formulas, same operands);
//  - the camera origin in each obstacle's frame (and the cylinder's constant quadratic term) is
//    computed once per frame with the reference's expressions.

// Depth of the clipping plane: every hit has depth t > 1e-6 (the intersection tests), so the part
// of a bounding box nearer than this can hold no hit.
constexpr double kClipZ = 1e-7;

// Screen bounds (+2 px margin, sample space) of the part of an obstacle's bounding box in front of
// the plane Z = kClipZ of camera cf: the convex hull of its corners in front and of the crossings of
// its 12 edges with that plane. Empty (u0 > u1) when nothing is in front.
void clipped_bounds(const Placed& p, const CameraFrame& cf, const CameraSpec& cam, double& u0, double& u1, double& v0,
                    double& v1) {
  Vec3 q[8];  // corners in the camera frame
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3 l{(corner & 1) ? p.hx : -p.hx, (corner & 2) ? p.hy : -p.hy, (corner & 4) ? p.h : 0.0};
    const Vec3 rel = p.base + to_world(p, l) - cf.origin;
    q[corner] = {detail::dot(rel, cf.xc), detail::dot(rel, cf.yc), detail::dot(rel, cf.zc)};
  }
  u0 = v0 = kInf;
  u1 = v1 = -kInf;
  auto add = [&](double X, double Y, double Z) {
    const double u = cam.cx + cam.focal_px * X / Z, v = cam.cy + cam.focal_px * Y / Z;
    u0 = std::min(u0, u); u1 = std::max(u1, u); v0 = std::min(v0, v); v1 = std::max(v1, v);
  };
  for (int a = 0; a < 8; ++a) {
    if (q[a].z >= kClipZ) add(q[a].x, q[a].y, q[a].z);
    for (int bit = 1; bit < 8; bit <<= 1) {  // the 3 edges from corner a to a corner with that bit set
      if (a & bit) continue;
      const Vec3 qa = q[a], qb = q[a | bit];
      if ((qa.z >= kClipZ) == (qb.z >= kClipZ)) continue;
      const double f = (kClipZ - qa.z) / (qb.z - qa.z);
      add(qa.x + f * (qb.x - qa.x), qa.y + f * (qb.y - qa.y), kClipZ);
    }
  }
  if (u0 > u1) return;
  u0 -= 2; v0 -= 2; u1 += 2; v1 += 2;
}

constexpr int kTile = 8;  // pixels

// Per camera: for each kTile x kTile tile, the indices of the obstacles whose screen bounds overlap
// the tile's sample area (pixel centre +- 0.5 px), as ranges into one array.
struct TileLists {
  int tw = 0;
  std::vector<int> start;  // tile i lists items[start[i] .. start[i + 1])
  std::vector<int> items;
};

// Items of a tile sorted by `zskip` (the obstacle's hit-depth lower bound), nearest first, so a
// ray can stop at the first obstacle that cannot beat its current hit.
TileLists build_tiles(const std::vector<Placed>& placed, const std::vector<std::array<double, 2>>& zskip, int cam, int W,
                      int H) {
  TileLists tl;
  tl.tw = (W + kTile - 1) / kTile;
  const int th = (H + kTile - 1) / kTile;
  tl.start.reserve(static_cast<std::size_t>(tl.tw * th + 1));
  for (int ty = 0; ty < th; ++ty)
    for (int tx = 0; tx < tl.tw; ++tx) {
      tl.start.push_back(static_cast<int>(tl.items.size()));
      const double lu = tx * kTile - 0.5, hu = std::min(W, (tx + 1) * kTile) - 0.5;
      const double lv = ty * kTile - 0.5, hv = std::min(H, (ty + 1) * kTile) - 0.5;
      for (std::size_t i = 0; i < placed.size(); ++i) {
        const Placed& o = placed[i];
        if (o.u0[cam] <= hu && o.u1[cam] >= lu && o.v0[cam] <= hv && o.v1[cam] >= lv) tl.items.push_back(static_cast<int>(i));
      }
      std::stable_sort(tl.items.begin() + tl.start.back(), tl.items.end(),
                       [&](int a, int b) { return zskip[static_cast<std::size_t>(a)][cam] < zskip[static_cast<std::size_t>(b)][cam]; });
    }
  tl.start.push_back(static_cast<int>(tl.items.size()));
  return tl;
}

// True when a hit at depth t on obstacle idx replaces `best`. The fast path visits obstacles nearest
// first, not in scene order; taking the lower index on an exact tie gives the reference's winner
// (it visits in scene order and keeps the first of equal depths; the ground, visited first there,
// has index -1 and is never replaced on a tie).
inline bool closer(double t, int idx, const Hit& best) { return t < best.t || (t == best.t && idx < best.what); }

// intersect_box() without the normal and surface coordinates; lo = ray origin in the box frame.
inline void first_hit_box(const Placed& o, int idx, Vec3 lo, Vec3 dir, Hit& best) {
  const Vec3 ld = to_local(o, dir);
  const double half[3] = {o.hx, o.hy, o.h * 0.5};
  const double po[3] = {lo.x, lo.y, lo.z}, pd[3] = {ld.x, ld.y, ld.z};
  double tnear = -kInf, tfar = kInf;
  int axis = 0;
  for (int i = 0; i < 3; ++i) {
    if (std::fabs(pd[i]) < kEps) {
      if (std::fabs(po[i]) > half[i]) return;
      continue;
    }
    double t1 = (-half[i] - po[i]) / pd[i], t2 = (half[i] - po[i]) / pd[i];
    if (t1 > t2) std::swap(t1, t2);
    if (t1 > tnear) { tnear = t1; axis = i; }
    tfar = std::min(tfar, t2);
  }
  if (tnear > tfar || tnear <= 1e-6 || !closer(tnear, idx, best)) return;
  best.t = tnear;
  best.what = idx;
  best.face = axis * 2 + (pd[axis] > 0 ? 0 : 1);
}

// The rest of intersect_box() for the winning hit.
inline void surface_box(const Placed& o, Vec3 lo, Vec3 dir, Hit& h) {
  const Vec3 ld = to_local(o, dir);
  const int axis = h.face / 2;
  const double sign = (h.face & 1) ? 1.0 : -1.0;
  const Vec3 p = lo + h.t * ld;
  Vec3 ln{0, 0, 0};
  const double z_from_base = p.z + o.h * 0.5;
  if (axis == 0) { ln.x = sign; h.s = p.y; h.tt = z_from_base; }
  else if (axis == 1) { ln.y = sign; h.s = p.x; h.tt = z_from_base; }
  else { ln.z = sign; h.s = p.x; h.tt = p.y; }
  h.n = to_world(o, ln);
}

// intersect_cylinder() without the normal and surface coordinates; lo = ray origin in the obstacle
// frame, cc = lo.x^2 + lo.y^2 - r^2.
inline void first_hit_cylinder(const Placed& o, int idx, Vec3 lo, double cc, Vec3 dir, Hit& best) {
  const Vec3 ld = to_local(o, dir);
  const double a = ld.x * ld.x + ld.y * ld.y;
  const double b = 2.0 * (lo.x * ld.x + lo.y * ld.y);
  if (a > kEps) {
    const double disc = b * b - 4.0 * a * cc;
    if (disc >= 0.0) {
      const double t0 = (-b - std::sqrt(disc)) / (2.0 * a);
      if (t0 > 1e-6 && closer(t0, idx, best)) {
        const double pz = lo.z + t0 * ld.z;
        if (pz >= 0.0 && pz <= o.h) {
          best.t = t0;
          best.what = idx;
          best.face = 0;
        }
      }
    }
  }
  if (std::fabs(ld.z) > kEps) {
    for (int cap = 0; cap < 2; ++cap) {
      const double zc = cap == 0 ? o.h : 0.0;
      // t <= 0 unless the ray heads towards the cap plane: skip the division then
      if (!((zc - lo.z > 0.0 && ld.z > 0.0) || (zc - lo.z < 0.0 && ld.z < 0.0))) continue;
      const double t = (zc - lo.z) / ld.z;
      if (t <= 1e-6 || !closer(t, idx, best)) continue;
      const double px = lo.x + t * ld.x, py = lo.y + t * ld.y;
      if (px * px + py * py > o.r * o.r) continue;
      best.t = t;
      best.what = idx;
      best.face = 1 + cap;
    }
  }
}

// The rest of intersect_cylinder() for the winning hit.
inline void surface_cylinder(const Placed& o, Vec3 lo, Vec3 dir, Hit& h) {
  const Vec3 ld = to_local(o, dir);
  const Vec3 p = lo + h.t * ld;
  if (h.face == 0) {
    h.n = to_world(o, Vec3{p.x / o.r, p.y / o.r, 0.0});
    h.s = std::atan2(p.y, p.x) * o.r;
    h.tt = p.z;
  } else {
    h.n = Vec3{0, 0, h.face == 1 ? 1.0 : -1.0};
    h.s = p.x;
    h.tt = p.y;
  }
}

struct RowInfo {
  double v = 0, b = 0;  // sample row and (v - cy) / f
  int cls = 0;          // FastTracer::row_info()
  double tg = kInf;     // ground depth when cls == -1
};

struct FastTracer {
  const Scene& sc;
  const std::vector<Placed>& placed;
  double far_m;
  const std::array<Vec3, 2>* lo;    // per obstacle and camera: the camera origin in the obstacle frame
  const std::array<double, 2>* cc;  // per obstacle and camera: lo.x^2 + lo.y^2 - r^2 (cylinders)
  // Per obstacle and camera: a lower bound of the depth of any hit on it (its bounding box's
  // nearest corner depth, less 1 um and 1e-9 relative for rounding): a ray that already has a
  // hit nearer than this cannot get a new nearest hit from it.
  const std::array<double, 2>* zskip;

  // Tracer::trace() of the ray through (u, r.v) over the candidate obstacles `cand` (build_tiles
  // order), without normal and surface coordinates (surface() adds them). a = (u - cx) / f and the
  // row's b, class and ground depth come precomputed (same expressions); `dir` receives the ray.
  Hit trace(const CameraFrame& cf, int cam, double u, double a, const RowInfo& r, const int* cand, int ncand,
            Vec3& dir) const {
    dir = a * cf.xc + r.b * cf.yc + cf.zc;
    Hit h;
    if (r.cls == -1) {  // ground within far_m along the whole row
      h.t = r.tg;
      h.what = -1;
      h.n = {0, 0, 1};
    } else if (r.cls == 0 && dir.z < -kEps) {
      const double t = -cf.origin.z / dir.z;
      const double range = t * std::sqrt(dir.x * dir.x + dir.y * dir.y);
      if (range <= far_m) {
        h.t = t;
        h.what = -1;
        h.n = {0, 0, 1};
      }
    }
    const double v = r.v;
    for (int j = 0; j < ncand; ++j) {
      const int i = cand[j];
      const Placed& o = placed[static_cast<std::size_t>(i)];
      if (h.t < zskip[i][cam]) break;  // and every later candidate (sorted by zskip)
      if (u < o.u0[cam] || u > o.u1[cam] || v < o.v0[cam] || v > o.v1[cam]) continue;
      if (o.cyl) first_hit_cylinder(o, i, lo[i][cam], cc[i][cam], dir, h);
      else first_hit_box(o, i, lo[i][cam], dir, h);
    }
    return h;
  }

  // Row constants of sample row v. cls: what every ray of the row hits when no obstacle is in the
  // way: -2 when all see the sky (dir.z >= -kEps; dir.z does not depend on u, the camera X axis
  // being horizontal), -1 when all hit the ground within far_m (the ground range grows with
  // |u - cx|, so checking both image ends, with a 1e-9 margin for rounding, covers the row), 0 when
  // it depends on u. tg: the ground depth -origin.z / dir.z of the row (when cls == -1).
  RowInfo row_info(const CameraFrame& cf, double v) const {
    const CameraSpec& c = sc.camera;
    RowInfo r;
    r.v = v;
    r.b = (v - c.cy) / c.focal_px;
    int cls[2];
    for (int e = 0; e < 2; ++e) {
      const double u = e == 0 ? -0.5 : c.width - 0.5;
      const double a = (u - c.cx) / c.focal_px;
      const Vec3 dir = a * cf.xc + r.b * cf.yc + cf.zc;
      if (!(dir.z < -kEps)) {
        cls[e] = -2;
        continue;
      }
      const double t = -cf.origin.z / dir.z;
      r.tg = t;
      const double range = t * std::sqrt(dir.x * dir.x + dir.y * dir.y);
      cls[e] = range <= far_m * (1.0 - 1e-9) ? -1 : 0;
    }
    r.cls = cls[0] == cls[1] ? cls[0] : 0;
    return r;
  }

  void surface(int cam, Vec3 dir, Hit& h) const {
    if (h.what < 0) return;
    const Placed& o = placed[static_cast<std::size_t>(h.what)];
    if (o.cyl) surface_cylinder(o, lo[h.what][cam], dir, h);
    else surface_box(o, lo[h.what][cam], dir, h);
  }
};

// Standard-normal quantile Phi^-1(p), 0 < p < 1: P. J. Acklam's rational approximation
// (relative error < 1.2e-9), no iteration.
double normal_quantile(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                                 1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                                 6.680131188771972e+01,  -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                                 -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                                 3.754408661907416e+00};
  constexpr double plow = 0.02425;
  if (p < plow) {
    const double q = std::sqrt(-2.0 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  }
  if (p > 1.0 - plow) return -normal_quantile(1.0 - p);
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
}

// Zero-mean unit Gaussian for (seed, camera, pixel, channel): a hash of those picks one of 2^16
// equally likely standard-normal quantiles Phi^-1((i + 0.5) / 2^16), tabulated once (one hash
// per sample instead of a log and a cos per Box-Muller pair).
const float* gauss_table() {
  static const std::vector<float> table = [] {
    std::vector<float> t(1u << 16);
    for (std::size_t i = 0; i < t.size(); ++i)
      t[i] = static_cast<float>(normal_quantile((static_cast<double>(i) + 0.5) / static_cast<double>(t.size())));
    return t;
  }();
  return table.data();
}

double gauss(std::uint64_t seed, int cam, int x, int y, int ch) {
  const std::uint64_t k = seed ^ (static_cast<std::uint64_t>(cam * 4 + ch) << 56);
  const double u = detail::hash01(x, y, k);
  return gauss_table()[static_cast<std::size_t>(u * 65536.0)];
}

// gauss() with the table passed in and the index taken from the hash bits: hash01 = (m >> 11) *
// 2^-53 is exact, so floor(hash01 * 2^16) = m >> 48 exactly (same sample, tested).
inline double gauss_fast(const float* table, std::uint64_t seed, int cam, int x, int y, int ch) {
  const std::uint64_t k = seed ^ (static_cast<std::uint64_t>(cam * 4 + ch) << 56) ^
                          (static_cast<std::uint64_t>(static_cast<std::int64_t>(x)) * 0x9E3779B97F4A7C15ULL) ^
                          (static_cast<std::uint64_t>(static_cast<std::int64_t>(y)) * 0xC2B2AE3D27D4EB4FULL);
  return table[detail::mix64(k) >> 48];
}

std::uint8_t to_u8(double c, const CameraRadiometry& r, double noise) {
  c = detail::clamp01(c);
  if (r.gamma != 1.0) c = std::pow(c, r.gamma);
  const double v = r.gain * c * 255.0 + r.bias + noise;
  return static_cast<std::uint8_t>(std::clamp(std::floor(v + 0.5), 0.0, 255.0));
}

// to_u8() without floor: w < 0 rounds to <= -1 and clamps to 0, w >= 255 clamps to 255, and in
// between truncation is floor (same value, tested).
inline std::uint8_t to_u8_fast(double c, const CameraRadiometry& r, double noise) {
  c = detail::clamp01(c);
  if (r.gamma != 1.0) c = std::pow(c, r.gamma);
  const double v = r.gain * c * 255.0 + r.bias + noise;
  const double w = v + 0.5;
  if (w < 0.0) return 0;
  if (w >= 255.0) return 255;
  return static_cast<std::uint8_t>(static_cast<int>(w));
}

}  // namespace

double footprint_distance(const Footprint& f, double x, double y) {
  const double dx = x - f.x_m, dy = y - f.y_m;
  if (f.circle) return std::hypot(dx, dy) - f.radius_m;
  const double c = std::cos(f.yaw_rad), s = std::sin(f.yaw_rad);
  const double lx = std::fabs(c * dx + s * dy) - f.half_length_m;
  const double ly = std::fabs(-s * dx + c * dy) - f.half_width_m;
  const double outside = std::hypot(std::max(lx, 0.0), std::max(ly, 0.0));
  return outside + std::min(std::max(lx, ly), 0.0);
}

World::World(Scene scene) : scene_(std::move(scene)) {}

StereoCalib World::calib() const {
  const CameraSpec& c = scene_.camera;
  StereoCalib k;
  k.focal_px = c.focal_px;
  k.cx = c.cx;
  k.cy = c.cy;
  k.baseline_m = c.baseline_m;
  k.height_m = c.height_m;
  k.pitch_rad = c.pitch_deg * kDeg;
  return k;
}

Pose2 World::scene_pose() const { return {scene_.robot.x_m, scene_.robot.y_m, scene_.robot.yaw_deg * kDeg}; }

std::vector<Footprint> World::obstacles_at(double t) const {
  std::vector<Footprint> out;
  for (const auto& o : scene_.obstacles) {
    Footprint f;
    f.id = o.id;
    f.circle = o.shape != Shape::Box;
    const auto at = o.position_at(t);
    f.x_m = at[0];
    f.y_m = at[1];
    f.yaw_rad = o.yaw_deg * kDeg;
    f.half_length_m = o.length_m * 0.5;
    f.half_width_m = o.width_m * 0.5;
    f.radius_m = o.radius_m;
    f.z0_m = o.z_m;
    f.z1_m = o.z_m + o.height_m;
    out.push_back(f);
  }
  return out;
}

double World::clearance(const Pose2& pose, double t) const {
  double best = kInf;
  for (const auto& f : obstacles_at(t)) best = std::min(best, footprint_distance(f, pose.x_m, pose.y_m));
  return best;
}

namespace {

// Everything a frame needs before the pixel loop: camera frames, obstacles placed at time t with
// their screen bounds, light.
struct FrameSetup {
  CameraFrame frames[2];
  std::vector<Placed> placed;
  Vec3 sun;
  Color sun_c, amb_c, horizon;
  double time_s = 0.0;  // scene time of the frame
};

// `clip`: replace the whole-image bounds of an obstacle straddling a camera plane by
// clipped_bounds() (fast path only; the reference keeps the whole image).
FrameSetup setup_frame(const Scene& sc, const Pose2& pose, double time_s, bool clip) {
  const CameraSpec& cam = sc.camera;
  FrameSetup f{{camera_frame(cam, pose, 0), camera_frame(cam, pose, 1)}, {}, {}, {}, {}, {}, time_s};
  const CameraFrame* frames = f.frames;
  std::vector<Placed>& placed = f.placed;

  // Obstacles at time t with conservative screen bounds (8 corners of the bounding box projected;
  // the whole image when a corner is behind the camera).
  for (std::size_t i = 0; i < sc.obstacles.size(); ++i) {
    const ObstacleSpec& o = sc.obstacles[i];
    Placed p;
    p.index = static_cast<int>(i);
    p.spec = &o;
    const auto at = o.position_at(time_s);
    p.base = {at[0], at[1], o.z_m};
    p.c = std::cos(o.yaw_deg * kDeg);
    p.s = std::sin(o.yaw_deg * kDeg);
    p.cyl = o.shape != Shape::Box;
    p.hx = p.cyl ? o.radius_m : o.length_m * 0.5;
    p.hy = p.cyl ? o.radius_m : o.width_m * 0.5;
    p.r = o.radius_m;
    p.h = o.height_m;
    p.tint = {o.color[0] / 255.0, o.color[1] / 255.0, o.color[2] / 255.0};
    p.seed = detail::mix64(sc.seed * 0x100000001b3ULL + static_cast<std::uint64_t>(o.id) + 1u);
    for (int k = 0; k < 2; ++k) {
      const CameraFrame& cf = frames[k];
      double u0 = kInf, u1 = -kInf, v0 = kInf, v1 = -kInf;
      bool behind = false, any_front = false;
      for (int corner = 0; corner < 8; ++corner) {
        const Vec3 l{(corner & 1) ? p.hx : -p.hx, (corner & 2) ? p.hy : -p.hy, (corner & 4) ? p.h : 0.0};
        const Vec3 rel = p.base + to_world(p, l) - cf.origin;
        const double X = detail::dot(rel, cf.xc), Y = detail::dot(rel, cf.yc), Z = detail::dot(rel, cf.zc);
        if (Z < 1e-3) { behind = true; continue; }
        any_front = true;
        const double u = cam.cx + cam.focal_px * X / Z, v = cam.cy + cam.focal_px * Y / Z;
        u0 = std::min(u0, u); u1 = std::max(u1, u); v0 = std::min(v0, v); v1 = std::max(v1, v);
      }
      if (!any_front) { u0 = v0 = kInf; u1 = v1 = -kInf; }
      else if (behind && clip) clipped_bounds(p, cf, cam, u0, u1, v0, v1);
      else if (behind) { u0 = v0 = -kInf; u1 = v1 = kInf; }
      else { u0 -= 2; v0 -= 2; u1 += 2; v1 += 2; }
      if (clip && p.cyl) {
        // A cylinder also lies in its bounding square turned by 45 deg: keep only what both
        // screen boxes cover (still every sample that can hit it).
        Placed q = p;
        q.c = (p.c - p.s) * std::sqrt(0.5);
        q.s = (p.s + p.c) * std::sqrt(0.5);
        double a0, a1, b0, b1;
        clipped_bounds(q, cf, cam, a0, a1, b0, b1);
        u0 = std::max(u0, a0); u1 = std::min(u1, a1); v0 = std::max(v0, b0); v1 = std::min(v1, b1);
        if (u0 > u1 || v0 > v1) { u0 = v0 = kInf; u1 = v1 = -kInf; }
      }
      p.u0[k] = u0; p.u1[k] = u1; p.v0[k] = v0; p.v1[k] = v1;
    }
    placed.push_back(p);
  }

  const double sun_az = sc.light.sun_azimuth_deg * kDeg, sun_el = sc.light.sun_elevation_deg * kDeg;
  f.sun = {std::cos(sun_el) * std::cos(sun_az), std::cos(sun_el) * std::sin(sun_az), std::sin(sun_el)};
  f.sun_c = detail::sun_light(sc.sky.kind);
  f.amb_c = detail::ambient_light(sc.sky.kind);
  // Horizon colour seen along the robot heading (haze target; direction-independent enough).
  f.horizon = detail::sky_color(sc.sky.kind, Vec3{std::cos(pose.yaw_rad), std::sin(pose.yaw_rad), 0.0}, Vec3{0, 0, 1},
                                sc.seed);
  return f;
}

// Output images and the per-pixel scratch the obstacle truth is computed from.
struct Canvas {
  RenderResult res;
  Image<float> depth;
  ImageI32 index;
  Canvas(int W, int H, const StereoCalib& calib) : depth(W, H, 0.0f), index(W, H, -1) {
    res.left = ImageRgb8(W, H);
    res.right = ImageRgb8(W, H);
    res.disparity = Image<float>(W, H, 0.0f);
    res.road_mask = ImageU8(W, H, 0);
    res.sky_mask = ImageU8(W, H, 0);
    res.obstacle_ids = ImageI32(W, H, -1);
    res.calib = calib;
  }

  // Writes pixel (x, y) of camera k: colour `acc` with sensor noise and, for the left camera, the
  // ground truth of the pixel-centre hit.
  // `fast`: gauss_fast/to_u8_fast instead of the reference gauss/to_u8.
  void store(const Scene& sc, const std::vector<Placed>& placed, int k, int x, int y, Color acc, const Hit& centre,
             bool fast) {
    const CameraRadiometry& rad = k == 0 ? sc.radiometric.left : sc.radiometric.right;
    Rgb8& out = (k == 0 ? res.left : res.right).at(x, y);
    const double sig = rad.noise_sigma;
    if (fast) {
      const float* table = gauss_table();
      out.r = to_u8_fast(acc.r, rad, sig > 0 ? sig * gauss_fast(table, sc.seed, k, x, y, 0) : 0.0);
      out.g = to_u8_fast(acc.g, rad, sig > 0 ? sig * gauss_fast(table, sc.seed, k, x, y, 1) : 0.0);
      out.b = to_u8_fast(acc.b, rad, sig > 0 ? sig * gauss_fast(table, sc.seed, k, x, y, 2) : 0.0);
    } else {
      out.r = to_u8(acc.r, rad, sig > 0 ? sig * gauss(sc.seed, k, x, y, 0) : 0.0);
      out.g = to_u8(acc.g, rad, sig > 0 ? sig * gauss(sc.seed, k, x, y, 1) : 0.0);
      out.b = to_u8(acc.b, rad, sig > 0 ? sig * gauss(sc.seed, k, x, y, 2) : 0.0);
    }
    if (k != 0) return;
    // Ground truth: the left ray through the pixel centre.
    const Hit& g = centre;
    if (g.what == -2) {
      res.sky_mask.at(x, y) = 255;
      return;
    }
    res.disparity.at(x, y) = static_cast<float>(sc.camera.focal_px * sc.camera.baseline_m / g.t);
    depth.at(x, y) = static_cast<float>(g.t);
    if (g.what == -1) {
      res.road_mask.at(x, y) = 255;
    } else {
      index.at(x, y) = g.what;
      res.obstacle_ids.at(x, y) = placed[static_cast<std::size_t>(g.what)].spec->id;
    }
  }

  // Obstacle list: boxes, counts and median depth over the visible pixels.
  RenderResult finish(const FrameSetup& f) {
    const int W = res.left.width, H = res.left.height;
    const std::vector<Placed>& placed = f.placed;
    std::vector<std::vector<float>> depths(placed.size());
    for (auto& p : placed) {
      ObstacleTruth t;
      t.id = p.spec->id;
      t.shape = p.spec->shape;
      t.x0 = W; t.y0 = H; t.x1 = -1; t.y1 = -1;
      const Vec3 centre = p.base + Vec3{0, 0, p.h * 0.5};
      t.world[0] = centre.x; t.world[1] = centre.y; t.world[2] = centre.z;
      const Vec3 rel = centre - f.frames[0].origin;
      t.cam[0] = detail::dot(rel, f.frames[0].xc);
      t.cam[1] = detail::dot(rel, f.frames[0].yc);
      t.cam[2] = detail::dot(rel, f.frames[0].zc);
      const auto v = p.spec->velocity_at(f.time_s);
      t.velocity[0] = v[0];
      t.velocity[1] = v[1];
      res.obstacles.push_back(t);
    }
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const int i = index.at(x, y);
        if (i < 0) continue;
        ObstacleTruth& t = res.obstacles[static_cast<std::size_t>(i)];
        t.x0 = std::min(t.x0, x); t.x1 = std::max(t.x1, x);
        t.y0 = std::min(t.y0, y); t.y1 = std::max(t.y1, y);
        ++t.visible_pixels;
        depths[static_cast<std::size_t>(i)].push_back(depth.at(x, y));
      }
    for (std::size_t i = 0; i < placed.size(); ++i) {
      ObstacleTruth& t = res.obstacles[i];
      auto& d = depths[i];
      if (d.empty()) {
        t.x0 = t.y0 = 0; t.x1 = t.y1 = -1;
        continue;
      }
      const std::size_t mid = d.size() / 2;
      std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(mid), d.end());
      double med = d[mid];
      if (d.size() % 2 == 0) med = 0.5 * (med + *std::max_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(mid)));
      t.distance_m = med;
      t.truncated = t.x0 == 0 || t.y0 == 0 || t.x1 == W - 1 || t.y1 == H - 1;
    }
    return std::move(res);
  }
};

#if defined(FS_HAVE_OPENMP)
int omp_threads(int threads) { return threads > 0 ? threads : omp_get_max_threads(); }
#endif

}  // namespace

RenderResult World::render_reference(const Pose2& pose, double time_s, int threads) const {
  const Scene& sc = scene_;
  const int W = sc.camera.width, H = sc.camera.height;
  const FrameSetup f = setup_frame(sc, pose, time_s, false);
  const Tracer tr{sc, f.placed, sc.render.far_m};
  Canvas cv(W, H, calib());
  const int n = sc.render.supersample;
  const int rows = 2 * H;
#if defined(FS_HAVE_OPENMP)
  const int nt = omp_threads(threads);
#pragma omp parallel for schedule(dynamic, 4) num_threads(nt) if (rows > 1)
#else
  (void)threads;
#endif
  for (int row = 0; row < rows; ++row) {
    const int k = row / H, y = row % H;  // camera, image row
    const CameraFrame& cf = f.frames[k];
    for (int x = 0; x < W; ++x) {
      // Geometry of the n x n sub-pixel rays and of the pixel centre. Where all of them see the same
      // surface (face), the pixel is shaded once at the centre: the textures are pre-filtered by
      // their level of detail (textures.cpp), so only geometric edges need the sub-samples.
      Hit sub[kMaxSub * kMaxSub];
      bool same = true;
      const Hit centre = tr.trace(cf, k, x, y);
      for (int sy = 0, i = 0; sy < n; ++sy)
        for (int sx = 0; sx < n; ++sx, ++i) {
          sub[i] = tr.trace(cf, k, x + (sx + 0.5) / n - 0.5, y + (sy + 0.5) / n - 0.5);
          same = same && sub[i].what == centre.what && sub[i].face == centre.face;
        }
      Color acc;
      if (same) {
        acc = tr.shade(cf, x, y, centre, f.sun, f.sun_c, f.amb_c, f.horizon);
      } else {
        for (int sy = 0, i = 0; sy < n; ++sy)
          for (int sx = 0; sx < n; ++sx, ++i)
            acc = acc + tr.shade(cf, x + (sx + 0.5) / n - 0.5, y + (sy + 0.5) / n - 0.5, sub[i], f.sun, f.sun_c,
                                 f.amb_c, f.horizon);
        acc = (1.0 / (n * n)) * acc;
      }
      cv.store(sc, f.placed, k, x, y, acc, centre, false);
    }
  }
  return cv.finish(f);
}

RenderResult World::render(const Pose2& pose, double time_s, int threads) const {
  const Scene& sc = scene_;
  const int W = sc.camera.width, H = sc.camera.height;
  const FrameSetup f = setup_frame(sc, pose, time_s, true);
  const std::size_t no = f.placed.size();
  // Camera origins in the obstacle frames, with the expressions of intersect_box/_cylinder.
  std::vector<std::array<Vec3, 2>> lo(no);
  std::vector<std::array<double, 2>> cc(no), zskip(no);
  for (std::size_t i = 0; i < no; ++i) {
    const Placed& o = f.placed[i];
    for (int k = 0; k < 2; ++k) {
      const CameraFrame& cf = f.frames[k];
      const Vec3 l = to_local(o, cf.origin - o.base);
      lo[i][k] = o.cyl ? l : l - Vec3{0, 0, o.h * 0.5};
      cc[i][k] = l.x * l.x + l.y * l.y - o.r * o.r;
      double zmin = kInf;
      for (int corner = 0; corner < 8; ++corner) {
        const Vec3 c{(corner & 1) ? o.hx : -o.hx, (corner & 2) ? o.hy : -o.hy, (corner & 4) ? o.h : 0.0};
        zmin = std::min(zmin, detail::dot(o.base + to_world(o, c) - cf.origin, cf.zc));
      }
      zskip[i][k] = zmin - 1e-6 - 1e-9 * std::fabs(zmin);
    }
  }
  const TileLists tiles[2] = {build_tiles(f.placed, zskip, 0, W, H), build_tiles(f.placed, zskip, 1, W, H)};
  const FastTracer ft{sc, f.placed, sc.render.far_m, lo.data(), cc.data(), zskip.data()};
  const Tracer tr{sc, f.placed, sc.render.far_m};  // shading
  Canvas cv(W, H, calib());
  const int n = sc.render.supersample;
  double off[kMaxSub];  // sub-sample offsets, as the reference computes them
  for (int s = 0; s < n; ++s) off[s] = (s + 0.5) / n;
  // Column constants a = (u - cx) / f of the pixel centres and sub-sample columns, and per camera
  // and pixel row the RowInfo of the centre row and of each sub-sample row, plus the class shared
  // by all of them (0 when they differ).
  std::vector<double> a_centre(static_cast<std::size_t>(W)), a_sub(static_cast<std::size_t>(W * n));
  for (int x = 0; x < W; ++x) {
    const double u = x;
    a_centre[static_cast<std::size_t>(x)] = (u - sc.camera.cx) / sc.camera.focal_px;
    for (int sx = 0; sx < n; ++sx) {
      const double us = x + off[sx] - 0.5;
      a_sub[static_cast<std::size_t>(x * n + sx)] = (us - sc.camera.cx) / sc.camera.focal_px;
    }
  }
  std::vector<RowInfo> row_centre(static_cast<std::size_t>(2 * H)), row_sub(static_cast<std::size_t>(2 * H * n));
  std::vector<int> pixel_row_class(static_cast<std::size_t>(2 * H));
  for (int k = 0; k < 2; ++k)
    for (int y = 0; y < H; ++y) {
      const std::size_t r = static_cast<std::size_t>(k * H + y);
      row_centre[r] = ft.row_info(f.frames[k], y);
      int cls = row_centre[r].cls;
      for (int sy = 0; sy < n; ++sy) {
        const RowInfo ri = ft.row_info(f.frames[k], y + off[sy] - 0.5);
        row_sub[r * static_cast<std::size_t>(n) + static_cast<std::size_t>(sy)] = ri;
        if (ri.cls != cls) cls = 0;
      }
      pixel_row_class[r] = cls;
    }
  const int rows = 2 * H;
#if defined(FS_HAVE_OPENMP)
  const int nt = omp_threads(threads);
#pragma omp parallel for schedule(dynamic, 4) num_threads(nt) if (rows > 1)
#else
  (void)threads;
#endif
  for (int row = 0; row < rows; ++row) {
    const int k = row / H, y = row % H;  // camera, image row
    const CameraFrame& cf = f.frames[k];
    const TileLists& tl = tiles[k];
    const int row_cls = pixel_row_class[static_cast<std::size_t>(row)];
    const RowInfo& rc = row_centre[static_cast<std::size_t>(row)];
    const RowInfo* rs = row_sub.data() + static_cast<std::size_t>(row) * n;
    bool lazy[kMaxSub * kMaxSub];  // sub-sample known to see its row's class (ground/sky), not traced yet
    const int* trow = tl.start.data() + (y / kTile) * tl.tw;
    Hit sub[kMaxSub * kMaxSub];  // [0, n * n) written for every pixel before use
    Vec3 sdir[kMaxSub * kMaxSub];
    for (int x = 0; x < W; ++x) {
      const int* cand = tl.items.data() + trow[x / kTile];
      const int ncand = trow[x / kTile + 1] - trow[x / kTile];
      const double* as = a_sub.data() + static_cast<std::size_t>(x) * n;
      Vec3 cdir;
      bool same = true;
      Hit centre = ft.trace(cf, k, x, a_centre[static_cast<std::size_t>(x)], rc, cand, ncand, cdir);
      // Every sample of the pixel sees the same ground or sky when its rows agree (row_cls) and no
      // obstacle's screen box reaches into the pixel: then the sub-sample rays are not traced.
      bool clean = row_cls != 0;
      for (int j = 0; j < ncand && clean; ++j) {
        const Placed& o = f.placed[static_cast<std::size_t>(cand[j])];
        clean = o.u0[k] > x + 0.5 || o.u1[k] < x - 0.5 || o.v0[k] > y + 0.5 || o.v1[k] < y - 0.5;
      }
      for (int sy = 0, i = 0; sy < n && !clean; ++sy)
        for (int sx = 0; sx < n; ++sx, ++i) {
          const double u = x + off[sx] - 0.5, v = rs[sy].v;
          // A sample on a ground/sky row that no obstacle's screen box holds sees that class.
          lazy[i] = rs[sy].cls != 0;
          for (int j = 0; j < ncand && lazy[i]; ++j) {
            const Placed& o = f.placed[static_cast<std::size_t>(cand[j])];
            lazy[i] = u < o.u0[k] || u > o.u1[k] || v < o.v0[k] || v > o.v1[k];
          }
          if (lazy[i]) {
            sub[i].what = rs[sy].cls;
            sub[i].face = 0;
          } else {
            sub[i] = ft.trace(cf, k, u, as[sx], rs[sy], cand, ncand, sdir[i]);
          }
          same = same && sub[i].what == centre.what && sub[i].face == centre.face;
        }
      Color acc;
      if (same) {
        ft.surface(k, cdir, centre);
        acc = tr.shade_dir(cf, cdir, centre, f.sun, f.sun_c, f.amb_c, f.horizon);
      } else {
        for (int i = 0; i < n * n; ++i) {
          if (lazy[i]) sub[i] = ft.trace(cf, k, x + off[i % n] - 0.5, as[i % n], rs[i / n], cand, ncand, sdir[i]);
          ft.surface(k, sdir[i], sub[i]);
          acc = acc + tr.shade_dir(cf, sdir[i], sub[i], f.sun, f.sun_c, f.amb_c, f.horizon);
        }
        acc = (1.0 / (n * n)) * acc;
      }
      cv.store(sc, f.placed, k, x, y, acc, centre, true);
    }
  }
  return cv.finish(f);
}

}  // namespace fs::sim
