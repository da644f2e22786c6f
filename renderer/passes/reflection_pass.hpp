// The direct reflection pass: one reflection ray per reflective cell of the reflection grid, traced and
// shaded in place (shaders/reflections.comp), and its instrumented variant for the capture. The
// compaction path (compaction_path.hpp) replaces it when RayTracingOptions::reflection_path asks.
#pragma once

#include "passes/rt_resources.hpp"

namespace hp {

class ReflectionPass {
 public:
  ReflectionPass(vk::Context& ctx, RtResources& rt);

  void record(VkCommandBuffer cmd) const;

  /// Workgroups of the full dispatch: 8x8 invocations each, over the reflection grid.
  glm::uvec2 workgroups() const;
  /// Builds the instrumented pipeline (once; the trace buffer is RtResources::attach_trace_buffer's).
  void attach_trace(vk::Context& ctx);
  /// Workgroup rows [first_row, first_row + rows) traced (RtResources::set_slice gives the shaders the offset).
  /// `sharing`: 0, or the workgroups of a work-sharing dispatch (gpu::TraceBufferHeader::units).
  void record_traced_slice(VkCommandBuffer cmd, uint32_t first_row, uint32_t rows, uint32_t sharing) const;

 private:
  RtResources& rt_;
  RtProgram program_;
  vk::Pipeline traced_;
};

}  // namespace hp
