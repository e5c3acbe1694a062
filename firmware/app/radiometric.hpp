// Synthetic radiometric distortions of the right image, for the robustness experiment (the paper
// evaluates on Middlebury pairs with radiometric variations; the public copies have none, so we
// make them). Input and output are 8-bit grey or colour (1, 3 or 4 channels), values saturated.
//   gain   I' = 0.6 I
//   gamma  I' = 255 (I/255)^1.3
//   mixed  I'/255 = 0.03 + 1.15 (I/255)^0.8, then radial vignetting: x (1 - 0.25 (r/rmax)^2), r from
//          the image centre, rmax the centre-to-corner distance (25 % darker in the corners)
//   noise  I' = I + N(0, 4^2), independent per pixel and channel, fixed seed (reproducible; `eval
//          --noise-seed` draws another field to see how much a figure depends on the one draw)
//   none   unchanged copy
// Each output is rounded to the nearest integer once, at the end.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace fs::app {

inline constexpr double kRadioGain = 0.6;
inline constexpr double kRadioGamma = 1.3;
inline constexpr double kRadioMixedOffset = 0.03, kRadioMixedGain = 1.15, kRadioMixedGamma = 0.8;
inline constexpr double kRadioVignette = 0.25;
inline constexpr double kRadioNoiseSigma = 4.0;
inline constexpr std::uint64_t kRadioNoiseSeed = 0x5EEDF00Du;

// Valid names, in documentation order: none, gain, gamma, mixed, noise.
const std::vector<std::string>& radiometric_names();

// Throws fs::UserError listing the valid names when `name` is not one of them.
void check_radiometric_name(const std::string& name);

// Applies distortion `name` to `img` (CV_8UC1/3/4). Unknown name -> fs::UserError listing the
// valid names; other input types -> std::invalid_argument.
// noise_seed: the seed of the noise field (cv::RNG), used by "noise" only.
cv::Mat apply_radiometric(const cv::Mat& img, const std::string& name, std::uint64_t noise_seed = kRadioNoiseSeed);

}  // namespace fs::app
