// Smoke test of the plain image buffer: row-major, tightly packed addressing (stride == width).
// Odd, non-square size so a swapped x/y or width/height shows up.
#include <gtest/gtest.h>

#include <cstdint>

#include "fuzzystereo/image.hpp"
#include "fuzzystereo/memory.hpp"

namespace {

constexpr int kW = 7;
constexpr int kH = 5;

TEST(ImageSmoke, ConstructsFilledTightlyPacked) {
  const fs::ImageU8 img(kW, kH, std::uint8_t{9});
  EXPECT_EQ(img.width, kW);
  EXPECT_EQ(img.height, kH);
  EXPECT_EQ(img.size(), std::size_t(kW * kH));
  EXPECT_FALSE(img.empty());
  for (const auto v : img.data) EXPECT_EQ(v, 9);
  EXPECT_TRUE(fs::ImageU8{}.empty());
}

TEST(ImageSmoke, RowAndAtAddressTheSameElement) {
  fs::ImageI16 img(kW, kH);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) img.at(x, y) = static_cast<std::int16_t>(100 * y + x);

  for (int y = 0; y < kH; ++y) {
    // Rows are consecutive: row(y) starts exactly y * width elements into the buffer.
    EXPECT_EQ(img.row(y), img.data.data() + y * kW);
    for (int x = 0; x < kW; ++x) {
      EXPECT_EQ(img.row(y)[x], 100 * y + x);
      EXPECT_EQ(img.data[std::size_t(y * kW + x)], 100 * y + x);
    }
  }
  // Last element of the buffer is the bottom-right pixel.
  EXPECT_EQ(img.data.back(), 100 * (kH - 1) + (kW - 1));

  const fs::ImageI16& cimg = img;
  EXPECT_EQ(cimg.at(6, 4), 406);
  EXPECT_EQ(cimg.row(2)[3], 203);
}

TEST(ImageSmoke, InvalidDisparityIsOutsideTheQ4Range) {
  // Q11.4 disparities are >= 0; kInvalidDisp must not collide with any of them.
  EXPECT_EQ(fs::kDispScale, 16);
  EXPECT_LT(fs::kInvalidDisp, 0);
}

}  // namespace

// The process memory policy (fuzzystereo/memory.hpp) must really be applied on glibc systems: an
// earlier version checked __GLIBC__ before any libc header had defined it and silently did nothing.
TEST(Runtime, RetainFreedMemoryAppliesOnGlibc) {
#if defined(__SANITIZE_ADDRESS__)
  EXPECT_FALSE(fs::retain_freed_memory());  // ASan's allocator, not glibc's
#elif defined(__GLIBC__)
  EXPECT_TRUE(fs::retain_freed_memory());
#else
  EXPECT_FALSE(fs::retain_freed_memory());
#endif
}
