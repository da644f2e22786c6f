// The G-buffer: depth (D32), world normal + roughness (RGBA16F), base colour + metalness (RGBA8 sRGB),
// filled by a raster pass with dynamic rendering.
#pragma once

#include "gpu_scene.hpp"
#include "vk/pipeline.hpp"
#include "vk/resources.hpp"

namespace hp {

struct GBuffer {
  static constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;
  static constexpr VkFormat kNormalFormat = VK_FORMAT_R16G16B16A16_SFLOAT;
  static constexpr VkFormat kAlbedoFormat = VK_FORMAT_R8G8B8A8_SRGB;

  GBuffer(vk::Context& ctx, uint32_t width, uint32_t height);
  vk::Image depth;
  vk::Image normal_roughness;
  vk::Image albedo_metal;
};

class GBufferPass {
 public:
  GBufferPass(vk::Context& ctx, const vk::Buffer& frame_uniforms, bool reversed_z);

  /// Records the pass. The G-buffer images go from any state to attachment layouts, are cleared and drawn,
  /// and end in SHADER_READ_ONLY_OPTIMAL, visible to compute shaders.
  /// Draws camera-relative: each draw's world matrix has `eye` subtracted from its translation (in double).
  void record(VkCommandBuffer cmd, const GpuScene& scene, const GBuffer& target, const glm::vec3& eye) const;

 private:
  bool reversed_z_;
  vk::DescriptorSet descriptors_;
  vk::Pipeline pipeline_;
};

}  // namespace hp
