#include "vk/rt_pipeline.hpp"

#include "error.hpp"
#include "vk/check.hpp"

#include <cstring>
#include <vector>

namespace hp::vk {

namespace {
VkDeviceSize align_up(VkDeviceSize v, VkDeviceSize a) { return a > 1 ? (v + a - 1) / a * a : v; }
}  // namespace

RtPipeline::RtPipeline(Context& ctx, VkPipelineLayout layout, std::span<const uint32_t> raygen,
                       std::span<const uint32_t> miss, std::span<const uint32_t> closest_hit,
                       const VkSpecializationInfo* specialization) {
  if (!ctx.ray_tracing_pipeline_enabled()) {
    throw DeviceError("Vulkan device '" + ctx.info().name +
                      "' has no ray-tracing pipelines (VK_KHR_ray_tracing_pipeline): --traversal pipeline needs them");
  }
  const RayTracingFunctions& fn = ctx.rt();
  const VkDevice dev = ctx.device();
  const VkShaderModule modules[3] = {create_shader_module(dev, raygen), create_shader_module(dev, miss),
                                     create_shader_module(dev, closest_hit)};
  const VkShaderStageFlagBits stages[3] = {VK_SHADER_STAGE_RAYGEN_BIT_KHR, VK_SHADER_STAGE_MISS_BIT_KHR,
                                           VK_SHADER_STAGE_CLOSEST_HIT_BIT_KHR};
  VkPipelineShaderStageCreateInfo si[3];
  for (int i = 0; i < 3; ++i) {
    si[i] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    si[i].stage = stages[i];
    si[i].module = modules[i];
    si[i].pName = "main";
  }
  si[0].pSpecializationInfo = specialization;
  VkRayTracingShaderGroupCreateInfoKHR groups[3];
  for (int i = 0; i < 3; ++i) {
    groups[i] = {VK_STRUCTURE_TYPE_RAY_TRACING_SHADER_GROUP_CREATE_INFO_KHR};
    groups[i].generalShader = VK_SHADER_UNUSED_KHR;
    groups[i].closestHitShader = VK_SHADER_UNUSED_KHR;
    groups[i].anyHitShader = VK_SHADER_UNUSED_KHR;
    groups[i].intersectionShader = VK_SHADER_UNUSED_KHR;
  }
  groups[0].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR;
  groups[0].generalShader = 0;
  groups[1].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_GENERAL_KHR;
  groups[1].generalShader = 1;
  groups[2].type = VK_RAY_TRACING_SHADER_GROUP_TYPE_TRIANGLES_HIT_GROUP_KHR;
  groups[2].closestHitShader = 2;
  VkRayTracingPipelineCreateInfoKHR ci{VK_STRUCTURE_TYPE_RAY_TRACING_PIPELINE_CREATE_INFO_KHR};
  ci.stageCount = 3;
  ci.pStages = si;
  ci.groupCount = 3;
  ci.pGroups = groups;
  ci.maxPipelineRayRecursionDepth = 1;  // rays are traced from the ray-generation shader only
  ci.layout = layout;
  VkPipeline p = VK_NULL_HANDLE;
  const VkResult r = fn.create_pipelines(dev, VK_NULL_HANDLE, VK_NULL_HANDLE, 1, &ci, nullptr, &p);
  for (VkShaderModule m : modules) vkDestroyShaderModule(dev, m, nullptr);
  HP_VK(r);
  pipeline_ = Pipeline(dev, p);
  trace_ = fn.cmd_trace_rays;
  trace_indirect_ = fn.cmd_trace_rays_indirect;

  // The shader binding table: raygen, miss, hit records, each region aligned to shaderGroupBaseAlignment.
  const auto& props = ctx.rt_pipeline_properties();
  const VkDeviceSize handle = props.shaderGroupHandleSize;
  const VkDeviceSize stride = align_up(handle, props.shaderGroupHandleAlignment);
  const VkDeviceSize region = align_up(stride, props.shaderGroupBaseAlignment);
  std::vector<uint8_t> handles(3 * handle);
  HP_VK(fn.get_group_handles(dev, p, 0, 3, handles.size(), handles.data()));
  sbt_ = Buffer(ctx, 3 * region + props.shaderGroupBaseAlignment,
                VK_BUFFER_USAGE_SHADER_BINDING_TABLE_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT, true);
  const VkDeviceAddress base = align_up(sbt_.device_address(), props.shaderGroupBaseAlignment);
  auto* bytes = static_cast<uint8_t*>(sbt_.mapped()) + (base - sbt_.device_address());
  for (int i = 0; i < 3; ++i) std::memcpy(bytes + i * region, handles.data() + i * handle, handle);
  raygen_ = {base, region, region};  // the raygen region's size equals its stride
  miss_ = {base + region, stride, stride};
  hit_ = {base + 2 * region, stride, stride};
}

void RtPipeline::record_trace(VkCommandBuffer cmd, uint32_t width, uint32_t height, uint32_t depth) const {
  trace_(cmd, &raygen_, &miss_, &hit_, &callable_, width, height, depth);
}

void RtPipeline::record_trace_indirect(VkCommandBuffer cmd, VkDeviceAddress arguments) const {
  trace_indirect_(cmd, &raygen_, &miss_, &hit_, &callable_, arguments);
}

}  // namespace hp::vk
