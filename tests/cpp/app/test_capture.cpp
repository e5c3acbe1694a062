// fs_capture: source strings, timestamp pairing, replay (order, ids, pacing with an injected clock,
// end of stream, loop, recorded timestamps), KITTI replay through the app's dataset hook, the
// Rectifier on a synthetic calibrated pair, and the clear errors of every backend.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "camera_source.hpp"
#include "dataset.hpp"
#include "fuzzystereo/capture/camera.hpp"
#include "fuzzystereo/capture/rectifier.hpp"
#include "fuzzystereo/capture/replay.hpp"
#include "fuzzystereo/capture/sync.hpp"

namespace stdfs = std::filesystem;
using namespace fs::capture;

namespace {

// A fresh temporary folder per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = stdfs::temp_directory_path() / ("fs_capture_" + std::string(info->test_suite_name()) + "_" + info->name() +
                                            "_" + std::to_string(std::random_device{}()));
    stdfs::create_directories(path_);
  }
  ~TempDir() { stdfs::remove_all(path_); }
  const stdfs::path& path() const { return path_; }

 private:
  stdfs::path path_;
};

// Image whose pixels all hold `v` (left) or `v + 100` (right), so a frame's origin is readable.
cv::Mat marked(int v, int w = 24, int h = 16) { return cv::Mat(h, w, CV_8UC3, cv::Scalar(v, v, v)); }
int mark_of(const cv::Mat& m) { return m.at<cv::Vec3b>(0, 0)[0]; }

void write_png(const stdfs::path& p, const cv::Mat& m) {
  stdfs::create_directories(p.parent_path());
  ASSERT_TRUE(cv::imwrite(p.string(), m)) << p;
}

// Fake clock: sleep_until advances time; every sleep is recorded.
struct FakeClock {
  std::int64_t t = 1'000'000'000;
  std::vector<std::int64_t> sleeps;
  Clock clock() {
    Clock c;
    c.now_ns = [this] { return t; };
    c.sleep_until_ns = [this](std::int64_t until) {
      sleeps.push_back(until);
      if (until > t) t = until;
    };
    return c;
  }
};

template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const CaptureError& e) {
    return e.what();
  }
  return "<no error>";
}

}  // namespace

// ---- source strings -----------------------------------------------------------------------------

TEST(CaptureSource, ParsesEveryKind) {
  auto s = parse_source("replay:/data/run 1");
  EXPECT_EQ(s.kind, SourceKind::Replay);
  EXPECT_EQ(s.devices, std::vector<std::string>{"/data/run 1"});
  s = parse_source("uvc:/dev/video0");
  EXPECT_EQ(s.kind, SourceKind::Uvc);
  EXPECT_EQ(s.devices.size(), 1u);
  s = parse_source("uvc:/dev/video0,/dev/video2");
  EXPECT_EQ(s.devices, (std::vector<std::string>{"/dev/video0", "/dev/video2"}));
  s = parse_source("libcamera");
  EXPECT_EQ(s.kind, SourceKind::Libcamera);
  EXPECT_TRUE(s.devices.empty());
  s = parse_source("libcamera:/base/a@10,/base/b@10");
  EXPECT_EQ(s.devices.size(), 2u);
  EXPECT_EQ(parse_source("oakd").kind, SourceKind::Oakd);
  EXPECT_TRUE(parse_source("oakd").devices.empty());
  EXPECT_EQ(parse_source("oakd:14442C10D13EABCE00").devices, std::vector<std::string>{"14442C10D13EABCE00"});
  EXPECT_EQ(parse_source("sim").kind, SourceKind::Sim);
  EXPECT_EQ(parse_source("sim:corridor").devices, std::vector<std::string>{"corridor"});
}

TEST(CaptureSource, MalformedStringsNameTheProblem) {
  const std::pair<const char*, const char*> cases[] = {
      {"", "empty"},
      {"webcam:0", "unknown kind 'webcam'"},
      {"replay:", "needs a folder"},
      {"replay", "needs a folder"},
      {"uvc:", "needs a device"},
      {"uvc:/dev/video0,", "empty device name"},
      {"uvc:a,b,c", "got 3"},
      {"uvc:/dev/video0,/dev/video0", "same device"},
      {"libcamera:only_one", "two camera ids"},
      {"libcamera:a,a", "same camera"},
      {"oakd:", "empty device id"},
  };
  for (const auto& [text, why] : cases) {
    const std::string e = error_of([&] { parse_source(text); });
    EXPECT_NE(e.find(why), std::string::npos) << text << " -> " << e;
    EXPECT_NE(e.find("valid sources: replay:DIR"), std::string::npos) << e;
  }
}

TEST(CaptureSource, ParamsFromDefaultConfig) {
  const fs::Config cfg = fs::parse_config("[camera]\nwidth = 1280\nreplay_loop = true\ncalibration = \"c.yml\"\n", "t.toml");
  const CameraParams p = camera_params_from(cfg.values);
  EXPECT_EQ(p.width, 1280);
  EXPECT_EQ(p.height, 480);
  EXPECT_TRUE(p.replay_loop);
  EXPECT_EQ(p.calibration, "c.yml");
  EXPECT_EQ(p.libcamera_format, "auto");
  EXPECT_THROW(fs::parse_config("[camera]\nlibcamera_format = \"NV12\"\n", "t.toml"), fs::ConfigError);
}

// ---- timestamp pairing --------------------------------------------------------------------------

TEST(CaptureSync, PairsWithinToleranceAndDropsTheOlderUnmatched) {
  TimestampPairer<int> p(2'000'000);  // 2 ms
  // Right runs 1 ms behind left; right frame 2 is lost; left frame 4 is lost.
  std::vector<std::pair<int, int>> got;
  for (int i = 0; i < 6; ++i) {  // frames arrive at 30 Hz; the consumer pops after each arrival
    if (i != 4) p.push_left(i * 33'000'000, i);
    if (i != 2) p.push_right(i * 33'000'000 + 1'000'000, 100 + i);
    while (auto pr = p.pop()) got.emplace_back(pr->left, pr->right);
  }
  EXPECT_EQ(got, (std::vector<std::pair<int, int>>{{0, 100}, {1, 101}, {3, 103}, {5, 105}}));
  auto dropped = p.take_dropped();
  std::sort(dropped.begin(), dropped.end());
  EXPECT_EQ(dropped, (std::vector<int>{2, 104}));
  EXPECT_TRUE(p.take_dropped().empty());
}

TEST(CaptureSync, WaitsForAPartnerThatMayStillCome) {
  TimestampPairer<int> p(2'000'000);
  p.push_left(10'000'000, 1);
  EXPECT_FALSE(p.pop());  // no right frame yet: keep the left one
  p.push_right(11'500'000, 2);
  auto pr = p.pop();
  ASSERT_TRUE(pr);
  EXPECT_EQ(pr->left_ns, 10'000'000);
  EXPECT_EQ(pr->right_ns, 11'500'000);
  EXPECT_EQ(p.dropped_count(), 0u);
}

TEST(CaptureSync, BoundedQueues) {
  TimestampPairer<int> p(1'000'000, 3);
  for (int i = 0; i < 10; ++i) p.push_left(i * 1'000'000'000LL, i);  // right camera silent
  EXPECT_EQ(p.pending_left(), 3u);
  EXPECT_EQ(p.take_dropped(), (std::vector<int>{0, 1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(p.drain().size(), 3u);
}

// ---- replay -------------------------------------------------------------------------------------

TEST(CaptureReplay, LeftRightFoldersInOrderThenEndOfStream) {
  TempDir d;
  for (int i : {0, 1, 2, 3}) {
    char name[16];
    std::snprintf(name, sizeof name, "%06d.png", i);
    write_png(d.path() / "left" / name, marked(10 + i));
    write_png(d.path() / "right" / name, marked(110 + i));
  }
  FakeClock fc;
  ReplayCamera cam("replay:" + d.path().string(), discover_image_sequence(d.path().string()), {0.0, false}, fc.clock());
  cam.start();
  StereoFrame f;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(cam.grab(f));
    EXPECT_EQ(f.frame_id, std::uint64_t(i));
    EXPECT_EQ(mark_of(f.left), 10 + i);
    EXPECT_EQ(mark_of(f.right), 110 + i);
    EXPECT_EQ(f.left.type(), CV_8UC3);
    EXPECT_EQ(f.timestamp_ns, fc.t);  // no timestamps.csv: the clock at release
    EXPECT_EQ(f.source, "replay:" + d.path().string());
  }
  EXPECT_FALSE(cam.grab(f));
  EXPECT_FALSE(cam.grab(f));
  EXPECT_TRUE(fc.sleeps.empty());  // rate 0: never sleeps
  EXPECT_EQ(cam.stats().pairs, 4u);
  cam.start();  // starts again from the first pair
  ASSERT_TRUE(cam.grab(f));
  EXPECT_EQ(f.frame_id, 0u);
  EXPECT_EQ(mark_of(f.left), 10);
}

TEST(CaptureReplay, SuffixLayoutInNaturalOrderAndLoop) {
  TempDir d;
  for (int i : {10, 2, 1}) {
    write_png(d.path() / ("img" + std::to_string(i) + "_left.png"), marked(i));
    write_png(d.path() / ("img" + std::to_string(i) + "_right.png"), marked(100 + i));
  }
  FakeClock fc;
  ReplayCamera cam("replay", discover_image_sequence(d.path().string()), {0.0, true}, fc.clock());
  cam.start();
  StereoFrame f;
  std::vector<int> marks;
  for (int i = 0; i < 7; ++i) {
    ASSERT_TRUE(cam.grab(f));
    EXPECT_EQ(f.frame_id, std::uint64_t(i));
    EXPECT_EQ(mark_of(f.right), 100 + mark_of(f.left));
    marks.push_back(mark_of(f.left));
  }
  EXPECT_EQ(marks, (std::vector<int>{1, 2, 10, 1, 2, 10, 1}));
}

TEST(CaptureReplay, KittiImage2Image3Folders) {
  TempDir d;
  write_png(d.path() / "image_2" / "000001.png", marked(1));
  write_png(d.path() / "image_3" / "000001.png", marked(101));
  write_png(d.path() / "image_2" / "000000.png", marked(0));
  write_png(d.path() / "image_3" / "000000.png", marked(100));
  const auto pairs = discover_image_sequence(d.path().string());
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_NE(pairs[0].left.find("image_2/000000.png"), std::string::npos);
  EXPECT_NE(pairs[0].right.find("image_3/000000.png"), std::string::npos);
}

TEST(CaptureReplay, RatePacingWithInjectedClock) {
  TempDir d;
  for (int i = 0; i < 3; ++i) {
    write_png(d.path() / "left" / (std::to_string(i) + ".png"), marked(i));
    write_png(d.path() / "right" / (std::to_string(i) + ".png"), marked(100 + i));
  }
  FakeClock fc;
  const std::int64_t t0 = fc.t;
  ReplayCamera cam("r", discover_image_sequence(d.path().string()), {10.0, true}, fc.clock());  // 10 Hz
  cam.start();
  StereoFrame f;
  std::vector<std::int64_t> stamps;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(cam.grab(f));
    stamps.push_back(f.timestamp_ns - t0);
    fc.t += 20'000'000;  // the consumer works 20 ms per pair
  }
  EXPECT_EQ(stamps, (std::vector<std::int64_t>{0, 100'000'000, 200'000'000, 300'000'000}));
  EXPECT_EQ(fc.sleeps.size(), 3u);  // first pair due immediately
  // A consumer 350 ms late: released at once (no sleep), then paced from there (no catch-up burst).
  fc.t += 350'000'000;
  const std::size_t sleeps_before = fc.sleeps.size();
  ASSERT_TRUE(cam.grab(f));
  EXPECT_EQ(fc.sleeps.size(), sleeps_before);
  const std::int64_t late = f.timestamp_ns;
  ASSERT_TRUE(cam.grab(f));
  EXPECT_EQ(f.timestamp_ns - late, 100'000'000);
}

TEST(CaptureReplay, RecordedTimestampsAndLoopShift) {
  TempDir d;
  std::ofstream csv(d.path() / "timestamps.csv");
  csv << "frame,timestamp_ns,left,right\n";
  for (int i = 0; i < 3; ++i) {
    const std::string n = std::to_string(i) + ".png";
    write_png(d.path() / "left" / n, marked(i));
    write_png(d.path() / "right" / n, marked(100 + i));
    csv << i << "," << 5'000 + i * 1'000 << ",left/" << n << ",right/" << n << "\n";
  }
  csv.close();
  FakeClock fc;
  ReplayCamera cam("r", discover_image_sequence(d.path().string()), {0.0, true}, fc.clock());
  cam.start();
  StereoFrame f;
  std::vector<std::int64_t> ts;
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(cam.grab(f));
    ts.push_back(f.timestamp_ns);
  }
  // Span 2000 ns + one mean interval 1000 ns per loop.
  EXPECT_EQ(ts, (std::vector<std::int64_t>{5'000, 6'000, 7'000, 8'000, 9'000}));
}

TEST(CaptureReplay, BadSequencesNameTheFile) {
  TempDir d;
  write_png(d.path() / "left" / "0.png", marked(0));
  write_png(d.path() / "right" / "0.png", marked(100));
  write_png(d.path() / "left" / "1.png", marked(1));
  EXPECT_NE(error_of([&] { discover_image_sequence(d.path().string()); }).find("1.png' has no partner"), std::string::npos);
  stdfs::remove(d.path() / "left" / "1.png");

  std::ofstream(d.path() / "timestamps.csv") << "frame,timestamp_ns,left,right\n0,abc,left/0.png,right/0.png\n";
  const std::string e = error_of([&] { discover_image_sequence(d.path().string()); });
  EXPECT_NE(e.find("timestamps.csv' line 2"), std::string::npos) << e;
  stdfs::remove(d.path() / "timestamps.csv");

  // Unreadable image: grab names it.
  std::ofstream(d.path() / "right" / "0.png") << "not a png";
  FakeClock fc;  // outlives the camera (its clock refers to it)
  ReplayCamera cam("r", discover_image_sequence(d.path().string()), {}, fc.clock());
  cam.start();
  StereoFrame f;
  EXPECT_NE(error_of([&] { cam.grab(f); }).find("right/0.png"), std::string::npos);

  EXPECT_NE(error_of([&] { discover_image_sequence((d.path() / "nope").string()); }).find("is not a directory"),
            std::string::npos);
  TempDir empty;
  const std::string e2 = error_of([&] { open_camera(parse_source("replay:" + empty.path().string()), {}); });
  EXPECT_NE(e2.find("no stereo pairs"), std::string::npos) << e2;
}

TEST(CaptureReplay, KittiDatasetThroughTheAppHook) {
  // Same rule as the other dataset tests: FUZZYSTEREO_DATASETS, else <repo>/../shared/datasets.
  const char* env = std::getenv("FUZZYSTEREO_DATASETS");
  const stdfs::path root = (env != nullptr && *env != '\0')
                               ? stdfs::path(env)
                               : stdfs::path(__FILE__).parent_path() / ".." / ".." / ".." / ".." / "shared" / "datasets";
  const stdfs::path kitti = root / "kitti2015";
  if (!stdfs::is_directory(kitti)) GTEST_SKIP() << "KITTI 2015 not found at " << kitti << " (set FUZZYSTEREO_DATASETS)";
  const auto frames = fs::app::discover_dataset(kitti.string());
  ASSERT_FALSE(frames.empty());
  auto cam = fs::app::open_stereo_source("replay:" + kitti.string(), CameraParams{});
  cam->start();
  StereoFrame f;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    ASSERT_TRUE(cam->grab(f));
    const auto imgs = fs::app::read_frame_images(frames[i]);
    ASSERT_EQ(f.left.size(), imgs.left.size());
    EXPECT_EQ(cv::norm(f.left, imgs.left, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(f.right, imgs.right, cv::NORM_INF), 0.0);
  }
  EXPECT_FALSE(cam->grab(f));
}

// ---- rectifier ----------------------------------------------------------------------------------

namespace {

struct SyntheticRig {
  cv::Size size{640, 480};
  cv::Mat K1 = (cv::Mat_<double>(3, 3) << 700, 0, 330, 0, 705, 245, 0, 0, 1);
  cv::Mat D1 = (cv::Mat_<double>(1, 5) << -0.12, 0.05, 0.001, -0.0005, 0.0);
  cv::Mat K2 = (cv::Mat_<double>(3, 3) << 690, 0, 315, 0, 695, 238, 0, 0, 1);
  cv::Mat D2 = (cv::Mat_<double>(1, 5) << -0.10, 0.03, -0.0008, 0.0006, 0.0);
  cv::Mat rvec = (cv::Mat_<double>(3, 1) << 0.01, -0.03, 0.008);
  cv::Mat T = (cv::Mat_<double>(3, 1) << -0.12, 0.003, -0.002);
  cv::Mat R() const {
    cv::Mat r;
    cv::Rodrigues(rvec, r);
    return r;
  }
};

void write_calib(const stdfs::path& p, const SyntheticRig& rig, const std::string& skip = "", bool mm = false) {
  cv::FileStorage f(p.string(), cv::FileStorage::WRITE);
  if (skip != "image_size") f << "image_width" << rig.size.width << "image_height" << rig.size.height;
  if (skip != "K1") f << "K1" << rig.K1;
  f << "D1" << (skip == "D1" ? cv::Mat(cv::Mat::zeros(1, 3, CV_64F)) : rig.D1);
  f << "K2" << rig.K2 << "D2" << rig.D2 << "R" << rig.R() << "T" << (mm ? cv::Mat(rig.T * 1000.0) : rig.T);
}

// Grey image with a Gaussian blob (sigma 1.6 px) at each point.
cv::Mat render_blobs(const std::vector<cv::Point2f>& pts, cv::Size size) {
  cv::Mat img(size, CV_32F, cv::Scalar(20));
  for (const auto& p : pts)
    for (int y = int(p.y) - 6; y <= int(p.y) + 6; ++y)
      for (int x = int(p.x) - 6; x <= int(p.x) + 6; ++x)
        if (x >= 0 && y >= 0 && x < size.width && y < size.height)
          img.at<float>(y, x) += 200.f * std::exp(-((float(x) - p.x) * (float(x) - p.x) + (float(y) - p.y) * (float(y) - p.y)) /
                                                  (2 * 1.6f * 1.6f));
  cv::Mat out;
  img.convertTo(out, CV_8U);
  return out;
}

// Intensity centroid (background removed) around the brightest pixel within +-6 px of `guess`.
cv::Point2d find_blob(const cv::Mat& img, cv::Point2f guess) {
  cv::Point best(int(guess.x + 0.5f), int(guess.y + 0.5f));
  int best_v = -1;
  for (int y = int(guess.y) - 6; y <= int(guess.y) + 6; ++y)
    for (int x = int(guess.x) - 6; x <= int(guess.x) + 6; ++x)
      if (img.at<std::uint8_t>(y, x) > best_v) best_v = img.at<std::uint8_t>(y, x), best = {x, y};
  double sw = 0, sx = 0, sy = 0;
  for (int y = best.y - 4; y <= best.y + 4; ++y)
    for (int x = best.x - 4; x <= best.x + 4; ++x) {
      const double w = std::max(0, img.at<std::uint8_t>(y, x) - 20);
      sw += w, sx += w * x, sy += w * y;
    }
  return {sx / sw, sy / sw};
}

}  // namespace

TEST(CaptureRectifier, SyntheticRigRowsAlignAndDepthMatches) {
  SyntheticRig rig;
  TempDir d;
  write_calib(d.path() / "calib.yml", rig);
  const Rectifier rect = Rectifier::from_file((d.path() / "calib.yml").string());
  ASSERT_TRUE(rect.remaps());
  EXPECT_NEAR(rect.calib().baseline_m, cv::norm(rig.T), 1e-9);
  EXPECT_NEAR(rect.calib().focal_px, rect.P1().at<double>(0, 0), 1e-12);
  EXPECT_GT(rect.calib().focal_px, 500.0);

  // Points in the left camera frame at 1.5 .. 4.2 m, projected through each real (distorted) camera.
  std::vector<cv::Point3f> X;
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 8; ++c) {
      const float z = 1.5f + float((r * 8 + c) * 7 % 10) * 0.3f;
      X.emplace_back((-0.32f + 0.09f * float(c)) * z, (-0.22f + 0.085f * float(r)) * z, z);
    }
  std::vector<cv::Point2f> pl, pr;
  cv::projectPoints(X, cv::Mat::zeros(3, 1, CV_64F), cv::Mat::zeros(3, 1, CV_64F), rig.K1, rig.D1, pl);
  cv::projectPoints(X, rig.rvec, rig.T, rig.K2, rig.D2, pr);
  // Raw images are NOT row-aligned (so the check below can fail).
  double raw_max_dy = 0;
  for (std::size_t i = 0; i < pl.size(); ++i) raw_max_dy = std::max(raw_max_dy, double(std::abs(pl[i].y - pr[i].y)));
  EXPECT_GT(raw_max_dy, 2.0);

  StereoFrame f;
  f.left = render_blobs(pl, rig.size);
  f.right = render_blobs(pr, rig.size);
  f.source = "synthetic";
  rect.apply(f);
  ASSERT_EQ(f.left.size(), rig.size);

  std::vector<cv::Point2f> el, er;  // where rectification should put each blob
  cv::undistortPoints(pl, el, rig.K1, rig.D1, rect.R1(), rect.P1());
  cv::undistortPoints(pr, er, rig.K2, rig.D2, rect.R2(), rect.P2());
  cv::Mat R1 = rect.R1();
  int used = 0;
  double max_dy = 0, max_rel_z = 0;
  for (std::size_t i = 0; i < X.size(); ++i) {
    const auto in = [&](cv::Point2f p) {
      return p.x > 12 && p.y > 12 && p.x < float(rig.size.width - 12) && p.y < float(rig.size.height - 12);
    };
    if (!in(el[i]) || !in(er[i]) || !in(pl[i]) || !in(pr[i])) continue;
    const cv::Point2d bl = find_blob(f.left, el[i]), br = find_blob(f.right, er[i]);
    max_dy = std::max(max_dy, std::abs(bl.y - br.y));  // epipolar error
    // Depth from the rectified disparity against the true depth in the rectified left frame.
    const cv::Mat Xr = R1 * (cv::Mat_<double>(3, 1) << X[i].x, X[i].y, X[i].z);
    const double z_true = Xr.at<double>(2);
    const double z_est = rect.calib().depth_of(bl.x - br.x);
    max_rel_z = std::max(max_rel_z, std::abs(z_est - z_true) / z_true);
    ++used;
  }
  RecordProperty("max_epipolar_px", std::to_string(max_dy));
  RecordProperty("max_rel_depth_err", std::to_string(max_rel_z));
  EXPECT_GE(used, 30);
  EXPECT_LT(max_dy, 0.5);
  EXPECT_LT(max_rel_z, 0.015);
}

TEST(CaptureRectifier, PreRectifiedFile) {
  TempDir d;
  {
    cv::FileStorage f((d.path() / "c.yml").string(), cv::FileStorage::WRITE);
    f << "rectified" << 1 << "f" << 721.5 << "B" << 0.54 << "cx" << 609.6 << "cy" << 172.9 << "image_width" << 1242
      << "image_height" << 375 << "height_m" << 1.65 << "pitch_deg" << 2.0;
  }
  const Rectifier r = Rectifier::from_file((d.path() / "c.yml").string());
  EXPECT_FALSE(r.remaps());
  EXPECT_DOUBLE_EQ(r.calib().focal_px, 721.5);
  EXPECT_DOUBLE_EQ(r.calib().baseline_m, 0.54);
  EXPECT_DOUBLE_EQ(r.calib().cy, 172.9);
  EXPECT_DOUBLE_EQ(r.calib().height_m, 1.65);
  EXPECT_NEAR(r.calib().pitch_rad, 2.0 * 3.14159265358979 / 180.0, 1e-12);
  StereoFrame f;
  f.left = f.right = cv::Mat(375, 1242, CV_8UC1, cv::Scalar(7));
  EXPECT_NO_THROW(r.apply(f));
  f.left = f.right = cv::Mat(480, 640, CV_8UC1, cv::Scalar(7));
  f.source = "uvc:/dev/video0";
  const std::string e = error_of([&] { r.apply(f); });
  EXPECT_NE(e.find("640x480"), std::string::npos) << e;
  EXPECT_NE(e.find("1242x375"), std::string::npos) << e;
  EXPECT_NE(e.find("uvc:/dev/video0"), std::string::npos) << e;
}

TEST(CaptureRectifier, ErrorsNameFileAndField) {
  SyntheticRig rig;
  TempDir d;
  const auto err = [&](const std::string& name) { return error_of([&] { Rectifier::from_file((d.path() / name).string()); }); };
  write_calib(d.path() / "nok1.yml", rig, "K1");
  std::string e = err("nok1.yml");
  EXPECT_NE(e.find("nok1.yml"), std::string::npos) << e;
  EXPECT_NE(e.find("'K1' is missing"), std::string::npos) << e;
  write_calib(d.path() / "d1.yml", rig, "D1");
  EXPECT_NE(err("d1.yml").find("'D1' must be a 1xN"), std::string::npos) << err("d1.yml");
  write_calib(d.path() / "size.yml", rig, "image_size");
  EXPECT_NE(err("size.yml").find("'image_width' is missing"), std::string::npos);
  write_calib(d.path() / "mm.yml", rig, "", true);
  EXPECT_NE(err("mm.yml").find("METRES"), std::string::npos) << err("mm.yml");
  rig.T.at<double>(0) = 0.12;  // right camera on the left
  write_calib(d.path() / "swap.yml", rig);
  EXPECT_NE(err("swap.yml").find("swapped"), std::string::npos) << err("swap.yml");
  EXPECT_NE(err("missing.yml").find("no such file"), std::string::npos);
  std::ofstream(d.path() / "junk.yml") << "this: [is not: closed\n";
  EXPECT_NE(err("junk.yml").find("junk.yml"), std::string::npos) << err("junk.yml");
  // Principal point outside the image: calibration made at another resolution.
  SyntheticRig small;
  small.size = {320, 240};
  write_calib(d.path() / "pp.yml", small);
  EXPECT_NE(err("pp.yml").find("outside the 320x240 image"), std::string::npos) << err("pp.yml");
}

// ---- live backends without hardware -------------------------------------------------------------

TEST(CaptureUvc, MissingDeviceNamesItAndWhatToCheck) {
  auto cam = open_camera(parse_source("uvc:/dev/video_fs_none"), CameraParams{});
  const std::string e = error_of([&] { cam->start(); });
  EXPECT_NE(e.find("'/dev/video_fs_none' does not exist"), std::string::npos) << e;
  EXPECT_NE(e.find("v4l2-ctl --list-devices"), std::string::npos) << e;
  auto two = open_camera(parse_source("uvc:/dev/video_fs_a,/dev/video_fs_b"), CameraParams{});
  EXPECT_NE(error_of([&] { two->start(); }).find("/dev/video_fs_a"), std::string::npos);
}

TEST(CaptureUvc, NotACameraIsReported) {
  TempDir d;
  const stdfs::path fake = d.path() / "video9";
  std::ofstream(fake) << "x";
  auto cam = open_camera(parse_source("uvc:" + fake.string()), CameraParams{});
  const std::string e = error_of([&] { cam->start(); });
  EXPECT_NE(e.find("cannot open '" + fake.string() + "'"), std::string::npos) << e;
}

TEST(CaptureLibcamera, NoCamerasGivesTheCountAndWhatToCheck) {
  if (!libcamera_built()) {
    const std::string e = error_of([] { open_camera(parse_source("libcamera"), CameraParams{}); });
    EXPECT_NE(e.find("built without libcamera"), std::string::npos) << e;
    return;
  }
  auto cam = open_camera(parse_source("libcamera"), CameraParams{});
  std::string e;
  try {
    cam->start();
  } catch (const CaptureError& ex) {
    e = ex.what();
  }
  cam->stop();
  if (e.empty()) GTEST_SKIP() << "two cameras are present: nothing to check here";
  EXPECT_NE(e.find("libcamera: found "), std::string::npos) << e;
  EXPECT_NE(e.find("need 2 for a stereo pair"), std::string::npos) << e;
  EXPECT_NE(e.find("ids: "), std::string::npos) << e;
  EXPECT_NE(e.find("--list-cameras"), std::string::npos) << e;
  // Named ids that do not exist.
  auto named = open_camera(parse_source("libcamera:/base/nope@10,/base/nope@20"), CameraParams{});
  const std::string e2 = error_of([&] { named->start(); });
  named->stop();
  EXPECT_NE(e2.find("left camera '/base/nope@10' not found"), std::string::npos) << e2;
}

// ---- oakd: the bridge child process (firmware/capture/oakd_bridge.py) -------------------------------
// Its simulated twin (--fake: random-dot pairs, right(x) = left(x + d)) drives the real pipe, framing,
// hello calibration, sequence gaps, timeout and exit paths; stub `depthai` modules on PYTHONPATH drive
// the bridge's device errors. Needs python3 on PATH (CI has it); skipped otherwise.
bool have_python3() { return std::system("python3 -c 'pass' > /dev/null 2>&1") == 0; }

// fps 20: a pair every 50 ms, slower than the test reads them even on a loaded machine (none
// replaced unread); 0 = a burst.
CameraParams fake_oakd(const std::string& extra, double fps = 20.0, int w = 64, int h = 48) {
  CameraParams p;
  p.width = w;
  p.height = h;
  p.timeout_ms = 5000;
  p.oakd_bridge_args = "--fake --fps " + std::to_string(fps) + " " + extra;
  return p;
}

// Sets PYTHONPATH for the bridge child to a folder holding `depthai.py` with `source`; restores it.
class StubDepthai {
 public:
  StubDepthai(const stdfs::path& dir, const std::string& source) {
    std::ofstream(dir / "depthai.py") << source;
    if (const char* old = std::getenv("PYTHONPATH")) old_ = old, had_ = true;
    ::setenv("PYTHONPATH", dir.c_str(), 1);
  }
  ~StubDepthai() {
    if (had_) ::setenv("PYTHONPATH", old_.c_str(), 1);
    else ::unsetenv("PYTHONPATH");
  }

 private:
  std::string old_;
  bool had_ = false;
};

TEST(CaptureOakd, FakeBridgeDeliversRectifiedPairsAndItsCalibration) {
  if (!have_python3()) GTEST_SKIP() << "python3 not on PATH";
  auto cam = open_camera(parse_source("oakd"), fake_oakd("--fake-disparity 5 --fake-count 4"));
  EXPECT_FALSE(cam->device_calibration().has_value());  // known only after start()
  cam->start();
  const auto calib = cam->device_calibration();
  ASSERT_TRUE(calib.has_value());
  EXPECT_DOUBLE_EQ(calib->focal_px, 400.0);
  EXPECT_DOUBLE_EQ(calib->baseline_m, 0.075);
  EXPECT_DOUBLE_EQ(calib->cx, 31.5);
  EXPECT_EQ(cam->name(), "oakd (device fake)");  // the hello's device id (and depthai version, none here)
  StereoFrame f;
  std::int64_t last_t = -1;
  for (std::uint64_t i = 0; i < 4; ++i) {
    ASSERT_TRUE(cam->grab(f));
    ASSERT_EQ(f.left.size(), cv::Size(64, 48));
    ASSERT_EQ(f.left.type(), CV_8UC1);
    EXPECT_EQ(f.frame_id, i);
    EXPECT_GT(f.timestamp_ns, last_t);
    last_t = f.timestamp_ns;
    EXPECT_EQ(f.source, "oakd");
    // The fake pair's disparity: right(x) = left(x + 5); the texture differs elsewhere.
    EXPECT_EQ(cv::norm(f.right.colRange(0, 59), f.left.colRange(5, 64), cv::NORM_INF), 0.0) << i;
    EXPECT_GT(cv::norm(f.right, f.left, cv::NORM_L1), 0.0);
  }
  EXPECT_EQ(cam->stats().pairs, 4u);
  EXPECT_EQ(cam->stats().dropped, 0u);
  // The bridge ends after 4 pairs: an error naming that, not a silent end of stream.
  const std::string e = error_of([&] { cam->grab(f); });
  EXPECT_NE(e.find("oakd: the bridge ended while sending a pair"), std::string::npos) << e;
  EXPECT_EQ(error_of([&] { cam->grab(f); }), e);  // the failure stays until start() again
  cam->stop();
  cam->stop();  // idempotent
}

TEST(CaptureOakd, SequenceGapsCountAsDroppedPairs) {
  if (!have_python3()) GTEST_SKIP() << "python3 not on PATH";
  auto cam = open_camera(parse_source("oakd"), fake_oakd("--fake-count 5 --fake-drop-at 2 --fake-skew-ns 3000"));
  cam->start();
  StereoFrame f;
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(cam->grab(f));
  EXPECT_EQ(cam->stats().dropped, 1u);
  EXPECT_EQ(cam->stats().last_offset_ns, -3000);  // t_left - t_right
  cam->stop();
}

TEST(CaptureOakd, OnlyTheNewestPairIsDelivered) {
  // A loop slower than the camera gets the latest pair, never a queue of old ones: a burst of 20
  // pairs read by the reader thread while nobody grabs leaves one, the other 19 count as dropped.
  if (!have_python3()) GTEST_SKIP() << "python3 not on PATH";
  auto cam = open_camera(parse_source("oakd"), fake_oakd("--fake-count 20", 0.0));
  cam->start();
  for (int i = 0; i < 500 && cam->stats().dropped < 19; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(cam->stats().dropped, 19u);
  StereoFrame f;
  ASSERT_TRUE(cam->grab(f));
  EXPECT_EQ(f.frame_id, 0u);
  EXPECT_EQ(cam->stats().pairs, 1u);
  EXPECT_NE(error_of([&] { cam->grab(f); }).find("the bridge ended"), std::string::npos);
  cam->stop();
}

TEST(CaptureOakd, HungBridgeTimesOutAndStopEndsIt) {
  if (!have_python3()) GTEST_SKIP() << "python3 not on PATH";
  CameraParams p = fake_oakd("--fake-stall-after 1", 0.0);
  p.timeout_ms = 300;
  auto cam = open_camera(parse_source("oakd"), p);
  cam->start();
  StereoFrame f;
  ASSERT_TRUE(cam->grab(f));
  const auto t0 = std::chrono::steady_clock::now();
  const std::string e = error_of([&] { cam->grab(f); });
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_NE(e.find("no pair from the bridge for 300 ms"), std::string::npos) << e;
  EXPECT_GE(waited, 0.29);
  const auto t1 = std::chrono::steady_clock::now();
  cam->stop();  // SIGTERM to the sleeping bridge
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count(), 2.5);
}

TEST(CaptureOakd, ErrorsNameTheInterpreterTheScriptAndTheBridgesReason) {
  if (!have_python3()) GTEST_SKIP() << "python3 not on PATH";
  CameraParams p = fake_oakd("");
  p.oakd_python = "/nonexistent/python3";
  std::string e = error_of([&] { open_camera(parse_source("oakd"), p)->start(); });
#ifndef FS_TEST_EMULATED
  EXPECT_NE(e.find("cannot start '/nonexistent/python3'"), std::string::npos) << e;
  EXPECT_NE(e.find("camera.oakd_python"), std::string::npos) << e;
#else
  // Under qemu-user (the aarch64 build's tests) posix_spawn's vfork is emulated by a fork, so the
  // child's failed exec cannot report back: the start fails later, as a bridge that exited 127.
  EXPECT_NE(e.find("exit code 127"), std::string::npos) << e;
#endif
  p = fake_oakd("");
  p.oakd_bridge = "/nonexistent/oakd_bridge.py";
  e = error_of([&] { open_camera(parse_source("oakd"), p)->start(); });
  EXPECT_NE(e.find("camera.oakd_bridge = '/nonexistent/oakd_bridge.py' is not a file"), std::string::npos) << e;
  // The bridge's own argument check (exit 2): its message reaches the user.
  p = fake_oakd("--fake-disparity 999");
  e = error_of([&] { open_camera(parse_source("oakd"), p)->start(); });
  EXPECT_NE(e.find("exit code 2"), std::string::npos) << e;
  EXPECT_NE(e.find("--fake-disparity 999 outside 0..63"), std::string::npos) << e;
}

TEST(CaptureOakd, DeviceErrorsFromTheBridge) {
  if (!have_python3()) GTEST_SKIP() << "python3 not on PATH";
  TempDir d;
  CameraParams p;  // the device path: no --fake
  p.timeout_ms = 5000;
  {
    StubDepthai stub(d.path(), "raise ImportError('stub: no depthai here')\n");
    const std::string e = error_of([&] { open_camera(parse_source("oakd"), p)->start(); });
    EXPECT_NE(e.find("exit code 3"), std::string::npos) << e;
    EXPECT_NE(e.find("depthai is not installed"), std::string::npos) << e;
    EXPECT_NE(e.find("pip install"), std::string::npos) << e;
  }
  {
    StubDepthai stub(d.path(), "__version__ = '2.24.0'\n");
    const std::string e = error_of([&] { open_camera(parse_source("oakd"), p)->start(); });
    EXPECT_NE(e.find("depthai 2.24.0 is too old"), std::string::npos) << e;
  }
  const std::string v3 =
      "__version__ = '3.12.0'\n"
      "class _Info:\n    deviceId = '14442C10D13EABCE00'\n    name = '1.1'\n"
      "class Device:\n    devices = []\n"
      "    @staticmethod\n    def getAllAvailableDevices():\n        return Device.devices\n";
  {
    StubDepthai stub(d.path(), v3);
    const std::string e = error_of([&] { open_camera(parse_source("oakd"), p)->start(); });
    EXPECT_NE(e.find("exit code 4"), std::string::npos) << e;
    EXPECT_NE(e.find("no OAK device found"), std::string::npos) << e;
  }
  {
    StubDepthai stub(d.path(), v3 + "Device.devices = [_Info()]\n");
    const std::string e = error_of([&] { open_camera(parse_source("oakd:NOPE"), p)->start(); });
    EXPECT_NE(e.find("OAK device 'NOPE' not found; available: 14442C10D13EABCE00"), std::string::npos) << e;
  }
}

TEST(CaptureSim, WithoutHookSaysNotLinked) {
  EXPECT_NE(error_of([] { open_camera(parse_source("sim"), CameraParams{}); }).find("not linked"), std::string::npos);
}
