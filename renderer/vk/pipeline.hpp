// Small owners for shader modules, descriptor sets and pipelines. A pass declares its bindings once;
// `DescriptorSet` writes buffers and images into them.
#pragma once

#include "vk/context.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace hp::vk {

VkShaderModule create_shader_module(VkDevice device, std::span<const uint32_t> spirv);

/// A descriptor set layout + pool + one set, and the pipeline layout built on it.
class DescriptorSet {
 public:
  DescriptorSet() = default;
  DescriptorSet(Context& ctx, const std::vector<VkDescriptorSetLayoutBinding>& bindings, uint32_t push_constant_bytes,
                VkShaderStageFlags push_stages);
  ~DescriptorSet();
  DescriptorSet(DescriptorSet&& o) noexcept;
  DescriptorSet& operator=(DescriptorSet&& o) noexcept;
  DescriptorSet(const DescriptorSet&) = delete;
  DescriptorSet& operator=(const DescriptorSet&) = delete;

  void write_buffer(uint32_t binding, VkDescriptorType type, VkBuffer buffer, VkDeviceSize range = VK_WHOLE_SIZE);
  void write_image(uint32_t binding, VkDescriptorType type, VkImageView view, VkImageLayout layout,
                   VkSampler sampler = VK_NULL_HANDLE);
  void write_texel_buffer(uint32_t binding, VkDescriptorType type, VkBufferView view);
  void write_acceleration_structure(uint32_t binding, VkAccelerationStructureKHR as);

  VkDescriptorSet set() const { return set_; }
  VkDescriptorSetLayout layout() const { return layout_; }
  VkPipelineLayout pipeline_layout() const { return pipeline_layout_; }

 private:
  void reset();
  void write(uint32_t binding, VkDescriptorType type, const VkDescriptorBufferInfo* buffer,
             const VkDescriptorImageInfo* image, const VkBufferView* texel_view);
  VkDevice device_ = VK_NULL_HANDLE;
  VkDescriptorSetLayout layout_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
  VkPipelineLayout pipeline_layout_ = VK_NULL_HANDLE;
};

/// Owns a VkPipeline.
class Pipeline {
 public:
  Pipeline() = default;
  Pipeline(VkDevice device, VkPipeline pipeline) : device_(device), pipeline_(pipeline) {}
  ~Pipeline();
  Pipeline(Pipeline&& o) noexcept;
  Pipeline& operator=(Pipeline&& o) noexcept;
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;
  VkPipeline handle() const { return pipeline_; }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
};

/// A compute pipeline from SPIR-V; `specialization` (optional) sets the shader's specialization constants.
Pipeline create_compute_pipeline(Context& ctx, std::span<const uint32_t> spirv, VkPipelineLayout layout,
                                 const VkSpecializationInfo* specialization = nullptr);

/// A nearest-filtering, clamp-to-edge sampler (texelFetch ignores it, but sampled images need one).
class Sampler {
 public:
  explicit Sampler(Context& ctx);
  ~Sampler();
  Sampler(const Sampler&) = delete;
  Sampler& operator=(const Sampler&) = delete;
  VkSampler handle() const { return sampler_; }

 private:
  VkDevice device_;
  VkSampler sampler_ = VK_NULL_HANDLE;
};

}  // namespace hp::vk
