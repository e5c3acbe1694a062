// The run record (`run --record DIR`) must never end a mission. A robot whose SD card fills up, or
// whose USB stick is pulled, should drive on and tell the user, not stop half-way because a PNG
// could not be written (before session 20 a failed snapshot threw and ended the run; a failed log
// line failed silently for the rest of the run).
//
// RunRecorder owns DIR/frames.jsonl and the snapshots in DIR/frames/:
//   * free space is checked every `check_every` frames (std::filesystem::space): below
//     [record] min_free_mb snapshots stop, below min_free_log_mb the frame log stops too — the
//     robot's own system needs the rest of the card;
//   * a failed write (snapshot or log line) stops that part of the record;
//   * each stop prints one warning line and is kept in warning() for the result; dropped
//     snapshots and log lines are counted.
#pragma once
#include <cstdint>
#include <fstream>
#include <functional>
#include <string>

namespace fs::app {

struct RecordParams {
  double min_free_mb = 200.0;     // snapshots stop below this much free space [MiB]
  double min_free_log_mb = 20.0;  // the frame log stops below this [MiB]
  int check_every = 10;           // frames between free-space checks
  int fail_frame = -1;            // fault injection: from this frame on every write fails (-1 = never)
};

class RunRecorder {
 public:
  RunRecorder() = default;
  // Opens DIR/frames.jsonl and creates DIR/frames (UserError when that fails: before the run).
  RunRecorder(const std::string& dir, const RecordParams& p, bool quiet);
  bool enabled() const { return !dir_.empty(); }
  // Call once per frame before writing: checks free space (every check_every frames).
  void begin_frame(int frame);
  bool snapshots_on() const { return enabled() && snapshots_; }
  // Writes one snapshot with `write` (which throws on failure, as write_image does); false when
  // skipped or failed.
  bool snapshot(const std::function<void()>& write);
  void log_line(const std::string& line);
  const std::string& dir() const { return dir_; }
  int dropped_snapshots() const { return dropped_snapshots_; }
  int dropped_lines() const { return dropped_lines_; }
  const std::string& warning() const { return warning_; }

 private:
  void stop_snapshots(const std::string& why);
  void stop_log(const std::string& why);
  double free_mb() const;
  std::string dir_;
  RecordParams p_;
  bool quiet_ = false, snapshots_ = true, log_ = true;
  int frame_ = 0;
  std::ofstream log_file_;
  int dropped_snapshots_ = 0, dropped_lines_ = 0;
  std::string warning_;
};

}  // namespace fs::app
