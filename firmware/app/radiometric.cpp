// Synthetic radiometric distortions (see radiometric.hpp for the formulas).
#include "radiometric.hpp"

#include <cmath>
#include <stdexcept>

#include "io.hpp"

namespace fs::app {
namespace {

// Per-intensity curve applied through a 256-entry table.
template <class F>
cv::Mat apply_curve(const cv::Mat& img, F curve) {
  cv::Mat lut(1, 256, CV_8U);
  for (int i = 0; i < 256; ++i) lut.at<std::uint8_t>(i) = cv::saturate_cast<std::uint8_t>(curve(double(i)));
  cv::Mat out;
  cv::LUT(img, lut, out);
  return out;
}

cv::Mat apply_mixed(const cv::Mat& img) {
  const int cn = img.channels();
  double tone[256];
  for (int i = 0; i < 256; ++i)
    tone[i] = 255.0 * (kRadioMixedOffset + kRadioMixedGain * std::pow(double(i) / 255.0, kRadioMixedGamma));
  const double cx = 0.5 * double(img.cols - 1), cy = 0.5 * double(img.rows - 1);
  const double rmax2 = cx * cx + cy * cy;
  cv::Mat out(img.size(), img.type());
  for (int y = 0; y < img.rows; ++y) {
    const std::uint8_t* src = img.ptr<std::uint8_t>(y);
    std::uint8_t* dst = out.ptr<std::uint8_t>(y);
    for (int x = 0; x < img.cols; ++x) {
      const double dx = double(x) - cx, dy = double(y) - cy;
      const double vig = rmax2 > 0.0 ? 1.0 - kRadioVignette * (dx * dx + dy * dy) / rmax2 : 1.0;
      for (int c = 0; c < cn; ++c) {
        const int i = x * cn + c;
        dst[i] = cv::saturate_cast<std::uint8_t>(tone[src[i]] * vig);
      }
    }
  }
  return out;
}

cv::Mat apply_noise(const cv::Mat& img, std::uint64_t seed) {
  cv::RNG rng(seed);  // cv::RNG is the same generator on every platform
  cv::Mat noise(img.rows, img.cols * img.channels(), CV_32F);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, kRadioNoiseSigma);
  cv::Mat f;
  img.reshape(1).convertTo(f, CV_32F);
  f += noise;
  cv::Mat out;
  f.convertTo(out, CV_8U);  // rounds to nearest and saturates
  return out.reshape(img.channels());
}

}  // namespace

const std::vector<std::string>& radiometric_names() {
  static const std::vector<std::string> kNames{"none", "gain", "gamma", "mixed", "noise"};
  return kNames;
}

void check_radiometric_name(const std::string& name) {
  bool known = false;
  for (const auto& n : radiometric_names()) known = known || n == name;
  if (!known) {
    std::string list;
    for (const auto& n : radiometric_names()) list += (list.empty() ? "" : ", ") + n;
    throw UserError("unknown radiometric distortion '" + name + "' (valid: " + list + ")");
  }
}

cv::Mat apply_radiometric(const cv::Mat& img, const std::string& name, std::uint64_t noise_seed) {
  check_radiometric_name(name);
  if (img.depth() != CV_8U || (img.channels() != 1 && img.channels() != 3 && img.channels() != 4))
    throw std::invalid_argument("apply_radiometric: expected an 8-bit 1/3/4-channel image");
  if (name == "gain") return apply_curve(img, [](double i) { return kRadioGain * i; });
  if (name == "gamma") return apply_curve(img, [](double i) { return 255.0 * std::pow(i / 255.0, kRadioGamma); });
  if (name == "mixed") return apply_mixed(img);
  if (name == "noise") return apply_noise(img, noise_seed);
  return img.clone();
}

}  // namespace fs::app
