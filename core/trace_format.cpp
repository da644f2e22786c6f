#include "trace_format.hpp"

#include <stdexcept>

namespace hp::trace {

uint64_t BufferInfo::address(uint32_t offset) const {
  switch (kind) {
    case BufferKind::buffer: return base_address + offset;
    case BufferKind::image_linear: {
      uint32_t texel = offset / texel_bytes, byte = offset % texel_bytes;
      uint32_t x = texel % width, y = texel / width;
      return base_address + uint64_t(y) * row_pitch_bytes + uint64_t(x) * texel_bytes + byte;
    }
    case BufferKind::image_tiled: {
      uint32_t texel = offset / texel_bytes, byte = offset % texel_bytes;
      uint32_t x = texel % width, y = texel / width;
      uint32_t tiles_x = (width + tile_width - 1) / tile_width;
      uint64_t tile = uint64_t(y / tile_height) * tiles_x + x / tile_width;
      uint64_t in_tile = uint64_t(y % tile_height) * tile_width + x % tile_width;
      return base_address + (tile * tile_width * tile_height + in_tile) * texel_bytes + byte;
    }
  }
  return base_address + offset;
}

const BufferInfo* TraceHeader::find_buffer(uint32_t id) const {
  for (const BufferInfo& b : buffers)
    if (b.id == id) return &b;
  return nullptr;
}

uint32_t TeeSink::begin_pass(const PassInfo& pass) {
  const uint32_t i = a_.begin_pass(pass);
  if (b_.begin_pass(pass) != i) throw std::logic_error("TeeSink: the two sinks number passes differently");
  return i;
}

void TeeSink::write_records(uint32_t pass, std::span<const TraceRecord> records, uint64_t first_workgroup,
                            uint64_t end_workgroup) {
  a_.write_records(pass, records, first_workgroup, end_workgroup);
  b_.write_records(pass, records, first_workgroup, end_workgroup);
}

}  // namespace hp::trace
