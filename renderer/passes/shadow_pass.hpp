// The shadow pass: one shadow ray per G-buffer pixel into the shadow mask (shaders/shadows.comp), and its
// instrumented variant for the capture.
#pragma once

#include "passes/rt_resources.hpp"

namespace hp {

class ShadowPass {
 public:
  ShadowPass(vk::Context& ctx, RtResources& rt);

  /// `then_barrier` false: no barrier after the pass, for a caller that records a pass with a compute
  /// barrier of its own next in the same command buffer (the reflections): the shadow and reflection passes
  /// do not depend on each other, so a device may run them concurrently.
  void record(VkCommandBuffer cmd, bool then_barrier = true) const;

  /// Workgroups of the full dispatch: 8x8 invocations each, over the image.
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
