#include "passes/composite.hpp"

#include "gpu/bindings.h"
#include "shaders/composite_comp.h"

namespace hp {

CompositePass::CompositePass(vk::Context& ctx, const vk::Buffer& frame_uniforms, const GBuffer& gbuffer,
                             const vk::Image& output, VkSampler sampler, const vk::Image& shadow_mask,
                             const vk::Image& reflection) {
  const VkShaderStageFlags cs = VK_SHADER_STAGE_COMPUTE_BIT;
  descriptors_ =
      vk::DescriptorSet(ctx,
                        {{HP_BIND_COMPOSITE_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, cs, nullptr},
                         {HP_BIND_COMPOSITE_GBUF_DEPTH, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, cs, nullptr},
                         {HP_BIND_COMPOSITE_GBUF_NORMAL, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, cs, nullptr},
                         {HP_BIND_COMPOSITE_GBUF_ALBEDO, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, cs, nullptr},
                         {HP_BIND_COMPOSITE_OUTPUT, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, cs, nullptr},
                         {HP_BIND_COMPOSITE_SHADOW_MASK, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, cs, nullptr},
                         {HP_BIND_COMPOSITE_REFLECTION, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, cs, nullptr}},
                        0, 0);
  const VkImageLayout ro = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
  descriptors_.write_buffer(HP_BIND_COMPOSITE_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, frame_uniforms.handle());
  descriptors_.write_image(HP_BIND_COMPOSITE_GBUF_DEPTH, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                           gbuffer.depth.view(), ro, sampler);
  descriptors_.write_image(HP_BIND_COMPOSITE_GBUF_NORMAL, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                           gbuffer.normal_roughness.view(), ro, sampler);
  descriptors_.write_image(HP_BIND_COMPOSITE_GBUF_ALBEDO, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                           gbuffer.albedo_metal.view(), ro, sampler);
  descriptors_.write_image(HP_BIND_COMPOSITE_OUTPUT, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, output.view(),
                           VK_IMAGE_LAYOUT_GENERAL);
  descriptors_.write_image(HP_BIND_COMPOSITE_SHADOW_MASK, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, shadow_mask.view(),
                           VK_IMAGE_LAYOUT_GENERAL);
  descriptors_.write_image(HP_BIND_COMPOSITE_REFLECTION, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, reflection.view(),
                           VK_IMAGE_LAYOUT_GENERAL);
  pipeline_ = vk::create_compute_pipeline(ctx, composite_comp, descriptors_.pipeline_layout());
}

void CompositePass::record(VkCommandBuffer cmd, const vk::Image& output) const {
  vk::transition(cmd, output, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL,
                 VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT, 0,
                 VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_.handle());
  VkDescriptorSet set = descriptors_.set();
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, descriptors_.pipeline_layout(), 0, 1, &set, 0, nullptr);
  // Round up: the study's dispatch truncated width/8 and left the ragged edge unshaded.
  vkCmdDispatch(cmd, (output.width() + 7) / 8, (output.height() + 7) / 8, 1);
  vk::transition(cmd, output, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                 VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT,
                 VK_ACCESS_2_MEMORY_READ_BIT);
}

}  // namespace hp
