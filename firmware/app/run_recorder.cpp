#include "run_recorder.hpp"

#include <cstdio>
#include <exception>
#include <filesystem>
#include <system_error>

#include "io.hpp"

namespace fs::app {
namespace stdfs = std::filesystem;

RunRecorder::RunRecorder(const std::string& dir, const RecordParams& p, bool quiet) : dir_(dir), p_(p), quiet_(quiet) {
  std::error_code ec;
  stdfs::create_directories(stdfs::path(dir) / "frames", ec);
  if (ec) throw UserError("cannot create " + (stdfs::path(dir) / "frames").string() + ": " + ec.message());
  log_file_.open(stdfs::path(dir) / "frames.jsonl");
  if (!log_file_) throw UserError("cannot write " + dir + "/frames.jsonl");
}

double RunRecorder::free_mb() const {
  std::error_code ec;
  const auto sp = stdfs::space(dir_, ec);
  if (ec) return -1.0;  // unknown: do not stop on a failed query (the writes themselves are checked)
  return double(sp.available) / (1024.0 * 1024.0);
}

void RunRecorder::begin_frame(int frame) {
  frame_ = frame;
  if (!enabled() || (!snapshots_ && !log_)) return;
  if (p_.check_every <= 0 || frame % p_.check_every != 0) return;
  const double mb = free_mb();
  if (mb < 0) return;
  char buf[128];
  if (snapshots_ && mb < p_.min_free_mb) {
    std::snprintf(buf, sizeof buf, "%.0f MiB free < [record] min_free_mb %.0f", mb, p_.min_free_mb);
    stop_snapshots(buf);
  }
  if (log_ && mb < p_.min_free_log_mb) {
    std::snprintf(buf, sizeof buf, "%.0f MiB free < [record] min_free_log_mb %.0f", mb, p_.min_free_log_mb);
    stop_log(buf);
  }
}

bool RunRecorder::snapshot(const std::function<void()>& write) {
  if (!enabled()) return false;
  if (!snapshots_) {
    ++dropped_snapshots_;
    return false;
  }
  std::string err;
  if (p_.fail_frame >= 0 && frame_ >= p_.fail_frame) {
    err = "injected write failure";
  } else {
    try {
      write();
      return true;
    } catch (const std::exception& e) {
      err = e.what();
    }
  }
  ++dropped_snapshots_;
  stop_snapshots(err);
  return false;
}

void RunRecorder::log_line(const std::string& line) {
  if (!enabled()) return;
  if (!log_) {
    ++dropped_lines_;
    return;
  }
  const bool inject = p_.fail_frame >= 0 && frame_ >= p_.fail_frame;
  if (!inject) {
    log_file_ << line << '\n';
    log_file_.flush();
  }
  if (inject || !log_file_) {
    ++dropped_lines_;
    stop_log(inject ? "injected write failure" : "write failed (disk full?)");
  }
}

void RunRecorder::stop_snapshots(const std::string& why) {
  if (!snapshots_) return;
  snapshots_ = false;
  const std::string msg = "record: snapshots stopped at frame " + std::to_string(frame_) + " (" + why + "); the run goes on";
  warning_ += (warning_.empty() ? "" : "; ") + msg;
  std::fprintf(stderr, "%s\n", msg.c_str());
}

void RunRecorder::stop_log(const std::string& why) {
  if (!log_) return;
  log_ = false;
  snapshots_ = false;
  const std::string msg = "record: frame log stopped at frame " + std::to_string(frame_) + " (" + why + "); the run goes on";
  warning_ += (warning_.empty() ? "" : "; ") + msg;
  std::fprintf(stderr, "%s\n", msg.c_str());
}

}  // namespace fs::app
