// Fuzz driver for the link decoder and the generated codec: random byte streams and mutations of
// valid frames (bit flips, byte insert/delete, truncation, splices) fed to FrameDecoder, and every
// frame that passes its CRC decoded and re-encoded. Any crash, sanitizer report or round-trip
// mismatch fails. Built in every preset; run under the asan preset for the sanitizers.
// usage: fs_link_fuzz [iterations] [seed]
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "fuzzystereo/link/framing.hpp"
#include "fuzzystereo/link/protocol_gen.hpp"

using namespace fs::link;

int main(int argc, char** argv) {
  const long iters = argc > 1 ? std::atol(argv[1]) : 100000;
  std::mt19937 rng(argc > 2 ? std::uint32_t(std::atol(argv[2])) : 1u);
  auto rnd = [&](std::uint32_t n) { return n ? rng() % n : 0u; };
  // seeds: valid frames of every message with random payload content
  std::vector<std::vector<std::uint8_t>> seeds;
  {
    msg::Telemetry t;
    t.source = "fuzz";
    t.stages = {{"cost", 1.5f}, {"wta", 0.5f}};
    t.obstacles = {{1, 2, 3.0f, -1.0f, 0.5f}};
    std::vector<std::uint8_t> pl;
    Writer w(pl);
    encode(t, w);
    seeds.push_back(encode_frame(msg::Telemetry::kId, 1, pl));
    msg::ConfigChunk c;
    c.offset = 10;
    c.data.assign(300, 0);
    pl.clear();
    encode(c, w);
    seeds.push_back(encode_frame(msg::ConfigChunk::kId, 2, pl));
    msg::LogFiles lf;
    lf.files = {{1, 2}, {3, 4}};
    pl.clear();
    encode(lf, w);
    seeds.push_back(encode_frame(msg::LogFiles::kId, 3, pl));
  }
  long frames_ok = 0, decoded_ok = 0;
  FrameDecoder dec(msg::kMaxPayload);
  std::vector<Frame> out;
  for (long it = 0; it < iters; ++it) {
    std::vector<std::uint8_t> data;
    if (rnd(4) == 0) {  // pure random
      data.resize(rnd(2048));
      for (auto& b : data) b = std::uint8_t(rnd(256));
      if (rnd(2)) {  // random payload with a valid CRC: exercises the message decoders
        std::vector<std::uint8_t> pl(rnd(200));
        for (auto& b : pl) b = std::uint8_t(rnd(4) ? rnd(256) : rnd(4));
        const std::uint8_t ids[] = {0x01, 0x02, 0x80, 0x81, 0x86, 0x88, 0x89, 0x0B, 0x04};
        data = encode_frame(ids[rnd(9)], std::uint16_t(rnd(65536)), pl);
      }
    } else {  // mutate a valid frame
      data = seeds[rnd(std::uint32_t(seeds.size()))];
      const int muts = 1 + int(rnd(4));
      for (int m = 0; m < muts && !data.empty(); ++m) {
        const std::size_t pos = rnd(std::uint32_t(data.size()));
        switch (rnd(5)) {
          case 0: data[pos] ^= std::uint8_t(1u << rnd(8)); break;
          case 1: data.insert(data.begin() + std::ptrdiff_t(pos), std::uint8_t(rnd(256))); break;
          case 2: data.erase(data.begin() + std::ptrdiff_t(pos)); break;
          case 3: data.resize(pos); break;
          default: {
            const auto& o = seeds[rnd(std::uint32_t(seeds.size()))];
            data.insert(data.end(), o.begin(), o.begin() + std::ptrdiff_t(rnd(std::uint32_t(o.size()))));
          }
        }
      }
    }
    out.clear();
    dec.feed(data.data(), data.size(), out);
    for (const auto& f : out) {
      ++frames_ok;
      std::string text;
      if (msg::describe_payload(f.id, f.payload.data(), f.payload.size(), text)) {
        ++decoded_ok;
        std::vector<std::uint8_t> again;
        if (!msg::reencode_payload(f.id, f.payload.data(), f.payload.size(), again) || again != f.payload) {
          std::fprintf(stderr, "round trip mismatch for %s\n", text.c_str());
          return 1;
        }
      }
    }
  }
  std::printf("fs_link_fuzz: %ld iterations, %ld frames passed the CRC, %ld decoded and round-tripped, "
              "%u dropped (cobs %u crc %u short %u oversize %u)\n",
              iters, frames_ok, decoded_ok, dec.errors().total(), dec.errors().cobs, dec.errors().crc,
              dec.errors().short_, dec.errors().oversize);
  return 0;
}
