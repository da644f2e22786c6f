// The composite: direct lighting × the shadow mask, plus the accumulated reflection weighted by Fresnel
// where one was traced; otherwise (Lambert + GGX, directional light, constant sky ambient) from the
// G-buffer into a linear RGBA32F image; sky colour where the depth buffer holds the background.
#pragma once

#include "passes/gbuffer.hpp"

namespace hp {

class CompositePass {
 public:
  static constexpr VkFormat kOutputFormat = VK_FORMAT_R32G32B32A32_SFLOAT;

  /// `shadow_mask` (R32F, full size) and `reflection` (RGBA32F, reflection grid) are read in GENERAL layout
  /// when the frame's flags enable them (FrameUniforms::extent.w).
  CompositePass(vk::Context& ctx, const vk::Buffer& frame_uniforms, const GBuffer& gbuffer, const vk::Image& output,
                VkSampler sampler, const vk::Image& shadow_mask, const vk::Image& reflection);
  /// Expects the G-buffer in SHADER_READ_ONLY_OPTIMAL; leaves `output` in GENERAL.
  void record(VkCommandBuffer cmd, const vk::Image& output) const;

 private:
  vk::DescriptorSet descriptors_;
  vk::Pipeline pipeline_;
};

}  // namespace hp
