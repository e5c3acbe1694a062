#include "fuzzystereo/link/log_store.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "fuzzystereo/link/framing.hpp"
#include "fuzzystereo/link/protocol_gen.hpp"

namespace fs::link {

namespace {
void put32(std::vector<std::uint8_t>& v, std::uint32_t x) {
  for (int i = 0; i < 4; ++i) v.push_back(static_cast<std::uint8_t>(x >> (8 * i)));
}
std::uint32_t get32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
bool parse_id(const std::string& name, std::uint32_t& id) {
  if (name.size() != 14 || name.rfind("log_", 0) != 0 || name.substr(10) != ".fsl") return false;
  id = 0;
  for (int i = 4; i < 10; ++i) {
    if (name[std::size_t(i)] < '0' || name[std::size_t(i)] > '9') return false;
    id = id * 10 + std::uint32_t(name[std::size_t(i)] - '0');
  }
  return true;
}
std::vector<std::uint32_t> ids_in(const std::filesystem::path& dir) {
  std::vector<std::uint32_t> ids;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    std::uint32_t id;
    if (parse_id(e.path().filename().string(), id)) ids.push_back(id);
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}
bool write_all(int fd, const std::vector<std::uint8_t>& v) {
  std::size_t done = 0;
  while (done < v.size()) {
    const ssize_t w = ::write(fd, v.data() + done, v.size() - done);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    done += std::size_t(w);
  }
  return true;
}
}  // namespace

LogStore::LogStore(std::filesystem::path dir, std::size_t rotate_bytes, int keep_files)
    : dir_(std::move(dir)), rotate_bytes_(std::max<std::size_t>(rotate_bytes, 1024)), keep_files_(std::max(keep_files, 1)) {
  std::filesystem::create_directories(dir_);
  const auto ids = ids_in(dir_);
  id_ = ids.empty() ? 0 : ids.back();
  open_next();
}

LogStore::~LogStore() {
  if (fd_ >= 0) ::close(fd_);
}

std::filesystem::path LogStore::path_of(std::uint32_t id) const {
  char name[32];
  std::snprintf(name, sizeof name, "log_%06u.fsl", id % 1000000u);
  return dir_ / name;
}

void LogStore::open_next() {
  if (fd_ >= 0) ::close(fd_);
  ++id_;
  const auto p = path_of(id_);
  fd_ = ::open(p.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (fd_ < 0) throw std::runtime_error("cannot create log file '" + p.string() + "': " + std::strerror(errno));
  std::vector<std::uint8_t> h(kLogMagic, kLogMagic + 8);
  h.insert(h.end(), msg::kSchemaHash.begin(), msg::kSchemaHash.end());
  if (!write_all(fd_, h)) throw std::runtime_error("cannot write log header '" + p.string() + "'");
  size_ = h.size();
  auto ids = ids_in(dir_);
  while (ids.size() > std::size_t(keep_files_)) {
    std::filesystem::remove(path_of(ids.front()));
    ids.erase(ids.begin());
  }
}

bool LogStore::append(std::uint32_t t_ms, std::uint8_t msg_id, const std::vector<std::uint8_t>& payload) {
  std::vector<std::uint8_t> body;
  body.reserve(payload.size() + 5);
  put32(body, t_ms);
  body.push_back(msg_id);
  body.insert(body.end(), payload.begin(), payload.end());
  std::vector<std::uint8_t> rec;
  rec.reserve(body.size() + 8);
  put32(rec, std::uint32_t(body.size()));
  put32(rec, crc32c(body));
  rec.insert(rec.end(), body.begin(), body.end());
  std::lock_guard lock(mu_);
  try {
    if (size_ + rec.size() > rotate_bytes_ && size_ > kLogHeaderSize) open_next();
  } catch (const std::exception&) {
    return false;
  }
  if (!write_all(fd_, rec)) return false;
  size_ += rec.size();
  return true;
}

std::vector<LogFileInfo> LogStore::list() const {
  std::lock_guard lock(mu_);
  std::vector<LogFileInfo> out;
  for (auto id : ids_in(dir_)) {
    std::error_code ec;
    const auto sz = std::filesystem::file_size(path_of(id), ec);
    if (!ec) out.push_back({id, std::uint32_t(sz)});
  }
  return out;
}

std::uint32_t LogStore::current_id() const {
  std::lock_guard lock(mu_);
  return id_;
}

bool LogStore::read(std::uint32_t id, std::uint32_t offset, std::size_t length, std::vector<std::uint8_t>& out,
                    std::uint32_t& size) const {
  std::lock_guard lock(mu_);  // no half-written record is read from the current file
  const int fd = ::open(path_of(id).c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const off_t end = ::lseek(fd, 0, SEEK_END);
  size = end < 0 ? 0u : std::uint32_t(end);
  out.clear();
  if (offset < size) {
    out.resize(std::min<std::size_t>(length, size - offset));
    const ssize_t r = ::pread(fd, out.data(), out.size(), off_t(offset));
    out.resize(r < 0 ? 0 : std::size_t(r));
  }
  ::close(fd);
  return true;
}

LogParse parse_log(const std::vector<std::uint8_t>& f) {
  LogParse p;
  if (f.size() < kLogHeaderSize || !std::equal(kLogMagic, kLogMagic + 8, f.begin())) return p;
  p.header_ok = true;
  std::size_t pos = kLogHeaderSize;
  while (f.size() - pos >= 8) {
    const std::uint32_t len = get32(&f[pos]), crc = get32(&f[pos + 4]);
    if (len < 5 || f.size() - pos - 8 < len) break;
    if (crc32c(&f[pos + 8], len) != crc) break;
    LogRecord r;
    r.t_ms = get32(&f[pos + 8]);
    r.msg_id = f[pos + 12];
    r.payload.assign(f.begin() + std::ptrdiff_t(pos + 13), f.begin() + std::ptrdiff_t(pos + 8 + len));
    p.records.push_back(std::move(r));
    pos += 8 + len;
  }
  p.good_bytes = pos;
  return p;
}

}  // namespace fs::link
