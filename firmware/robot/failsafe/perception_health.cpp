#include "fuzzystereo/robot/perception_health.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace fs::robot {

ImageStats image_stats(const std::uint8_t* data, int width, int height, std::size_t stride, int step) {
  ImageStats st;
  if (data == nullptr || width <= 0 || height <= 0) return st;
  if (step < 1) step = 1;
  std::uint64_t n = 0, s = 0, s2 = 0, hash = 1469598103934665603ull;  // FNV-1a offset basis
  for (int y = 0; y < height; y += step) {
    const std::uint8_t* r = data + std::size_t(y) * stride;
    for (int x = 0; x < width; x += step) {
      const std::uint64_t v = r[x];
      s += v;
      s2 += v * v;
      ++n;
      hash = (hash ^ v) * 1099511628211ull;  // FNV prime
    }
  }
  const double mean = double(s) / double(n);
  st.stddev = std::sqrt(std::max(0.0, double(s2) / double(n) - mean * mean));
  st.hash = hash;
  return st;
}

double signal_contrast(double stddev, double noise) { return std::sqrt(std::max(0.0, stddev * stddev - noise * noise)); }

std::string perception_fault(const FrameHealth& h, const PerceptionHealthParams& p) {
  char buf[160];
  const auto blind = [&](const char* side, double c) {
    std::snprintf(buf, sizeof buf, "%s camera blind: contrast %.1f < %g grey levels", side, c, p.min_contrast);
    return std::string(buf);
  };
  if (h.contrast_left < p.min_contrast) return blind("left", h.contrast_left);
  if (h.contrast_right < p.min_contrast) return blind("right", h.contrast_right);
  const auto noise_only = [&](const char* side, double c, double n) {
    std::snprintf(buf, sizeof buf,
                  "%s camera blind: only noise (contrast %.1f, noise %.1f grey levels) and %.1f %% of the pixels match (< %g %%)",
                  side, c, n, h.valid_pct, p.noise_only_valid_pct);
    return std::string(buf);
  };
  if (h.valid_pct < p.noise_only_valid_pct) {
    if (signal_contrast(h.contrast_left, h.noise_left) < p.min_contrast) return noise_only("left", h.contrast_left, h.noise_left);
    if (signal_contrast(h.contrast_right, h.noise_right) < p.min_contrast)
      return noise_only("right", h.contrast_right, h.noise_right);
  }
  if (p.frozen_frames > 0 && (h.same_left >= p.frozen_frames || h.same_right >= p.frozen_frames)) {
    const bool left = h.same_left >= p.frozen_frames;
    std::snprintf(buf, sizeof buf, "%s camera frozen: %d identical frames in a row", left ? "left" : "right",
                  (left ? h.same_left : h.same_right) + 1);
    return buf;
  }
  if (h.valid_pct < p.min_valid_pct) {
    std::snprintf(buf, sizeof buf, "views do not match: %.1f %% of the pixels have a disparity (< %g %%)", h.valid_pct,
                  p.min_valid_pct);
    return buf;
  }
  return {};
}

bool PerceptionMonitor::update(const FrameHealth& h) {
  if (!p_.enabled) {
    fault_.clear();
    return false;
  }
  fault_ = perception_fault(h, p_);
  if (fault_.empty()) {
    bad_run_ = 0;
    ++good_run_;
    if (stopped_ && good_run_ >= (started_ ? p_.clear_frames : p_.startup_frames)) {
      stopped_ = false;
      started_ = true;
    }
  } else {
    good_run_ = 0;
    ++bad_run_;
    if (started_ && !stopped_ && bad_run_ >= p_.trip_frames) {
      stopped_ = true;
      ++trips_;
    }
  }
  return stopped_;
}

}  // namespace fs::robot
