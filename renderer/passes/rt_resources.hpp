// What the ray-tracing compute passes share: one descriptor set (shaders/common/rt_bindings.glsl, the
// bindings of core/gpu/bindings.h), the ray parameters, the output images, the counter buffer, the optional
// ray dumps and the compaction path's buffers. The passes (shadow_pass, reflection_pass, compaction_path,
// accumulate_pass) hold only their pipelines and record against these.
#pragma once

#include "accel_structure.hpp"
#include "bvh/geometry.hpp"
#include "frame_settings.hpp"
#include "gpu/shared_types.h"
#include "passes/gbuffer.hpp"
#include "rt_scene.hpp"
#include "vk/pipeline.hpp"
#include "vk/rt_pipeline.hpp"

#include <span>
#include <vector>

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

/// A ray-tracing pass's program as RayTracingOptions::traversal asks: a compute pipeline (the BVH traversal,
/// or ray queries) or a ray-tracing pipeline (its ray-generation shader the same source).
struct RtProgram {
  vk::Pipeline compute;
  vk::RtPipeline trace;
  bool empty() const { return !compute.handle() && !trace.handle(); }
};

class RtResources {
 public:
  /// `scene_bounds` quantizes origin sort keys. `as`: the driver's acceleration structure, for the ray-query
  /// and pipeline traversals (nullptr for compute). Throws InputError for an unusable reflection scale or
  /// bias, or compaction buffers over the device's maxStorageBufferRange.
  RtResources(vk::Context& ctx, const RtScene& scene, const GBuffer& gbuffer, const vk::Buffer& frame_uniforms,
              VkSampler sampler, const RayTracingOptions& options, const Aabb& scene_bounds,
              const AccelStructure* as = nullptr);

  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  uint32_t grid_width() const { return grid_w_; }
  uint32_t grid_height() const { return grid_h_; }
  const RayTracingOptions& options() const { return options_; }
  /// The reflections take the compaction path (compact -> [sort] -> consume).
  bool compaction() const { return options_.reflections && options_.reflection_path == ReflectionPath::compact; }

  /// A compute pipeline of this set's layout, specialized for the scene and the frame's flags (HP_RT_*).
  vk::Pipeline create_pipeline(vk::Context& ctx, std::span<const uint32_t> spirv) const;
  /// A tracing pass's program for this frame's traversal: the compute BVH variant, the ray-query variant or
  /// the ray-generation shader (with the shared miss and closest-hit shaders).
  RtProgram create_program(vk::Context& ctx, std::span<const uint32_t> compute, std::span<const uint32_t> ray_query,
                           std::span<const uint32_t> raygen) const;
  /// The instrumented variant of a tracing pass (compute or ray-query traversal); throws InputError for the
  /// pipeline traversal, whose ray-generation shaders have no instrumented variant.
  vk::Pipeline create_traced_pipeline(vk::Context& ctx, std::span<const uint32_t> compute,
                                      std::span<const uint32_t> ray_query) const;
  Traversal traversal() const { return options_.traversal; }

  /// Sets the per-frame parameters (sample index for accumulation and jitter) before recording.
  void begin_frame(uint32_t sample_index);
  /// A traced slice's first workgroup row (RayParams.frame.z) and sampling (k | log2(burst) << 20).
  void set_slice(uint32_t first_row, uint32_t sampling);
  /// Layouts of the output images, counter reset. Expects the G-buffer in SHADER_READ_ONLY_OPTIMAL.
  void record_prepare(VkCommandBuffer cmd);

  void bind(VkCommandBuffer cmd, const vk::Pipeline& p) const;
  /// Binds `p` and dispatches 8x8 groups over w x h invocations; `then_barrier`: then makes its writes
  /// visible to the next compute pass and to copies.
  void dispatch(VkCommandBuffer cmd, const vk::Pipeline& p, uint32_t w, uint32_t h, bool then_barrier = true) const;
  /// The same for a tracing pass's program: a ray-tracing pipeline launches w x h rays between two barriers
  /// (every earlier write visible to it; its writes visible to every later command), whatever `then_barrier`.
  void dispatch(VkCommandBuffer cmd, const RtProgram& p, uint32_t w, uint32_t h, bool then_barrier = true) const;
  /// A ray-tracing pipeline's launch sized by a VkTraceRaysIndirectCommandKHR at byte `offset` of
  /// ray_count() (the consume pass), between the same barriers.
  void trace_indirect(VkCommandBuffer cmd, const RtProgram& p, VkDeviceSize offset) const;
  /// A traced slice: binds `p`, dispatches gx x gy groups, then makes the records visible to the host.
  void dispatch_traced(VkCommandBuffer cmd, const vk::Pipeline& p, uint32_t gx, uint32_t gy) const;
  /// A traced slice of a dispatch of `workgroups` (8x8 each) sliced by rows of workgroups: rows
  /// [first_row, first_row + rows), clipped to the dispatch; or, where `sharing` is not 0, `sharing`
  /// workgroups that take the slice's tiles between them (gpu::TraceBufferHeader::units). `unattached` is the
  /// logic_error's message when the pass's instrumented pipeline `p` was not built.
  void dispatch_traced_rows(VkCommandBuffer cmd, const vk::Pipeline& p, glm::uvec2 workgroups, uint32_t first_row,
                            uint32_t rows, uint32_t sharing, const char* unattached) const;
  /// Binds the capture's trace buffer (a TraceBufferHeader then TraceRecords) at HP_BIND_TRACE_RECORDS.
  void attach_trace_buffer(const vk::Buffer& trace_buffer);

  /// The running mean of the reflections copied aside and back (one submission each, outside any timed
  /// frame): a frame that repeats a measured frame's sample for timing (Frame::render with
  /// FrameQueries::frame_span) leaves the accumulation as it found it.
  void save_accumulation(vk::Context& ctx);
  void restore_accumulation(vk::Context& ctx);

  const vk::Image& shadow_mask() const { return shadow_mask_; }
  const vk::Image& reflection() const { return reflection_; }
  const vk::Image& reflection_accum() const { return accum_; }
  const vk::Buffer& compact_rays() const { return compact_rays_; }
  const vk::Buffer& sort_keys() const { return sort_keys_; }
  const vk::Buffer& sort_values() const { return sort_values_; }
  const vk::Buffer& ray_count() const { return ray_count_; }

  /// Rays appended by the last compaction (a readback, for tests and reports; the frame never waits on it).
  uint32_t read_compacted_count(vk::Context& ctx) const;
  RayCounters read_counters(vk::Context& ctx) const;
  std::vector<gpu::RayDump> read_shadow_dump(vk::Context& ctx) const;
  std::vector<gpu::RayDump> read_reflection_dump(vk::Context& ctx) const;

 private:
  void create_buffers(vk::Context& ctx);
  void write_descriptors(const GBuffer& gbuffer, const vk::Buffer& frame_uniforms, VkSampler sampler);
  /// Before a ray-tracing launch: the barrier that makes earlier writes visible to it, `p` and the set bound.
  void bind_trace(VkCommandBuffer cmd, const RtProgram& p) const;

  RayTracingOptions options_;
  uint32_t width_, height_, grid_w_ = 0, grid_h_ = 0;
  vk::Buffer params_;
  vk::Buffer counters_;
  vk::Buffer shadow_dump_, reflection_dump_;
  vk::Image shadow_mask_, reflection_, accum_;
  vk::Image accum_saved_;  // save_accumulation's copy, made on first use
  vk::DescriptorSet descriptors_;
  vk::Buffer compact_rays_, sort_keys_, sort_values_, ray_count_;
  Aabb bounds_;
  vk::Buffer dummy_trace_;
  const RtScene& scene_;  // owned by the Frame, which destroys these resources first
  const AccelStructure* as_;
  // What the frame records and its ray modes (HP_RT_*): a specialization constant of every pipeline.
  uint32_t flags_;
  gpu::RayParams params_cache_{};
  bool images_initialised_ = false;
};

}  // namespace hp
