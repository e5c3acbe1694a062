// Replay backend: a recorded image sequence or a stereo dataset folder played as a camera pair, at a
// chosen rate, optionally looping. Time comes from an injectable clock so tests never sleep.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "fuzzystereo/capture/camera.hpp"

namespace fs::capture {

// Monotonic time source and sleep, injectable for tests. Defaults: std::chrono::steady_clock and
// std::this_thread::sleep_until.
struct Clock {
  std::function<std::int64_t()> now_ns;
  std::function<void(std::int64_t)> sleep_until_ns;
  static Clock steady();
};

// Image sequence layouts (first match wins; docs/capture.md):
//   1. DIR/left/*.png  + DIR/right/*.png       paired by identical file name (what `capture` writes);
//      timestamps from DIR/timestamps.csv (frame,timestamp_ns,left,right) when present
//   2. DIR/image_2/*.png + DIR/image_3/*.png   KITTI raw / odometry colour pair, paired by file name
//      (image_0 + image_1, the grey pair, when image_2/image_3 are absent)
//   3. DIR/*_left.<ext> + DIR/*_right.<ext>     paired by the common prefix
// Extensions: .png .jpg .jpeg .bmp .ppm .pgm .tif .tiff (case-insensitive). Pairs are sorted by name
// (natural order: "2" before "10"). Returns an empty vector when DIR holds none of these layouts;
// throws CaptureError when a layout is half present (a left image without its right partner, naming
// it) or timestamps.csv is malformed (naming the line).
std::vector<PairPaths> discover_image_sequence(const std::string& dir);

struct ReplayOptions {
  double rate_hz = 0.0;  // pairs per second; 0 = as fast as grab() is called
  bool loop = false;     // after the last pair, start again (frame ids keep counting)
};

// Plays `pairs` in order. Pacing: pair i is released at start + i / rate_hz; when the consumer is
// late the schedule restarts from now (no burst to catch up, no frame skipped — replay never drops).
// timestamp_ns: the recorded timestamp when the sequence has one (shifted by one sequence span per
// loop so it keeps increasing), else the clock at release.
class ReplayCamera final : public StereoCamera {
 public:
  ReplayCamera(std::string source, std::vector<PairPaths> pairs, ReplayOptions opt, Clock clock = Clock::steady());
  void start() override;
  bool grab(StereoFrame& out) override;
  void stop() override;
  std::string name() const override { return source_; }
  CaptureStats stats() const override { return {frame_id_, 0, 0}; }
  std::size_t size() const { return pairs_.size(); }

 private:
  std::string source_;
  std::vector<PairPaths> pairs_;
  ReplayOptions opt_;
  Clock clock_;
  bool started_ = false;
  std::size_t next_ = 0;       // index into pairs_
  std::uint64_t loops_ = 0;    // completed passes
  std::uint64_t frame_id_ = 0;
  std::int64_t anchor_ns_ = 0;     // release time of pair `anchor_count_`
  std::uint64_t anchor_count_ = 0;
  std::int64_t loop_span_ns_ = 0;  // recorded timestamps: shift per loop
};

}  // namespace fs::capture
