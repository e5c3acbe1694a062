// Link framing (docs/protocol.md): a frame is
//     id:u8 | seq:u16 LE | payload (<= kMaxPayload) | crc:u32 LE = CRC-32C(id..payload)
// COBS-encoded and sent as 0x00 <cobs> 0x00 (the leading delimiter flushes any garbage the
// receiver holds). The decoder takes bytes as they come, resynchronises on the next 0x00 after
// garbage, counts every dropped frame by reason and keeps going.
//
// Hand-written (CRC-32C table + COBS, ~100 lines): Debian has no COBS library, and these few lines
// keep fs_link free of packages that would need :arm64 variants for the cross build. Checked
// against common/protocol/vectors.toml, which the Python side (PyPI `cobs`, `google-crc32c`) checks too.
#pragma once
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace fs::link {

// CRC-32C (Castagnoli, reflected poly 0x82F63B78, init and xorout 0xFFFFFFFF); "123456789" -> 0xE3069283.
std::uint32_t crc32c(const std::uint8_t* data, std::size_t n, std::uint32_t crc = 0);
inline std::uint32_t crc32c(const std::vector<std::uint8_t>& v) { return crc32c(v.data(), v.size()); }

// COBS (Cheshire & Baker 1999): no 0x00 in the output; decode returns nullopt for invalid input.
std::vector<std::uint8_t> cobs_encode(const std::uint8_t* data, std::size_t n);
std::optional<std::vector<std::uint8_t>> cobs_decode(const std::uint8_t* data, std::size_t n);

struct Frame {
  std::uint8_t id = 0;
  std::uint16_t seq = 0;
  std::vector<std::uint8_t> payload;
};

inline constexpr std::size_t kFrameOverhead = 7;  // id + seq + crc

// Bytes on the wire for one frame, delimiters included.
std::vector<std::uint8_t> encode_frame(std::uint8_t id, std::uint16_t seq, const std::vector<std::uint8_t>& payload);

struct FrameErrors {
  std::uint32_t cobs = 0;      // invalid COBS (a lost or corrupted byte)
  std::uint32_t crc = 0;       // CRC mismatch
  std::uint32_t short_ = 0;    // fewer than kFrameOverhead bytes
  std::uint32_t oversize = 0;  // longer than the largest frame (missing delimiter)
  std::uint32_t total() const { return cobs + crc + short_ + oversize; }
};

class FrameDecoder {
 public:
  explicit FrameDecoder(std::size_t max_payload);
  // Feeds bytes; every whole valid frame is appended to `out`. Returns the number of frames dropped.
  std::size_t feed(const std::uint8_t* data, std::size_t n, std::vector<Frame>& out);
  const FrameErrors& errors() const { return errors_; }

 private:
  void finish(std::vector<Frame>& out, std::size_t& dropped);
  std::size_t max_encoded_;
  std::vector<std::uint8_t> buf_;
  bool overflow_ = false;
  FrameErrors errors_;
};

}  // namespace fs::link
