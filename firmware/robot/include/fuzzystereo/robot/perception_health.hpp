// Perception health failsafe: a blind or frozen camera must not read as "no obstacles".
//
// The matcher and the detector find obstacles only where the two views match. A covered or
// dazzled lens, a camera that lost exposure, or a driver that keeps delivering the same buffer gives
// a disparity map with nothing in it, and an empty map looks exactly like free space: the planner
// would drive on, and the map would even clear the cells it "sees through". Per frame, the loop
// measures (docs/robot.md "Failsafes"):
//   * contrast: the grey-level standard deviation of each image (every 4th pixel of every 4th row):
//     a black, saturated or flat image has almost none;
//   * noise only: the same without its noise, sqrt(max(0, std^2 - noise^2)) with the matcher's noise
//     estimate (Immerkaer, docs/algorithm.md 2c). A lens under a hand keeps only its sensor noise
//     (measured: std 3.0, noise 2.97 -> 0.4). A single image cannot tell noise from a noise-like
//     texture (a random-dot pattern reads std 74, "noise" 74), so a noise-only camera is a fault
//     only when the views do not match either: fewer than noise_only_valid_pct of the pixels with a
//     disparity (the covered lens: 8.6-8.9 % consistent by chance; the random-dot pair: most of them);
//   * valid %: the share of pixels with a disparity after ESR, below min_valid_pct on its own (a
//     scene in the simulator: 30-60 %);
//   * frozen: how many consecutive frames of one camera were identical (live cameras only: their
//     sensor noise makes two real frames differ; the simulator and replays repeat frames legally).
// A frame that fails any test is not given to the map or the tracker (nothing is cleared or
// forgotten on the strength of a blind frame). After trip_frames faulty frames in a row the motors
// are stopped and kept stopped until clear_frames healthy frames in a row. Like a flight
// controller's pre-arm check, the robot also starts stopped: it drives only after startup_frames
// healthy frames (a camera covered at power-on never gets a first blind plan).
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

namespace fs::robot {

// [perception]
struct PerceptionHealthParams {
  bool enabled = true;          // health_check
  double min_contrast = 2.0;    // grey-level std below which a camera is blind [levels]
  double min_valid_pct = 2.0;   // % of pixels with a disparity below which the pair is blind
  double noise_only_valid_pct = 20.0;  // ... below which a camera that shows only noise is blind
  int frozen_frames = 5;        // identical consecutive frames of a live camera = frozen (0 = off)
  int trip_frames = 3;          // faulty frames in a row before the stop
  int clear_frames = 5;         // healthy frames in a row before driving again
  int startup_frames = 1;       // healthy frames in a row before the first drive
};

// One frame's measurements.
struct FrameHealth {
  double contrast_left = 0, contrast_right = 0;  // grey-level std [levels]
  double noise_left = 0, noise_right = 0;        // estimated noise std [levels] (0 = none known)
  double valid_pct = 0;                           // % of pixels with a disparity
  int same_left = 0, same_right = 0;              // consecutive frames identical to this one (0 = new)
};

// Grey-level standard deviation and a 64-bit FNV-1a hash of every `step`-th pixel of every
// `step`-th row of an 8-bit image (stride in bytes).
struct ImageStats {
  double stddev = 0;
  std::uint64_t hash = 0;
};
ImageStats image_stats(const std::uint8_t* data, int width, int height, std::size_t stride, int step = 4);

// Contrast without the noise: sqrt(max(0, std^2 - noise^2)) [levels].
double signal_contrast(double stddev, double noise);

// "" when the frame is healthy, else the first failed test with its value and limit
// (e.g. "left camera blind: contrast 0.4 < 2 grey levels").
std::string perception_fault(const FrameHealth& h, const PerceptionHealthParams& p);

// Debounced state: update() once per frame; true while the motors must stay stopped.
class PerceptionMonitor {
 public:
  explicit PerceptionMonitor(const PerceptionHealthParams& p) : p_(p), stopped_(p.enabled) {}
  bool update(const FrameHealth& h);
  bool stopped() const { return stopped_; }
  const std::string& fault() const { return fault_; }  // this frame's fault ("" = healthy frame)
  int trips() const { return trips_; }                 // transitions into the stopped state (not the start)
  bool started() const { return started_; }            // the start-up check has passed

 private:
  PerceptionHealthParams p_;
  int bad_run_ = 0, good_run_ = 0, trips_ = 0;
  bool stopped_ = false, started_ = false;
  std::string fault_;
};

// Counts consecutive identical frames of one camera from their hashes.
class FrozenCounter {
 public:
  int update(std::uint64_t hash) {
    same_ = have_ && hash == last_ ? same_ + 1 : 0;
    last_ = hash;
    have_ = true;
    return same_;
  }

 private:
  std::uint64_t last_ = 0;
  bool have_ = false;
  int same_ = 0;
};

}  // namespace fs::robot
