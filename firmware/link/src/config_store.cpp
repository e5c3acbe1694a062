#include "fuzzystereo/link/config_store.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "fuzzystereo/link/framing.hpp"

namespace fs::link {

namespace {

std::uint32_t text_crc(const std::string& t) {
  return crc32c(reinterpret_cast<const std::uint8_t*>(t.data()), t.size());
}

[[noreturn]] void sys_fail(const std::string& what, const std::filesystem::path& p) {
  throw std::runtime_error(what + " '" + p.string() + "': " + std::strerror(errno));
}

void fsync_dir(const std::filesystem::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) sys_fail("cannot open directory", dir);
  if (::fsync(fd) != 0) {
    ::close(fd);
    sys_fail("cannot fsync directory", dir);
  }
  ::close(fd);
}

ActiveConfig make(fs::Config cfg, std::string text, std::string source) {
  ActiveConfig a;
  a.config = std::move(cfg);
  a.id = text_crc(text);
  a.text = std::move(text);
  a.source = std::move(source);
  return a;
}

}  // namespace

std::string read_file_text(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  if (!f) throw std::runtime_error("cannot read '" + p.string() + "'");
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

ConfigStore::ConfigStore(std::filesystem::path dir) : dir_(std::move(dir)) {
  std::filesystem::create_directories(dir_);
}

ActiveConfig ConfigStore::load() const {
  const auto active = dir_ / "active.toml", backup = dir_ / "backup.toml";
  std::string why;
  if (std::filesystem::exists(active)) {
    try {
      std::string t = read_file_text(active);
      return make(fs::parse_config(t, active.string()), t, "active");
    } catch (const std::exception& e) {
      why = std::string("active config unusable (") + e.what() + ")";
    }
  }
  if (std::filesystem::exists(backup)) {
    try {
      std::string t = read_file_text(backup);
      ActiveConfig a = make(fs::parse_config(t, backup.string()), t, "backup");
      a.warning = (why.empty() ? std::string("no active config") : why) + "; using the backup " + backup.string();
      return a;
    } catch (const std::exception& e) {
      why += std::string(why.empty() ? "" : "; ") + "backup unusable (" + e.what() + ")";
    }
  }
  std::string t = fs::embedded_default_config();
  ActiveConfig a = make(fs::parse_config(t, "default.toml"), t, "defaults");
  if (!why.empty()) a.warning = why + "; using the built-in defaults";
  return a;
}

ActiveConfig ConfigStore::commit(const std::string& text) const {
  fs::Config cfg = fs::parse_config(text, "pushed config");  // throws ConfigError: nothing changes
  const auto active = dir_ / "active.toml", backup = dir_ / "backup.toml";
  const auto tmp = dir_ / "active.toml.tmp", btmp = dir_ / "backup.toml.tmp";
  {
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) sys_fail("cannot create", tmp);
    std::size_t done = 0;
    while (done < text.size()) {
      const ssize_t w = ::write(fd, text.data() + done, text.size() - done);
      if (w < 0 && errno == EINTR) continue;
      if (w < 0) {
        ::close(fd);
        sys_fail("cannot write", tmp);
      }
      done += std::size_t(w);
    }
    if (::fsync(fd) != 0) {
      ::close(fd);
      sys_fail("cannot fsync", tmp);
    }
    ::close(fd);
  }
  if (std::filesystem::exists(active)) {
    ::unlink(btmp.c_str());
    if (::link(active.c_str(), btmp.c_str()) != 0) sys_fail("cannot link backup", btmp);
    if (::rename(btmp.c_str(), backup.c_str()) != 0) sys_fail("cannot rename backup", backup);
  }
  if (::rename(tmp.c_str(), active.c_str()) != 0) sys_fail("cannot rename", active);
  fsync_dir(dir_);
  return make(std::move(cfg), text, "active");
}

}  // namespace fs::link
