#include "passes/rt_resources.hpp"

#include "error.hpp"
#include "gpu/bindings.h"
#include "vk/check.hpp"

#include "shaders/rt_hit_rchit.h"
#include "shaders/rt_miss_rmiss.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace hp {

// RayParams.bounds_min.w carries the sort key mode as the shaders' HP_SORT_* value.
static_assert(int(SortKey::none) == HP_SORT_NONE && int(SortKey::octant) == HP_SORT_OCTANT &&
                  int(SortKey::direction) == HP_SORT_DIRECTION && int(SortKey::origin) == HP_SORT_ORIGIN,
              "hp::SortKey must match the shaders' HP_SORT_* values");

namespace {

constexpr VkShaderStageFlags kCS = VK_SHADER_STAGE_COMPUTE_BIT;

// Halton (2, 3) point i, the shared jitter of frame i: the same sequence the per-thread mode rotates.
glm::vec2 halton23(uint32_t i) {
  float f = 0.5f, r2 = 0.0f;
  for (uint32_t k = i; k > 0; k >>= 1, f *= 0.5f) r2 += f * float(k & 1u);
  float g = 1.0f / 3.0f, r3 = 0.0f;
  for (uint32_t k = i; k > 0; k /= 3, g /= 3.0f) r3 += g * float(k % 3u);
  return {r2, r3};
}

// `stages`: compute, plus ray generation for the pipeline traversal (its ray-generation shaders read the
// same set; the miss and closest-hit shaders read none of it).
std::vector<VkDescriptorSetLayoutBinding> rt_set_layout(VkShaderStageFlags stages, bool driver_traversal) {
  std::vector<VkDescriptorSetLayoutBinding> b;
  auto add = [&](uint32_t binding, VkDescriptorType type) { b.push_back({binding, type, 1, stages, nullptr}); };
  const VkDescriptorType SB = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  add(HP_BIND_RT_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER);
  add(HP_BIND_RT_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER);
  RtScene::add_traversal_bindings(b, stages);
  if (driver_traversal) AccelStructure::add_bindings(b, stages);
  add(HP_BIND_RT_NODES, SB);
  for (uint32_t i : {HP_BIND_RT_NORMALS, HP_BIND_RT_SOUP_NORMALS, HP_BIND_RT_SLOT_MATERIAL, HP_BIND_RT_MATERIALS,
                     HP_BIND_RT_COUNTERS, HP_BIND_RT_SHADOW_DUMP, HP_BIND_RT_REFLECTION_DUMP}) {
    add(i, SB);
  }
  for (uint32_t i : {HP_BIND_RT_GBUF_DEPTH, HP_BIND_RT_GBUF_NORMAL, HP_BIND_RT_GBUF_ALBEDO}) {
    add(i, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER);
  }
  for (uint32_t i : {HP_BIND_RT_SHADOW_MASK, HP_BIND_RT_REFLECTION, HP_BIND_RT_REFLECTION_ACCUM}) {
    add(i, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE);
  }
  add(HP_BIND_TRACE_RECORDS, SB);  // trace records (instrumented variants)
  for (uint32_t i : {HP_BIND_RT_COMPACT_RAYS, HP_BIND_RT_SORT_KEYS, HP_BIND_RT_SORT_VALUES, HP_BIND_RT_RAY_COUNT}) {
    add(i, SB);  // compaction
  }
  for (uint32_t i : {HP_BIND_RT_NORMAL_TEXELS, HP_BIND_RT_SOUP_NORMAL_TEXELS, HP_BIND_RT_SLOT_MATERIAL_TEXELS,
                     HP_BIND_RT_MATERIAL_TEXELS}) {
    add(i, VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER);  // shading data as texels
  }
  return b;
}

}  // namespace

RtResources::RtResources(vk::Context& ctx, const RtScene& scene, const GBuffer& gbuffer,
                         const vk::Buffer& frame_uniforms, VkSampler sampler, const RayTracingOptions& options,
                         const Aabb& scene_bounds, const AccelStructure* as)
    : options_(options),
      width_(gbuffer.depth.width()),
      height_(gbuffer.depth.height()),
      bounds_(scene_bounds),
      scene_(scene),
      as_(as),
      flags_((options.counters ? HP_RT_COUNTERS : 0u) | (options.dump_rays ? HP_RT_DUMP_RAYS : 0u) |
             (options.reflection_shadows ? HP_RT_REFLECTION_SHADOWS : 0u) |
             (options.offset == ShadowOffset::robust ? HP_RT_ROBUST_OFFSET : 0u) |
             (options.jitter == JitterMode::shared ? HP_RT_SHARED_JITTER : 0u)) {
  if (options.reflection_divisor != 1 && options.reflection_divisor != 2 && options.reflection_divisor != 4) {
    throw InputError("--reflection-scale: must be 1, 0.5 or 0.25");
  }
  if (!std::isfinite(options.bias) || options.bias < 0.0f) {
    throw InputError("--bias " + std::to_string(options.bias) + ": must be a finite value >= 0");
  }
  const uint32_t d = options.reflection_divisor;
  grid_w_ = (width_ + d - 1) / d;
  grid_h_ = (height_ + d - 1) / d;
  if ((options.traversal != Traversal::compute) != (as != nullptr)) {
    throw std::logic_error("RtResources: an acceleration structure exactly for the driver traversals");
  }
  create_buffers(ctx);
  const VkShaderStageFlags stages =
      kCS | (options.traversal == Traversal::pipeline ? VkShaderStageFlags(VK_SHADER_STAGE_RAYGEN_BIT_KHR)
                                                      : VkShaderStageFlags(0));
  descriptors_ = vk::DescriptorSet(ctx, rt_set_layout(stages, as != nullptr), 0, 0);
  write_descriptors(gbuffer, frame_uniforms, sampler);
  begin_frame(0);
}

void RtResources::create_buffers(vk::Context& ctx) {
  params_ = vk::Buffer(ctx, sizeof(gpu::RayParams), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
  counters_ = vk::Buffer(ctx, HP_COUNTER_WORDS * 4,
                         VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                             VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
                         false);
  const VkBufferUsageFlags dump_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  const bool dump = options_.dump_rays;
  shadow_dump_ = vk::Buffer(ctx, dump ? uint64_t(width_) * height_ * sizeof(gpu::RayDump) : 4, dump_usage, false);
  reflection_dump_ = vk::Buffer(ctx, dump ? uint64_t(grid_w_) * grid_h_ * sizeof(gpu::RayDump) : 4, dump_usage, false);
  const VkImageUsageFlags img_usage =
      VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  // A disabled pass's output is a 1x1 stand-in (the composite reads it only when the pass is on): a frame
  // without reflections does not hold two 16-byte-per-cell images for them (29 MiB at 1280x720).
  const bool sh = options_.shadows, refl = options_.reflections;
  shadow_mask_ = vk::Image(ctx, sh ? width_ : 1, sh ? height_ : 1, VK_FORMAT_R32_SFLOAT, img_usage);
  reflection_ = vk::Image(ctx, refl ? grid_w_ : 1, refl ? grid_h_ : 1, VK_FORMAT_R32G32B32A32_SFLOAT, img_usage);
  accum_ = vk::Image(ctx, refl ? grid_w_ : 1, refl ? grid_h_ : 1, VK_FORMAT_R32G32B32A32_SFLOAT, img_usage);
  dummy_trace_ = vk::Buffer(ctx, 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  // Compaction buffers: sized for every grid cell when that path is on, else 4-byte dummies.
  const bool compact = compaction();
  const uint64_t cells = uint64_t(grid_w_) * grid_h_;
  const VkBufferUsageFlags sb_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  compact_rays_ = vk::Buffer(ctx, compact ? cells * sizeof(gpu::CompactRay) : 4, sb_usage, false);
  sort_keys_ = vk::Buffer(ctx, compact ? cells * 4 : 4, sb_usage, false);
  sort_values_ = vk::Buffer(ctx, compact ? cells * 4 : 4, sb_usage, false);
  // The count, the consume dispatch's arguments and the consume launch's (common/compaction.glsl); the
  // pipeline traversal reads the launch through its device address.
  const VkBufferUsageFlags launch_usage = options_.traversal == Traversal::pipeline
                                              ? VkBufferUsageFlags(VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT)
                                              : VkBufferUsageFlags(0);
  ray_count_ =
      vk::Buffer(ctx, 32,
                 sb_usage | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT | launch_usage,
                 false);
  if (compact && cells * sizeof(gpu::CompactRay) > ctx.properties().limits.maxStorageBufferRange) {
    throw InputError("compact reflections: " + std::to_string(cells) + " rays need " +
                     std::to_string((cells * sizeof(gpu::CompactRay)) >> 20) +
                     " MiB, over this device's maxStorageBufferRange");
  }
}

void RtResources::write_descriptors(const GBuffer& gbuffer, const vk::Buffer& frame_uniforms, VkSampler sampler) {
  auto& ds = descriptors_;
  const RtScene& scene = scene_;
  const VkDescriptorType SB = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, TB = VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
  ds.write_buffer(HP_BIND_RT_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, frame_uniforms.handle());
  ds.write_buffer(HP_BIND_RT_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, params_.handle());
  ds.write_buffer(HP_BIND_RT_NODES, SB, scene.nodes().handle());
  scene.write_traversal_bindings(ds);
  ds.write_texel_buffer(HP_BIND_RT_NORMAL_TEXELS, TB, scene.normal_texels());
  ds.write_texel_buffer(HP_BIND_RT_SOUP_NORMAL_TEXELS, TB, scene.soup_normal_texels());
  ds.write_texel_buffer(HP_BIND_RT_SLOT_MATERIAL_TEXELS, TB, scene.slot_material_texels());
  ds.write_texel_buffer(HP_BIND_RT_MATERIAL_TEXELS, TB, scene.material_texels());
  ds.write_buffer(HP_BIND_RT_NORMALS, SB, scene.normals().handle());
  ds.write_buffer(HP_BIND_RT_SOUP_NORMALS, SB, scene.soup_normals().handle());
  ds.write_buffer(HP_BIND_RT_SLOT_MATERIAL, SB, scene.slot_material().handle());
  ds.write_buffer(HP_BIND_RT_MATERIALS, SB, scene.materials().handle());
  ds.write_buffer(HP_BIND_RT_COUNTERS, SB, counters_.handle());
  ds.write_buffer(HP_BIND_RT_SHADOW_DUMP, SB, shadow_dump_.handle());
  ds.write_buffer(HP_BIND_RT_REFLECTION_DUMP, SB, reflection_dump_.handle());
  const VkImageLayout ro = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
  const VkDescriptorType CIS = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, SI = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
  ds.write_image(HP_BIND_RT_GBUF_DEPTH, CIS, gbuffer.depth.view(), ro, sampler);
  ds.write_image(HP_BIND_RT_GBUF_NORMAL, CIS, gbuffer.normal_roughness.view(), ro, sampler);
  ds.write_image(HP_BIND_RT_GBUF_ALBEDO, CIS, gbuffer.albedo_metal.view(), ro, sampler);
  ds.write_image(HP_BIND_RT_SHADOW_MASK, SI, shadow_mask_.view(), VK_IMAGE_LAYOUT_GENERAL);
  ds.write_image(HP_BIND_RT_REFLECTION, SI, reflection_.view(), VK_IMAGE_LAYOUT_GENERAL);
  ds.write_image(HP_BIND_RT_REFLECTION_ACCUM, SI, accum_.view(), VK_IMAGE_LAYOUT_GENERAL);
  ds.write_buffer(HP_BIND_TRACE_RECORDS, SB, dummy_trace_.handle());
  ds.write_buffer(HP_BIND_RT_COMPACT_RAYS, SB, compact_rays_.handle());
  ds.write_buffer(HP_BIND_RT_SORT_KEYS, SB, sort_keys_.handle());
  ds.write_buffer(HP_BIND_RT_SORT_VALUES, SB, sort_values_.handle());
  ds.write_buffer(HP_BIND_RT_RAY_COUNT, SB, ray_count_.handle());
  if (as_) as_->write_bindings(ds);
}

vk::Pipeline RtResources::create_pipeline(vk::Context& ctx, std::span<const uint32_t> spirv) const {
  return create_rt_pipeline(ctx, spirv, descriptors_.pipeline_layout(), scene_, flags_, as_ && as_->remapped());
}

RtProgram RtResources::create_program(vk::Context& ctx, std::span<const uint32_t> compute,
                                      std::span<const uint32_t> ray_query, std::span<const uint32_t> raygen) const {
  RtProgram p;
  switch (options_.traversal) {
    case Traversal::compute: p.compute = create_pipeline(ctx, compute); break;
    case Traversal::ray_query: p.compute = create_pipeline(ctx, ray_query); break;
    case Traversal::pipeline: {
      const RtSpecialization spec(scene_, flags_, as_->remapped());
      p.trace = vk::RtPipeline(ctx, descriptors_.pipeline_layout(), raygen, rt_miss_rmiss, rt_hit_rchit, &spec.info);
      break;
    }
  }
  return p;
}

vk::Pipeline RtResources::create_traced_pipeline(vk::Context& ctx, std::span<const uint32_t> compute,
                                                 std::span<const uint32_t> ray_query) const {
  if (options_.traversal == Traversal::pipeline) {
    throw InputError(
        "--traversal pipeline: the memory-trace capture has no instrumented ray-generation shaders; capture with "
        "--traversal compute or ray-query (the same passes' own accesses)");
  }
  return create_pipeline(ctx, options_.traversal == Traversal::ray_query ? ray_query : compute);
}

void RtResources::attach_trace_buffer(const vk::Buffer& trace_buffer) {
  descriptors_.write_buffer(HP_BIND_TRACE_RECORDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, trace_buffer.handle());
}

void RtResources::begin_frame(uint32_t sample_index) {
  gpu::RayParams p{};
  // The modes and what the frame records are the pipelines' specialization constant (flags_), not here.
  p.grid = glm::uvec4(grid_w_, grid_h_, options_.reflection_divisor, 0u);
  p.shadow = glm::vec4(options_.bias, 0.0f, 0.0f, 0.0f);
  p.reflection = glm::vec4(options_.roughness_threshold, 0.0f, 0.0f, 0.0f);
  p.frame = glm::uvec4(sample_index, options_.seed, 0u, 0u);
  p.bounds_min = glm::vec4(bounds_.empty() ? glm::vec3(0.0f) : bounds_.min, float(int(options_.sort)));
  p.bounds_max =
      glm::vec4(bounds_.empty() ? glm::vec3(1.0f) : bounds_.max,
                options_.writeback == Writeback::reproject ? float(HP_WRITEBACK_REPROJECT) : float(HP_WRITEBACK_INDEX));
  // The shared offset: the Halton point of this frame, Cranley-Patterson-rotated by the seed so that a
  // different seed gives a different (still low-discrepancy) sequence.
  const glm::vec2 h = halton23(sample_index + 1);
  const float rx = float((options_.seed * 2654435761u) >> 16) / 65536.0f;
  const float ry = float((options_.seed * 2246822519u) >> 16) / 65536.0f;
  p.jitter = glm::vec4(glm::fract(h + glm::vec2(rx, ry)), 0.0f, 0.0f);
  params_cache_ = p;
  std::memcpy(params_.mapped(), &p, sizeof(p));
}

void RtResources::set_slice(uint32_t first_row, uint32_t sampling) {
  params_cache_.frame.z = first_row;
  params_cache_.frame.w = sampling;
  std::memcpy(params_.mapped(), &params_cache_, sizeof(params_cache_));
}

void RtResources::record_prepare(VkCommandBuffer cmd) {
  // The accumulation image keeps its contents between frames: only its first use starts from UNDEFINED.
  const VkImageLayout from = images_initialised_ ? VK_IMAGE_LAYOUT_GENERAL : VK_IMAGE_LAYOUT_UNDEFINED;
  for (const vk::Image* img : {&shadow_mask_, &reflection_}) {
    vk::transition(cmd, *img, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL,
                   VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT, 0,
                   VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
  }
  vk::transition(cmd, accum_, from, VK_IMAGE_LAYOUT_GENERAL,
                 VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                 VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT | VK_ACCESS_2_TRANSFER_READ_BIT,
                 VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                 VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
  images_initialised_ = true;
  vkCmdFillBuffer(cmd, counters_.handle(), 0, VK_WHOLE_SIZE, 0);
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
}

namespace {
// Both images are in GENERAL before and after; the copy runs in the transfer layouts.
void copy_whole(VkCommandBuffer cmd, const vk::Image& from, const vk::Image& to) {
  VkImageCopy region{};
  region.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.dstSubresource = region.srcSubresource;
  region.extent = {from.width(), from.height(), 1};
  const VkPipelineStageFlags2 all = VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, copy = VK_PIPELINE_STAGE_2_COPY_BIT;
  const VkAccessFlags2 rw = VK_ACCESS_2_MEMORY_READ_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT;
  vk::transition(cmd, from, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, all,
                 VK_ACCESS_2_MEMORY_WRITE_BIT, copy, VK_ACCESS_2_TRANSFER_READ_BIT);
  vk::transition(cmd, to, VK_IMAGE_LAYOUT_GENERAL, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, all, rw, copy,
                 VK_ACCESS_2_TRANSFER_WRITE_BIT);
  vkCmdCopyImage(cmd, from.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, to.handle(),
                 VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
  vk::transition(cmd, from, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL, copy,
                 VK_ACCESS_2_TRANSFER_READ_BIT, all, rw);
  vk::transition(cmd, to, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL, copy,
                 VK_ACCESS_2_TRANSFER_WRITE_BIT, all, rw);
}
}  // namespace

void RtResources::save_accumulation(vk::Context& ctx) {
  if (!images_initialised_) return;  // nothing accumulated yet: the next frame starts from UNDEFINED anyway
  ctx.submit_and_wait([&](VkCommandBuffer cmd) {
    if (accum_saved_.handle() == VK_NULL_HANDLE) {
      accum_saved_ =
          vk::Image(ctx, accum_.width(), accum_.height(), accum_.format(),
                    VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT);
      vk::transition(cmd, accum_saved_, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_NONE, 0,
                     VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
    }
    copy_whole(cmd, accum_, accum_saved_);
  });
}

void RtResources::restore_accumulation(vk::Context& ctx) {
  if (accum_saved_.handle() == VK_NULL_HANDLE || !images_initialised_) return;
  ctx.submit_and_wait([&](VkCommandBuffer cmd) { copy_whole(cmd, accum_saved_, accum_); });
}

void RtResources::bind(VkCommandBuffer cmd, const vk::Pipeline& p) const {
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, p.handle());
  VkDescriptorSet set = descriptors_.set();
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, descriptors_.pipeline_layout(), 0, 1, &set, 0, nullptr);
}

void RtResources::dispatch(VkCommandBuffer cmd, const vk::Pipeline& p, uint32_t w, uint32_t h,
                           bool then_barrier) const {
  bind(cmd, p);
  vkCmdDispatch(cmd, (w + 7) / 8, (h + 7) / 8, 1);
  if (!then_barrier) return;
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                         VK_ACCESS_2_TRANSFER_READ_BIT);
}

namespace {
// Around a ray-tracing launch: every earlier command's writes visible to the ray-tracing stages, and the
// launch's writes visible to every later command (the compute passes' own barriers name the compute stage).
void ray_tracing_barrier(VkCommandBuffer cmd, bool before) {
  const VkPipelineStageFlags2 rt = VK_PIPELINE_STAGE_2_RAY_TRACING_SHADER_BIT_KHR;
  const VkPipelineStageFlags2 all = VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT;
  const VkAccessFlags2 rw = VK_ACCESS_2_MEMORY_READ_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT;
  if (before) {
    vk::memory_barrier(cmd, all, VK_ACCESS_2_MEMORY_WRITE_BIT, rt | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT, rw);
  } else {
    vk::memory_barrier(cmd, rt, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, all, rw);
  }
}
}  // namespace

void RtResources::dispatch(VkCommandBuffer cmd, const RtProgram& p, uint32_t w, uint32_t h, bool then_barrier) const {
  if (!p.trace.handle()) {
    dispatch(cmd, p.compute, w, h, then_barrier);
    return;
  }
  bind_trace(cmd, p);
  p.trace.record_trace(cmd, w, h);
  ray_tracing_barrier(cmd, false);
}

void RtResources::bind_trace(VkCommandBuffer cmd, const RtProgram& p) const {
  ray_tracing_barrier(cmd, true);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, p.trace.handle());
  const VkDescriptorSet set = descriptors_.set();
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR, descriptors_.pipeline_layout(), 0, 1, &set, 0,
                          nullptr);
}

void RtResources::trace_indirect(VkCommandBuffer cmd, const RtProgram& p, VkDeviceSize offset) const {
  if (!p.trace.handle()) throw std::logic_error("RtResources::trace_indirect: a ray-tracing pipeline only");
  bind_trace(cmd, p);
  p.trace.record_trace_indirect(cmd, ray_count_.device_address() + offset);
  ray_tracing_barrier(cmd, false);
}

void RtResources::dispatch_traced(VkCommandBuffer cmd, const vk::Pipeline& p, uint32_t gx, uint32_t gy) const {
  bind(cmd, p);
  vkCmdDispatch(cmd, gx, gy, 1);
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT |
                         VK_PIPELINE_STAGE_2_HOST_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                         VK_ACCESS_2_TRANSFER_READ_BIT | VK_ACCESS_2_HOST_READ_BIT);
}

void RtResources::dispatch_traced_rows(VkCommandBuffer cmd, const vk::Pipeline& p, glm::uvec2 workgroups,
                                       uint32_t first_row, uint32_t rows, uint32_t sharing,
                                       const char* unattached) const {
  if (!p.handle()) throw std::logic_error(unattached);
  if (sharing) {
    dispatch_traced(cmd, p, sharing, 1);
    return;
  }
  dispatch_traced(cmd, p, workgroups.x, std::min(rows, workgroups.y - first_row));
}

uint32_t RtResources::read_compacted_count(vk::Context& ctx) const {
  const auto bytes = vk::read_buffer(ctx, ray_count_);
  uint32_t n = 0;
  std::memcpy(&n, bytes.data(), 4);
  return n;
}

RayCounters RtResources::read_counters(vk::Context& ctx) const {
  const auto bytes = vk::read_buffer(ctx, counters_);
  uint32_t w[HP_COUNTER_WORDS];
  std::memcpy(w, bytes.data(), sizeof(w));
  auto at = [&](int i) { return uint64_t(w[i]) | (uint64_t(w[i + 1]) << 32); };
  RayCounters c;
  c.shadow_rays = at(HP_COUNTER_SHADOW_RAYS);
  c.shadow_nodes = at(HP_COUNTER_SHADOW_NODES);
  c.shadow_tris = at(HP_COUNTER_SHADOW_TRIS);
  c.reflection_rays = at(HP_COUNTER_REFL_RAYS);
  c.reflection_nodes = at(HP_COUNTER_REFL_NODES);
  c.reflection_tris = at(HP_COUNTER_REFL_TRIS);
  c.reflection_shadow_rays = at(HP_COUNTER_REFL_SHADOW_RAYS);
  c.reprojection_misplaced = at(HP_COUNTER_REPROJECT_MISPLACED);
  c.reprojected = options_.reflections && options_.reflection_path == ReflectionPath::compact &&
                  options_.writeback == Writeback::reproject;
  if (c.reprojected) {
    // Cells that had a ray but were left unwritten: the compacted rays name their cells, and the
    // reflection grid's alpha says which cells the consume pass wrote.
    const uint32_t rays = read_compacted_count(ctx);
    const auto ray_bytes = vk::read_buffer(ctx, compact_rays_);
    const auto image = vk::read_image(ctx, reflection_, VK_IMAGE_LAYOUT_GENERAL);
    const auto* cr = reinterpret_cast<const gpu::CompactRay*>(ray_bytes.data());
    const auto* px = reinterpret_cast<const float*>(image.data());
    for (uint32_t i = 0; i < rays; ++i) {
      uint32_t cell;
      std::memcpy(&cell, &cr[i].origin_cell.w, 4);
      c.reprojection_unwritten += px[size_t(cell) * 4 + 3] < 0.5f;
    }
  }
  return c;
}

namespace {
std::vector<gpu::RayDump> read_dump(vk::Context& ctx, const vk::Buffer& b, bool enabled) {
  if (!enabled) throw std::logic_error("ray dumps were not enabled (RayTracingOptions::dump_rays)");
  const auto bytes = vk::read_buffer(ctx, b);
  std::vector<gpu::RayDump> out(bytes.size() / sizeof(gpu::RayDump));
  std::memcpy(out.data(), bytes.data(), out.size() * sizeof(gpu::RayDump));
  return out;
}
}  // namespace

std::vector<gpu::RayDump> RtResources::read_shadow_dump(vk::Context& ctx) const {
  return read_dump(ctx, shadow_dump_, options_.dump_rays);
}
std::vector<gpu::RayDump> RtResources::read_reflection_dump(vk::Context& ctx) const {
  return read_dump(ctx, reflection_dump_, options_.dump_rays);
}

}  // namespace hp
