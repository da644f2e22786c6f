// The replay's fast offset-to-address map against BufferInfo::address, the definition: every layout a
// capture declares and the awkward ones (widths that are not powers of two, one texel wide, tiles of other
// sides, offsets up to 2^32 - 1), on offsets at random and at every row and tile boundary.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "cachesim/address_map.hpp"

namespace hp::cachesim {
namespace {

trace::BufferInfo image(trace::BufferKind kind, uint32_t texel_bytes, uint32_t width, uint32_t height, uint32_t tile_w,
                        uint32_t tile_h) {
  trace::BufferInfo b;
  b.kind = kind;
  b.base_address = 0x123456789000ull;
  b.texel_bytes = texel_bytes;
  b.width = width;
  b.height = height;
  b.row_pitch_bytes = width * texel_bytes + 256;
  b.tile_width = tile_w;
  b.tile_height = tile_h;
  b.size_bytes = uint64_t(width) * height * texel_bytes;
  return b;
}

TEST(AddressMap, EqualsBufferInfoAddressOnEveryLayout) {
  using K = trace::BufferKind;
  const trace::BufferInfo layouts[] = {
      image(K::image_tiled, 8, 1920, 1080, 8, 8),    image(K::image_tiled, 4, 1920, 1080, 8, 8),
      image(K::image_tiled, 16, 1280, 720, 8, 8),    image(K::image_linear, 8, 1920, 1080, 0, 0),
      image(K::image_tiled, 8, 100, 64, 8, 8),       image(K::image_tiled, 8, 1001, 7, 16, 4),
      image(K::image_tiled, 2, 3, 5, 2, 2),          image(K::image_linear, 4, 1, 1000, 0, 0),
      image(K::image_tiled, 12, 640, 480, 8, 8),     image(K::image_tiled, 4, 640, 480, 6, 8),
      image(K::image_linear, 8, 65537, 65535, 0, 0), image(K::image_tiled, 1, 4099, 1048573, 32, 1),
  };
  std::mt19937_64 rng(7);
  for (const trace::BufferInfo& b : layouts) {
    SCOPED_TRACE(std::to_string(int(b.kind)) + " " + std::to_string(b.texel_bytes) + " " + std::to_string(b.width));
    const AddressMap map(&b);
    uint64_t checked = 0;
    const auto check = [&](uint64_t offset) {
      if (offset > 0xFFFFFFFFull) return;
      ASSERT_EQ(map(uint32_t(offset)), b.address(uint32_t(offset))) << "offset " << offset;
      ++checked;
    };
    for (int k = 0; k < 20000; ++k) check(rng() % std::min<uint64_t>(b.size_bytes + 1, uint64_t(1) << 32));
    for (int k = 0; k < 2000; ++k) check(rng() & 0xFFFFFFFFull);  // past the image too: the same arithmetic
    for (uint64_t y = 0; y < b.height && y < 4096; y += 1 + y / 8)
      for (int64_t dx : {-1, 0, 1})
        check(uint64_t(std::max<int64_t>(0, int64_t(y * b.width) + dx)) * b.texel_bytes + b.texel_bytes - 1);
    check(0xFFFFFFFFull);
    EXPECT_GT(checked, 20000u);
  }
  // A plain buffer: the base plus the offset.
  trace::BufferInfo plain;
  plain.base_address = 4096;
  plain.size_bytes = 1 << 20;
  EXPECT_EQ(AddressMap(&plain)(77), 4096u + 77u);
}

}  // namespace
}  // namespace hp::cachesim
