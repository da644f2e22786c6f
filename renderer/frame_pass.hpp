// A frame as a list of passes, built once from the settings (Frame::passes()): recording, the host-timed
// fallback, timestamps, pipeline statistics, the captured pass names and the capture all iterate this one
// list, so the frame's order is written once (renderer/frame_passes.cpp).
#pragma once

#include "vk/context.hpp"
#include "vk/resources.hpp"

#include <glm/glm.hpp>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace hp {

/// One dispatch as the capture traces it: one trace pass, dispatched in slices that fit the trace buffer.
struct TracedStep {
  std::string name;             ///< the trace pass's name ("shadows", "sort_scatter_1")
  glm::uvec2 group_size{8, 8};  ///< invocations per workgroup, x and y
  bool one_d = false;           ///< sliced by workgroups of one row (else by rows of workgroups)
  /// The full dispatch's workgroups, called when the step is captured (the consume pass reads the count).
  std::function<glm::uvec2()> workgroups;
  /// Records units [first, first + n) (rows, or groups when one_d) with the instrumented pipeline; `sampling`
  /// is the workgroup sampling word (k | log2(burst) << 20); `sharing`: 0, or (for a step that shares_work)
  /// the workgroups of a work-sharing dispatch (gpu::TraceBufferHeader::units). Its own submission.
  std::function<void(VkCommandBuffer cmd, uint32_t first, uint32_t n, uint32_t sampling, uint32_t sharing)>
      record_slice;
  /// Its instrumented shader can take a slice's 8x8 tiles whole, a subgroup at a time, from the trace
  /// buffer's counter (hp_next_shared_tile, shaders/common/dispatch_order.glsl).
  bool shares_work = false;
  /// For writes that are not idempotent (the compaction's atomic append): `save` runs before each slice,
  /// `restore` after an overflow, before the slice is re-run smaller.
  std::function<void()> save, restore;
  std::function<void()> finish;  ///< after the last slice (resets the slice parameters)
};

/// How the capture runs a pass instead of recording it plainly.
struct TracedVariant {
  enum class Switch { none, shadows, reflections };
  Switch selected_by = Switch::none;  ///< the CaptureOptions flag that asks for it; none: never traced
  /// Builds the instrumented pipelines (the trace buffer is bound to every set that records into it).
  std::function<void(vk::Context& ctx, const vk::Buffer& trace_buffer)> attach;
  std::function<void(VkCommandBuffer cmd)> before, after;  ///< own submissions around the steps (optional)
  std::vector<TracedStep> steps;
};

struct FramePass {
  /// The timed pass's name (FrameTiming, timestamps, pipeline statistics); empty: an untimed step between
  /// passes (image layouts, counter reset), recorded wherever the frame is.
  std::string name;
  bool compute = true;          ///< counted by the pipeline-statistics queries
  bool capture_always = false;  ///< the capture runs it even without CaptureOptions::final_image
  /// Records the pass. `alone`: it is a submission of its own (host timing, capture) and ends with its
  /// barrier even where, in the frame, the next pass's barrier covers it.
  std::function<void(VkCommandBuffer cmd, bool alone)> record;
  TracedVariant traced;
  /// Documentation, for the barriers: the dispatch geometry and what the pass reads and writes.
  std::string dispatch, reads, writes;
};

}  // namespace hp
