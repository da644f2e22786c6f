#include "passes/ray_batch.hpp"

#include "error.hpp"
#include "gpu/bindings.h"
#include "gpu/shared_types.h"

#include "shaders/rt_hit_rchit.h"
#include "shaders/rt_miss_rmiss.h"
#include "shaders/trace_rays_comp.h"
#include "shaders/trace_rays_rgen.h"
#include "shaders/trace_rays_rq_comp.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace hp {

namespace {

constexpr VkShaderStageFlags kCS = VK_SHADER_STAGE_COMPUTE_BIT;
constexpr uint32_t kGroup = 64;                                 // trace_rays.comp's local_size_x
constexpr uint64_t kTexelsPerRay = sizeof(gpu::BatchRay) / 16;  // RGBA32UI texels

struct BatchParams {
  uint32_t count, any_hit, groups_x;
};

}  // namespace

glm::uvec2 RayBatchTracer::check_limits(uint64_t rays, const VkPhysicalDeviceLimits& limits) {
  // The rays are read as a storage texel buffer (two RGBA32UI texels each), the answers written to a storage
  // buffer.
  const uint64_t texels = rays * kTexelsPerRay;
  if (texels > limits.maxTexelBufferElements) {
    throw InputError("ray batch: " + std::to_string(rays) + " rays need " + std::to_string(texels) +
                     " texels, over this device's maxTexelBufferElements of " +
                     std::to_string(limits.maxTexelBufferElements));
  }
  const uint64_t bytes = rays * sizeof(gpu::BatchResult);
  if (bytes > limits.maxStorageBufferRange) {
    throw InputError("ray batch: " + std::to_string(rays) + " answers need " + std::to_string(bytes) +
                     " bytes, over this device's maxStorageBufferRange of " +
                     std::to_string(limits.maxStorageBufferRange));
  }
  const uint64_t groups = std::max<uint64_t>((rays + kGroup - 1) / kGroup, 1);
  const uint64_t x = std::min<uint64_t>(groups, limits.maxComputeWorkGroupCount[0]);
  const uint64_t y = (groups + x - 1) / x;
  if (y > limits.maxComputeWorkGroupCount[1]) {
    throw InputError("ray batch: " + std::to_string(rays) + " rays need " + std::to_string(groups) + " workgroups of " +
                     std::to_string(kGroup) + ", over this device's maxComputeWorkGroupCount of " +
                     std::to_string(limits.maxComputeWorkGroupCount[0]) + " x " +
                     std::to_string(limits.maxComputeWorkGroupCount[1]));
  }
  return {uint32_t(x), uint32_t(y)};
}

RayBatchTracer::RayBatchTracer(vk::Context& ctx, const RtScene& scene, std::span<const bvh::Ray> rays,
                               const AccelStructure* as, Traversal traversal)
    : timestamps_(ctx, 1) {
  if ((traversal != Traversal::compute) != (as != nullptr)) {
    throw std::logic_error("RayBatchTracer: an acceleration structure exactly for the driver traversals");
  }
  const glm::uvec2 grid = check_limits(rays.size(), ctx.properties().limits);
  count_ = uint32_t(rays.size());
  groups_x_ = grid.x;
  groups_y_ = grid.y;

  std::vector<gpu::BatchRay> packed(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) {
    packed[i].origin_tmin = glm::vec4(rays[i].origin, rays[i].tmin);
    packed[i].dir_tmax = glm::vec4(rays[i].dir, rays[i].tmax);
  }
  if (packed.empty()) packed.resize(1);  // a buffer cannot be empty; count_ = 0 reads none of it
  rays_ = vk::upload_vector(ctx, packed, VK_BUFFER_USAGE_STORAGE_TEXEL_BUFFER_BIT);
  results_ = vk::Buffer(ctx, std::max<uint64_t>(count_, 1) * sizeof(gpu::BatchResult),
                        VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, false);
  ray_texels_ = vk::BufferView(ctx, rays_, VK_FORMAT_R32G32B32A32_UINT);

  // The bindings the traversal reads, then the batch's own.
  // The rays through a texel view: lavapipe loads a storage buffer at a per-invocation address lane by lane
  // (a bounds check and a scalar load per word, 64 per vector of eight rays), an image texel in one call.
  // The answers stay a storage buffer: lavapipe's image store costs about as much as the lane-by-lane store
  // (docs/gpu-passes.md).
  const VkDescriptorType SB = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  const VkDescriptorType ST = VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER;
  const bool rt_pipeline = traversal == Traversal::pipeline;
  stages_ = kCS | (rt_pipeline ? VkShaderStageFlags(VK_SHADER_STAGE_RAYGEN_BIT_KHR) : VkShaderStageFlags(0));
  std::vector<VkDescriptorSetLayoutBinding> b;
  RtScene::add_traversal_bindings(b, stages_);
  if (as) AccelStructure::add_bindings(b, stages_);
  b.push_back({HP_BIND_BATCH_RAYS, ST, 1, stages_, nullptr});
  b.push_back({HP_BIND_BATCH_RESULTS, SB, 1, stages_, nullptr});
  descriptors_ = vk::DescriptorSet(ctx, b, sizeof(BatchParams), stages_);
  auto& ds = descriptors_;
  scene.write_traversal_bindings(ds);
  if (as) as->write_bindings(ds);
  ds.write_texel_buffer(HP_BIND_BATCH_RAYS, ST, ray_texels_.handle());
  ds.write_buffer(HP_BIND_BATCH_RESULTS, SB, results_.handle());
  const bool remap = as && as->remapped();
  if (rt_pipeline) {
    const uint64_t launches = uint64_t(groups_x_) * kGroup * groups_y_;
    const uint32_t most = ctx.rt_pipeline_properties().maxRayDispatchInvocationCount;
    if (launches > most) {
      throw InputError("ray batch: " + std::to_string(rays.size()) + " rays need " + std::to_string(launches) +
                       " ray-generation invocations, over this device's maxRayDispatchInvocationCount of " +
                       std::to_string(most));
    }
    const RtSpecialization spec(scene, 0, remap);
    rt_pipeline_ = vk::RtPipeline(ctx, ds.pipeline_layout(), trace_rays_rgen, rt_miss_rmiss, rt_hit_rchit, &spec.info);
  } else {
    pipeline_ = create_rt_pipeline(ctx,
                                   traversal == Traversal::ray_query ? std::span<const uint32_t>(trace_rays_rq_comp)
                                                                     : std::span<const uint32_t>(trace_rays_comp),
                                   ds.pipeline_layout(), scene, 0, remap);
  }
}

uint64_t RayBatchTracer::trace(vk::Context& ctx, bvh::HitMode mode) {
  const BatchParams params{count_, mode == bvh::HitMode::any ? 1u : 0u, groups_x_};
  const bool timed = timestamps_.supported();
  ctx.submit_and_wait([&](VkCommandBuffer cmd) {
    if (timed) {
      timestamps_.reset(cmd);
      timestamps_.begin(cmd, "trace_rays");
    }
    // Barriers on both sides of the dispatch, as between a frame's passes: lavapipe resolves a timestamp
    // when its next flush runs (a barrier flushes) and runs a dispatch synchronously, so without the first
    // barrier both timestamps would be taken after the dispatch (measured: 0.1 ms for a 75 ms dispatch).
    const bool rtp = rt_pipeline_.handle() != VK_NULL_HANDLE;
    const VkPipelineStageFlags2 stage =
        rtp ? VK_PIPELINE_STAGE_2_RAY_TRACING_SHADER_BIT_KHR : VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT;
    const VkPipelineBindPoint point = rtp ? VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR : VK_PIPELINE_BIND_POINT_COMPUTE;
    vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_WRITE_BIT, stage,
                       VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
    vkCmdBindPipeline(cmd, point, rtp ? rt_pipeline_.handle() : pipeline_.handle());
    const VkDescriptorSet set = descriptors_.set();
    vkCmdBindDescriptorSets(cmd, point, descriptors_.pipeline_layout(), 0, 1, &set, 0, nullptr);
    vkCmdPushConstants(cmd, descriptors_.pipeline_layout(), stages_, 0, sizeof(params), &params);
    if (count_ > 0) {
      // The ray-generation shader numbers its rays as the compute dispatch does (trace_rays.comp).
      if (rtp) {
        rt_pipeline_.record_trace(cmd, groups_x_ * kGroup, groups_y_);
      } else {
        vkCmdDispatch(cmd, groups_x_, groups_y_, 1);
      }
    }
    // The results are read back by a copy (vk::read_buffer).
    vk::memory_barrier(cmd, stage, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT, VK_PIPELINE_STAGE_2_COPY_BIT,
                       VK_ACCESS_2_TRANSFER_READ_BIT);
    if (timed) timestamps_.end(cmd);
  });
  if (!timed) return 0;
  const auto intervals = timestamps_.read(ctx);
  return intervals.empty() ? 0 : intervals.front().end_ns - intervals.front().begin_ns;
}

std::vector<RayBatchTracer::Result> RayBatchTracer::results(vk::Context& ctx) const {
  const auto bytes = vk::read_buffer(ctx, results_);
  std::vector<Result> out(count_);
  for (uint32_t i = 0; i < count_; ++i) {
    gpu::BatchResult r;
    std::memcpy(&r, bytes.data() + size_t(i) * sizeof(r), sizeof(r));
    Result& o = out[i];
    o.hit = {r.hit.x, std::bit_cast<float>(r.hit.y), std::bit_cast<float>(r.hit.z), std::bit_cast<float>(r.hit.w)};
    o.stats.nodes_visited = r.work.x;
    o.stats.triangles_tested = r.work.y;
  }
  return out;
}

BatchCheck check_against_reference(const RtGeometry& g, std::span<const bvh::Ray> rays, bvh::HitMode mode,
                                   std::span<const RayBatchTracer::Result> gpu, size_t keep) {
  if (gpu.size() != rays.size()) throw std::logic_error("check_against_reference: one GPU answer per ray expected");
  const auto bits = [](float f) { return std::bit_cast<uint32_t>(f); };
  BatchCheck c;
  for (size_t i = 0; i < rays.size(); ++i) {
    bvh::TraversalStats st;
    const bvh::Hit ref = trace_reference(g, rays[i], mode, &st);
    const RayBatchTracer::Result& gr = gpu[i];
    ++c.rays;
    c.hits += ref.hit() ? 1 : 0;
    const bool same = gr.hit.prim == ref.prim && bits(gr.hit.t) == bits(ref.t) && bits(gr.hit.u) == bits(ref.u) &&
                      bits(gr.hit.v) == bits(ref.v) && gr.stats.nodes_visited == st.nodes_visited &&
                      gr.stats.triangles_tested == st.triangles_tested;
    if (same) continue;
    ++c.differ;
    if (c.first_differences.size() < keep) {
      const bvh::Ray& r = rays[i];
      char line[512];
      std::snprintf(line, sizeof(line),
                    "ray %zu: o=(%.9g, %.9g, %.9g) d=(%.9g, %.9g, %.9g) [%.9g, %.9g]: "
                    "gpu prim %d t %.9g u %.9g v %.9g, %llu nodes, %llu triangles; "
                    "reference prim %d t %.9g u %.9g v %.9g, %llu nodes, %llu triangles",
                    i, r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax, gr.hit.prim,
                    gr.hit.t, gr.hit.u, gr.hit.v, (unsigned long long)gr.stats.nodes_visited,
                    (unsigned long long)gr.stats.triangles_tested, ref.prim, ref.t, ref.u, ref.v,
                    (unsigned long long)st.nodes_visited, (unsigned long long)st.triangles_tested);
      c.first_differences.push_back(line);
    }
  }
  return c;
}

DriverAgreement compare_driver_with_reference(const bvh::Bvh& bvh, const bvh::LeafOrderTriangles& tris,
                                              std::span<const bvh::Ray> rays, bvh::HitMode mode,
                                              std::span<const RayBatchTracer::Result> gpu, double t_tolerance,
                                              size_t keep) {
  if (gpu.size() != rays.size()) {
    throw std::logic_error("compare_driver_with_reference: one GPU answer per ray expected");
  }
  DriverAgreement a;
  a.t_tolerance = t_tolerance;
  for (size_t i = 0; i < rays.size(); ++i) {
    const bvh::Hit ref =
        mode == bvh::HitMode::any ? bvh::intersect_any(bvh, tris, rays[i]) : bvh::intersect_closest(bvh, tris, rays[i]);
    const bvh::Hit& g = gpu[i].hit;
    ++a.rays;
    a.reference_hits += ref.hit();
    a.gpu_hits += g.hit();
    const char* what = nullptr;
    if (ref.hit() != g.hit()) {
      ++a.hit_miss_differ;
      what = ref.hit() ? "the driver misses" : "the driver hits";
    } else if (ref.hit() && mode == bvh::HitMode::closest) {
      const double scale = std::max(1.0, double(std::abs(ref.t)));
      const double dt = std::abs(double(g.t) - double(ref.t)) / scale;
      if (g.prim == ref.prim) {
        a.max_t_relative = std::max(a.max_t_relative, dt);
        if (dt > t_tolerance) {
          ++a.t_differ;
          what = "t differs";
        }
      } else if (dt <= t_tolerance) {
        ++a.ties;
      } else {
        ++a.triangle_differ;
        what = "another triangle";
      }
    }
    if (what && a.first_differences.size() < keep) {
      const bvh::Ray& r = rays[i];
      char line[400];
      std::snprintf(line, sizeof(line),
                    "ray %zu (%s): o=(%.9g, %.9g, %.9g) d=(%.9g, %.9g, %.9g) [%.9g, %.9g]: driver prim %d t %.9g; "
                    "reference prim %d t %.9g",
                    i, what, r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z, r.tmin, r.tmax, g.prim, g.t,
                    ref.prim, ref.t);
      a.first_differences.push_back(line);
    }
  }
  return a;
}

}  // namespace hp
