// GPU timestamps around the passes of a frame, written at VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT: each one
// waits for all earlier work, but holds back no later work, so an interval holds one pass only where the
// caller adds an execution dependency after each timestamp (Frame does: PassIsolation::Serialized).
// Passes recorded back to back share the boundary timestamp (the end of one is the begin of the next:
// N + 1 queries for N passes, not 2N), which halves the queries' own cost; the barriers between two passes
// then count toward the later one. Ticks are masked with timestampValidBits and converted with
// timestampPeriod.
#pragma once

#include "vk/context.hpp"

#include <string>
#include <vector>

namespace hp::vk {

/// A raw timestamp in ns, unwrapped against the frame's first one: the counter has timestampValidBits bits
/// (`mask`) and wraps (every 68.7 s at 36 bits and 1 ns), so each tick is taken as `first` plus its
/// distance from `first` modulo the counter. A frame that spans a wrap keeps ordered, positive intervals.
inline double unwrapped_timestamp_ns(uint64_t tick, uint64_t first, uint64_t mask, double period_ns) {
  const uint64_t base = first & mask;
  return double(base + (((tick & mask) - base) & mask)) * period_ns;
}

class TimestampQueries {
 public:
  /// max_passes == 0 creates no pool: supported() is false, as on a queue without timestamps.
  TimestampQueries(Context& ctx, uint32_t max_passes);
  ~TimestampQueries();
  TimestampQueries(const TimestampQueries&) = delete;
  TimestampQueries& operator=(const TimestampQueries&) = delete;

  /// False when the queue family has no timestamp support (timestampValidBits == 0).
  bool supported() const { return pool_ != VK_NULL_HANDLE; }

  void reset(VkCommandBuffer cmd);
  /// Returns whether it wrote a timestamp (false when the previous pass's end is this pass's begin, or
  /// without a pool).
  bool begin(VkCommandBuffer cmd, const std::string& pass);
  void end(VkCommandBuffer cmd);

  struct Interval {
    std::string pass;
    uint64_t begin_ns = 0;  ///< device time base (nanoseconds), valid bits only
    uint64_t end_ns = 0;
  };
  /// After the frame's submission completed: the intervals of the passes recorded since reset().
  std::vector<Interval> read(Context& ctx) const;

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueryPool pool_ = VK_NULL_HANDLE;
  uint32_t capacity_ = 0;
  uint32_t used_ = 0;
  uint64_t mask_ = 0;
  double period_ns_ = 1.0;
  std::vector<std::string> names_;
  std::vector<std::pair<uint32_t, uint32_t>> slots_;  // per pass: begin and end query index
  bool open_ = false;                                 // a pass is between begin() and end()
  bool boundary_ = false;                             // the last query written was an end()
};

}  // namespace hp::vk
