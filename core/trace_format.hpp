// What a memory-trace capture produces, as the renderer hands it on: the buffer table that maps a record's
// offset to a byte address, the passes with their dispatch sizes, and the sink that receives record slices
// (a trace file, the cache simulator, both). The record itself is gpu::TraceRecord (gpu/trace_record.h),
// which the instrumented shaders write. The file format is in profiler/trace/trace_file.hpp.
#pragma once

#include "gpu/trace_record.h"

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace hp::trace {

using gpu::TraceRecord;

enum class BufferKind : uint32_t { buffer = 0, image_linear = 1, image_tiled = 2 };

struct BufferInfo {
  uint32_t id = 0;  // the buffer id records carry in their info word (< 256)
  std::string name;
  uint64_t base_address = 0;
  uint64_t size_bytes = 0;  // bytes the records may address (images: width * height * texel_bytes)
  BufferKind kind = BufferKind::buffer;
  uint32_t texel_bytes = 0;  // images only
  uint32_t width = 0, height = 0;
  uint32_t row_pitch_bytes = 0;              // image_linear: >= width * texel_bytes
  uint32_t tile_width = 0, tile_height = 0;  // image_tiled

  // Byte address of a record's offset: buffers add the base; images apply the declared layout.
  uint64_t address(uint32_t offset) const;
};

struct DispatchGeometry {
  uint32_t workgroup_size[3] = {1, 1, 1};
  uint32_t workgroup_count[3] = {1, 1, 1};
  uint64_t invocations_per_workgroup() const {
    return uint64_t(workgroup_size[0]) * workgroup_size[1] * workgroup_size[2];
  }
  uint64_t workgroups() const { return uint64_t(workgroup_count[0]) * workgroup_count[1] * workgroup_count[2]; }
  uint64_t invocations() const { return invocations_per_workgroup() * workgroups(); }
};

struct PassInfo {
  std::string name;
  DispatchGeometry dispatch;
};

struct TraceHeader {
  uint32_t image_width = 0, image_height = 0;
  std::vector<BufferInfo> buffers;
  const BufferInfo* find_buffer(uint32_t id) const;
};

// Where a capture sends its trace, pass by pass and slice by slice (a file, the cache simulator, both).
// Passes begin in order; a pass's slices come in increasing, non-overlapping workgroup order, and each
// slice's records are only valid during the call. A capture writes slices on worker threads while the
// device runs the next ones: the calls come one at a time, in that order, but not always from one thread;
// only stage_record_parts runs beside other calls (on other slices).
class TraceSink {
 public:
  virtual ~TraceSink() = default;
  virtual uint32_t begin_pass(const PassInfo& pass) = 0;  // returns the pass index
  // One slice of a pass; [first_workgroup, end_workgroup) is the slice's dispatched range.
  virtual void write_records(uint32_t pass, std::span<const TraceRecord> records, uint64_t first_workgroup,
                             uint64_t end_workgroup) = 0;
  // The same for a slice whose records are `parts` put together in order (a capture's trace buffer regions),
  // where the sink can take them as they lie. False (the default): nothing was written, and the caller puts
  // the parts together and calls write_records.
  virtual bool write_record_parts(uint32_t /*pass*/, std::span<const std::span<const TraceRecord>> /*parts*/,
                                  uint64_t /*first_workgroup*/, uint64_t /*end_workgroup*/) {
    return false;
  }
  // A slice in two steps, for a sink whose work on the records can run beside other slices' on other
  // threads: stage reads the parts (valid during the call only) and returns what is left to do in slice
  // order (the file write), which the caller runs after the previous slices' (and before begin_pass of
  // the next pass). Null (the default): the sink cannot, and the caller uses write_record_parts or
  // write_records in slice order instead.
  using Commit = std::function<void()>;
  virtual Commit stage_record_parts(uint32_t /*pass*/, std::span<const std::span<const TraceRecord>> /*parts*/,
                                    uint64_t /*first_workgroup*/, uint64_t /*end_workgroup*/) {
    return nullptr;
  }
};

// Sends everything to two sinks (keep the trace file while simulating it).
class TeeSink final : public TraceSink {
 public:
  TeeSink(TraceSink& a, TraceSink& b) : a_(a), b_(b) {}
  uint32_t begin_pass(const PassInfo& pass) override;
  void write_records(uint32_t pass, std::span<const TraceRecord> records, uint64_t first_workgroup,
                     uint64_t end_workgroup) override;

 private:
  TraceSink &a_, &b_;
};

}  // namespace hp::trace
