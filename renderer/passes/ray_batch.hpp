// The passes' one traversal (shaders/common/traversal.glsl) on a batch of rays given by the host, without
// a pass's ray generation or shading (shaders/trace_rays.comp): the GPU half of the traversal's agreement
// with the C++ reference on arbitrary rays (hard cases included), and the traversal's own speed.
#pragma once

#include "accel_structure.hpp"
#include "bvh/traverse.hpp"
#include "rt_geometry.hpp"
#include "rt_scene.hpp"
#include "vk/pipeline.hpp"
#include "vk/rt_pipeline.hpp"
#include "vk/timestamps.hpp"

#include <glm/glm.hpp>

#include <span>
#include <string>
#include <vector>

namespace hp {

class RayBatchTracer {
 public:
  /// Uploads `rays` once; throws InputError when they do not fit the device's buffer or dispatch limits.
  /// `as` (with `traversal` ray-query or pipeline): the rays go through the driver's acceleration structure,
  /// by ray queries in the same compute shader or by a ray-tracing pipeline (shaders/trace_rays.comp either
  /// way); the work counters are then 0 (the driver's traversal is opaque).
  RayBatchTracer(vk::Context& ctx, const RtScene& scene, std::span<const bvh::Ray> rays,
                 const AccelStructure* as = nullptr, Traversal traversal = Traversal::compute);

  /// Traces every ray (one thread each) and waits. Returns the dispatch's GPU time in nanoseconds from
  /// timestamp queries, or 0 when the queue has none.
  uint64_t trace(vk::Context& ctx, bvh::HitMode mode);

  /// The last trace's answers, one per ray: the bvh::Hit (scene triangle index) and the ray's counters.
  struct Result {
    bvh::Hit hit;
    bvh::TraversalStats stats;
  };
  std::vector<Result> results(vk::Context& ctx) const;

  size_t size() const { return count_; }

  /// The dispatch for `rays` rays under `limits` (workgroups in x, then y); throws InputError naming the
  /// limit a batch that size would break (maxTexelBufferElements, maxStorageBufferRange,
  /// maxComputeWorkGroupCount).
  static glm::uvec2 check_limits(uint64_t rays, const VkPhysicalDeviceLimits& limits);

 private:
  uint32_t count_ = 0;
  uint32_t groups_x_ = 0, groups_y_ = 0;
  vk::Buffer rays_, results_;
  vk::BufferView ray_texels_;  // after the buffers: destroyed before them
  vk::DescriptorSet descriptors_;
  vk::Pipeline pipeline_;
  vk::RtPipeline rt_pipeline_;  // Traversal::pipeline
  VkShaderStageFlags stages_ = VK_SHADER_STAGE_COMPUTE_BIT;
  vk::TimestampQueries timestamps_;
};

/// Every ray's GPU answer against the reference traversal's (the same mode): equal means the same hit
/// (scene triangle, t, u, v bit for bit) and the same work (nodes visited, triangles tested).
struct BatchCheck {
  size_t rays = 0, hits = 0, differ = 0;
  std::vector<std::string> first_differences;  ///< one line per differing ray, the first `keep` of them
};
/// The reference is trace_reference: the C++ traversal of the node layout the scene was uploaded with.
BatchCheck check_against_reference(const RtGeometry& g, std::span<const bvh::Ray> rays, bvh::HitMode mode,
                                   std::span<const RayBatchTracer::Result> gpu, size_t keep = 10);

/// A driver traversal's answers against the reference's, where bit equality is not promised: the API
/// guarantees neither watertightness nor a closest-hit tie-break, and the driver computes t and the
/// barycentrics its own way. Closest hit: a ray agrees when both miss, or both hit the same triangle with
/// |t_gpu - t_ref| <= t_tolerance * max(1, |t_ref|); a different triangle at the same t (within the
/// tolerance) is a tie, counted apart. Any hit: hit or miss agree (which triangle is any).
struct DriverAgreement {
  size_t rays = 0, reference_hits = 0, gpu_hits = 0;
  size_t hit_miss_differ = 0;   ///< one hits, the other misses
  size_t ties = 0;              ///< closest hit: another triangle at the same t
  size_t triangle_differ = 0;   ///< closest hit: another triangle at another t
  size_t t_differ = 0;          ///< closest hit: the same triangle, t beyond the tolerance
  double max_t_relative = 0.0;  ///< largest |t_gpu - t_ref| / max(1, |t_ref|) where both name the same triangle
  double t_tolerance = 0.0;
  size_t agree() const { return rays - hit_miss_differ - triangle_differ - t_differ; }
  std::vector<std::string> first_differences;
};
DriverAgreement compare_driver_with_reference(const bvh::Bvh& bvh, const bvh::LeafOrderTriangles& tris,
                                              std::span<const bvh::Ray> rays, bvh::HitMode mode,
                                              std::span<const RayBatchTracer::Result> gpu, double t_tolerance = 1e-4,
                                              size_t keep = 10);

}  // namespace hp
