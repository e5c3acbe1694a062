// OpenCV StereoBM / StereoSGBM baselines (settings documented in baselines.hpp).
#include "baselines.hpp"

#include "io.hpp"

namespace fs::app {

const char* baseline_name(Baseline b) { return b == Baseline::BM ? "bm" : "sgbm"; }

std::vector<Baseline> parse_baselines(const std::vector<std::string>& names) {
  std::vector<Baseline> out;
  for (const auto& n : names) {
    Baseline b{};
    if (n == "bm") b = Baseline::BM;
    else if (n == "sgbm") b = Baseline::SGBM;
    else if (n.empty() || n == "none") continue;
    else throw UserError("unknown baseline '" + n + "' (valid: bm, sgbm)");
    bool dup = false;
    for (const Baseline o : out) dup = dup || o == b;
    if (!dup) out.push_back(b);
  }
  return out;
}

BaselineMatcher::BaselineMatcher(Baseline kind, int max_disparity) : kind_(kind) {
  // OpenCV requires numDisparities > 0 and divisible by 16; Frame::max_disparity always is.
  const int num_disp = (max_disparity + 15) / 16 * 16;
  if (kind == Baseline::BM) {
    constexpr int kBlock = 9;
    auto bm = cv::StereoBM::create(num_disp, kBlock);
    bm->setPreFilterCap(31);
    bm->setMinDisparity(0);
    bm->setTextureThreshold(10);
    bm->setUniquenessRatio(15);
    bm->setSpeckleWindowSize(100);
    bm->setSpeckleRange(32);
    bm->setDisp12MaxDiff(1);
    matcher_ = bm;
  } else {
    constexpr int kBlock = 5, kChannels = 1;
    matcher_ = cv::StereoSGBM::create(0, num_disp, kBlock, 8 * kChannels * kBlock * kBlock,
                                      32 * kChannels * kBlock * kBlock, /*disp12MaxDiff=*/1,
                                      /*preFilterCap=*/63, /*uniquenessRatio=*/10, /*speckleWindowSize=*/100,
                                      /*speckleRange=*/32, cv::StereoSGBM::MODE_SGBM_3WAY);
  }
}

cv::Mat BaselineMatcher::compute_raw(const cv::Mat& left_gray, const cv::Mat& right_gray) const {
  cv::Mat raw;
  matcher_->compute(left_gray, right_gray, raw);
  return raw;
}

cv::Mat BaselineMatcher::raw_to_float(const cv::Mat& raw16) {
  // StereoMatcher::DISP_SHIFT = 4; invalid = (minDisparity - 1) * 16 < 0.
  cv::Mat out(raw16.size(), CV_32F);
  for (int y = 0; y < raw16.rows; ++y) {
    const short* s = raw16.ptr<short>(y);
    float* d = out.ptr<float>(y);
    for (int x = 0; x < raw16.cols; ++x)
      d[x] = s[x] < 0 ? -1.0f : float(s[x]) / float(cv::StereoMatcher::DISP_SCALE);
  }
  return out;
}

cv::Mat BaselineMatcher::compute(const cv::Mat& left_gray, const cv::Mat& right_gray) const {
  return raw_to_float(compute_raw(left_gray, right_gray));
}

}  // namespace fs::app
