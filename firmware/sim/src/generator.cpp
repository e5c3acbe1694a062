// Random scenario generator (docs/simulator.md, "Generator": every distribution is listed there).
#include "fuzzystereo/sim/generator.hpp"

#include <cmath>
#include <random>

#include "sim_internal.hpp"

namespace fs::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

const std::vector<std::string> kTypes{"clear", "overcast", "sunset", "radiometric", "many_obstacles", "few_obstacles"};

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : g_(seed) {}
  double uni() { return static_cast<double>(g_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double range(double a, double b) { return a + (b - a) * uni(); }
  int irange(int a, int b) { return a + static_cast<int>(uni() * (b - a + 1)); }  // inclusive
  bool chance(double p) { return uni() < p; }

 private:
  std::mt19937_64 g_;
};

double r3(double v) { return std::round(v * 1000.0) / 1000.0; }
double r1(double v) { return std::round(v * 10.0) / 10.0; }

double bounding_radius(const ObstacleSpec& o) {
  return o.shape == Shape::Box ? 0.5 * std::hypot(o.length_m, o.width_m) : o.radius_m;
}

}  // namespace

const std::vector<std::string>& scenario_types() { return kTypes; }

Scene generate_scene(std::uint64_t set_seed, int index, const GeneratorOptions& opt) {
  const std::uint64_t seed =
      detail::mix64(set_seed ^ detail::mix64(static_cast<std::uint64_t>(index) + 1u)) & 0x7fffffffffffffffULL;
  Rng rng(seed);
  Scene s;
  s.seed = seed;
  s.type = kTypes[static_cast<std::size_t>(index) % kTypes.size()];

  CameraSpec& c = s.camera;
  c.width = opt.width;
  c.height = opt.height;
  c.focal_px = r1(420.0 * opt.width / 640.0);
  c.cx = (c.width - 1) / 2.0;
  c.cy = (c.height - 1) / 2.0;
  c.baseline_m = 0.12;
  c.height_m = r3(rng.range(0.30, 0.50));
  c.pitch_deg = r1(rng.range(2.0, 8.0));

  s.robot.yaw_deg = r1(rng.range(-180.0, 180.0));
  const double yaw = s.robot.yaw_deg * kDeg;
  const double fx = std::cos(yaw), fy = std::sin(yaw);  // heading
  const double rx = std::sin(yaw), ry = -std::cos(yaw);  // camera X (right)
  s.mission = MissionSpec{r3(15.0 * fx), r3(15.0 * fy), 60.0};

  if (s.type == "clear") s.sky.kind = SkyKind::Clear;
  else if (s.type == "overcast") s.sky.kind = SkyKind::Overcast;
  else if (s.type == "sunset") s.sky.kind = SkyKind::Sunset;
  else s.sky.kind = static_cast<SkyKind>(rng.irange(0, 2));
  s.light.sun_azimuth_deg = r1(rng.range(-180.0, 180.0));
  switch (s.sky.kind) {
    case SkyKind::Clear:
      s.light.sun_elevation_deg = r1(rng.range(30.0, 70.0));
      s.light.ambient = r3(rng.range(0.30, 0.45));
      break;
    case SkyKind::Overcast:
      s.light.sun_elevation_deg = r1(rng.range(50.0, 85.0));
      s.light.ambient = r3(rng.range(0.65, 0.85));
      break;
    case SkyKind::Sunset:
      s.light.sun_elevation_deg = r1(rng.range(3.0, 15.0));
      s.light.ambient = r3(rng.range(0.25, 0.40));
      break;
  }
  s.ground.texture = static_cast<GroundTexture>(rng.irange(0, 3));
  s.ground.scale_m = r3(rng.range(0.6, 1.6));

  if (s.type == "radiometric") {
    auto& l = s.radiometric.left;
    auto& r = s.radiometric.right;
    l.gain = r3(rng.range(0.9, 1.1));
    l.gamma = r3(rng.range(0.9, 1.1));
    l.bias = r1(rng.range(-5.0, 5.0));
    l.noise_sigma = r1(rng.range(1.0, 3.0));
    r.gain = r3(rng.range(0.7, 1.3));
    r.gamma = r3(rng.range(0.75, 1.35));
    r.bias = r1(rng.range(-25.0, 25.0));
    r.noise_sigma = r1(rng.range(1.0, 4.0));
  } else {
    s.radiometric.left.noise_sigma = r1(rng.range(0.5, 1.5));
    s.radiometric.right.noise_sigma = r1(rng.range(0.5, 1.5));
  }

  int count = rng.irange(3, 6);
  if (s.type == "many_obstacles") count = rng.irange(8, 15);
  else if (s.type == "few_obstacles") count = rng.irange(1, 2);

  // Placement in the left camera's horizontal frame: forward distance Z in [1.5, 10] m, lateral X
  // with the centre inside the middle 80 % of the image width.
  const double tan_max = 0.8 * c.cx / c.focal_px;
  struct Placed2 {
    double z, x, rb;
  };
  std::vector<Placed2> placed;
  for (int i = 0; i < count; ++i) {
    ObstacleSpec o;
    o.id = i;
    const double pick = rng.uni();
    o.shape = pick < 0.45 ? Shape::Box : (pick < 0.75 ? Shape::Cylinder : Shape::Post);
    if (o.shape == Shape::Box) {
      o.length_m = r3(rng.range(0.25, 1.2));
      o.width_m = r3(rng.range(0.25, 1.2));
      o.height_m = r3(rng.range(0.25, 1.4));
      o.yaw_deg = r1(rng.range(-90.0, 90.0));
    } else if (o.shape == Shape::Cylinder) {
      o.radius_m = r3(rng.range(0.10, 0.45));
      o.height_m = r3(rng.range(0.30, 1.5));
    } else {
      o.radius_m = r3(rng.range(0.20, 0.30));
      o.height_m = r3(rng.range(1.5, 1.9));
    }
    o.texture = static_cast<Texture>(rng.irange(0, 5));
    for (auto& ch : o.color) ch = rng.irange(40, 230);
    if (rng.chance(0.2)) {
      const double speed = rng.range(0.2, 1.5), dir = rng.range(-kPi, kPi);
      o.vx_mps = r3(speed * std::cos(dir));
      o.vy_mps = r3(speed * std::sin(dir));
    }
    const double rb = bounding_radius(o);
    bool ok = false;
    double z = 0, x = 0;
    for (int attempt = 0; attempt < 60 && !ok; ++attempt) {
      if (!placed.empty() && rng.chance(0.35)) {
        // Partly hidden behind an earlier obstacle: further away, shifted sideways by about the
        // angular half-width of the one in front.
        const Placed2& f = placed[static_cast<std::size_t>(rng.irange(0, static_cast<int>(placed.size()) - 1))];
        z = f.z + rng.range(1.0, 3.0);
        const double side = rng.chance(0.5) ? 1.0 : -1.0;
        x = (f.x / f.z) * z + side * (f.rb / f.z) * z * rng.range(0.6, 1.3);
      } else {
        z = rng.range(1.5, 10.0);
        x = z * rng.range(-tan_max, tan_max);
      }
      if (z < 1.5 || z > 10.0 || std::fabs(x / z) > tan_max) continue;
      ok = true;
      for (const auto& p : placed)
        if (std::hypot(p.z - z, p.x - x) < p.rb + rb + 0.15) ok = false;
    }
    if (!ok) continue;
    placed.push_back({z, x, rb});
    o.x_m = r3(s.robot.x_m + z * fx + x * rx);
    o.y_m = r3(s.robot.y_m + z * fy + x * ry);
    s.obstacles.push_back(o);
  }
  // Renumber the ids densely (an obstacle that found no place leaves no gap).
  for (std::size_t i = 0; i < s.obstacles.size(); ++i) s.obstacles[i].id = static_cast<int>(i);
  return s;
}

}  // namespace fs::sim
