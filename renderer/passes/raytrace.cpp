#include "passes/raytrace.hpp"

#include "error.hpp"
#include "gpu/bindings.h"
#include "vk/check.hpp"

#include "shaders/accumulate_comp.h"
#include "shaders/compact_args_comp.h"
#include "shaders/compact_comp.h"
#include "shaders/compact_traced_comp.h"
#include "shaders/consume_traced_comp.h"
#include "shaders/consume_comp.h"
#include "shaders/reflections_comp.h"
#include "shaders/reflections_traced_comp.h"
#include "shaders/shadows_comp.h"
#include "shaders/shadows_traced_comp.h"

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

}  // namespace

RayTracingPasses::RayTracingPasses(vk::Context& ctx, const RtScene& scene, const GBuffer& gbuffer,
                                   const vk::Buffer& frame_uniforms, VkSampler sampler,
                                   const RayTracingOptions& options, const Aabb& scene_bounds)
    : options_(options),
      width_(gbuffer.depth.width()),
      height_(gbuffer.depth.height()),
      bounds_(scene_bounds),
      scene_(scene),
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

  params_ = vk::Buffer(ctx, sizeof(gpu::RayParams), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
  counters_ = vk::Buffer(ctx, HP_COUNTER_WORDS * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                                        VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                                        VK_BUFFER_USAGE_TRANSFER_SRC_BIT, false);
  const VkBufferUsageFlags dump_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  shadow_dump_ = vk::Buffer(ctx, options.dump_rays ? uint64_t(width_) * height_ * sizeof(gpu::RayDump) : 4,
                            dump_usage, false);
  reflection_dump_ = vk::Buffer(ctx, options.dump_rays ? uint64_t(grid_w_) * grid_h_ * sizeof(gpu::RayDump) : 4,
                                dump_usage, false);
  const VkImageUsageFlags img_usage =
      VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  // A disabled pass's output is a 1x1 stand-in (the composite reads it only when the pass is on): a frame
  // without reflections does not hold two 16-byte-per-cell images for them (29 MiB at 1280x720).
  const bool sh = options.shadows, refl = options.reflections;
  shadow_mask_ = vk::Image(ctx, sh ? width_ : 1, sh ? height_ : 1, VK_FORMAT_R32_SFLOAT, img_usage);
  reflection_ = vk::Image(ctx, refl ? grid_w_ : 1, refl ? grid_h_ : 1, VK_FORMAT_R32G32B32A32_SFLOAT, img_usage);
  accum_ = vk::Image(ctx, refl ? grid_w_ : 1, refl ? grid_h_ : 1, VK_FORMAT_R32G32B32A32_SFLOAT, img_usage);

  std::vector<VkDescriptorSetLayoutBinding> b;
  b.push_back({HP_BIND_RT_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, kCS, nullptr});
  b.push_back({HP_BIND_RT_PARAMS, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, kCS, nullptr});
  RtScene::add_traversal_bindings(b);
  b.push_back({HP_BIND_RT_NODES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, kCS, nullptr});
  for (uint32_t i : {HP_BIND_RT_NORMALS, HP_BIND_RT_SOUP_NORMALS, HP_BIND_RT_SLOT_MATERIAL, HP_BIND_RT_MATERIALS,
                     HP_BIND_RT_COUNTERS, HP_BIND_RT_SHADOW_DUMP, HP_BIND_RT_REFLECTION_DUMP}) {
    b.push_back({i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, kCS, nullptr});
  }
  for (uint32_t i : {HP_BIND_RT_GBUF_DEPTH, HP_BIND_RT_GBUF_NORMAL, HP_BIND_RT_GBUF_ALBEDO}) {
    b.push_back({i, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, kCS, nullptr});
  }
  for (uint32_t i : {HP_BIND_RT_SHADOW_MASK, HP_BIND_RT_REFLECTION, HP_BIND_RT_REFLECTION_ACCUM}) {
    b.push_back({i, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, kCS, nullptr});
  }
  // trace records (instrumented variants)
  b.push_back({HP_BIND_TRACE_RECORDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, kCS, nullptr});
  for (uint32_t i : {HP_BIND_RT_COMPACT_RAYS, HP_BIND_RT_SORT_KEYS, HP_BIND_RT_SORT_VALUES, HP_BIND_RT_RAY_COUNT}) {
    b.push_back({i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, kCS, nullptr});  // compaction
  }
  for (uint32_t i : {HP_BIND_RT_NORMAL_TEXELS, HP_BIND_RT_SOUP_NORMAL_TEXELS, HP_BIND_RT_SLOT_MATERIAL_TEXELS,
                     HP_BIND_RT_MATERIAL_TEXELS}) {
    b.push_back({i, VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, 1, kCS, nullptr});  // shading data as texels
  }
  descriptors_ = vk::DescriptorSet(ctx, b, 0, 0);
  auto& ds = descriptors_;
  const VkDescriptorType SB = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  const VkDescriptorType TB = VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
  const VkDescriptorType CIS = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, SI = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE;
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
  ds.write_image(HP_BIND_RT_GBUF_DEPTH, CIS, gbuffer.depth.view(), ro, sampler);
  ds.write_image(HP_BIND_RT_GBUF_NORMAL, CIS, gbuffer.normal_roughness.view(), ro, sampler);
  ds.write_image(HP_BIND_RT_GBUF_ALBEDO, CIS, gbuffer.albedo_metal.view(), ro, sampler);
  ds.write_image(HP_BIND_RT_SHADOW_MASK, SI, shadow_mask_.view(), VK_IMAGE_LAYOUT_GENERAL);
  ds.write_image(HP_BIND_RT_REFLECTION, SI, reflection_.view(), VK_IMAGE_LAYOUT_GENERAL);
  ds.write_image(HP_BIND_RT_REFLECTION_ACCUM, SI, accum_.view(), VK_IMAGE_LAYOUT_GENERAL);
  dummy_trace_ = vk::Buffer(ctx, 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);
  ds.write_buffer(HP_BIND_TRACE_RECORDS, SB, dummy_trace_.handle());
  // Compaction buffers: sized for every grid cell when that path is on, else 4-byte dummies.
  const bool compact = options.reflections && options.reflection_path == ReflectionPath::compact;
  const uint64_t cells = uint64_t(grid_w_) * grid_h_;
  const VkBufferUsageFlags sb_usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  compact_rays_ = vk::Buffer(ctx, compact ? cells * sizeof(gpu::CompactRay) : 4, sb_usage, false);
  sort_keys_ = vk::Buffer(ctx, compact ? cells * 4 : 4, sb_usage, false);
  sort_values_ = vk::Buffer(ctx, compact ? cells * 4 : 4, sb_usage, false);
  ray_count_ = vk::Buffer(ctx, 16, sb_usage | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                          false);
  if (compact && cells * sizeof(gpu::CompactRay) > ctx.properties().limits.maxStorageBufferRange) {
    throw InputError("compact reflections: " + std::to_string(cells) + " rays need " +
                     std::to_string((cells * sizeof(gpu::CompactRay)) >> 20) +
                     " MiB, over this device's maxStorageBufferRange");
  }
  ds.write_buffer(HP_BIND_RT_COMPACT_RAYS, SB, compact_rays_.handle());
  ds.write_buffer(HP_BIND_RT_SORT_KEYS, SB, sort_keys_.handle());
  ds.write_buffer(HP_BIND_RT_SORT_VALUES, SB, sort_values_.handle());
  ds.write_buffer(HP_BIND_RT_RAY_COUNT, SB, ray_count_.handle());

  // Only the pipelines the options ask for are compiled (lavapipe compiles each one with LLVM).
  if (options.shadows) shadow_pipeline_ = create_rt_pipeline(ctx, shadows_comp, ds.pipeline_layout(), scene, flags_);
  if (compact) {
    compact_pipeline_ = create_rt_pipeline(ctx, compact_comp, ds.pipeline_layout(), scene, flags_);
    args_pipeline_ = create_rt_pipeline(ctx, compact_args_comp, ds.pipeline_layout(), scene, flags_);
    consume_pipeline_ = create_rt_pipeline(ctx, consume_comp, ds.pipeline_layout(), scene, flags_);
    if (options.sort != SortKey::none) sorter_ = std::make_unique<RadixSort>(ctx, uint32_t(cells));
  }
  if (options.reflections && !compact) {
    reflection_pipeline_ = create_rt_pipeline(ctx, reflections_comp, ds.pipeline_layout(), scene, flags_);
  }
  if (options.reflections) {
    accumulate_pipeline_ = create_rt_pipeline(ctx, accumulate_comp, ds.pipeline_layout(), scene, flags_);
  }
  begin_frame(0);
}

void RayTracingPasses::begin_frame(uint32_t sample_index) {
  gpu::RayParams p{};
  // The modes and what the frame records are the pipelines' specialization constant (flags_), not here.
  p.grid = glm::uvec4(grid_w_, grid_h_, options_.reflection_divisor, 0u);
  p.shadow = glm::vec4(options_.bias, 0.0f, 0.0f, 0.0f);
  p.reflection = glm::vec4(options_.roughness_threshold, 0.0f, 0.0f, 0.0f);
  p.frame = glm::uvec4(sample_index, options_.seed, 0u, 0u);
  p.bounds_min = glm::vec4(bounds_.empty() ? glm::vec3(0.0f) : bounds_.min, float(int(options_.sort)));
  p.bounds_max = glm::vec4(bounds_.empty() ? glm::vec3(1.0f) : bounds_.max,
                           options_.writeback == Writeback::reproject ? float(HP_WRITEBACK_REPROJECT)
                                                                      : float(HP_WRITEBACK_INDEX));
  // The shared offset: the Halton point of this frame, Cranley-Patterson-rotated by the seed so that a
  // different seed gives a different (still low-discrepancy) sequence.
  const glm::vec2 h = halton23(sample_index + 1);
  const float rx = float((options_.seed * 2654435761u) >> 16) / 65536.0f;
  const float ry = float((options_.seed * 2246822519u) >> 16) / 65536.0f;
  p.jitter = glm::vec4(glm::fract(h + glm::vec2(rx, ry)), 0.0f, 0.0f);
  params_cache_ = p;
  std::memcpy(params_.mapped(), &p, sizeof(p));
}

void RayTracingPasses::set_slice(uint32_t first_row, uint32_t sampling) {
  params_cache_.frame.z = first_row;
  params_cache_.frame.w = sampling;
  std::memcpy(params_.mapped(), &params_cache_, sizeof(params_cache_));
}

glm::uvec2 RayTracingPasses::workgroups(Traced pass, uint32_t rays) const {
  switch (pass) {
    case Traced::shadows: return {(width_ + 7) / 8, (height_ + 7) / 8};
    case Traced::consume: return {(rays + 63) / 64, 1u};
    default: return {(grid_w_ + 7) / 8, (grid_h_ + 7) / 8};
  }
}

void RayTracingPasses::attach_trace_buffer(vk::Context& ctx, const vk::Buffer& trace_buffer, bool shadows,
                                           bool reflections) {
  descriptors_.write_buffer(HP_BIND_TRACE_RECORDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, trace_buffer.handle());
  if (options_.shadows && shadows && !shadow_traced_.handle()) {
    shadow_traced_ = create_rt_pipeline(ctx, shadows_traced_comp, descriptors_.pipeline_layout(), scene_, flags_);
  }
  const bool compact = options_.reflections && reflections && options_.reflection_path == ReflectionPath::compact;
  if (options_.reflections && reflections && !compact && !reflection_traced_.handle()) {
    reflection_traced_ =
        create_rt_pipeline(ctx, reflections_traced_comp, descriptors_.pipeline_layout(), scene_, flags_);
  }
  if (compact && sorter_) sorter_->attach_trace_buffer(ctx, trace_buffer);
  if (compact && !compact_traced_.handle()) {
    compact_traced_ = create_rt_pipeline(ctx, compact_traced_comp, descriptors_.pipeline_layout(), scene_, flags_);
    consume_traced_ = create_rt_pipeline(ctx, consume_traced_comp, descriptors_.pipeline_layout(), scene_, flags_);
  }
}

void RayTracingPasses::record_traced_slice(VkCommandBuffer cmd, Traced pass, uint32_t first_row, uint32_t rows) {
  const vk::Pipeline* pipelines[] = {&shadow_traced_, &reflection_traced_, &compact_traced_, &consume_traced_};
  const vk::Pipeline& p = *pipelines[int(pass)];
  if (!p.handle()) throw std::logic_error("record_traced_slice: attach_trace_buffer first (pass enabled?)");
  bind(cmd, p);
  if (pass == Traced::consume) {
    vkCmdDispatch(cmd, rows, 1, 1);  // a slice of the one row of consume groups, offset by frame.z
  } else {
    const glm::uvec2 wg = workgroups(pass);
    vkCmdDispatch(cmd, wg.x, std::min(rows, wg.y - first_row), 1);
  }
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT | VK_PIPELINE_STAGE_2_HOST_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                         VK_ACCESS_2_TRANSFER_READ_BIT | VK_ACCESS_2_HOST_READ_BIT);
}

void RayTracingPasses::record_prepare(VkCommandBuffer cmd) {
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

void RayTracingPasses::save_accumulation(vk::Context& ctx) {
  if (!images_initialised_) return;  // nothing accumulated yet: the next frame starts from UNDEFINED anyway
  ctx.submit_and_wait([&](VkCommandBuffer cmd) {
    if (accum_saved_.handle() == VK_NULL_HANDLE) {
      accum_saved_ = vk::Image(ctx, accum_.width(), accum_.height(), accum_.format(),
                               VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT |
                                   VK_IMAGE_USAGE_TRANSFER_DST_BIT);
      vk::transition(cmd, accum_saved_, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_NONE, 0,
                     VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
    }
    copy_whole(cmd, accum_, accum_saved_);
  });
}

void RayTracingPasses::restore_accumulation(vk::Context& ctx) {
  if (accum_saved_.handle() == VK_NULL_HANDLE || !images_initialised_) return;
  ctx.submit_and_wait([&](VkCommandBuffer cmd) { copy_whole(cmd, accum_saved_, accum_); });
}

void RayTracingPasses::bind(VkCommandBuffer cmd, const vk::Pipeline& p) const {
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, p.handle());
  VkDescriptorSet set = descriptors_.set();
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, descriptors_.pipeline_layout(), 0, 1, &set, 0, nullptr);
}

void RayTracingPasses::dispatch(VkCommandBuffer cmd, const vk::Pipeline& p, uint32_t w, uint32_t h,
                                bool then_barrier) const {
  bind(cmd, p);
  vkCmdDispatch(cmd, (w + 7) / 8, (h + 7) / 8, 1);
  if (!then_barrier) return;
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                         VK_ACCESS_2_TRANSFER_READ_BIT);
}

void RayTracingPasses::record_shadows(VkCommandBuffer cmd, bool then_barrier) const {
  const uint32_t rows = options_.inject_shadow_fraction > 0.0f
                            ? std::min(height_, uint32_t(std::ceil(height_ * options_.inject_shadow_fraction)))
                            : 0u;
  // The injected re-trace writes the same texels: a barrier between the two dispatches.
  dispatch(cmd, shadow_pipeline_, width_, height_, then_barrier || rows > 0);
  if (rows > 0) dispatch(cmd, shadow_pipeline_, width_, rows, then_barrier);
}

void RayTracingPasses::record_reflections(VkCommandBuffer cmd) const {
  dispatch(cmd, reflection_pipeline_, grid_w_, grid_h_);
}

void RayTracingPasses::record_accumulate(VkCommandBuffer cmd) const {
  dispatch(cmd, accumulate_pipeline_, grid_w_, grid_h_);
}

void RayTracingPasses::record_compact(VkCommandBuffer cmd) const {
  vkCmdFillBuffer(cmd, ray_count_.handle(), 0, VK_WHOLE_SIZE, 0);
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
  dispatch(cmd, compact_pipeline_, grid_w_, grid_h_);
  record_args(cmd);
}

void RayTracingPasses::record_args(VkCommandBuffer cmd) const {
  bind(cmd, args_pipeline_);
  vkCmdDispatch(cmd, 1, 1, 1);
  // Read as indirect arguments (the frame), by shaders and by a host readback (the capture).
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT | VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT |
                         VK_PIPELINE_STAGE_2_COPY_BIT,
                     VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_READ_BIT |
                         VK_ACCESS_2_TRANSFER_READ_BIT);
}

std::vector<RadixSort::Step> RayTracingPasses::sort_steps() const {
  return sorter_ ? sorter_->steps(sort_key_bits(options_.sort)) : std::vector<RadixSort::Step>{};
}

void RayTracingPasses::record_traced_sort_step(VkCommandBuffer cmd, const RadixSort::Step& step, uint32_t first_group,
                                               uint32_t groups, uint32_t sampling) {
  sorter_->record_traced_step(cmd, step, sort_keys_, sort_values_, ray_count_, sort_key_bits(options_.sort), first_group,
                              groups, sampling);
}

void RayTracingPasses::record_reset_count(VkCommandBuffer cmd, uint32_t count) const {
  vkCmdUpdateBuffer(cmd, ray_count_.handle(), 0, sizeof(count), &count);
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT | VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
}

void RayTracingPasses::record_sort(VkCommandBuffer cmd) {
  if (!sorter_) return;
  sorter_->record(cmd, sort_keys_, sort_values_, ray_count_, sort_key_bits(options_.sort));
}

void RayTracingPasses::record_consume(VkCommandBuffer cmd) const {
  bind(cmd, consume_pipeline_);
  vkCmdDispatchIndirect(cmd, ray_count_.handle(), 4);  // consume_groups_x/y/z follow the count
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                         VK_ACCESS_2_TRANSFER_READ_BIT);
}

uint32_t RayTracingPasses::read_compacted_count(vk::Context& ctx) const {
  const auto bytes = vk::read_buffer(ctx, ray_count_);
  uint32_t n = 0;
  std::memcpy(&n, bytes.data(), 4);
  return n;
}

RayCounters RayTracingPasses::read_counters(vk::Context& ctx) const {
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

std::vector<gpu::RayDump> RayTracingPasses::read_shadow_dump(vk::Context& ctx) const {
  return read_dump(ctx, shadow_dump_, options_.dump_rays);
}
std::vector<gpu::RayDump> RayTracingPasses::read_reflection_dump(vk::Context& ctx) const {
  return read_dump(ctx, reflection_dump_, options_.dump_rays);
}

}  // namespace hp
