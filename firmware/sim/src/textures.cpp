// Procedural textures of the synthetic world (docs/simulator.md, "Textures"). Every texture is a
// function of surface coordinates in metres — world (x, y) for the ground, the obstacle's own
// frame for obstacles — so both cameras see the same surface pattern (stereo-consistent) and a
// moving obstacle carries its texture. Patterns finer than the pixel footprint fade to their
// mean (lod()), which with the 2x2 supersampling keeps far surfaces free of aliasing.
#include <limits>

#include "sim_internal.hpp"

namespace fs::sim::detail {

namespace {

// value_noise() with the lattice values of the last cell seen per seed kept per thread: along an
// image row the coarse octaves stay in one cell for many pixels and the fine ones step to a
// neighbouring cell, so most of the four hashes are reused. The cached numbers are the hashes
// themselves, so the result is the same bits as value_noise() (tested against the reference).
struct NoiseCell {
  std::uint64_t seed = 0;
  std::int64_t ix = 0, iy = 0;
  double v[4] = {0, 0, 0, 0};  // hash01 at (ix, iy), (ix + 1, iy), (ix, iy + 1), (ix + 1, iy + 1)
  bool valid = false;
};
thread_local NoiseCell noise_cache[64];

inline double value_noise_cached(double x, double y, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  double tx = x - fx, ty = y - fy;
  tx = tx * tx * (3.0 - 2.0 * tx);
  ty = ty * ty * (3.0 - 2.0 * ty);
  NoiseCell& e = noise_cache[(seed * 0x9E3779B97F4A7C15ULL) >> 58];
  if (!e.valid || e.seed != seed || e.ix != ix || e.iy != iy) {
    double nv[4];
    const bool same_seed = e.valid && e.seed == seed;
    for (int c = 0; c < 4; ++c) {
      const std::int64_t cx = ix + (c & 1), cy = iy + (c >> 1);
      // offsets into the cached cell, in wrapping unsigned arithmetic (0 or 1 = a cached corner)
      const std::uint64_t ox = static_cast<std::uint64_t>(cx) - static_cast<std::uint64_t>(e.ix);
      const std::uint64_t oy = static_cast<std::uint64_t>(cy) - static_cast<std::uint64_t>(e.iy);
      nv[c] = same_seed && ox <= 1 && oy <= 1 ? e.v[ox + 2 * oy] : hash01(cx, cy, seed);
    }
    e.seed = seed;
    e.ix = ix;
    e.iy = iy;
    e.valid = true;
    for (int c = 0; c < 4; ++c) e.v[c] = nv[c];
  }
  const double a = e.v[0], b = e.v[1], c = e.v[2], d = e.v[3];
  const double top = a + (b - a) * tx, bot = c + (d - c) * tx;
  return top + (bot - top) * ty;
}

}  // namespace

double fbm(double x, double y, std::uint64_t seed, double wl, int octaves, double fp) {
  // Octave k has wavelength wl * 2^-k (exact), so x / wl_k = (x / wl) * 2^k and wl_k / fp =
  // (wl / fp) * 2^-k exactly: binary rounding commutes with power-of-two scaling while the values
  // stay normal (or zero / infinite). The divisions of the first octave are scaled instead of
  // repeated, and the lattice hashes come from value_noise_cached(); subnormal quotients (never met
  // in practice) take fbm_reference(). Same bits as fbm_reference() (tests/cpp/sim).
  const double qx = x / wl, qy = y / wl, qw = wl / fp;
  auto normal = [](double q) { return q == 0.0 || std::fabs(q) >= std::numeric_limits<double>::min(); };
  if (normal(qx) && normal(qy) && normal(qw)) {
    double sum = 0.0, amp = 0.5, scale = 1.0, inv = 1.0;
    for (int k = 0; k < octaves; ++k, scale *= 2.0, inv *= 0.5, amp *= 0.6) {
      const double w = clamp01(qw * inv - 1.0);  // lod(wl_k, fp); qw * 2^-k is exact (or underflows below 1)
      if (w <= 0.0) break;  // every next octave is finer still
      sum += amp * w * (value_noise_cached(qx * scale, qy * scale, seed + static_cast<std::uint64_t>(k) * 7919u) - 0.5);
    }
    return sum;
  }
  return fbm_reference(x, y, seed, wl, octaves, fp);
}

double fbm_reference(double x, double y, std::uint64_t seed, double wl, int octaves, double fp) {
  double sum = 0.0, amp = 0.5;
  for (int k = 0; k < octaves; ++k, wl *= 0.5, amp *= 0.6) {
    const double w = lod(wl, fp);
    if (w <= 0.0) break;  // every next octave is finer still
    sum += amp * w * (value_noise(x / wl, y / wl, seed + static_cast<std::uint64_t>(k) * 7919u) - 0.5);
  }
  return sum;
}

namespace {

Color grey(double v) { return {v, v, v}; }

// Fine grain laid over every obstacle texture so no surface is perfectly uniform (stereo needs
// texture; real paint and materials have some).
double grain(double s, double t, double fp, std::uint64_t seed) { return 1.0 + 0.35 * fbm(s, t, seed ^ 0x5151u, 0.04, 3, fp); }

}  // namespace

Color ground_albedo(GroundTexture tex, double x, double y, double scale_m, double fp, std::uint64_t seed) {
  const double u = x / scale_m, v = y / scale_m, f = fp / scale_m;
  switch (tex) {
    case GroundTexture::Asphalt: {
      double g = 0.32 + 0.12 * fbm(u, v, seed, 6.0, 3, f) + 0.45 * fbm(u, v, seed + 1, 0.12, 4, f);
      const double cell = 0.012;
      const double h = hash01(static_cast<std::int64_t>(std::floor(u / cell)), static_cast<std::int64_t>(std::floor(v / cell)), seed + 2);
      g += (h > 0.9 ? 0.22 : (h < 0.08 ? -0.1 : 0.0)) * lod(cell, f);
      return g * Color{0.96, 0.98, 1.0};
    }
    case GroundTexture::Gravel: {
      const double n = value_noise(u / 0.035, v / 0.035, seed);
      const double stone = smoothstep(0.35, 0.65, n);
      const double w = lod(0.035, f);
      const Color dark{0.30, 0.27, 0.23}, light{0.66, 0.63, 0.58};
      Color c = mix(mix(dark, light, 0.5), mix(dark, light, stone), w);
      return (1.0 + 0.5 * fbm(u, v, seed + 3, 0.5, 5, f)) * c;
    }
    case GroundTexture::Grass: {
      const double b = 0.9 + 0.7 * fbm(u, v, seed, 2.0, 4, f);
      const double blades = value_noise(u / 0.006, v / 0.04, seed + 5) - 0.5;
      const double k = b + 0.9 * fbm(u, v, seed + 6, 0.12, 4, f) + 0.5 * blades * lod(0.012, f);
      return k * Color{0.20, 0.40, 0.12};
    }
    case GroundTexture::Tiles: {
      const double size = 0.4, grout = 0.035;
      const double cu = std::floor(u / size), cv = std::floor(v / size);
      const double fu = u / size - cu, fv = v / size - cv;
      const double tone = 0.55 + 0.3 * hash01(static_cast<std::int64_t>(cu), static_cast<std::int64_t>(cv), seed);
      const Color tile = tone * Color{0.95, 0.80, 0.70};
      const Color grout_c{0.35, 0.35, 0.35};
      const bool in_grout = fu < grout || fv < grout;
      const Color sharp = in_grout ? grout_c : tile;
      const Color mean = mix(tile, grout_c, 2.0 * grout);
      const Color c = mix(mean, sharp, lod(size * grout * 2.0, f));
      return (1.0 + 0.5 * fbm(u, v, seed + 4, 0.1, 4, f)) * c;
    }
  }
  return grey(0.5);
}

Color obstacle_albedo(Texture tex, Color tint, double s, double t, double fp, std::uint64_t seed) {
  Color c;
  switch (tex) {
    case Texture::Bricks: {
      const double bw = 0.22, bh = 0.075, mortar = 0.012;
      const double row = std::floor(t / bh);
      const double off = std::fmod(row, 2.0) != 0.0 ? bw * 0.5 : 0.0;
      const double col = std::floor((s + off) / bw);
      const double fs = s + off - col * bw, ft = t - row * bh;
      const Color mortar_c{0.78, 0.76, 0.72};
      const double tone = 0.7 + 0.45 * hash01(static_cast<std::int64_t>(col), static_cast<std::int64_t>(row), seed);
      const Color brick = tone * tint;
      const Color sharp = (fs < mortar || ft < mortar) ? mortar_c : brick;
      const Color mean = mix(0.92 * tint, mortar_c, 0.25);
      c = mix(mean, sharp, lod(bh, fp));
      break;
    }
    case Texture::Noise:
      c = (0.75 + 1.3 * fbm(s, t, seed, 0.35, 6, fp)) * tint;
      break;
    case Texture::Stripes: {
      const double p = (s * 0.8 + t * 0.6) / 0.14;
      const double sharp = (p - std::floor(p)) < 0.5 ? 1.0 : 0.35;
      c = (0.675 + (sharp - 0.675) * lod(0.07, fp)) * tint;
      c = (1.0 + 0.6 * fbm(s, t, seed, 0.3, 4, fp)) * c;
      break;
    }
    case Texture::Checker: {
      const double q = 0.12;
      const bool odd = (static_cast<std::int64_t>(std::floor(s / q)) + static_cast<std::int64_t>(std::floor(t / q))) & 1;
      const Color other{0.9, 0.9, 0.88};
      c = mix(mix(tint, other, 0.5), odd ? other : tint, lod(q, fp));
      c = (1.0 + 0.4 * fbm(s, t, seed, 0.2, 3, fp)) * c;
      break;
    }
    case Texture::Wood: {
      const double warp = 0.6 * fbm(s, t, seed, 0.5, 3, fp);
      const double rings = (s * 14.0 + warp * 6.0);
      const double r = 0.5 + 0.5 * std::sin(rings * 6.283185307179586);
      const double streak = value_noise(s / 0.004, t / 0.25, seed + 9) - 0.5;
      const double k = 0.8 + 0.3 * (r - 0.5) * lod(1.0 / 14.0, fp) + 0.35 * streak * lod(0.008, fp);
      c = k * mix(tint, Color{0.55, 0.36, 0.2}, 0.5);
      break;
    }
    case Texture::Camo: {
      const double n = fbm(s, t, seed, 0.6, 4, fp);
      const Color dark{0.12, 0.14, 0.09}, olive{0.33, 0.36, 0.18}, tan{0.62, 0.56, 0.40};
      const Color sharp = n < -0.1 ? dark : (n < 0.0 ? olive : (n < 0.1 ? tint : tan));
      const Color mean = 0.25 * (dark + olive + tint + tan);
      c = mix(mean, sharp, lod(0.1, fp));
      break;
    }
  }
  return grain(s, t, fp, seed) * c;
}

namespace {
// x^8 and x^256 by repeated squaring (std::pow costs ~20x more and these run for every sky pixel).
double pow8(double x) {
  x *= x;
  x *= x;
  return x * x;
}
double pow256(double x) {
  double y = pow8(pow8(x));  // x^64
  y *= y;
  return y * y;
}
}  // namespace

Color sky_color(SkyKind kind, Vec3 d, Vec3 sun, std::uint64_t seed) {
  const double elev = std::max(0.0, d.z);  // sin(elevation), below the horizon = horizon colour
  const double sun_dot = std::max(0.0, dot(d, sun));
  switch (kind) {
    case SkyKind::Clear: {
      const Color c = mix(Color{0.78, 0.86, 0.95}, Color{0.22, 0.42, 0.82}, std::sqrt(elev));
      return c + (0.6 * pow256(sun_dot) + 0.15 * pow8(sun_dot)) * Color{1.0, 0.95, 0.85};
    }
    case SkyKind::Overcast: {
      const double h = std::max(d.z, 0.03);
      const double px = d.x / h * 2.0, py = d.y / h * 2.0;  // cloud layer, 2 km up per km of range
      const double n = fbm(px, py, seed + 77, 3.0, 4, 0.0);
      const double g = 0.70 + 0.12 * elev + 0.16 * n;
      return Color{g, g, g * 1.02};
    }
    case SkyKind::Sunset: {
      const Color horizon{1.0, 0.58, 0.28}, mid{0.82, 0.45, 0.48}, zenith{0.22, 0.2, 0.45};
      const double e = std::sqrt(elev);
      const Color c = e < 0.4 ? mix(horizon, mid, e / 0.4) : mix(mid, zenith, (e - 0.4) / 0.6);
      return c + (0.8 * pow256(sun_dot) + 0.35 * pow8(sun_dot)) * Color{1.0, 0.7, 0.35};
    }
  }
  return grey(0.5);
}

Color sun_light(SkyKind kind) {
  switch (kind) {
    case SkyKind::Clear: return {1.0, 0.97, 0.9};
    case SkyKind::Overcast: return {0.9, 0.9, 0.92};
    case SkyKind::Sunset: return {1.0, 0.72, 0.45};
  }
  return grey(1.0);
}

Color ambient_light(SkyKind kind) {
  switch (kind) {
    case SkyKind::Clear: return {0.85, 0.9, 1.05};
    case SkyKind::Overcast: return {0.95, 0.95, 0.97};
    case SkyKind::Sunset: return {0.95, 0.75, 0.8};
  }
  return grey(1.0);
}

}  // namespace fs::sim::detail
