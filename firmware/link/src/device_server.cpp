#include "fuzzystereo/link/device_server.hpp"

#include <poll.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>

#include "fuzzystereo/link/framing.hpp"
#include "fuzzystereo/link/log_store.hpp"
#include "fuzzystereo/link/port.hpp"

namespace fs::link {

namespace {
constexpr std::size_t kLogQueueMax = 256;  // records waiting for the link thread to write them
constexpr int kPollMs = 20;
constexpr int kWriteTimeoutMs = 500;       // a frame the host does not take by then is dropped

std::string hex(const std::uint8_t* p, std::size_t n) {
  static const char* h = "0123456789abcdef";
  std::string s;
  for (std::size_t i = 0; i < n; ++i) { s += h[p[i] >> 4]; s += h[p[i] & 15]; }
  return s;
}

struct Staging {
  bool open = false;
  std::string data;
  std::size_t total = 0, received = 0;  // received = contiguous bytes from offset 0
};
}  // namespace

struct DeviceServer::Impl {
  std::unique_ptr<Port> port;
  std::unique_ptr<ConfigStore> config_store;
  std::unique_ptr<LogStore> logs;
  FrameDecoder decoder{msg::kMaxPayload};
  std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();

  mutable std::mutex cfg_mu;
  ActiveConfig active;
  Staging staging;

  std::mutex latest_mu;
  msg::Telemetry latest;
  bool has_latest = false;

  std::mutex log_mu;
  std::deque<std::pair<std::uint8_t, std::vector<std::uint8_t>>> log_queue;
  std::uint32_t last_log_ms = 0;
  bool logged_any = false;
  std::uint32_t log_period_ms = 1000;

  std::atomic<std::uint32_t> tx_dropped{0}, log_dropped{0};

  // duplicate requests (a retry after a lost answer) get the cached answer, not a second execution
  bool have_last = false;
  std::uint8_t last_id = 0;
  std::uint16_t last_seq = 0;
  std::vector<std::uint8_t> last_answer;

  std::uint32_t snap_id = 0;
  std::vector<SnapshotFile> snapshot;

  void send(const std::vector<std::uint8_t>& wire) {
    std::size_t done = 0;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(kWriteTimeoutMs);
    while (done < wire.size()) {
      const ssize_t w = ::write(port->fd(), wire.data() + done, wire.size() - done);
      if (w > 0) { done += std::size_t(w); continue; }
      if (w < 0 && errno != EAGAIN && errno != EINTR && errno != EIO) break;
      if (std::chrono::steady_clock::now() > deadline) break;
      pollfd p{port->fd(), POLLOUT, 0};
      ::poll(&p, 1, 10);
    }
    if (done < wire.size()) ++tx_dropped;
  }
};

DeviceServer::DeviceServer(DeviceHooks hooks, ServerOptions opts)
    : hooks_(std::move(hooks)), opts_(std::move(opts)), impl_(std::make_unique<Impl>()) {}

DeviceServer::~DeviceServer() { stop(); }

std::uint32_t DeviceServer::uptime_ms() const {
  return std::uint32_t(std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - impl_->t0).count());
}

std::string DeviceServer::link_name() const { return impl_->port ? impl_->port->name() : std::string(); }

ActiveConfig DeviceServer::active_config() const {
  std::lock_guard lock(impl_->cfg_mu);
  return impl_->active;
}

void DeviceServer::start() {
  if (opts_.state_dir.empty()) throw std::runtime_error("the device server needs a state directory");
  const std::filesystem::path state(opts_.state_dir);
  impl_->config_store = std::make_unique<ConfigStore>(state / "config");
  impl_->active = impl_->config_store->load();
  const auto& v = impl_->active.config.values;
  impl_->log_period_ms = std::uint32_t(v.integer("link.log_period_ms"));
  impl_->logs = std::make_unique<LogStore>(state / "logs", std::size_t(v.integer("link.log_rotate_kib")) * 1024,
                                           v.integer("link.log_keep_files"));
  if (!impl_->active.warning.empty()) std::fprintf(stderr, "fuzzystereo: warning: %s\n", impl_->active.warning.c_str());
  if (hooks_.config_applied) hooks_.config_applied(impl_->active.config);
  impl_->port = Port::open(opts_.link, opts_.baud);
  if (opts_.announce) {
    std::printf("link: %s %s (baud %d, layout %s)\n", impl_->port->is_pty() ? "pty" : "serial", impl_->port->name().c_str(),
                opts_.baud, msg::kSchemaHashHex);
    std::printf("config: %s (id %08x)\n", impl_->active.source.c_str(), impl_->active.id);
    std::fflush(stdout);
  }
  if (!opts_.pty_link_file.empty()) {
    const std::string tmp = opts_.pty_link_file + ".tmp";
    {
      std::ofstream f(tmp);
      f << impl_->port->name() << "\n";
      if (!f) throw std::runtime_error("cannot write '" + tmp + "'");
    }
    std::filesystem::rename(tmp, opts_.pty_link_file);
  }
  running_ = true;
  thread_ = std::thread([this] { run(); });
}

void DeviceServer::stop() {
  if (running_.exchange(false) && thread_.joinable()) thread_.join();
}

void DeviceServer::publish(const msg::Telemetry& t) {
  if (impl_->latest_mu.try_lock()) {
    impl_->latest = t;
    impl_->has_latest = true;
    impl_->latest_mu.unlock();
  }
  if (impl_->logged_any && t.t_ms - impl_->last_log_ms < impl_->log_period_ms) return;
  impl_->logged_any = true;
  impl_->last_log_ms = t.t_ms;
  std::vector<std::uint8_t> payload;
  Writer w(payload);
  encode(t, w);
  log(msg::Telemetry::kId, payload);
}

void DeviceServer::log(std::uint8_t msg_id, const std::vector<std::uint8_t>& payload) {
  if (!impl_->log_mu.try_lock()) { ++impl_->log_dropped; return; }
  if (impl_->log_queue.size() >= kLogQueueMax) ++impl_->log_dropped;
  else impl_->log_queue.emplace_back(msg_id, payload);
  impl_->log_mu.unlock();
}

void DeviceServer::run() {
  std::uint8_t buf[4096];
  std::vector<Frame> frames;
  while (running_) {
    pollfd p{impl_->port->fd(), POLLIN, 0};
    const int pr = ::poll(&p, 1, kPollMs);
    if (pr > 0 && (p.revents & POLLIN)) {
      const ssize_t n = ::read(impl_->port->fd(), buf, sizeof buf);
      if (n > 0) {
        frames.clear();
        const std::size_t dropped = impl_->decoder.feed(buf, std::size_t(n), frames);
        if (dropped) {
          // tell the host at once so it resends instead of waiting for its timeout
          msg::RxError e;
          e.errors = impl_->decoder.errors().total();
          std::vector<std::uint8_t> pl;
          Writer w(pl);
          encode(e, w);
          impl_->send(encode_frame(msg::RxError::kId, 0, pl));
        }
        for (const auto& f : frames) {
          std::vector<std::uint8_t> raw;  // id, seq, payload: handle() re-reads the frame fields
          raw.push_back(f.id);
          raw.push_back(std::uint8_t(f.seq & 0xFF));
          raw.push_back(std::uint8_t(f.seq >> 8));
          raw.insert(raw.end(), f.payload.begin(), f.payload.end());
          handle(raw);
        }
      }
    } else if (pr > 0 && (p.revents & (POLLHUP | POLLERR))) {
      std::this_thread::sleep_for(std::chrono::milliseconds(kPollMs));  // serial device gone: keep trying
    }
    // write queued log records (the vision thread only queued them)
    std::deque<std::pair<std::uint8_t, std::vector<std::uint8_t>>> q;
    {
      std::lock_guard lock(impl_->log_mu);
      q.swap(impl_->log_queue);
    }
    for (auto& [id, pl] : q)
      if (!impl_->logs->append(uptime_ms(), id, pl)) ++impl_->log_dropped;
  }
}

void DeviceServer::handle(const std::vector<std::uint8_t>& raw) {
  Impl& I = *impl_;
  const std::uint8_t id = raw[0];
  const std::uint16_t seq = std::uint16_t(raw[1] | (raw[2] << 8));
  const std::uint8_t* pl = raw.data() + 3;
  const std::size_t pn = raw.size() - 3;

  if (id != msg::Hello::kId && I.have_last && id == I.last_id && seq == I.last_seq) {
    I.send(I.last_answer);  // duplicate of the last request: same answer, no second execution
    return;
  }
  std::vector<std::uint8_t> out;
  std::uint8_t out_id = msg::Ack::kId;
  auto reply = [&](const auto& m) {
    out.clear();
    Writer w(out);
    encode(m, w);
    out_id = std::remove_cvref_t<decltype(m)>::kId;
  };
  auto nack = [&](msg::Status s, std::string text) {
    msg::Ack a;
    a.status = static_cast<std::uint8_t>(s);
    if (text.size() > 255) text.resize(255);
    a.text = std::move(text);
    reply(a);
  };
  auto ack = [&] { nack(msg::Status::OK, ""); };
  auto decode_req = [&](auto& m) {
    Reader r(pl, pn);
    if (decode(r, m) && r.at_end()) return true;
    nack(msg::Status::MALFORMED, std::string("malformed ") + std::remove_cvref_t<decltype(m)>::kName + " payload (" +
                                     std::to_string(pn) + " bytes)");
    return false;
  };

  try {
    switch (id) {
      case msg::Hello::kId: {
        msg::Hello h;
        Reader r(pl, pn);
        // only the hash is read strictly: a peer with another layout must still be told which one
        if (!r.bytes(h.schema_hash)) { nack(msg::Status::MALFORMED, "malformed hello"); break; }
        if (h.schema_hash.size() != 8 || !std::equal(h.schema_hash.begin(), h.schema_hash.end(), msg::kSchemaHash.begin())) {
          nack(msg::Status::SCHEMA_MISMATCH, std::string("protocol layout mismatch: device ") + msg::kSchemaHashHex +
                                                 ", host " + hex(h.schema_hash.data(), h.schema_hash.size()));
          break;
        }
        msg::Info info;
        info.schema_hash.assign(msg::kSchemaHash.begin(), msg::kSchemaHash.end());
        info.fw_version = opts_.fw_version;
        info.uptime_ms = uptime_ms();
        {
          std::lock_guard lock(I.cfg_mu);
          info.config_id = I.active.id;
          info.config_source = I.active.source;
        }
        info.state = std::uint8_t(state_.load());
        info.max_payload = std::uint16_t(msg::kMaxPayload);
        info.link = I.port->name();
        info.baud = std::uint32_t(opts_.baud);
        reply(info);
        break;
      }
      case msg::ConfigGet::kId: {
        msg::ConfigGet g;
        if (!decode_req(g)) break;
        msg::ConfigData d;
        std::lock_guard lock(I.cfg_mu);
        const std::string& t = I.active.text;
        d.total = std::uint32_t(t.size());
        d.crc = I.active.id;
        d.offset = g.offset;
        if (g.offset > t.size()) { nack(msg::Status::BAD_OFFSET, "offset " + std::to_string(g.offset) + " past the config's " + std::to_string(t.size()) + " bytes"); break; }
        const std::size_t n = std::min<std::size_t>(g.length, t.size() - g.offset);
        d.data.assign(t.begin() + std::ptrdiff_t(g.offset), t.begin() + std::ptrdiff_t(g.offset + n));
        reply(d);
        break;
      }
      case msg::ConfigBegin::kId: {
        msg::ConfigBegin b;
        if (!decode_req(b)) break;
        I.staging = Staging{true, std::string(b.total, '\0'), b.total, 0};
        ack();
        break;
      }
      case msg::ConfigChunk::kId: {
        msg::ConfigChunk c;
        if (!decode_req(c)) break;
        Staging& s = I.staging;
        if (!s.open) { nack(msg::Status::NO_SESSION, "no config push in progress (send config_begin first)"); break; }
        if (c.offset > s.received || c.offset + c.data.size() > s.total) {
          nack(msg::Status::BAD_OFFSET, "chunk at " + std::to_string(c.offset) + "+" + std::to_string(c.data.size()) +
                                            " but " + std::to_string(s.received) + " of " + std::to_string(s.total) + " bytes received");
          break;
        }
        std::copy(c.data.begin(), c.data.end(), s.data.begin() + std::ptrdiff_t(c.offset));
        s.received = std::max<std::size_t>(s.received, c.offset + c.data.size());
        ack();
        break;
      }
      case msg::ConfigCommit::kId: {
        msg::ConfigCommit c;
        if (!decode_req(c)) break;
        Staging& s = I.staging;
        if (!s.open) { nack(msg::Status::NO_SESSION, "no config push in progress (send config_begin first)"); break; }
        if (s.received < s.total) { nack(msg::Status::BAD_OFFSET, "only " + std::to_string(s.received) + " of " + std::to_string(s.total) + " bytes received"); break; }
        const std::uint32_t crc = crc32c(reinterpret_cast<const std::uint8_t*>(s.data.data()), s.data.size());
        if (crc != c.crc) {
          char t[128];
          std::snprintf(t, sizeof t, "CRC mismatch: device computed %08x over %zu bytes, host sent %08x", crc, s.data.size(), c.crc);
          s.open = false;
          nack(msg::Status::CRC_MISMATCH, t);
          break;
        }
        ActiveConfig a;
        try {
          a = I.config_store->commit(s.data);
        } catch (const fs::ConfigError& e) {
          s.open = false;
          nack(msg::Status::INVALID_CONFIG, e.what());  // nothing changed on disk
          break;
        } catch (const std::exception& e) {
          s.open = false;
          nack(msg::Status::IO_ERROR, e.what());
          break;
        }
        s.open = false;
        {
          std::lock_guard lock(I.cfg_mu);
          I.active = a;
        }
        if (hooks_.config_applied) hooks_.config_applied(a.config);
        msg::ConfigCommitted r;
        r.crc = crc;
        r.config_id = a.id;
        reply(r);
        break;
      }
      case msg::LogList::kId: {
        msg::LogList l;
        if (!decode_req(l)) break;
        msg::LogFiles f;
        auto files = I.logs->list();
        if (files.size() > 64) files.erase(files.begin(), files.end() - 64);  // newest 64
        for (auto& x : files) f.files.push_back({x.id, x.size});
        reply(f);
        break;
      }
      case msg::LogRead::kId: {
        msg::LogRead rq;
        if (!decode_req(rq)) break;
        msg::LogData d;
        d.id = rq.id;
        d.offset = rq.offset;
        if (!I.logs->read(rq.id, rq.offset, rq.length, d.data, d.size)) {
          nack(msg::Status::NOT_FOUND, "no log file " + std::to_string(rq.id));
          break;
        }
        reply(d);
        break;
      }
      case msg::TelemetryGet::kId: {
        msg::TelemetryGet g;
        if (!decode_req(g)) break;
        msg::Telemetry t;
        {
          std::lock_guard lock(I.latest_mu);
          if (I.has_latest) t = I.latest;
        }
        t.state = std::uint8_t(state_.load());
        t.rx_errors = I.decoder.errors().total();
        t.tx_dropped = I.tx_dropped;
        t.log_dropped = I.log_dropped;
        if (t.source.empty()) t.source = "none (nothing published yet)";
        reply(t);
        break;
      }
      case msg::SnapshotBegin::kId: {
        msg::SnapshotBegin b;
        if (!decode_req(b)) break;
        if (!hooks_.snapshot) { nack(msg::Status::UNSUPPORTED, "this runtime provides no snapshots"); break; }
        I.snapshot = hooks_.snapshot();
        msg::SnapshotInfo info;
        info.snap_id = ++I.snap_id;
        for (const auto& f : I.snapshot) info.files.push_back({f.name, std::uint32_t(f.data.size()), crc32c(f.data)});
        if (info.files.size() > 32) { nack(msg::Status::INTERNAL, "snapshot has more than 32 files"); break; }
        reply(info);
        break;
      }
      case msg::SnapshotRead::kId: {
        msg::SnapshotRead rq;
        if (!decode_req(rq)) break;
        if (rq.snap_id != I.snap_id || rq.file >= I.snapshot.size()) {
          nack(msg::Status::NOT_FOUND, "no snapshot " + std::to_string(rq.snap_id) + " file " + std::to_string(rq.file));
          break;
        }
        const auto& f = I.snapshot[rq.file].data;
        if (rq.offset > f.size()) { nack(msg::Status::BAD_OFFSET, "offset past the end of the file"); break; }
        msg::SnapshotData d;
        d.snap_id = rq.snap_id;
        d.file = rq.file;
        d.offset = rq.offset;
        const std::size_t n = std::min<std::size_t>(rq.length, f.size() - rq.offset);
        d.data.assign(f.begin() + std::ptrdiff_t(rq.offset), f.begin() + std::ptrdiff_t(rq.offset + n));
        reply(d);
        break;
      }
      case msg::Control::kId: {
        msg::Control c;
        if (!decode_req(c)) break;
        const auto a = static_cast<msg::ControlAction>(c.action);
        const auto st = static_cast<msg::RunState>(state_.load());
        if (a == msg::ControlAction::RESUME && st == msg::RunState::ESTOP) {
          nack(msg::Status::BUSY, "e-stop is active: clear it first (CLEAR_ESTOP)");
          break;
        }
        if (a == msg::ControlAction::PAUSE && st == msg::RunState::ESTOP) {
          nack(msg::Status::BUSY, "e-stop is active");
          break;
        }
        state_ = int(a == msg::ControlAction::ESTOP ? msg::RunState::ESTOP
                     : a == msg::ControlAction::PAUSE ? msg::RunState::PAUSED
                                                : msg::RunState::RUNNING);
        if (hooks_.control) hooks_.control(a);
        ack();
        break;
      }
      default:
        nack(msg::Status::UNKNOWN_MESSAGE, "unknown message id " + std::to_string(id));
    }
  } catch (const std::exception& e) {
    nack(msg::Status::INTERNAL, e.what());
  }
  auto wire = encode_frame(out_id, seq, out);
  I.send(wire);
  I.have_last = true;
  I.last_id = id;
  I.last_seq = seq;
  I.last_answer = std::move(wire);
}

}  // namespace fs::link
