#include "vk/pipeline.hpp"

#include "vk/check.hpp"

#include <map>
#include <utility>

namespace hp::vk {

VkShaderModule create_shader_module(VkDevice device, std::span<const uint32_t> spirv) {
  VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  ci.codeSize = spirv.size_bytes();
  ci.pCode = spirv.data();
  VkShaderModule m = VK_NULL_HANDLE;
  HP_VK(vkCreateShaderModule(device, &ci, nullptr, &m));
  return m;
}

DescriptorSet::DescriptorSet(Context& ctx, const std::vector<VkDescriptorSetLayoutBinding>& bindings,
                             uint32_t push_constant_bytes, VkShaderStageFlags push_stages)
    : device_(ctx.device()) {
  VkDescriptorSetLayoutCreateInfo lci{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  lci.bindingCount = static_cast<uint32_t>(bindings.size());
  lci.pBindings = bindings.data();
  HP_VK(vkCreateDescriptorSetLayout(device_, &lci, nullptr, &layout_));

  std::map<VkDescriptorType, uint32_t> counts;
  for (const auto& b : bindings) counts[b.descriptorType] += b.descriptorCount;
  std::vector<VkDescriptorPoolSize> sizes;
  for (auto [type, n] : counts) sizes.push_back({type, n});
  VkDescriptorPoolCreateInfo pci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pci.maxSets = 1;
  pci.poolSizeCount = static_cast<uint32_t>(sizes.size());
  pci.pPoolSizes = sizes.data();
  HP_VK(vkCreateDescriptorPool(device_, &pci, nullptr, &pool_));
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = pool_;
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &layout_;
  HP_VK(vkAllocateDescriptorSets(device_, &ai, &set_));

  VkPushConstantRange range{push_stages, 0, push_constant_bytes};
  VkPipelineLayoutCreateInfo plci{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  plci.setLayoutCount = 1;
  plci.pSetLayouts = &layout_;
  plci.pushConstantRangeCount = push_constant_bytes ? 1 : 0;
  plci.pPushConstantRanges = push_constant_bytes ? &range : nullptr;
  HP_VK(vkCreatePipelineLayout(device_, &plci, nullptr, &pipeline_layout_));
}

DescriptorSet::~DescriptorSet() { reset(); }
DescriptorSet::DescriptorSet(DescriptorSet&& o) noexcept { *this = std::move(o); }
DescriptorSet& DescriptorSet::operator=(DescriptorSet&& o) noexcept {
  if (this != &o) {
    reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    layout_ = std::exchange(o.layout_, VK_NULL_HANDLE);
    pool_ = std::exchange(o.pool_, VK_NULL_HANDLE);
    set_ = std::exchange(o.set_, VK_NULL_HANDLE);
    pipeline_layout_ = std::exchange(o.pipeline_layout_, VK_NULL_HANDLE);
  }
  return *this;
}

void DescriptorSet::reset() {
  if (device_) {
    if (pipeline_layout_) vkDestroyPipelineLayout(device_, pipeline_layout_, nullptr);
    if (pool_) vkDestroyDescriptorPool(device_, pool_, nullptr);  // frees the set
    if (layout_) vkDestroyDescriptorSetLayout(device_, layout_, nullptr);
  }
  pipeline_layout_ = VK_NULL_HANDLE;
  pool_ = VK_NULL_HANDLE;
  layout_ = VK_NULL_HANDLE;
  set_ = VK_NULL_HANDLE;
}

// One descriptor write; exactly one of the three infos is set, as the descriptor type needs.
void DescriptorSet::write(uint32_t binding, VkDescriptorType type, const VkDescriptorBufferInfo* buffer,
                          const VkDescriptorImageInfo* image, const VkBufferView* texel_view) {
  VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  w.dstSet = set_;
  w.dstBinding = binding;
  w.descriptorCount = 1;
  w.descriptorType = type;
  w.pBufferInfo = buffer;
  w.pImageInfo = image;
  w.pTexelBufferView = texel_view;
  vkUpdateDescriptorSets(device_, 1, &w, 0, nullptr);
}

void DescriptorSet::write_buffer(uint32_t binding, VkDescriptorType type, VkBuffer buffer, VkDeviceSize range) {
  const VkDescriptorBufferInfo bi{buffer, 0, range};
  write(binding, type, &bi, nullptr, nullptr);
}

void DescriptorSet::write_texel_buffer(uint32_t binding, VkDescriptorType type, VkBufferView view) {
  write(binding, type, nullptr, nullptr, &view);
}

void DescriptorSet::write_acceleration_structure(uint32_t binding, VkAccelerationStructureKHR as) {
  VkWriteDescriptorSetAccelerationStructureKHR a{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET_ACCELERATION_STRUCTURE_KHR};
  a.accelerationStructureCount = 1;
  a.pAccelerationStructures = &as;
  VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  w.pNext = &a;
  w.dstSet = set_;
  w.dstBinding = binding;
  w.descriptorCount = 1;
  w.descriptorType = VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR;
  vkUpdateDescriptorSets(device_, 1, &w, 0, nullptr);
}

void DescriptorSet::write_image(uint32_t binding, VkDescriptorType type, VkImageView view, VkImageLayout layout,
                                VkSampler sampler) {
  const VkDescriptorImageInfo ii{sampler, view, layout};
  write(binding, type, nullptr, &ii, nullptr);
}

Pipeline::~Pipeline() {
  if (device_ && pipeline_) vkDestroyPipeline(device_, pipeline_, nullptr);
}
Pipeline::Pipeline(Pipeline&& o) noexcept { *this = std::move(o); }
Pipeline& Pipeline::operator=(Pipeline&& o) noexcept {
  if (this != &o) {
    if (device_ && pipeline_) vkDestroyPipeline(device_, pipeline_, nullptr);
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    pipeline_ = std::exchange(o.pipeline_, VK_NULL_HANDLE);
  }
  return *this;
}

Pipeline create_compute_pipeline(Context& ctx, std::span<const uint32_t> spirv, VkPipelineLayout layout,
                                 const VkSpecializationInfo* specialization) {
  VkShaderModule module = create_shader_module(ctx.device(), spirv);
  VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  ci.stage.module = module;
  ci.stage.pName = "main";
  ci.stage.pSpecializationInfo = specialization;
  ci.layout = layout;
  VkPipeline p = VK_NULL_HANDLE;
  VkResult r = vkCreateComputePipelines(ctx.device(), VK_NULL_HANDLE, 1, &ci, nullptr, &p);
  vkDestroyShaderModule(ctx.device(), module, nullptr);
  HP_VK(r);
  return Pipeline(ctx.device(), p);
}

Sampler::Sampler(Context& ctx) : device_(ctx.device()) {
  VkSamplerCreateInfo ci{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  ci.magFilter = VK_FILTER_NEAREST;
  ci.minFilter = VK_FILTER_NEAREST;
  ci.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
  ci.addressModeU = ci.addressModeV = ci.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  HP_VK(vkCreateSampler(device_, &ci, nullptr, &sampler_));
}

Sampler::~Sampler() {
  if (sampler_) vkDestroySampler(device_, sampler_, nullptr);
}

}  // namespace hp::vk
