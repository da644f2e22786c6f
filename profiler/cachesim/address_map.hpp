// Mapping a trace record's offset to a byte address, fast (the replay does it for every image access).
#pragma once

#include <bit>
#include <cstdint>

#include "trace_format.hpp"

namespace hp::cachesim {

// BufferInfo::address with its divisions done by shifts (texel size and tile sides that are powers of two,
// as captures declare them) and one multiplication (by the width): the same address for every offset
// (tests/unit/cachesim/address_map_test.cpp compares them), at a fraction of the cost. Other layouts use
// BufferInfo::address itself.
class AddressMap {
 public:
  AddressMap() = default;
  explicit AddressMap(const trace::BufferInfo* b) : b_(b) {
    if (!b || b->kind == trace::BufferKind::buffer) return;
    const auto pow2 = [](uint32_t v) { return v != 0 && std::has_single_bit(v); };
    if (!pow2(b->texel_bytes) || b->width < 2) return;
    if (b->kind == trace::BufferKind::image_tiled && (!pow2(b->tile_width) || !pow2(b->tile_height))) return;
    texel_shift_ = uint32_t(std::countr_zero(b->texel_bytes));
    width_magic_ = ~uint64_t(0) / b->width + 1;  // exact for 32-bit dividends (width >= 2)
    if (b->kind == trace::BufferKind::image_tiled) {
      tile_w_shift_ = uint32_t(std::countr_zero(b->tile_width));
      tile_h_shift_ = uint32_t(std::countr_zero(b->tile_height));
      tiles_x_ = (b->width + b->tile_width - 1) / b->tile_width;
    }
    fast_ = true;
  }
  uint64_t operator()(uint32_t offset) const {
    if (!fast_) return b_->address(offset);
    const trace::BufferInfo& b = *b_;
    const uint32_t texel = offset >> texel_shift_, byte = offset & (b.texel_bytes - 1);
    const uint32_t y = uint32_t((static_cast<unsigned __int128>(width_magic_) * texel) >> 64);
    const uint32_t x = texel - y * b.width;
    if (b.kind == trace::BufferKind::image_linear)
      return b.base_address + uint64_t(y) * b.row_pitch_bytes + uint64_t(x) * b.texel_bytes + byte;
    const uint64_t tile = uint64_t(y >> tile_h_shift_) * tiles_x_ + (x >> tile_w_shift_);
    const uint64_t in_tile = uint64_t(y & (b.tile_height - 1)) * b.tile_width + (x & (b.tile_width - 1));
    return b.base_address + (tile * b.tile_width * b.tile_height + in_tile) * b.texel_bytes + byte;
  }

 private:
  const trace::BufferInfo* b_ = nullptr;
  bool fast_ = false;
  uint32_t texel_shift_ = 0, tile_w_shift_ = 0, tile_h_shift_ = 0, tiles_x_ = 0;
  uint64_t width_magic_ = 0;
};

}  // namespace hp::cachesim
