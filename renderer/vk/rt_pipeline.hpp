// A ray-tracing pipeline (VK_KHR_ray_tracing_pipeline) of one ray-generation shader, one miss shader and one
// triangle hit group with a closest-hit shader, and its shader binding table (one record each, no
// shader-record data). Move-only RAII.
#pragma once

#include "vk/pipeline.hpp"
#include "vk/resources.hpp"

#include <span>

namespace hp::vk {

class RtPipeline {
 public:
  RtPipeline() = default;
  /// `specialization` applies to the ray-generation shader. Throws DeviceError without the extension.
  RtPipeline(Context& ctx, VkPipelineLayout layout, std::span<const uint32_t> raygen, std::span<const uint32_t> miss,
             std::span<const uint32_t> closest_hit, const VkSpecializationInfo* specialization);
  RtPipeline(RtPipeline&&) noexcept = default;
  RtPipeline& operator=(RtPipeline&&) noexcept = default;

  VkPipeline handle() const { return pipeline_.handle(); }
  /// vkCmdTraceRaysKHR over width x height x depth launches (the pipeline and its set bound by the caller).
  void record_trace(VkCommandBuffer cmd, uint32_t width, uint32_t height, uint32_t depth = 1) const;
  /// vkCmdTraceRaysIndirectKHR with a VkTraceRaysIndirectCommandKHR at `arguments` (a device address).
  void record_trace_indirect(VkCommandBuffer cmd, VkDeviceAddress arguments) const;

 private:
  Pipeline pipeline_;
  Buffer sbt_;
  PFN_vkCmdTraceRaysKHR trace_ = nullptr;
  PFN_vkCmdTraceRaysIndirectKHR trace_indirect_ = nullptr;
  VkStridedDeviceAddressRegionKHR raygen_{}, miss_{}, hit_{}, callable_{};
};

}  // namespace hp::vk
