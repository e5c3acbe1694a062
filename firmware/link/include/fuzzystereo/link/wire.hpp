// Little-endian primitives of the link payloads, used by the generated codec
// (build/<preset>/firmware/generated/fuzzystereo/link/protocol_gen.hpp, from
// common/protocol/protocol.toml). Encoding rules are in that file's header comment.
#pragma once
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace fs::link {

// Appends to a byte vector; ok() turns false when a str/bytes value is longer than its length prefix.
class Writer {
 public:
  explicit Writer(std::vector<std::uint8_t>& out) : out_(out) {}
  void u8(std::uint8_t v) { out_.push_back(v); }
  void u16(std::uint16_t v) { put(v, 2); }
  void u32(std::uint32_t v) { put(v, 4); }
  void i32(std::int32_t v) { put(static_cast<std::uint32_t>(v), 4); }
  void f32(float v) {
    std::uint32_t b;
    std::memcpy(&b, &v, 4);
    put(b, 4);
  }
  void str(const std::string& s) {
    if (s.size() > 255) { ok_ = false; return; }
    u8(static_cast<std::uint8_t>(s.size()));
    out_.insert(out_.end(), s.begin(), s.end());
  }
  void bytes(const std::vector<std::uint8_t>& b) {
    if (b.size() > 65535) { ok_ = false; return; }
    u16(static_cast<std::uint16_t>(b.size()));
    out_.insert(out_.end(), b.begin(), b.end());
  }
  bool ok() const { return ok_; }

 private:
  void put(std::uint32_t v, int n) {
    for (int i = 0; i < n; ++i) out_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t>& out_;
  bool ok_ = true;
};

// Reads from a byte range; every getter returns false (and leaves the value alone) when the
// payload is too short, so a truncated or garbage payload is rejected, never read past its end.
class Reader {
 public:
  Reader(const std::uint8_t* data, std::size_t n) : p_(data), n_(n) {}
  bool u8(std::uint8_t& v) { return get(v, 1); }
  bool u16(std::uint16_t& v) { return get(v, 2); }
  bool u32(std::uint32_t& v) { return get(v, 4); }
  bool i32(std::int32_t& v) {
    std::uint32_t b;
    if (!get(b, 4)) return false;
    v = static_cast<std::int32_t>(b);
    return true;
  }
  bool f32(float& v) {
    std::uint32_t b;
    if (!get(b, 4)) return false;
    std::memcpy(&v, &b, 4);
    return true;
  }
  bool str(std::string& s) {
    std::uint8_t len;
    if (!u8(len) || n_ - pos_ < len) return false;
    s.assign(reinterpret_cast<const char*>(p_ + pos_), len);
    pos_ += len;
    return true;
  }
  bool bytes(std::vector<std::uint8_t>& b) {
    std::uint16_t len;
    if (!u16(len) || n_ - pos_ < len) return false;
    b.assign(p_ + pos_, p_ + pos_ + len);
    pos_ += len;
    return true;
  }
  bool at_end() const { return pos_ == n_; }

 private:
  template <class T>
  bool get(T& v, int n) {
    if (n_ - pos_ < std::size_t(n)) return false;
    std::uint32_t x = 0;
    for (int i = 0; i < n; ++i) x |= std::uint32_t(p_[pos_ + std::size_t(i)]) << (8 * i);
    pos_ += std::size_t(n);
    v = static_cast<T>(x);
    return true;
  }
  const std::uint8_t* p_;
  std::size_t n_, pos_ = 0;
};

// Canonical text of a value, identical to fuzzyctl.link.schema.describe (checked by the shared
// vectors): integers in decimal, f32 as %.9g, str in double quotes, bytes as h'<hex>'.
inline void describe_value(std::uint32_t v, std::string& s) { s += std::to_string(v); }
inline void describe_value(std::uint16_t v, std::string& s) { s += std::to_string(v); }
inline void describe_value(std::uint8_t v, std::string& s) { s += std::to_string(v); }
inline void describe_value(std::int32_t v, std::string& s) { s += std::to_string(v); }
inline void describe_value(float v, std::string& s) {
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", static_cast<double>(v));
  s += b;
}
inline void describe_value(const std::string& v, std::string& s) { s += '"' + v + '"'; }
inline void describe_value(const std::vector<std::uint8_t>& v, std::string& s) {
  static const char* hex = "0123456789abcdef";
  s += "h'";
  for (auto c : v) { s += hex[c >> 4]; s += hex[c & 15]; }
  s += '\'';
}

}  // namespace fs::link
