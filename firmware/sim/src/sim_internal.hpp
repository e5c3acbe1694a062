// Internal helpers of the synthetic world: small vector maths, integer hashing and the procedural
// textures (textures.cpp). Hand-written on purpose: the core builds for the robot with nothing but
// the standard library, and the renderer needs only value noise and a few patterns.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "fuzzystereo/sim/scene.hpp"

namespace fs::sim::detail {

struct Vec3 {
  double x = 0, y = 0, z = 0;
};
inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline double norm(Vec3 a) { return std::sqrt(dot(a, a)); }

struct Color {
  double r = 0, g = 0, b = 0;
};
inline Color operator*(double s, Color c) { return {s * c.r, s * c.g, s * c.b}; }
inline Color operator*(Color a, Color b) { return {a.r * b.r, a.g * b.g, a.b * b.b}; }
inline Color operator+(Color a, Color b) { return {a.r + b.r, a.g + b.g, a.b + b.b}; }
inline Color mix(Color a, Color b, double t) { return {a.r + (b.r - a.r) * t, a.g + (b.g - a.g) * t, a.b + (b.b - a.b) * t}; }

inline double clamp01(double v) { return std::min(1.0, std::max(0.0, v)); }
inline double smoothstep(double e0, double e1, double x) {
  const double t = clamp01((x - e0) / (e1 - e0));
  return t * t * (3.0 - 2.0 * t);
}

// splitmix64 finaliser: a well-mixed 64-bit hash of a 64-bit key.
inline std::uint64_t mix64(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}
// Uniform in [0, 1) from a lattice point and a seed.
inline double hash01(std::int64_t ix, std::int64_t iy, std::uint64_t seed) {
  const std::uint64_t k = seed ^ (static_cast<std::uint64_t>(ix) * 0x9E3779B97F4A7C15ULL) ^
                          (static_cast<std::uint64_t>(iy) * 0xC2B2AE3D27D4EB4FULL);
  return static_cast<double>(mix64(k) >> 11) * 0x1.0p-53;
}

// Bilinear value noise with a smooth fade, in [0, 1], lattice spacing 1. Inline: it runs for
// every octave of every textured pixel.
inline double value_noise(double x, double y, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  double tx = x - fx, ty = y - fy;
  tx = tx * tx * (3.0 - 2.0 * tx);
  ty = ty * ty * (3.0 - 2.0 * ty);
  const double a = hash01(ix, iy, seed), b = hash01(ix + 1, iy, seed);
  const double c = hash01(ix, iy + 1, seed), d = hash01(ix + 1, iy + 1, seed);
  const double top = a + (b - a) * tx, bot = c + (d - c) * tx;
  return top + (bot - top) * ty;
}

// Level of detail: weight of a pattern of wavelength `wl` [m] seen with a pixel footprint `fp` [m]:
// 1 when the wavelength spans >= 2 pixels, 0 at <= 1 pixel (faded to its mean, no aliasing).
inline double lod(double wl, double fp) { return clamp01(wl / fp - 1.0); }

// Fractal sum of `octaves` value-noise octaves, the first of wavelength wl [m], each next half as
// long and 0.6x as strong; octaves too fine for the footprint fade out. Roughly in [-0.5, 0.5].
double fbm(double x, double y, std::uint64_t seed, double wl, int octaves, double fp);
// The plain per-octave loop fbm() must reproduce bit for bit (its test oracle).
double fbm_reference(double x, double y, std::uint64_t seed, double wl, int octaves, double fp);

// Albedo of the ground at world (x, y) [m]; fp = pixel footprint [m].
Color ground_albedo(GroundTexture tex, double x, double y, double scale_m, double fp, std::uint64_t seed);
// Albedo of an obstacle surface at face coordinates (s, t) [m] (object frame), tinted by `tint`.
Color obstacle_albedo(Texture tex, Color tint, double s, double t, double fp, std::uint64_t seed);
// Sky radiance along the unit world direction `d`; `sun` = unit vector towards the sun.
Color sky_color(SkyKind kind, Vec3 d, Vec3 sun, std::uint64_t seed);
// Colour of sunlight and of ambient sky light for a sky kind.
Color sun_light(SkyKind kind);
Color ambient_light(SkyKind kind);

}  // namespace fs::sim::detail
