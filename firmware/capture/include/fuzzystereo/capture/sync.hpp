// Software synchronisation of two free-running cameras: pairs left and right frames whose sensor
// timestamps differ by at most a tolerance. Pure logic (no device), shared by the uvc (two devices)
// and libcamera backends and unit-tested on its own.
//
// Why software matching: the Pi's two CSI ports and two UVC webcams have no common trigger, so
// each sensor free-runs at the same nominal rate with an unknown, slowly drifting phase. Pairing the
// nearest timestamps bounds the left/right time offset by the tolerance (moving robot: offset x
// speed = the stereo error it causes), and dropping the older unmatched frame re-locks after a
// dropped frame on one side. Hardware-synchronised sensors (external trigger / XVS) would make
// this a no-op, not wrong.
#pragma once
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <utility>
#include <vector>

namespace fs::capture {

template <class T>
class TimestampPairer {
 public:
  struct Pair {
    T left, right;
    std::int64_t left_ns, right_ns;
  };
  // tolerance_ns: largest |t_left - t_right| paired; max_pending: frames kept per side (older dropped).
  explicit TimestampPairer(std::int64_t tolerance_ns, std::size_t max_pending = 4)
      : tol_(tolerance_ns), max_pending_(max_pending) {}

  void push_left(std::int64_t ts_ns, T item) { push(left_, ts_ns, std::move(item)); }
  void push_right(std::int64_t ts_ns, T item) { push(right_, ts_ns, std::move(item)); }

  // The next pair, if one can be formed. Invariant: frames leave in timestamp order per side; an
  // unmatched frame is dropped only when a newer frame on the OTHER side proves no partner can
  // come for it (the other side's oldest frame is already later than ts + tolerance).
  std::optional<Pair> pop() {
    while (!left_.empty() && !right_.empty()) {
      auto& l = left_.front();
      auto& r = right_.front();
      const std::int64_t d = l.first - r.first;
      if (d <= tol_ && -d <= tol_) {
        Pair p{std::move(l.second), std::move(r.second), l.first, r.first};
        left_.pop_front();
        right_.pop_front();
        ++paired_;
        return p;
      }
      if (d < 0) drop(left_); else drop(right_);  // the older one has no partner
    }
    return std::nullopt;
  }

  // Frames dropped (no partner or queue overflow) since the last call, for the caller to recycle.
  std::vector<T> take_dropped() { return std::exchange(dropped_, {}); }
  std::uint64_t paired() const { return paired_; }
  std::uint64_t dropped_count() const { return dropped_count_; }
  std::size_t pending_left() const { return left_.size(); }
  std::size_t pending_right() const { return right_.size(); }
  // Every frame still queued (for the caller to recycle at stop()).
  std::vector<T> drain() {
    std::vector<T> out;
    for (auto* q : {&left_, &right_})
      while (!q->empty()) { out.push_back(std::move(q->front().second)); q->pop_front(); }
    return out;
  }

 private:
  using Queue = std::deque<std::pair<std::int64_t, T>>;
  void push(Queue& q, std::int64_t ts, T item) {
    q.emplace_back(ts, std::move(item));
    while (q.size() > max_pending_) drop(q);
  }
  void drop(Queue& q) {
    dropped_.push_back(std::move(q.front().second));
    q.pop_front();
    ++dropped_count_;
  }
  std::int64_t tol_;
  std::size_t max_pending_;
  Queue left_, right_;
  std::vector<T> dropped_;
  std::uint64_t paired_ = 0, dropped_count_ = 0;
};

}  // namespace fs::capture
