// Dataset discovery and ground-truth decoding on small synthetic copies of every layout, plus a
// check of the real datasets when they are present (skipped otherwise).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "dataset.hpp"
#include "io.hpp"

namespace {

namespace stdfs = std::filesystem;
using fs::app::Frame;
using fs::app::GtEncoding;

class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = stdfs::temp_directory_path() / ("fs_test_dataset_" + std::to_string(rd()) + std::to_string(rd()));
    stdfs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    stdfs::remove_all(path_, ec);
  }
  const stdfs::path& path() const { return path_; }

 private:
  stdfs::path path_;
};

void write(const stdfs::path& p, const cv::Mat& m) {
  stdfs::create_directories(p.parent_path());
  ASSERT_TRUE(cv::imwrite(p.string(), m)) << p;
}

void write_text(const stdfs::path& p, const std::string& s) {
  stdfs::create_directories(p.parent_path());
  std::ofstream(p) << s;
}

// PFM with rows bottom-to-top; little-endian when scale < 0.
void write_pfm(const stdfs::path& p, const cv::Mat& top_first, bool little_endian) {
  stdfs::create_directories(p.parent_path());
  std::ofstream out(p, std::ios::binary);
  out << "Pf\n" << top_first.cols << " " << top_first.rows << "\n" << (little_endian ? "-1.0" : "1.0") << "\n";
  for (int y = top_first.rows - 1; y >= 0; --y) {
    for (int x = 0; x < top_first.cols; ++x) {
      const float v = top_first.at<float>(y, x);
      unsigned char b[4];
      std::memcpy(b, &v, 4);
      if (!little_endian) {
        std::swap(b[0], b[3]);
        std::swap(b[1], b[2]);
      }
      out.write(reinterpret_cast<const char*>(b), 4);
    }
  }
}

cv::Mat grey(int w, int h) { return cv::Mat(h, w, CV_8UC1, cv::Scalar(100)); }
cv::Mat colour(int w, int h) { return cv::Mat(h, w, CV_8UC3, cv::Scalar(10, 20, 30)); }

// One GT pixel at (1, 1) with stored value `v`, the rest unknown.
template <class T>
cv::Mat gt_one(int w, int h, int type, T v) {
  cv::Mat m(h, w, type, cv::Scalar(0));
  m.at<T>(1, 1) = v;
  return m;
}

const char* kKitti2012Calib =
    "P0: 7.188560e+02 0.000000e+00 6.071928e+02 0.000000e+00 0.000000e+00 7.188560e+02 1.852157e+02 "
    "0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n"
    "P1: 7.188560e+02 0.000000e+00 6.071928e+02 -3.861448e+02 0.000000e+00 7.188560e+02 1.852157e+02 "
    "0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n"
    "P2: 7.188560e+02 0.000000e+00 6.071928e+02 4.538225e+01 0.000000e+00 7.188560e+02 1.852157e+02 "
    "-1.130887e-01 0.000000e+00 0.000000e+00 1.000000e+00 3.779761e-03\n"
    "P3: 7.188560e+02 0.000000e+00 6.071928e+02 -3.372877e+02 0.000000e+00 7.188560e+02 1.852157e+02 "
    "2.369057e+00 0.000000e+00 0.000000e+00 1.000000e+00 4.915215e-03\n";

const char* kKitti2015Calib =
    "P_rect_02: 7.215377e+02 0.000000e+00 6.095593e+02 4.485728e+01 0.000000e+00 7.215377e+02 1.728540e+02 "
    "2.163791e-01 0.000000e+00 0.000000e+00 1.000000e+00 2.745884e-03\n"
    "P_rect_03: 7.215377e+02 0.000000e+00 6.095593e+02 -3.395242e+02 0.000000e+00 7.215377e+02 1.728540e+02 "
    "2.199936e+00 0.000000e+00 0.000000e+00 1.000000e+00 2.729905e-03\n";

const char* kMidd2014Calib =
    "cam0=[999.421 0 294.182; 0 999.421 252.932; 0 0 1]\ncam1=[999.421 0 326.96; 0 999.421 252.932; 0 0 1]\n"
    "doffs=32.778\nbaseline=193.001\nwidth=741\nheight=497\nndisp=70\nisint=0\nvmin=7\nvmax=65\n";

// Builds every layout under root (tiny 8x6 images).
void build_all_layouts(const stdfs::path& root) {
  const int w = 8, h = 6;
  // KITTI 2015 (frame _11 is the flow partner and must be ignored)
  const auto k15 = root / "kitti2015" / "training";
  write(k15 / "image_2" / "000001_10.png", colour(w, h));
  write(k15 / "image_2" / "000001_11.png", colour(w, h));
  write(k15 / "image_3" / "000001_10.png", colour(w, h));
  write(k15 / "disp_occ_0" / "000001_10.png", gt_one<std::uint16_t>(w, h, CV_16UC1, 5 * 256 + 128));
  write_text(k15 / "calib_cam_to_cam" / "000001.txt", kKitti2015Calib);
  // KITTI 2012 with both colour and grey folders: colour wins
  const auto k12 = root / "kitti2012" / "training";
  write(k12 / "colored_0" / "000002_10.png", colour(w, h));
  write(k12 / "colored_1" / "000002_10.png", colour(w, h));
  write(k12 / "image_0" / "000002_10.png", grey(w, h));
  write(k12 / "image_1" / "000002_10.png", grey(w, h));
  write(k12 / "disp_occ" / "000002_10.png", gt_one<std::uint16_t>(w, h, CV_16UC1, 147 * 256));
  write(k12 / "disp_noc" / "000002_10.png", gt_one<std::uint16_t>(w, h, CV_16UC1, 147 * 256));
  write_text(k12 / "calib" / "000002.txt", kKitti2012Calib);
  // Middlebury 2001-3
  const auto m01 = root / "middlebury2001-3";
  write(m01 / "tsukuba" / "im3.png", colour(w, h));
  write(m01 / "tsukuba" / "im4.png", colour(w, h));
  write(m01 / "tsukuba" / "disp3.pgm", gt_one<std::uint8_t>(w, h, CV_8UC1, 48));
  write(m01 / "venus" / "im2.png", colour(w, h));
  write(m01 / "venus" / "im6.png", colour(w, h));
  write(m01 / "venus" / "disp2.pgm", gt_one<std::uint8_t>(w, h, CV_8UC1, 20));
  write(m01 / "teddy" / "im2.png", colour(w, h));
  write(m01 / "teddy" / "im6.png", colour(w, h));
  write(m01 / "teddy" / "disp2.png", gt_one<std::uint8_t>(w, h, CV_8UC1, 10));
  // Middlebury 2005-6
  for (const char* res : {"ThirdSize", "HalfSize"}) {
    const auto s = root / "middlebury2005-6" / res / "Aloe";
    write(s / "view1.png", colour(w, h));
    write(s / "view5.png", colour(w, h));
    write(s / "disp1.png", gt_one<std::uint8_t>(w, h, CV_8UC1, 30));
  }
  // Middlebury 2014
  const auto m14 = root / "middlebury2014" / "MiddEval3" / "trainingQ" / "Motorcycle";
  write(m14 / "im0.png", colour(w, h));
  write(m14 / "im1.png", colour(w, h));
  write_text(m14 / "calib.txt", kMidd2014Calib);
  cv::Mat pfm(h, w, CV_32F, cv::Scalar(std::numeric_limits<float>::infinity()));
  pfm.at<float>(1, 1) = 12.5f;
  write_pfm(m14 / "disp0GT.pfm", pfm, true);
  cv::Mat nocc(h, w, CV_8UC1, cv::Scalar(0));  // 255 non-occluded, 128 occluded, 0 no GT
  nocc.at<unsigned char>(1, 1) = 255;
  nocc.at<unsigned char>(2, 2) = 128;
  write(m14 / "mask0nocc.png", nocc);
}

const Frame& find(const std::vector<Frame>& frames, const std::string& set, const std::string& name) {
  for (const auto& f : frames)
    if (f.set == set && f.name == name) return f;
  ADD_FAILURE() << "frame " << set << "/" << name << " not found";
  static const Frame kNone;
  return kNone;
}

// GT decodes to `v` at (1, 1) and 0 everywhere else.
void expect_gt(const Frame& f, float v) {
  const cv::Mat gt = fs::app::load_ground_truth(f);
  ASSERT_EQ(gt.type(), CV_32FC1) << f.name;
  EXPECT_FLOAT_EQ(gt.at<float>(1, 1), v) << f.set << "/" << f.name;
  EXPECT_EQ(cv::countNonZero(gt), 1) << f.set << "/" << f.name;
}

TEST(Dataset, DiscoversEveryLayoutWithScalesAndRanges) {
  TempDir tmp;
  build_all_layouts(tmp.path());
  const auto frames = fs::app::discover_dataset(tmp.path().string());
  ASSERT_EQ(frames.size(), 8u);
  // sorted by (set, name)
  for (std::size_t i = 1; i < frames.size(); ++i)
    EXPECT_LE(frames[i - 1].set + "/" + frames[i - 1].name, frames[i].set + "/" + frames[i].name);

  const Frame& k15 = find(frames, "kitti2015", "000001");
  EXPECT_EQ(k15.max_disparity, 160);
  EXPECT_NE(k15.left_path.find("image_2"), std::string::npos);
  EXPECT_NE(k15.right_path.find("image_3"), std::string::npos);
  expect_gt(k15, 5.5f);
  EXPECT_TRUE(k15.calib.valid);
  EXPECT_NEAR(k15.calib.focal_px, 721.5377, 1e-4);
  EXPECT_NEAR(k15.calib.baseline_m, (44.85728 + 339.5242) / 721.5377, 1e-6);

  const Frame& k12 = find(frames, "kitti2012", "000002");
  EXPECT_EQ(k12.max_disparity, 160);
  EXPECT_NE(k12.left_path.find("colored_0"), std::string::npos);
  expect_gt(k12, 147.0f);
  EXPECT_NEAR(k12.calib.baseline_m, (45.38225 + 337.2877) / 718.856, 1e-6);  // P2/P3 for colour

  expect_gt(find(frames, "middlebury2001-3", "tsukuba"), 3.0f);
  EXPECT_EQ(find(frames, "middlebury2001-3", "tsukuba").max_disparity, 16);
  expect_gt(find(frames, "middlebury2001-3", "venus"), 2.5f);
  EXPECT_EQ(find(frames, "middlebury2001-3", "venus").max_disparity, 32);
  expect_gt(find(frames, "middlebury2001-3", "teddy"), 2.5f);
  EXPECT_EQ(find(frames, "middlebury2001-3", "teddy").max_disparity, 64);

  expect_gt(find(frames, "middlebury2006-third", "Aloe"), 10.0f);
  EXPECT_EQ(find(frames, "middlebury2006-third", "Aloe").max_disparity, 80);
  expect_gt(find(frames, "middlebury2006-half", "Aloe"), 15.0f);
  EXPECT_EQ(find(frames, "middlebury2006-half", "Aloe").max_disparity, 128);

  const Frame& m14 = find(frames, "middlebury2014-Q", "Motorcycle");
  EXPECT_EQ(m14.max_disparity, 80);  // ndisp 70 rounded up to 16
  EXPECT_EQ(m14.gt_encoding, GtEncoding::Pfm);
  expect_gt(m14, 12.5f);  // inf -> 0
  EXPECT_NEAR(m14.calib.baseline_m, 0.193001, 1e-9);
  EXPECT_NEAR(m14.calib.focal_px, 999.421, 1e-9);
  EXPECT_NEAR(m14.calib.doffs_px, 32.778, 1e-9);
}

// The non-occluded evaluation area where a set ships it (KITTI disp_noc, MiddEval3 mask0nocc), as a
// 0 / 255 mask; none elsewhere; an unreadable one is a user error naming the file.
TEST(Dataset, NonOccludedMasksWhereTheSetShipsThem) {
  TempDir tmp;
  build_all_layouts(tmp.path());
  const auto frames = fs::app::discover_dataset(tmp.path().string());
  for (const auto& f : frames) {
    const bool expected = f.set == "kitti2012" || f.set == "middlebury2014-Q";
    EXPECT_EQ(f.has_noc(), expected) << f.set << "/" << f.name;
    if (!f.has_noc()) {
      EXPECT_THROW(fs::app::load_nonoccluded_mask(f), fs::UserError) << f.set;
      continue;
    }
    const cv::Mat m = fs::app::load_nonoccluded_mask(f);
    ASSERT_EQ(m.type(), CV_8UC1) << f.set;
    EXPECT_EQ(m.at<unsigned char>(1, 1), 255) << f.set;
    EXPECT_EQ(cv::countNonZero(m), 1) << f.set << ": occluded (128) and unknown (0) pixels are outside";
  }
  Frame bad = find(frames, "middlebury2014-Q", "Motorcycle");
  bad.noc_path = (tmp.path() / "missing.png").string();
  try {
    fs::app::load_nonoccluded_mask(bad);
    ADD_FAILURE() << "no error for a missing mask";
  } catch (const fs::UserError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.png"), std::string::npos) << e.what();
  }
}

TEST(Dataset, AcceptsOneSetOrOneSceneFolder) {
  TempDir tmp;
  build_all_layouts(tmp.path());
  const auto k12 = fs::app::discover_dataset((tmp.path() / "kitti2012").string());
  ASSERT_EQ(k12.size(), 1u);
  EXPECT_EQ(k12[0].set, "kitti2012");
  const auto aloe = fs::app::discover_dataset((tmp.path() / "middlebury2005-6" / "HalfSize" / "Aloe").string());
  ASSERT_EQ(aloe.size(), 1u);
  EXPECT_EQ(aloe[0].set, "middlebury2006-half");
  const auto motor =
      fs::app::discover_dataset((tmp.path() / "middlebury2014" / "MiddEval3" / "trainingQ" / "Motorcycle").string());
  ASSERT_EQ(motor.size(), 1u);
  EXPECT_EQ(motor[0].set, "middlebury2014-Q");
}

// `fuzzystereo sim generate` layout: KITTI 2015 folders under training/ plus the marker, which
// makes the set "synthetic" with the marker's search range — from the root, the training/ folder
// or a parent; a bad marker is a user error naming it.
TEST(Dataset, SyntheticSetFromMarker) {
  TempDir tmp;
  const auto root = tmp.path() / "sim";
  const auto tr = root / "training";
  write(tr / "image_2" / "000000_10.png", colour(8, 6));
  write(tr / "image_3" / "000000_10.png", colour(8, 6));
  write(tr / "disp_occ_0" / "000000_10.png", gt_one<std::uint16_t>(8, 6, CV_16UC1, 3 * 256));
  write_text(tr / "calib_cam_to_cam" / "000000.txt",
             "P_rect_02: 420 0 319.5 0 0 420 179.5 0 0 0 1 0\nP_rect_03: 420 0 319.5 -50.4 0 420 179.5 0 0 0 1 0\n");
  write_text(root / "fuzzystereo_sim.json", R"({"format": "fuzzystereo-sim", "count": 1, "max_disparity": 80})");
  for (const auto& dir : {tmp.path(), root, tr}) {
    const auto frames = fs::app::discover_dataset(dir.string());
    ASSERT_EQ(frames.size(), 1u) << dir;
    EXPECT_EQ(frames[0].set, "synthetic") << dir;
    EXPECT_EQ(frames[0].max_disparity, 80);
    EXPECT_NEAR(frames[0].calib.baseline_m, 0.12, 1e-12);
    expect_gt(frames[0], 3.0f);
  }
  write_text(root / "fuzzystereo_sim.json", R"({"count": 1, "max_disparity": 70})");
  try {
    fs::app::discover_dataset(root.string());
    FAIL() << "expected fs::UserError";
  } catch (const fs::UserError& e) {
    EXPECT_NE(std::string(e.what()).find("max_disparity = 70"), std::string::npos) << e.what();
  }
  write_text(root / "fuzzystereo_sim.json", "{ not json");
  EXPECT_THROW(fs::app::discover_dataset(root.string()), fs::UserError);
}

TEST(Dataset, KittiGreyFallbackWithoutColourFolders) {
  TempDir tmp;
  const auto k12 = tmp.path() / "training";
  write(k12 / "image_0" / "000003_10.png", grey(8, 6));
  write(k12 / "image_1" / "000003_10.png", grey(8, 6));
  write_text(k12 / "calib" / "000003.txt", kKitti2012Calib);
  const auto frames = fs::app::discover_dataset(tmp.path().string());
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_NE(frames[0].left_path.find("image_0"), std::string::npos);
  EXPECT_FALSE(frames[0].has_gt());
  EXPECT_NEAR(frames[0].calib.baseline_m, 386.1448 / 718.856, 1e-6);  // P0/P1 for grey
  EXPECT_THROW(fs::app::load_ground_truth(frames[0]), fs::UserError);
}

TEST(Dataset, UnknownLayoutAndMissingDirectoryAreUserErrors) {
  TempDir tmp;
  write_text(tmp.path() / "notes" / "readme.txt", "nothing here");
  try {
    fs::app::discover_dataset(tmp.path().string());
    FAIL() << "expected fs::UserError";
  } catch (const fs::UserError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(tmp.path().string()), std::string::npos);
    EXPECT_NE(msg.find("KITTI 2012"), std::string::npos);
    EXPECT_NE(msg.find("Middlebury 2014"), std::string::npos);
    EXPECT_EQ(msg.find('\n'), std::string::npos);
  }
  EXPECT_THROW(fs::app::discover_dataset((tmp.path() / "missing").string()), fs::UserError);
}

TEST(Dataset, SizeMismatchNamesBothFiles) {
  TempDir tmp;
  const auto d = tmp.path() / "venus";
  write(d / "im2.png", colour(8, 6));
  write(d / "im6.png", colour(9, 6));
  write(d / "disp2.pgm", gt_one<std::uint8_t>(8, 6, CV_8UC1, 8));
  const auto frames = fs::app::discover_dataset(tmp.path().string());
  ASSERT_EQ(frames.size(), 1u);
  try {
    fs::app::read_frame_images(frames[0]);
    FAIL() << "expected fs::UserError";
  } catch (const fs::UserError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("im2.png"), std::string::npos);
    EXPECT_NE(msg.find("im6.png"), std::string::npos);
  }
}

TEST(Dataset, PfmBothEndiannessesAndFlip) {
  TempDir tmp;
  const cv::Mat m = (cv::Mat_<float>(2, 3) << 1, 2, 3, 4, 5, std::numeric_limits<float>::infinity());
  for (const bool le : {true, false}) {
    const auto p = tmp.path() / (le ? "le.pfm" : "be.pfm");
    write_pfm(p, m, le);
    const cv::Mat r = fs::app::read_pfm(p.string());
    ASSERT_EQ(r.size(), m.size());
    EXPECT_FLOAT_EQ(r.at<float>(0, 0), 1.0f);
    EXPECT_FLOAT_EQ(r.at<float>(1, 1), 5.0f);
    EXPECT_TRUE(std::isinf(r.at<float>(1, 2)));
  }
  write_text(tmp.path() / "bad.pfm", "P5\n2 2\n255\n");
  EXPECT_THROW(fs::app::read_pfm((tmp.path() / "bad.pfm").string()), fs::UserError);
  write_text(tmp.path() / "short.pfm", "Pf\n4 4\n-1.0\nabc");
  EXPECT_THROW(fs::app::read_pfm((tmp.path() / "short.pfm").string()), fs::UserError);
}

TEST(Dataset, RoundUp16) {
  EXPECT_EQ(fs::app::round_up_16(70), 80);
  EXPECT_EQ(fs::app::round_up_16(64), 64);
  EXPECT_EQ(fs::app::round_up_16(1), 16);
  EXPECT_EQ(fs::app::round_up_16(0), 16);
}

// The shared copies described in datasets/SOURCES.md, when present next to the repository.
TEST(Dataset, RealDatasetsWhenPresent) {
  const char* env = std::getenv("FUZZYSTEREO_DATASETS");
  const stdfs::path dir = (env != nullptr && *env != '\0')
                              ? stdfs::path(env)
                              : stdfs::path(__FILE__).parent_path() / ".." / ".." / ".." / ".." / "shared" / "datasets";
  if (!stdfs::is_directory(dir / "kitti2012")) GTEST_SKIP() << "no datasets at " << dir;
  const auto frames = fs::app::discover_dataset(dir.string());
  EXPECT_GE(frames.size(), 27u);
  for (const auto& f : frames) {
    ASSERT_TRUE(f.has_gt()) << f.set << "/" << f.name;
    const cv::Mat gt = fs::app::load_ground_truth(f);
    double mx = 0;
    cv::minMaxLoc(gt, nullptr, &mx);
    EXPECT_GT(mx, 0.0) << f.set << "/" << f.name;
    EXPECT_LT(mx, f.max_disparity) << f.set << "/" << f.name << ": range does not cover the GT";
  }
  const Frame& k12 = find(frames, "kitti2012", "000070");
  double mx = 0;
  cv::minMaxLoc(fs::app::load_ground_truth(k12), nullptr, &mx);
  EXPECT_NEAR(mx, 147.0, 0.05);  // SOURCES.md: disp_occ max 147.0 px
  // SOURCES.md: disp_noc 28.8 % valid (disp_occ 29.4 %); every non-occluded pixel has GT.
  ASSERT_TRUE(k12.has_noc());
  const cv::Mat noc = fs::app::load_nonoccluded_mask(k12);
  EXPECT_NEAR(100.0 * cv::countNonZero(noc) / double(noc.total()), 28.8, 0.1);
  EXPECT_EQ(cv::countNonZero(noc & (fs::app::load_ground_truth(k12) == 0.0f)), 0);
}

}  // namespace
