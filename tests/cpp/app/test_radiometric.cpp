// Radiometric distortions on tiny images with hand-computed values.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "io.hpp"
#include "radiometric.hpp"

namespace {

using fs::app::apply_radiometric;

std::uint8_t round_sat(double v) { return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 255.0))); }

TEST(Radiometric, GainScalesAndRounds) {
  const cv::Mat img = (cv::Mat_<std::uint8_t>(1, 4) << 0, 10, 101, 255);
  const cv::Mat out = apply_radiometric(img, "gain");
  ASSERT_EQ(out.type(), CV_8UC1);
  EXPECT_EQ(out.at<std::uint8_t>(0), 0);
  EXPECT_EQ(out.at<std::uint8_t>(1), 6);
  EXPECT_EQ(out.at<std::uint8_t>(2), 61);  // 60.6
  EXPECT_EQ(out.at<std::uint8_t>(3), 153);
}

TEST(Radiometric, GammaKeepsEndpointsAndDarkensMidtones) {
  const cv::Mat img = (cv::Mat_<std::uint8_t>(1, 3) << 0, 128, 255);
  const cv::Mat out = apply_radiometric(img, "gamma");
  EXPECT_EQ(out.at<std::uint8_t>(0), 0);
  EXPECT_EQ(out.at<std::uint8_t>(1), round_sat(255.0 * std::pow(128.0 / 255.0, 1.3)));  // 104
  EXPECT_EQ(out.at<std::uint8_t>(2), 255);
}

TEST(Radiometric, ColourChannelsAreTreatedAlike) {
  const cv::Mat img(2, 2, CV_8UC3, cv::Scalar(50, 100, 200));
  const cv::Mat out = apply_radiometric(img, "gain");
  ASSERT_EQ(out.type(), CV_8UC3);
  EXPECT_EQ(out.at<cv::Vec3b>(1, 1), cv::Vec3b(30, 60, 120));
}

TEST(Radiometric, MixedToneCurveAndVignetting) {
  // 3x3: the centre pixel has no vignetting, the corners the full 25 %.
  const cv::Mat img(3, 3, CV_8UC1, cv::Scalar(100));
  const cv::Mat out = apply_radiometric(img, "mixed");
  const double tone = 255.0 * (0.03 + 1.15 * std::pow(100.0 / 255.0, 0.8));
  EXPECT_EQ(out.at<std::uint8_t>(1, 1), round_sat(tone));
  EXPECT_EQ(out.at<std::uint8_t>(0, 0), round_sat(tone * 0.75));
  EXPECT_EQ(out.at<std::uint8_t>(2, 2), round_sat(tone * 0.75));
  EXPECT_EQ(out.at<std::uint8_t>(0, 1), round_sat(tone * (1.0 - 0.25 * 0.5)));  // (r/rmax)^2 = 1/2
  // Bright values saturate (1.18 * 255 > 255 at the centre).
  const cv::Mat white(3, 3, CV_8UC1, cv::Scalar(255));
  EXPECT_EQ(apply_radiometric(white, "mixed").at<std::uint8_t>(1, 1), 255);
}

TEST(Radiometric, NoiseIsReproducibleZeroMeanWithSigma4) {
  const cv::Mat img(64, 64, CV_8UC3, cv::Scalar(128, 128, 128));
  const cv::Mat a = apply_radiometric(img, "noise");
  const cv::Mat b = apply_radiometric(img, "noise");
  ASSERT_EQ(a.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  cv::Mat diff;
  a.reshape(1).convertTo(diff, CV_64F);
  diff -= 128.0;
  cv::Scalar mean, stddev;
  cv::meanStdDev(diff, mean, stddev);
  EXPECT_NEAR(mean[0], 0.0, 0.3);
  EXPECT_NEAR(stddev[0], 4.0, 0.3);
  // Every channel is perturbed (not only the first).
  std::vector<cv::Mat> ch;
  cv::split(a, ch);
  for (const auto& c : ch) EXPECT_GT(cv::norm(c, cv::Mat(c.size(), CV_8U, cv::Scalar(128)), cv::NORM_INF), 0.0);
}

// eval --noise-seed: another seed is another field with the same statistics; the default is the fixed seed.
TEST(Radiometric, NoiseSeedDrawsAnotherFieldWithTheSameSigma) {
  const cv::Mat img(64, 64, CV_8UC1, cv::Scalar(128));
  const cv::Mat fixed = apply_radiometric(img, "noise");
  EXPECT_EQ(cv::norm(fixed, apply_radiometric(img, "noise", fs::app::kRadioNoiseSeed), cv::NORM_INF), 0.0);
  const cv::Mat other = apply_radiometric(img, "noise", 7);
  EXPECT_GT(cv::norm(fixed, other, cv::NORM_L1), 64.0 * 64.0);  // most pixels differ
  cv::Mat diff;
  other.convertTo(diff, CV_64F);
  diff -= 128.0;
  cv::Scalar mean, stddev;
  cv::meanStdDev(diff, mean, stddev);
  EXPECT_NEAR(mean[0], 0.0, 0.3);
  EXPECT_NEAR(stddev[0], 4.0, 0.3);
  // The other distortions ignore the seed.
  EXPECT_EQ(cv::norm(apply_radiometric(img, "gamma"), apply_radiometric(img, "gamma", 7), cv::NORM_INF), 0.0);
}

TEST(Radiometric, NoneIsACopyAndUnknownNamesAreRejected) {
  const cv::Mat img = (cv::Mat_<std::uint8_t>(1, 2) << 7, 9);
  EXPECT_EQ(cv::norm(apply_radiometric(img, "none"), img, cv::NORM_INF), 0.0);
  try {
    apply_radiometric(img, "sepia");
    FAIL() << "expected fs::UserError";
  } catch (const fs::UserError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("sepia"), std::string::npos);
    EXPECT_NE(msg.find("gain, gamma, mixed, noise"), std::string::npos);
  }
}

}  // namespace
