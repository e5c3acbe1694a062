// Config store (validated, atomic, backup fallback) and log store (records, rotation, truncation).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "config.hpp"
#include "fuzzystereo/link/config_store.hpp"
#include "fuzzystereo/link/log_store.hpp"

using namespace fs::link;
namespace sfs = std::filesystem;

namespace {
// A fresh directory under the system temp directory, removed again when the test ends (pass or
// fail), so repeated test runs leave nothing behind in /tmp.
class FreshDir {
 public:
  explicit FreshDir(const std::string& name)
      : d_(sfs::temp_directory_path() / ("fs_link_test_" + name + "_" + std::to_string(::getpid()))) {
    sfs::remove_all(d_);
    sfs::create_directories(d_);
  }
  ~FreshDir() {
    std::error_code ec;
    sfs::remove_all(d_, ec);
  }
  FreshDir(const FreshDir&) = delete;
  FreshDir& operator=(const FreshDir&) = delete;
  operator const sfs::path&() const { return d_; }
  sfs::path operator/(const std::string& f) const { return d_ / f; }

 private:
  sfs::path d_;
};
std::vector<std::uint8_t> file_bytes(const sfs::path& p) {
  const std::string t = read_file_text(p);
  return {t.begin(), t.end()};
}
}  // namespace

TEST(ConfigStore, CommitValidatesKeepsBackupAndRefusesBadConfig) {
  const FreshDir d("cfg");
  ConfigStore s(d);
  EXPECT_EQ(s.load().source, "defaults");
  const auto a = s.commit("[esr]\nwindow = 7\n");
  EXPECT_EQ(a.source, "active");
  EXPECT_EQ(a.config.matcher.esr.window, 7);
  s.commit("[esr]\nwindow = 9\n");
  EXPECT_EQ(read_file_text(d / "backup.toml"), "[esr]\nwindow = 7\n");
  try {
    s.commit("[esr]\nwindow = 4\n");  // must be odd
    FAIL() << "an even window was accepted";
  } catch (const fs::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("esr.window"), std::string::npos) << e.what();
  }
  EXPECT_EQ(s.load().config.matcher.esr.window, 9);  // the old one stays active
  EXPECT_FALSE(sfs::exists(d / "active.toml.tmp") && read_file_text(d / "active.toml.tmp").find("= 4") == std::string::npos);
}

TEST(ConfigStore, CorruptActiveFallsBackToBackupAndSaysSo) {
  const FreshDir d("cfg2");
  ConfigStore s(d);
  s.commit("[esr]\nwindow = 7\n");
  s.commit("[esr]\nwindow = 9\n");
  { std::ofstream(d / "active.toml") << "[esr]\nwindow = \x01\x02 garbage"; }
  const auto a = s.load();
  EXPECT_EQ(a.source, "backup");
  EXPECT_EQ(a.config.matcher.esr.window, 7);
  EXPECT_NE(a.warning.find("active config unusable"), std::string::npos) << a.warning;
}

TEST(LogStore, RecordsRotationAndTruncatedTail) {
  const FreshDir d("log");
  std::vector<std::uint32_t> ids;
  {
    LogStore s(d, 4096, 3);
    std::vector<std::uint8_t> pl(100, 0xAB);
    for (std::uint32_t i = 0; i < 200; ++i) {
      pl[0] = std::uint8_t(i);
      ASSERT_TRUE(s.append(i, 0x88, pl));
    }
    const auto files = s.list();
    ASSERT_EQ(files.size(), 3u);  // rotated, only the newest 3 kept
    for (auto& f : files) EXPECT_LE(f.size, 4096u);
    std::vector<std::uint8_t> buf;
    std::uint32_t size = 0;
    ASSERT_TRUE(s.read(files.back().id, 0, 100000, buf, size));
    EXPECT_EQ(buf.size(), size);
    const auto p = parse_log(buf);
    EXPECT_TRUE(p.header_ok);
    ASSERT_FALSE(p.records.empty());
    EXPECT_EQ(p.records.back().t_ms, 199u);
    EXPECT_EQ(p.good_bytes, buf.size());
    EXPECT_FALSE(s.read(999, 0, 10, buf, size));
  }
  // a file cut off mid-record stays readable up to its last whole record
  sfs::path last;
  for (auto& e : sfs::directory_iterator(d)) if (last.empty() || e.path() > last) last = e.path();
  auto bytes = file_bytes(last);
  const auto whole = parse_log(bytes);
  bytes.resize(bytes.size() - 50);
  const auto cut = parse_log(bytes);
  EXPECT_EQ(cut.records.size(), whole.records.size() - 1);
  // a corrupted byte ends the readable part at the record before it
  auto flipped = file_bytes(last);
  flipped[kLogHeaderSize + 8 + 2] ^= 1;
  EXPECT_EQ(parse_log(flipped).records.size(), 0u);
}
