// Device services of the serial link (docs/protocol.md): handshake, config get/push/commit, log
// list/read, telemetry, snapshot, control. Runs on its own thread; the vision loop only calls
// publish(), which never blocks (a latest-telemetry slot and a bounded log queue, both try_lock).
//
// Wiring in a runtime:
//   fs::link::DeviceServer server(hooks, opts);
//   server.start();                        // loads the config store, opens the port, announces a pty
//   ... each frame: server.publish(telemetry);
#pragma once
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "fuzzystereo/link/config_store.hpp"
#include "fuzzystereo/link/protocol_gen.hpp"

namespace fs::link {

class Port;
class LogStore;

struct SnapshotFile {
  std::string name;                 // file name in the dump directory (docs/formats.md)
  std::vector<std::uint8_t> data;
};

// Callbacks into the runtime. All are called on the link thread; any may be empty.
struct DeviceHooks {
  // The current frame's inputs and stage outputs in the dump format; throw to refuse.
  std::function<std::vector<SnapshotFile>()> snapshot;
  // E-stop / pause / resume / clear e-stop (after the server updated its state).
  std::function<void(msg::ControlAction)> control;
  // A new config was validated and written (also called once by start() with the startup config).
  std::function<void(const fs::Config&)> config_applied;
};

struct ServerOptions {
  std::string link = "pty";       // "pty" or a serial device path
  int baud = 115200;
  std::string state_dir;          // <state_dir>/config, <state_dir>/logs
  std::string pty_link_file;      // write the pty path here (atomically) when not empty
  std::string fw_version = "unknown";
  bool announce = true;           // print the link and config source on stdout
};

class DeviceServer {
 public:
  DeviceServer(DeviceHooks hooks, ServerOptions opts);
  ~DeviceServer();
  DeviceServer(const DeviceServer&) = delete;
  DeviceServer& operator=(const DeviceServer&) = delete;

  void start();  // throws PortError / std::runtime_error
  void stop();

  // From the vision loop: never blocks. The server fills in its own link counters and state.
  void publish(const msg::Telemetry& t);
  // Appends any message as a log record (same queue as publish's telemetry records).
  void log(std::uint8_t msg_id, const std::vector<std::uint8_t>& payload);

  msg::RunState state() const { return static_cast<msg::RunState>(state_.load()); }
  std::string link_name() const;
  std::uint32_t uptime_ms() const;
  ActiveConfig active_config() const;

 private:
  struct Impl;
  void run();
  void handle(const std::vector<std::uint8_t>& bytes);
  DeviceHooks hooks_;
  ServerOptions opts_;
  std::unique_ptr<Impl> impl_;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<int> state_{0};
};

}  // namespace fs::link
