#include "accel_structure.hpp"

#include "error.hpp"
#include "gpu/bindings.h"
#include "vk/check.hpp"
#include "vk/timestamps.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <limits>
#include <numeric>

namespace hp {

namespace {

// The 10 low bits of v spread to every third bit (Morton interleave).
uint32_t spread3(uint32_t v) {
  v &= 0x3FFu;
  v = (v | (v << 16)) & 0x030000FFu;
  v = (v | (v << 8)) & 0x0300F00Fu;
  v = (v | (v << 4)) & 0x030C30C3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

VkDeviceAddress align_up(VkDeviceAddress a, VkDeviceAddress alignment) {
  return alignment > 1 ? (a + alignment - 1) / alignment * alignment : a;
}

constexpr VkBufferUsageFlags kAddress = VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;
constexpr VkBufferUsageFlags kBuildInput =
    VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR | VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT;

// Timestamps resolve when lavapipe flushes (a barrier does) and a build runs when its command executes: a
// barrier on each side keeps the build between its two timestamps (as RayBatchTracer::trace does).
void full_barrier(VkCommandBuffer cmd) {
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_READ_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT);
}

}  // namespace

std::string traversal_unsupported(const vk::Context& ctx, Traversal t) {
  if (t == Traversal::ray_query && !ctx.ray_query_enabled()) {
    return "'" + ctx.info().name + "' has no ray queries (VK_KHR_ray_query with acceleration structures)";
  }
  if (t == Traversal::pipeline && !ctx.ray_tracing_pipeline_enabled()) {
    return "'" + ctx.info().name +
           "' has no ray-tracing pipelines (VK_KHR_ray_tracing_pipeline with acceleration structures)";
  }
  return "";
}

void require_traversal(const vk::Context& ctx, Traversal t) {
  const std::string why = traversal_unsupported(ctx, t);
  if (!why.empty()) throw DeviceError("Vulkan device " + why + ": --traversal " + to_string(t) + " needs them");
}

std::vector<uint32_t> as_primitive_slots(const RtGeometry& g, AsOrder order) {
  const auto& leaf = g.leaf;
  std::vector<uint32_t> slots(leaf.triangles.size());
  std::iota(slots.begin(), slots.end(), 0u);
  if (order == AsOrder::scene) {
    std::stable_sort(slots.begin(), slots.end(),
                     [&](uint32_t a, uint32_t b) { return leaf.scene_index[a] < leaf.scene_index[b]; });
  } else if (order == AsOrder::morton) {
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    std::vector<glm::vec3> centroid(slots.size());
    for (size_t k = 0; k < slots.size(); ++k) {
      const bvh::Triangle& t = leaf.triangles[k];
      centroid[k] = (t.v0 + t.v1 + t.v2) * (1.0f / 3.0f);
      lo = glm::min(lo, centroid[k]);
      hi = glm::max(hi, centroid[k]);
    }
    const glm::vec3 extent = glm::max(hi - lo, glm::vec3(1e-30f));
    std::vector<uint32_t> code(slots.size());
    for (size_t k = 0; k < slots.size(); ++k) {
      const glm::vec3 q = glm::clamp((centroid[k] - lo) / extent * 1023.0f, glm::vec3(0.0f), glm::vec3(1023.0f));
      code[k] = (spread3(uint32_t(q.x)) << 2) | (spread3(uint32_t(q.y)) << 1) | spread3(uint32_t(q.z));
    }
    std::stable_sort(slots.begin(), slots.end(), [&](uint32_t a, uint32_t b) { return code[a] < code[b]; });
  }
  return slots;
}

AccelStructure::AccelStructure(vk::Context& ctx, const RtGeometry& g, AsOrder order, bool compaction, AsLayout layout,
                               const Scene* scene)
    : device_(ctx.device()), destroy_(ctx.rt().destroy_as), order_(order), layout_(layout) {
  if (layout == AsLayout::instances && order != AsOrder::leaf) {
    throw InputError("--as-order " + std::string(to_string(order)) +
                     " applies to --as-layout flat (the instances layout keeps each mesh's own order)");
  }
  try {
    build(ctx, g, scene, compaction);
  } catch (...) {
    release();  // the destructor does not run for a constructor that throws
    throw;
  }
}

namespace {

// One bottom-level structure's build input: triangles with or without an index buffer (freed after the
// build) and the instances that place it.
struct BlasInput {
  std::vector<float> vertices;    // float3 each
  std::vector<uint32_t> indices;  // empty: three vertices per triangle
  uint32_t triangles = 0;
  vk::Buffer vertex_buffer, index_buffer;
};

VkTransformMatrixKHR to_transform(const glm::mat4& m) {
  VkTransformMatrixKHR t{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) t.matrix[r][c] = m[c][r];  // glm is column-major, the transform row-major 3x4
  return t;
}

}  // namespace

void AccelStructure::build(vk::Context& ctx, const RtGeometry& g, const Scene* scene, bool compaction) {
  if (!ctx.buffer_device_address_enabled()) {
    throw DeviceError("Vulkan device '" + ctx.info().name +
                      "' has no acceleration structures (VK_KHR_acceleration_structure with ray queries or "
                      "ray-tracing pipelines): --traversal ray-query|pipeline needs them");
  }
  const auto t0 = std::chrono::steady_clock::now();
  const vk::RayTracingFunctions& fn = ctx.rt();

  // The inputs, the primitive -> slot table and the top level's instances.
  std::vector<BlasInput> inputs;
  std::vector<uint32_t> as_slot;
  struct Placed {
    uint32_t blas;
    glm::mat4 world;
    uint32_t first;  // instanceCustomIndex: added to the primitive index before the table lookup
  };
  std::vector<Placed> placed;
  if (layout_ == AsLayout::flat) {
    // The leaf-order triangles (degenerate ones already collapsed, which the driver treats as inactive)
    // listed in AS order, three float3 vertices each, no index buffer.
    const std::vector<uint32_t> slots = as_primitive_slots(g, order_);
    BlasInput in;
    in.triangles = uint32_t(slots.size());
    in.vertices.reserve(size_t(std::max(in.triangles, 1u)) * 9);
    for (uint32_t k : slots) {
      const bvh::Triangle& t = g.leaf.triangles[k];
      in.vertices.insert(in.vertices.end(), {t.v0.x, t.v0.y, t.v0.z, t.v1.x, t.v1.y, t.v1.z, t.v2.x, t.v2.y, t.v2.z});
    }
    inputs.push_back(std::move(in));
    placed.push_back({0, glm::mat4(1.0f), 0});
    remapped_ = order_ != AsOrder::leaf;
    if (remapped_) as_slot = slots;
    stats_.triangles = uint32_t(slots.size());
  } else {
    // One bottom level per mesh (object space, its index buffer), one instance per scene instance; the
    // instance's custom index is its first scene triangle, so custom index + primitive is the scene triangle,
    // which the table maps to its slot (none, 0xFFFFFFFF, for a degenerate triangle the BVH left out).
    if (!scene) throw std::logic_error("AccelStructure: the instances layout needs the scene");
    std::vector<int> blas_of_mesh(scene->meshes.size(), -1);
    for (size_t i = 0; i < scene->instances.size(); ++i) {
      const uint32_t m = scene->instances[i].mesh;
      if (blas_of_mesh[m] < 0) {
        const Mesh& mesh = scene->meshes[m];
        BlasInput in;
        for (const glm::vec3& p : mesh.positions) in.vertices.insert(in.vertices.end(), {p.x, p.y, p.z});
        in.indices = mesh.indices;
        in.triangles = uint32_t(mesh.triangle_count());
        stats_.triangles += in.triangles;
        blas_of_mesh[m] = int(inputs.size());
        inputs.push_back(std::move(in));
      }
      const uint32_t first = g.world.instance_first_triangle[i];
      if (first > 0xFFFFFFu) {
        throw InputError("--as-layout instances: instance " + std::to_string(i) + " starts at triangle " +
                         std::to_string(first) + ", over the 24-bit instanceCustomIndex limit of 16777215");
      }
      placed.push_back({uint32_t(blas_of_mesh[m]), scene->instances[i].world, first});
    }
    as_slot.assign(g.world.triangle_count(), 0xFFFFFFFFu);
    for (size_t k = 0; k < g.leaf.scene_index.size(); ++k) {
      // Object granularity keeps degenerate triangles (collapsed) in its objects: any slot of the triangle.
      as_slot[g.leaf.scene_index[k]] = uint32_t(k);
    }
    remapped_ = true;
  }
  stats_.blas_count = uint32_t(inputs.size());
  stats_.instances = uint32_t(placed.size());
  as_slot_ = remapped_ && !as_slot.empty() ? vk::upload_vector(ctx, as_slot, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT)
                                           : vk::Buffer(ctx, 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);

  VkPhysicalDeviceAccelerationStructurePropertiesKHR as_props{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR};
  VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  p2.pNext = &as_props;
  vkGetPhysicalDeviceProperties2(ctx.physical_device(), &p2);
  const VkDeviceAddress scratch_align =
      std::max<VkDeviceAddress>(as_props.minAccelerationStructureScratchOffsetAlignment, 1);

  const auto create_as = [&](vk::Buffer& storage, VkDeviceSize bytes, VkAccelerationStructureTypeKHR type) {
    storage = vk::Buffer(ctx, bytes, VK_BUFFER_USAGE_ACCELERATION_STRUCTURE_STORAGE_BIT_KHR | kAddress, false);
    VkAccelerationStructureCreateInfoKHR ci{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_CREATE_INFO_KHR};
    ci.buffer = storage.handle();
    ci.size = bytes;
    ci.type = type;
    VkAccelerationStructureKHR as = VK_NULL_HANDLE;
    HP_VK(fn.create_as(device_, &ci, nullptr, &as));
    return as;
  };
  const auto address_of = [&](VkAccelerationStructureKHR as) {
    VkAccelerationStructureDeviceAddressInfoKHR ai{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_DEVICE_ADDRESS_INFO_KHR};
    ai.accelerationStructure = as;
    return fn.get_as_address(device_, &ai);
  };

  // The bottom levels: sizes, storage, one scratch buffer holding every build's scratch (built together).
  const size_t nb = inputs.size();
  std::vector<VkAccelerationStructureGeometryKHR> geoms(nb);
  std::vector<VkAccelerationStructureBuildGeometryInfoKHR> infos(nb);
  std::vector<VkAccelerationStructureBuildRangeInfoKHR> ranges(nb);
  std::vector<VkDeviceSize> scratch_offset(nb);
  VkDeviceSize scratch_total = 0;
  blas_.assign(nb, VK_NULL_HANDLE);
  blas_buffers_.resize(nb);
  for (size_t b = 0; b < nb; ++b) {
    BlasInput& in = inputs[b];
    if (in.vertices.empty()) in.vertices.resize(9, 0.0f);
    in.vertex_buffer = vk::upload_vector(ctx, in.vertices, kBuildInput);
    if (!in.indices.empty()) in.index_buffer = vk::upload_vector(ctx, in.indices, kBuildInput);
    VkAccelerationStructureGeometryKHR& geom = geoms[b];
    geom = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
    geom.geometryType = VK_GEOMETRY_TYPE_TRIANGLES_KHR;
    geom.flags = VK_GEOMETRY_OPAQUE_BIT_KHR;
    auto& tri = geom.geometry.triangles;
    tri.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR;
    tri.vertexFormat = VK_FORMAT_R32G32B32_SFLOAT;
    tri.vertexData.deviceAddress = in.vertex_buffer.device_address();
    tri.vertexStride = 12;
    tri.maxVertex = uint32_t(in.vertices.size() / 3) - 1;
    tri.indexType = in.indices.empty() ? VK_INDEX_TYPE_NONE_KHR : VK_INDEX_TYPE_UINT32;
    if (!in.indices.empty()) tri.indexData.deviceAddress = in.index_buffer.device_address();
    VkAccelerationStructureBuildGeometryInfoKHR& info = infos[b];
    info = {VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
    info.type = VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR;
    info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR |
                 (compaction ? VK_BUILD_ACCELERATION_STRUCTURE_ALLOW_COMPACTION_BIT_KHR : 0);
    info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
    info.geometryCount = 1;
    info.pGeometries = &geom;
    VkAccelerationStructureBuildSizesInfoKHR sizes{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
    fn.get_build_sizes(device_, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &info, &in.triangles, &sizes);
    blas_[b] =
        create_as(blas_buffers_[b], sizes.accelerationStructureSize, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR);
    info.dstAccelerationStructure = blas_[b];
    stats_.blas_built_bytes += sizes.accelerationStructureSize;
    scratch_offset[b] = scratch_total;
    scratch_total += (sizes.buildScratchSize + scratch_align - 1) / scratch_align * scratch_align;
    ranges[b] = {in.triangles, 0, 0, 0};
  }
  stats_.scratch_bytes = scratch_total;
  vk::Buffer scratch(ctx, scratch_total + scratch_align, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | kAddress, false);
  const VkDeviceAddress scratch_base = align_up(scratch.device_address(), scratch_align);
  for (size_t b = 0; b < nb; ++b) infos[b].scratchData.deviceAddress = scratch_base + scratch_offset[b];

  vk::TimestampQueries timer(ctx, 3);
  double device_ns = 0.0;
  const auto add_intervals = [&] {
    for (const auto& i : timer.read(ctx)) device_ns += double(i.end_ns - i.begin_ns);
  };
  VkQueryPool size_query = VK_NULL_HANDLE;
  if (compaction) {
    VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    qi.queryType = VK_QUERY_TYPE_ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR;
    qi.queryCount = uint32_t(nb);
    HP_VK(vkCreateQueryPool(device_, &qi, nullptr, &size_query));
  }
  std::vector<const VkAccelerationStructureBuildRangeInfoKHR*> range_ptrs(nb);
  for (size_t b = 0; b < nb; ++b) range_ptrs[b] = &ranges[b];
  try {
    ctx.submit_and_wait([&](VkCommandBuffer cmd) {
      if (timer.supported()) timer.reset(cmd);
      if (size_query) vkCmdResetQueryPool(cmd, size_query, 0, uint32_t(nb));
      full_barrier(cmd);
      if (timer.supported()) timer.begin(cmd, "blas");
      full_barrier(cmd);
      fn.cmd_build(cmd, uint32_t(nb), infos.data(), range_ptrs.data());
      full_barrier(cmd);
      if (timer.supported()) timer.end(cmd);
      if (size_query) {
        fn.cmd_write_properties(cmd, uint32_t(nb), blas_.data(),
                                VK_QUERY_TYPE_ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR, size_query, 0);
      }
    });
  } catch (...) {
    if (size_query) vkDestroyQueryPool(device_, size_query, nullptr);
    throw;
  }
  if (timer.supported()) add_intervals();

  stats_.blas_bytes = stats_.blas_built_bytes;
  if (size_query) {
    std::vector<VkDeviceSize> compact_bytes(nb, 0);
    const VkResult r =
        vkGetQueryPoolResults(device_, size_query, 0, uint32_t(nb), nb * sizeof(VkDeviceSize), compact_bytes.data(),
                              sizeof(VkDeviceSize), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
    vkDestroyQueryPool(device_, size_query, nullptr);
    HP_VK(r);
    uint64_t compact_total = 0;
    for (VkDeviceSize c : compact_bytes) compact_total += c;
    if (compact_total > 0 && compact_total < stats_.blas_built_bytes) {
      std::vector<vk::Buffer> compact_buffers(nb);
      std::vector<VkAccelerationStructureKHR> compact(nb, VK_NULL_HANDLE);
      const auto drop_compact = [&] {
        for (VkAccelerationStructureKHR c : compact)
          if (c) destroy_(device_, c, nullptr);
      };
      try {
        for (size_t b = 0; b < nb; ++b) {
          compact[b] = create_as(compact_buffers[b], compact_bytes[b], VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR);
        }
        ctx.submit_and_wait([&](VkCommandBuffer cmd) {
          if (timer.supported()) timer.reset(cmd);
          full_barrier(cmd);
          if (timer.supported()) timer.begin(cmd, "compact");
          full_barrier(cmd);
          for (size_t b = 0; b < nb; ++b) {
            VkCopyAccelerationStructureInfoKHR ci{VK_STRUCTURE_TYPE_COPY_ACCELERATION_STRUCTURE_INFO_KHR};
            ci.src = blas_[b];
            ci.dst = compact[b];
            ci.mode = VK_COPY_ACCELERATION_STRUCTURE_MODE_COMPACT_KHR;
            fn.cmd_copy(cmd, &ci);
          }
          full_barrier(cmd);
          if (timer.supported()) timer.end(cmd);
        });
      } catch (...) {
        drop_compact();
        throw;
      }
      if (timer.supported()) add_intervals();
      for (size_t b = 0; b < nb; ++b) {
        destroy_(device_, blas_[b], nullptr);
        blas_[b] = compact[b];
        blas_buffers_[b] = std::move(compact_buffers[b]);
      }
      stats_.blas_bytes = compact_total;
      stats_.compacted = true;
    }
  }

  // The top level: the instances of the bottom levels, opaque, no culling.
  std::vector<VkAccelerationStructureInstanceKHR> instances;
  for (const Placed& p : placed) {
    VkAccelerationStructureInstanceKHR inst{};
    inst.transform = to_transform(p.world);
    inst.instanceCustomIndex = p.first;
    inst.mask = 0xFF;
    inst.instanceShaderBindingTableRecordOffset = 0;
    inst.flags = VK_GEOMETRY_INSTANCE_FORCE_OPAQUE_BIT_KHR | VK_GEOMETRY_INSTANCE_TRIANGLE_FACING_CULL_DISABLE_BIT_KHR;
    inst.accelerationStructureReference = address_of(blas_[p.blas]);
    instances.push_back(inst);
  }
  const vk::Buffer instance_buffer = vk::upload_vector(ctx, instances, kBuildInput);

  VkAccelerationStructureGeometryKHR tgeom{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  tgeom.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;
  tgeom.geometry.instances.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR;
  tgeom.geometry.instances.arrayOfPointers = VK_FALSE;
  tgeom.geometry.instances.data.deviceAddress = instance_buffer.device_address();
  VkAccelerationStructureBuildGeometryInfoKHR tlas_info{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
  tlas_info.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;
  tlas_info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
  tlas_info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
  tlas_info.geometryCount = 1;
  tlas_info.pGeometries = &tgeom;
  const uint32_t count = uint32_t(instances.size());
  VkAccelerationStructureBuildSizesInfoKHR tlas_sizes{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
  fn.get_build_sizes(device_, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &tlas_info, &count, &tlas_sizes);
  tlas_ = create_as(tlas_buffer_, tlas_sizes.accelerationStructureSize, VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR);
  stats_.tlas_bytes = tlas_sizes.accelerationStructureSize;
  vk::Buffer tlas_scratch(ctx, tlas_sizes.buildScratchSize + scratch_align,
                          VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | kAddress, false);
  stats_.scratch_bytes = std::max<uint64_t>(stats_.scratch_bytes, tlas_sizes.buildScratchSize);
  tlas_info.dstAccelerationStructure = tlas_;
  tlas_info.scratchData.deviceAddress = align_up(tlas_scratch.device_address(), scratch_align);
  ctx.submit_and_wait([&](VkCommandBuffer cmd) {
    if (timer.supported()) timer.reset(cmd);
    full_barrier(cmd);
    if (timer.supported()) timer.begin(cmd, "tlas");
    full_barrier(cmd);
    const VkAccelerationStructureBuildRangeInfoKHR range{count, 0, 0, 0};
    const VkAccelerationStructureBuildRangeInfoKHR* r = &range;
    fn.cmd_build(cmd, 1, &tlas_info, &r);
    // Traversals read it next (compute shaders and ray-tracing stages).
    full_barrier(cmd);
    if (timer.supported()) timer.end(cmd);
  });
  if (timer.supported()) add_intervals();
  stats_.host_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  stats_.build_timed_on_device = timer.supported();
  stats_.build_ms = timer.supported() ? device_ns * 1e-6 : stats_.host_ms;
}

void AccelStructure::add_bindings(std::vector<VkDescriptorSetLayoutBinding>& b, VkShaderStageFlags stages) {
  b.push_back({HP_BIND_RT_TLAS, VK_DESCRIPTOR_TYPE_ACCELERATION_STRUCTURE_KHR, 1, stages, nullptr});
  b.push_back({HP_BIND_RT_AS_SLOT, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, stages, nullptr});
}

void AccelStructure::write_bindings(vk::DescriptorSet& ds) const {
  ds.write_acceleration_structure(HP_BIND_RT_TLAS, tlas_);
  ds.write_buffer(HP_BIND_RT_AS_SLOT, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, as_slot_.handle());
}

AccelStructure::~AccelStructure() { release(); }

void AccelStructure::release() {
  if (tlas_) destroy_(device_, tlas_, nullptr);
  for (VkAccelerationStructureKHR b : blas_)
    if (b) destroy_(device_, b, nullptr);
  tlas_ = VK_NULL_HANDLE;
  blas_.clear();
}

}  // namespace hp
