// Golden hashes shared by the cross-platform tests (tests/cpp/sim/test_golden.cpp,
// tests/cpp/robot/test_golden_robot.cpp): 64-bit FNV-1a over the bytes of a stage's output, and the
// expected-hash files in tests/golden/ ("name hex" per line, '#' comments). The same file is checked
// natively, under qemu-aarch64 and under qemu-x86_64 -cpu Nehalem (`make test`); with
// FS_UPDATE_GOLDEN=1 a test rewrites its file instead (on x86-64, after an intended change).
#pragma once
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "fuzzystereo/image.hpp"

namespace fs::golden {

// FNV-1a, 64 bit, over the bytes of trivially copyable values (little-endian on every target here).
struct Fnv {
  std::uint64_t h = 1469598103934665603ull;
  void bytes(const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  }
  template <class T>
  Fnv& add(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    bytes(&v, sizeof v);
    return *this;
  }
  template <class T>
  Fnv& add(const std::vector<T>& v) {
    add(v.size());
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
    return *this;
  }
  template <class T>
  Fnv& add(const fs::Image<T>& im) {
    add(im.width).add(im.height);
    return add(im.data);
  }
};

template <class... T>
std::uint64_t hash_of(const T&... v) {
  Fnv f;
  (f.add(v), ...);
  return f.h;
}

using Hashes = std::map<std::string, std::uint64_t>;

inline std::string hex(std::uint64_t v) {
  char b[17];
  std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(v));
  return b;
}

inline Hashes read_file(const std::string& path) {
  Hashes g;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string name, h;
    if (ls >> name >> h) g[name] = std::stoull(h, nullptr, 16);
  }
  return g;
}

// Compares `got` with the file (every name, both ways), or rewrites the file with FS_UPDATE_GOLDEN=1
// (the test then skips). `what` names the test for the file's header.
inline void check(const Hashes& got, const std::string& path, const std::string& what) {
  const char* update = std::getenv("FS_UPDATE_GOLDEN");
  if (update && std::strcmp(update, "1") == 0) {
    std::ofstream f(path);
    f << "# Golden FNV-1a hashes of " << what << "; regenerate on x86-64 with\n"
      << "# FS_UPDATE_GOLDEN=1 and the test binary (--gtest_filter='Golden*'), then commit.\n";
    for (const auto& [k, v] : got) f << k << ' ' << hex(v) << '\n';
    GTEST_SKIP() << "wrote " << path;
  }
  const Hashes want = read_file(path);
  ASSERT_FALSE(want.empty()) << path << " is missing or empty";
  for (const auto& [k, v] : want) {
    const auto it = got.find(k);
    ASSERT_NE(it, got.end()) << "stage " << k << " of " << path << " is not computed any more";
    EXPECT_EQ(hex(it->second), hex(v)) << "stage " << k << " differs from " << path;
  }
  for (const auto& [k, v] : got) EXPECT_TRUE(want.count(k)) << "stage " << k << " is not in " << path;
}

}  // namespace fs::golden
