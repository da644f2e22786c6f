// The compaction path of the reflections (RayTracingOptions::reflection_path = compact): append the valid
// reflection rays and size the consume dispatch on the GPU (shaders/compact.comp, compact_args.comp), sort
// them when a key is chosen (RadixSort), trace and shade them one thread per ray (shaders/consume.comp).
// Three timed passes (compact, sort, consume); the capture traces compact, each sort dispatch and consume.
#pragma once

#include "passes/radix_sort.hpp"
#include "passes/rt_resources.hpp"

#include <memory>
#include <vector>

namespace hp {

class CompactionPath {
 public:
  CompactionPath(vk::Context& ctx, RtResources& rt);

  /// Resets the count, appends the rays, records the consume dispatch arguments.
  void record_compact(VkCommandBuffer cmd) const;
  void record_sort(VkCommandBuffer cmd);  ///< nothing without a sort key
  void record_consume(VkCommandBuffer cmd) const;
  /// Records the consume dispatch arguments (from the compacted count).
  void record_args(VkCommandBuffer cmd) const;
  /// Sets the compacted ray count (capture: restart an overflowed compaction slice).
  void record_reset_count(VkCommandBuffer cmd, uint32_t count) const;

  /// Workgroups of the compaction's full dispatch (8x8, over the reflection grid) and of the consume pass
  /// (64 x 1, one row of ceil(rays / 64) groups; `rays` is read back by the caller).
  glm::uvec2 compact_workgroups() const;
  static glm::uvec2 consume_workgroups(uint32_t rays) { return {(rays + 63) / 64, 1u}; }
  /// The ray sort's dispatches (none without a sort key).
  std::vector<RadixSort::Step> sort_steps() const;
  const RadixSort* sorter() const { return sorter_.get(); }

  /// Builds the instrumented pipelines: the compaction's, the consume pass's (`consume`) and the sort's
  /// (`sort`, given the trace buffer), each once.
  void attach_trace_compact(vk::Context& ctx);
  void attach_trace_consume(vk::Context& ctx);
  void attach_trace_sort(vk::Context& ctx, const vk::Buffer& trace_buffer);
  /// Traced slices: workgroup rows of the compaction, groups of the consume pass (offset by frame.z), groups
  /// of one sort step (with the capture's sampling word).
  void record_traced_compact(VkCommandBuffer cmd, uint32_t first_row, uint32_t rows) const;
  void record_traced_consume(VkCommandBuffer cmd, uint32_t groups) const;
  void record_traced_sort_step(VkCommandBuffer cmd, const RadixSort::Step& step, uint32_t first_group, uint32_t groups,
                               uint32_t sampling);

 private:
  RtResources& rt_;
  vk::Pipeline compact_, args_;
  RtProgram consume_;
  vk::Pipeline compact_traced_, consume_traced_;
  std::unique_ptr<RadixSort> sorter_;
};

}  // namespace hp
