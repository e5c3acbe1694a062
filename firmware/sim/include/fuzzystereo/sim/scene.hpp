// Scene description of the deterministic synthetic stereo world (docs/simulator.md): camera,
// robot pose, sky, light, ground, obstacles and per-camera radiometry, read from a TOML file and
// validated once, with an error naming the file, the field and its valid range. Everything after
// loading assumes a valid Scene.
//
// Units: metres, seconds, degrees in files (`*_deg`) and radians in code (`*_rad`); world frame
// x forward (east), y left, z up, ground plane z = 0 (see docs/simulator.md, "Conventions").
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace fs::sim {

enum class SkyKind { Clear, Overcast, Sunset };
enum class GroundTexture { Asphalt, Gravel, Grass, Tiles };
enum class Shape { Box, Cylinder, Post };
enum class Texture { Bricks, Noise, Stripes, Checker, Wood, Camo };

const char* to_string(SkyKind k);
const char* to_string(GroundTexture t);
const char* to_string(Shape s);
const char* to_string(Texture t);
// The valid names, in declaration order (for generators and messages).
const std::vector<std::string>& sky_kind_names();
const std::vector<std::string>& ground_texture_names();
const std::vector<std::string>& shape_names();
const std::vector<std::string>& texture_names();

struct CameraSpec {
  int width = 640, height = 360;  // [px]
  double focal_px = 420.0;        // fx = fy [px]
  double cx = -1.0, cy = -1.0;    // principal point [px]; the parser resolves the default (w-1)/2, (h-1)/2
  double baseline_m = 0.12;       // right camera at +baseline along camera X [m]
  double height_m = 0.40;         // left optical centre above the ground [m]
  double pitch_deg = 5.0;         // downward tilt, positive = looking down [deg]
};

struct RobotSpec {
  double x_m = 0.0, y_m = 0.0;  // world position [m]
  double yaw_deg = 0.0;         // heading, counter-clockwise from +x [deg]
  double radius_m = 0.20;       // footprint radius for collisions [m]
};

struct MissionSpec {
  double goal_x_m = 0.0, goal_y_m = 0.0;  // [m]
  double time_limit_s = 60.0;             // [s]
};

struct SkySpec {
  SkyKind kind = SkyKind::Clear;
};

struct LightSpec {
  double sun_azimuth_deg = 135.0;  // counter-clockwise from +x [deg]
  double sun_elevation_deg = 45.0; // above the horizon [deg]
  double ambient = 0.35;           // share of diffuse sky light, 0..1
};

struct GroundSpec {
  GroundTexture texture = GroundTexture::Asphalt;
  double scale_m = 1.0;  // texture scale [m] (1 = nominal feature sizes)
};

struct ObstacleSpec {
  int id = 0;                 // >= 0, unique (auto-assigned when absent in the file)
  Shape shape = Shape::Box;
  double x_m = 0.0, y_m = 0.0;  // centre of the footprint at t = 0 [m]
  double z_m = 0.0;             // base height above the ground, >= 0 [m]
  double yaw_deg = 0.0;         // [deg]
  double length_m = 0.6, width_m = 0.6;  // box: along its local x / y [m]
  double radius_m = 0.3;                 // cylinder / post [m]
  double height_m = 0.6;                 // every shape [m]
  Texture texture = Texture::Noise;
  std::array<int, 3> color{180, 180, 180};  // albedo tint, 0..255 per channel
  double vx_mps = 0.0, vy_mps = 0.0;        // constant world velocity [m/s]
  // Changes of velocity (t [s], vx, vy [m/s]), in time order: the obstacle moves with (vx_mps,
  // vy_mps) from t = 0, with the new velocity from each t on (a stop is a turn to 0, 0). The suite's
  // solid movers (docs/robot.md); empty = constant velocity.
  std::vector<std::array<double, 3>> turns;
  // Position of the centre at time t [m] and velocity [m/s].
  std::array<double, 2> position_at(double t) const {
    double x = x_m, y = y_m, vx = vx_mps, vy = vy_mps, t0 = 0.0;
    for (const auto& k : turns) {
      if (k[0] > t) break;
      x += (k[0] - t0) * vx;
      y += (k[0] - t0) * vy;
      t0 = k[0];
      vx = k[1];
      vy = k[2];
    }
    return {x + (t - t0) * vx, y + (t - t0) * vy};
  }
  std::array<double, 2> velocity_at(double t) const {
    std::array<double, 2> v{vx_mps, vy_mps};
    for (const auto& k : turns) {
      if (k[0] > t) break;
      v = {k[1], k[2]};
    }
    return v;
  }
};

struct CameraRadiometry {
  double gain = 1.0;         // multiplies the normalised intensity
  double gamma = 1.0;        // exponent applied to the normalised intensity (1 = linear)
  double bias = 0.0;         // added, in 8-bit grey levels
  double noise_sigma = 0.0;  // Gaussian sensor noise, 8-bit grey levels (seeded, per pixel/channel)
};

struct RadiometricSpec {
  CameraRadiometry left, right;
};

struct RenderSpec {
  int supersample = 2;  // n x n samples per pixel (anti-aliased edges)
  double far_m = 80.0;  // ground drawn up to this horizontal distance, sky beyond [m]
};

struct Scene {
  std::uint64_t seed = 0;
  std::string type = "custom";  // scenario tag for reporting (clear, overcast, sunset, ...)
  CameraSpec camera;
  RobotSpec robot;
  std::optional<MissionSpec> mission;
  SkySpec sky;
  LightSpec light;
  GroundSpec ground;
  std::vector<ObstacleSpec> obstacles;
  RadiometricSpec radiometric;
  RenderSpec render;
  std::string source = "<scene>";  // file name used in messages
};

// Parses and validates a scene. Throws fs::ConfigError ("<source>: <field> = <value> is out of
// range: <valid range>", unknown fields, wrong types, unknown names, obstacle below ground ...).
Scene parse_scene(const std::string& toml_text, const std::string& source_name);
Scene load_scene(const std::string& path);

// The scene as TOML (every field, shortest round-trip numbers): parse_scene(scene_to_toml(s))
// gives back the same scene, so a written scene renders bit-identically.
std::string scene_to_toml(const Scene& s);

}  // namespace fs::sim
