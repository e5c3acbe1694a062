#include "fuzzystereo/link/framing.hpp"

#include <array>
#include <cstdint>

namespace fs::link {

namespace {
constexpr std::array<std::uint32_t, 256> make_table() {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? (c >> 1) ^ 0x82F63B78u : c >> 1;
    t[i] = c;
  }
  return t;
}
constexpr auto kTable = make_table();
}  // namespace

std::uint32_t crc32c(const std::uint8_t* data, std::size_t n, std::uint32_t crc) {
  crc = ~crc;
  for (std::size_t i = 0; i < n; ++i) crc = kTable[(crc ^ data[i]) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

std::vector<std::uint8_t> cobs_encode(const std::uint8_t* data, std::size_t n) {
  std::vector<std::uint8_t> out;
  out.reserve(n + n / 254 + 2);
  std::size_t code_pos = out.size();
  out.push_back(0);
  std::uint8_t code = 1;
  for (std::size_t i = 0; i < n; ++i) {
    if (data[i] == 0) {
      out[code_pos] = code;
      code_pos = out.size();
      out.push_back(0);
      code = 1;
    } else {
      out.push_back(data[i]);
      if (++code == 0xFF) {  // a full block: the next one starts only if more bytes follow
        out[code_pos] = code;
        code = 1;
        if (i + 1 < n) {
          code_pos = out.size();
          out.push_back(0);
        } else {
          code_pos = SIZE_MAX;
        }
      }
    }
  }
  if (code_pos != SIZE_MAX) out[code_pos] = code;
  return out;
}

std::optional<std::vector<std::uint8_t>> cobs_decode(const std::uint8_t* data, std::size_t n) {
  std::vector<std::uint8_t> out;
  out.reserve(n);
  std::size_t i = 0;
  while (i < n) {
    const std::uint8_t code = data[i++];
    if (code == 0) return std::nullopt;
    for (std::uint8_t k = 1; k < code; ++k) {
      if (i >= n || data[i] == 0) return std::nullopt;
      out.push_back(data[i++]);
    }
    if (code != 0xFF && i < n) out.push_back(0);
  }
  return out;
}

std::vector<std::uint8_t> encode_frame(std::uint8_t id, std::uint16_t seq, const std::vector<std::uint8_t>& payload) {
  std::vector<std::uint8_t> raw;
  raw.reserve(payload.size() + kFrameOverhead);
  raw.push_back(id);
  raw.push_back(static_cast<std::uint8_t>(seq & 0xFF));
  raw.push_back(static_cast<std::uint8_t>(seq >> 8));
  raw.insert(raw.end(), payload.begin(), payload.end());
  const std::uint32_t c = crc32c(raw.data(), raw.size());
  for (int i = 0; i < 4; ++i) raw.push_back(static_cast<std::uint8_t>(c >> (8 * i)));
  std::vector<std::uint8_t> out;
  out.reserve(raw.size() + raw.size() / 254 + 4);
  out.push_back(0);
  const auto enc = cobs_encode(raw.data(), raw.size());
  out.insert(out.end(), enc.begin(), enc.end());
  out.push_back(0);
  return out;
}

FrameDecoder::FrameDecoder(std::size_t max_payload)
    : max_encoded_(max_payload + kFrameOverhead + (max_payload + kFrameOverhead) / 254 + 2) {}

void FrameDecoder::finish(std::vector<Frame>& out, std::size_t& dropped) {
  if (overflow_) {
    ++errors_.oversize;
    ++dropped;
  } else if (!buf_.empty()) {
    auto raw = cobs_decode(buf_.data(), buf_.size());
    if (!raw) {
      ++errors_.cobs;
      ++dropped;
    } else if (raw->size() < kFrameOverhead) {
      ++errors_.short_;
      ++dropped;
    } else {
      const std::size_t body = raw->size() - 4;
      std::uint32_t c = 0;
      for (int i = 0; i < 4; ++i) c |= std::uint32_t((*raw)[body + std::size_t(i)]) << (8 * i);
      if (c != crc32c(raw->data(), body)) {
        ++errors_.crc;
        ++dropped;
      } else {
        Frame f;
        f.id = (*raw)[0];
        f.seq = static_cast<std::uint16_t>((*raw)[1] | ((*raw)[2] << 8));
        f.payload.assign(raw->begin() + 3, raw->begin() + static_cast<std::ptrdiff_t>(body));
        out.push_back(std::move(f));
      }
    }
  }
  buf_.clear();
  overflow_ = false;
}

std::size_t FrameDecoder::feed(const std::uint8_t* data, std::size_t n, std::vector<Frame>& out) {
  std::size_t dropped = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (data[i] == 0) {
      finish(out, dropped);  // an empty frame (two delimiters) is no error
    } else if (buf_.size() < max_encoded_) {
      buf_.push_back(data[i]);
    } else {
      overflow_ = true;  // drop bytes until the next delimiter: resync there
    }
  }
  return dropped;
}

}  // namespace fs::link
