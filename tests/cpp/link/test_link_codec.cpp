// The C++ link codec (hand-written framing + the codec generated from protocol.toml) against the
// shared vectors written by the Python codec (common/protocol/vectors.toml).
#include <gtest/gtest.h>

#include <toml++/toml.h>

#include <string>
#include <vector>

#include "fuzzystereo/link/framing.hpp"
#include "fuzzystereo/link/protocol_gen.hpp"

using namespace fs::link;

namespace {
std::vector<std::uint8_t> unhex(const std::string& h) {
  std::vector<std::uint8_t> v;
  for (std::size_t i = 0; i + 1 < h.size(); i += 2) v.push_back(std::uint8_t(std::stoi(h.substr(i, 2), nullptr, 16)));
  return v;
}
std::string hex(const std::vector<std::uint8_t>& v) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (auto c : v) { s += d[c >> 4]; s += d[c & 15]; }
  return s;
}
toml::table vectors() { return toml::parse_file(FS_PROTOCOL_DIR "/vectors.toml"); }
}  // namespace

TEST(LinkCodec, SchemaHashMatchesPythonSide) {
  auto v = vectors();
  EXPECT_EQ(std::string(msg::kSchemaHashHex), v["schema_hash"].value_or(std::string()));
}

TEST(LinkCodec, Crc32cVectors) {
  auto v = vectors();
  const std::vector<std::uint8_t> check = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(crc32c(check), 0xE3069283u);  // the catalogue check value of CRC-32C
  int n = 0;
  for (auto& e : *v["crc"].as_array()) {
    auto& t = *e.as_table();
    EXPECT_EQ(crc32c(unhex(t["data_hex"].value_or(std::string()))), std::uint32_t(t["crc32c"].value_or(std::int64_t(0))));
    ++n;
  }
  EXPECT_GE(n, 5);
}

TEST(LinkCodec, CobsVectors) {
  auto v = vectors();
  for (auto& e : *v["cobs"].as_array()) {
    auto& t = *e.as_table();
    const auto raw = unhex(t["raw_hex"].value_or(std::string()));
    const auto enc = unhex(t["encoded_hex"].value_or(std::string()));
    EXPECT_EQ(hex(cobs_encode(raw.data(), raw.size())), hex(enc));
    auto dec = cobs_decode(enc.data(), enc.size());
    ASSERT_TRUE(dec.has_value());
    EXPECT_EQ(hex(*dec), hex(raw));
  }
}

TEST(LinkCodec, FrameVectors) {
  auto v = vectors();
  int n = 0;
  for (auto& e : *v["frame"].as_array()) {
    auto& t = *e.as_table();
    const auto id = std::uint8_t(t["id"].value_or(std::int64_t(0)));
    const auto seq = std::uint16_t(t["seq"].value_or(std::int64_t(0)));
    const auto payload = unhex(t["payload_hex"].value_or(std::string()));
    const std::string frame_hex = t["frame_hex"].value_or(std::string());
    SCOPED_TRACE(t["message"].value_or(std::string()));
    EXPECT_EQ(hex(encode_frame(id, seq, payload)), frame_hex);
    FrameDecoder d(msg::kMaxPayload);
    std::vector<Frame> out;
    const auto wire = unhex(frame_hex);
    EXPECT_EQ(d.feed(wire.data(), wire.size(), out), 0u);
    ASSERT_EQ(out.size(), 1u);
    EXPECT_EQ(out[0].id, id);
    EXPECT_EQ(out[0].seq, seq);
    EXPECT_EQ(hex(out[0].payload), hex(payload));
    std::string text;
    ASSERT_TRUE(msg::describe_payload(id, payload.data(), payload.size(), text));
    EXPECT_EQ(text, t["describe"].value_or(std::string()));
    std::vector<std::uint8_t> again;
    ASSERT_TRUE(msg::reencode_payload(id, payload.data(), payload.size(), again));
    EXPECT_EQ(hex(again), hex(payload));
    ++n;
  }
  EXPECT_GE(n, 10);
}

TEST(LinkCodec, DecoderResyncsAfterGarbageAndCountsErrors) {
  const auto good = encode_frame(msg::Control::kId, 5, {1});
  auto bad = encode_frame(msg::Control::kId, 6, {2});
  bad[3] ^= 0x40;  // corrupt one byte inside
  std::vector<std::uint8_t> stream = {0x13, 0x37, 0xFF, 0x42};  // garbage without a delimiter
  stream.insert(stream.end(), good.begin(), good.end());
  stream.insert(stream.end(), bad.begin(), bad.end());
  stream.insert(stream.end(), good.begin(), good.end());
  std::vector<std::uint8_t> junk(5000, 0x55);  // longer than any frame: resync at the next 0x00
  stream.insert(stream.end(), junk.begin(), junk.end());
  stream.insert(stream.end(), good.begin(), good.end());
  FrameDecoder d(msg::kMaxPayload);
  std::vector<Frame> out;
  for (auto b : stream) d.feed(&b, 1, out);  // byte by byte, as a UART delivers them
  ASSERT_EQ(out.size(), 3u);
  for (auto& f : out) EXPECT_EQ(f.seq, 5);
  EXPECT_EQ(d.errors().crc + d.errors().cobs, 2u);  // the garbage prefix and the corrupted frame
  EXPECT_EQ(d.errors().oversize, 1u);
}

TEST(LinkCodec, DecoderRejectsOutOfRangeValues) {
  msg::Control c;
  c.action = 9;  // valid 1..4
  std::vector<std::uint8_t> pl;
  Writer w(pl);
  encode(c, w);
  std::string text;
  EXPECT_FALSE(msg::describe_payload(msg::Control::kId, pl.data(), pl.size(), text));
  pl[0] = 1;
  EXPECT_TRUE(msg::describe_payload(msg::Control::kId, pl.data(), pl.size(), text));
  pl.push_back(0);  // trailing byte
  EXPECT_FALSE(msg::describe_payload(msg::Control::kId, pl.data(), pl.size(), text));
}
