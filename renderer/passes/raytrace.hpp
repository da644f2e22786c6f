// The ray-tracing compute passes (shadows, reflections, temporal accumulation) and what they share: one
// descriptor set (shaders/common/rt_bindings.glsl), the ray parameters, the output images, the counter
// buffer and the optional ray dumps.
#pragma once

#include "bvh/geometry.hpp"
#include "frame_settings.hpp"
#include "gpu/shared_types.h"
#include "passes/gbuffer.hpp"
#include "passes/radix_sort.hpp"
#include "rt_scene.hpp"
#include "vk/pipeline.hpp"

#include <array>
#include <optional>

namespace hp {



/// The ray of a dump record (RayTracingOptions::dump_rays): its first two vectors are the bvh::Ray layout.
inline bvh::Ray dumped_ray(const gpu::RayDump& d) {
  return {glm::vec3(d.origin_tmin), d.origin_tmin.w, glm::vec3(d.dir_tmax), d.dir_tmax.w};
}

/// Deterministic work counters of one frame (HP_RT_COUNTERS).
struct RayCounters {
  uint64_t shadow_rays = 0, shadow_nodes = 0, shadow_tris = 0;
  uint64_t reflection_rays = 0, reflection_nodes = 0, reflection_tris = 0, reflection_shadow_rays = 0;
  uint64_t reprojection_misplaced = 0;  ///< compact path, write-back by reprojection: rays written elsewhere
  uint64_t reprojection_unwritten = 0;  ///< ... and reflective cells that no ray wrote (read back on the host)
  bool reprojected = false;             ///< the frame wrote back by reprojection (the counters above apply)
  bool operator==(const RayCounters&) const = default;
};

class RayTracingPasses {
 public:
  /// `scene_bounds` quantizes origin sort keys.
  RayTracingPasses(vk::Context& ctx, const RtScene& scene, const GBuffer& gbuffer, const vk::Buffer& frame_uniforms,
                   VkSampler sampler, const RayTracingOptions& options, const Aabb& scene_bounds);

  uint32_t grid_width() const { return grid_w_; }
  uint32_t grid_height() const { return grid_h_; }
  const RayTracingOptions& options() const { return options_; }

  /// Sets the per-frame parameters (sample index for accumulation and jitter) before recording.
  void begin_frame(uint32_t sample_index);
  /// Each expects the G-buffer in SHADER_READ_ONLY_OPTIMAL and leaves its outputs readable by the next pass.
  void record_prepare(VkCommandBuffer cmd);  ///< layouts of the output images, counter reset
  /// `then_barrier` false: no barrier after the pass, for a caller that records a pass with a compute
  /// barrier of its own next in the same command buffer (the reflections): the shadow and reflection passes
  /// do not depend on each other, so a device may run them concurrently.
  void record_shadows(VkCommandBuffer cmd, bool then_barrier = true) const;
  void record_reflections(VkCommandBuffer cmd) const;
  void record_accumulate(VkCommandBuffer cmd) const;
  /// The compaction path: append the valid rays and size the consume dispatch on the GPU; sort them
  /// (when a key is chosen); trace and shade them one thread per ray.
  void record_compact(VkCommandBuffer cmd) const;
  void record_sort(VkCommandBuffer cmd);
  void record_consume(VkCommandBuffer cmd) const;
  /// Rays appended by the last compaction (a readback, for tests and reports; the frame never waits on it).
  uint32_t read_compacted_count(vk::Context& ctx) const;

  /// The running mean of the reflections copied aside and back (one submission each, outside any timed
  /// frame): a frame that repeats a measured frame's sample for timing (Frame::render with
  /// FrameQueries::frame_span) leaves the accumulation as it found it.
  void save_accumulation(vk::Context& ctx);
  void restore_accumulation(vk::Context& ctx);

  const vk::Image& shadow_mask() const { return shadow_mask_; }
  const vk::Image& reflection() const { return reflection_; }
  const vk::Image& reflection_accum() const { return accum_; }

  /// Memory-trace capture: binds `trace_buffer` (a TraceBufferHeader then TraceRecords) and builds the
  /// instrumented pipelines (compiled from the same sources with HP_TRACE) of the passes to be traced:
  /// `shadows`, `reflections` (the compaction path's compact, sort kernels and consume).
  void attach_trace_buffer(vk::Context& ctx, const vk::Buffer& trace_buffer, bool shadows, bool reflections);
  /// Records one slice of a traced pass: workgroup rows [first_row, first_row + rows) of the full
  /// dispatch; every `sample_every`-th workgroup (in dispatch order) records its accesses.
  enum class Traced { shadows, reflections, compact, consume };
  void record_traced_slice(VkCommandBuffer cmd, Traced pass, uint32_t first_row, uint32_t rows);
  void set_slice(uint32_t first_row, uint32_t sampling);  ///< sampling: k | log2(burst) << 20
  /// Workgroups of a pass's full dispatch, x and y: 8x8 invocations each, except the consume pass
  /// (64 x 1, one row of ceil(rays / 64) groups; `rays` is read back by the caller).
  glm::uvec2 workgroups(Traced pass, uint32_t rays = 0) const;
  /// Records the consume dispatch arguments (from the compacted count).
  void record_args(VkCommandBuffer cmd) const;
  /// The ray sort's dispatches (none without a sort key), and one slice of one of them traced.
  std::vector<RadixSort::Step> sort_steps() const;
  void record_traced_sort_step(VkCommandBuffer cmd, const RadixSort::Step& step, uint32_t first_group,
                               uint32_t groups, uint32_t sampling);
  const RadixSort* sorter() const { return sorter_.get(); }
  /// Sets the compacted ray count (capture: restart an overflowed compaction slice).
  void record_reset_count(VkCommandBuffer cmd, uint32_t count) const;

  RayCounters read_counters(vk::Context& ctx) const;
  std::vector<gpu::RayDump> read_shadow_dump(vk::Context& ctx) const;
  std::vector<gpu::RayDump> read_reflection_dump(vk::Context& ctx) const;

 private:
  void bind(VkCommandBuffer cmd, const vk::Pipeline& p) const;
  void dispatch(VkCommandBuffer cmd, const vk::Pipeline& p, uint32_t w, uint32_t h, bool then_barrier = true) const;

  RayTracingOptions options_;
  uint32_t width_, height_, grid_w_, grid_h_;
  vk::Buffer params_;
  vk::Buffer counters_;
  vk::Buffer shadow_dump_, reflection_dump_;
  vk::Image shadow_mask_, reflection_, accum_;
  vk::Image accum_saved_;  // save_accumulation's copy, made on first use
  vk::DescriptorSet descriptors_;
  vk::Pipeline shadow_pipeline_, reflection_pipeline_, accumulate_pipeline_;
  vk::Pipeline shadow_traced_, reflection_traced_;
  vk::Pipeline compact_pipeline_, args_pipeline_, consume_pipeline_;
  vk::Pipeline compact_traced_, consume_traced_;
  vk::Buffer compact_rays_, sort_keys_, sort_values_, ray_count_;
  std::unique_ptr<RadixSort> sorter_;
  Aabb bounds_;
  vk::Buffer dummy_trace_;
  const RtScene& scene_;  // owned by the Frame, which destroys these passes first
  // What the frame records and its ray modes (HP_RT_*): a specialization constant of every pipeline.
  uint32_t flags_;
  gpu::RayParams params_cache_{};
  bool images_initialised_ = false;
};

}  // namespace hp
