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

AccelStructure::AccelStructure(vk::Context& ctx, const RtGeometry& g, AsOrder order, bool compaction)
    : device_(ctx.device()), destroy_(ctx.rt().destroy_as), order_(order) {
  if (!ctx.buffer_device_address_enabled()) {
    throw DeviceError("Vulkan device '" + ctx.info().name +
                      "' has no acceleration structures (VK_KHR_acceleration_structure with ray queries or "
                      "ray-tracing pipelines): --traversal ray-query|pipeline needs them");
  }
  const auto t0 = std::chrono::steady_clock::now();
  const vk::RayTracingFunctions& fn = ctx.rt();
  const std::vector<uint32_t> slots = as_primitive_slots(g, order);
  const uint32_t n = uint32_t(slots.size());
  stats_.triangles = n;
  remapped_ = order != AsOrder::leaf;
  as_slot_ = remapped_ && n > 0 ? vk::upload_vector(ctx, slots, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT)
                                : vk::Buffer(ctx, 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, false);

  // The build input: the leaf-order triangles (degenerate ones already collapsed, which the driver treats as
  // inactive) listed in AS order, three float3 vertices each, no index buffer. Freed after the build.
  std::vector<float> vertices;
  vertices.reserve(size_t(std::max(n, 1u)) * 9);
  for (uint32_t s : slots) {
    const bvh::Triangle& t = g.leaf.triangles[s];
    vertices.insert(vertices.end(), {t.v0.x, t.v0.y, t.v0.z, t.v1.x, t.v1.y, t.v1.z, t.v2.x, t.v2.y, t.v2.z});
  }
  if (vertices.empty()) vertices.resize(9, 0.0f);
  const vk::Buffer vertex_buffer = vk::upload_vector(ctx, vertices, kBuildInput);

  VkPhysicalDeviceAccelerationStructurePropertiesKHR as_props{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR};
  VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  p2.pNext = &as_props;
  vkGetPhysicalDeviceProperties2(ctx.physical_device(), &p2);
  const VkDeviceAddress scratch_align =
      std::max<VkDeviceAddress>(as_props.minAccelerationStructureScratchOffsetAlignment, 1);

  VkAccelerationStructureGeometryKHR geom{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  geom.geometryType = VK_GEOMETRY_TYPE_TRIANGLES_KHR;
  geom.flags = VK_GEOMETRY_OPAQUE_BIT_KHR;
  auto& tri = geom.geometry.triangles;
  tri.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_TRIANGLES_DATA_KHR;
  tri.vertexFormat = VK_FORMAT_R32G32B32_SFLOAT;
  tri.vertexData.deviceAddress = vertex_buffer.device_address();
  tri.vertexStride = 12;
  tri.maxVertex = std::max(n * 3, 3u) - 1;
  tri.indexType = VK_INDEX_TYPE_NONE_KHR;

  VkAccelerationStructureBuildGeometryInfoKHR blas_info{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
  blas_info.type = VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR;
  blas_info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR |
                    (compaction ? VK_BUILD_ACCELERATION_STRUCTURE_ALLOW_COMPACTION_BIT_KHR : 0);
  blas_info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
  blas_info.geometryCount = 1;
  blas_info.pGeometries = &geom;
  VkAccelerationStructureBuildSizesInfoKHR blas_sizes{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
  fn.get_build_sizes(device_, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &blas_info, &n, &blas_sizes);

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

  blas_ =
      create_as(blas_buffer_, blas_sizes.accelerationStructureSize, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR);
  stats_.blas_built_bytes = blas_sizes.accelerationStructureSize;
  vk::Buffer scratch(ctx, blas_sizes.buildScratchSize + scratch_align, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | kAddress,
                     false);
  blas_info.dstAccelerationStructure = blas_;
  blas_info.scratchData.deviceAddress = align_up(scratch.device_address(), scratch_align);
  stats_.scratch_bytes = blas_sizes.buildScratchSize;

  vk::TimestampQueries timer(ctx, 3);
  double device_ns = 0.0;
  const auto add_intervals = [&] {
    for (const auto& i : timer.read(ctx)) device_ns += double(i.end_ns - i.begin_ns);
  };
  VkQueryPool size_query = VK_NULL_HANDLE;
  if (compaction) {
    VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    qi.queryType = VK_QUERY_TYPE_ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR;
    qi.queryCount = 1;
    HP_VK(vkCreateQueryPool(device_, &qi, nullptr, &size_query));
  }
  ctx.submit_and_wait([&](VkCommandBuffer cmd) {
    if (timer.supported()) timer.reset(cmd);
    if (size_query) vkCmdResetQueryPool(cmd, size_query, 0, 1);
    full_barrier(cmd);
    if (timer.supported()) timer.begin(cmd, "blas");
    full_barrier(cmd);
    const VkAccelerationStructureBuildRangeInfoKHR range{n, 0, 0, 0};
    const VkAccelerationStructureBuildRangeInfoKHR* ranges = &range;
    fn.cmd_build(cmd, 1, &blas_info, &ranges);
    full_barrier(cmd);
    if (timer.supported()) timer.end(cmd);
    if (size_query)
      fn.cmd_write_properties(cmd, 1, &blas_, VK_QUERY_TYPE_ACCELERATION_STRUCTURE_COMPACTED_SIZE_KHR, size_query, 0);
  });
  if (timer.supported()) add_intervals();

  stats_.blas_bytes = stats_.blas_built_bytes;
  if (size_query) {
    VkDeviceSize compact_bytes = 0;
    const VkResult r = vkGetQueryPoolResults(device_, size_query, 0, 1, sizeof(compact_bytes), &compact_bytes,
                                             sizeof(compact_bytes), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
    vkDestroyQueryPool(device_, size_query, nullptr);
    HP_VK(r);
    if (compact_bytes > 0 && compact_bytes < stats_.blas_built_bytes) {
      vk::Buffer compact_buffer;
      VkAccelerationStructureKHR compact =
          create_as(compact_buffer, compact_bytes, VK_ACCELERATION_STRUCTURE_TYPE_BOTTOM_LEVEL_KHR);
      ctx.submit_and_wait([&](VkCommandBuffer cmd) {
        if (timer.supported()) timer.reset(cmd);
        full_barrier(cmd);
        if (timer.supported()) timer.begin(cmd, "compact");
        full_barrier(cmd);
        VkCopyAccelerationStructureInfoKHR ci{VK_STRUCTURE_TYPE_COPY_ACCELERATION_STRUCTURE_INFO_KHR};
        ci.src = blas_;
        ci.dst = compact;
        ci.mode = VK_COPY_ACCELERATION_STRUCTURE_MODE_COMPACT_KHR;
        fn.cmd_copy(cmd, &ci);
        full_barrier(cmd);
        if (timer.supported()) timer.end(cmd);
      });
      if (timer.supported()) add_intervals();
      destroy_(device_, blas_, nullptr);
      blas_ = compact;
      blas_buffer_ = std::move(compact_buffer);
      stats_.blas_bytes = compact_bytes;
      stats_.compacted = true;
    }
  }

  // The top level: one instance of the bottom level, identity transform, opaque.
  VkAccelerationStructureInstanceKHR instance{};
  instance.transform.matrix[0][0] = instance.transform.matrix[1][1] = instance.transform.matrix[2][2] = 1.0f;
  instance.instanceCustomIndex = 0;
  instance.mask = 0xFF;
  instance.instanceShaderBindingTableRecordOffset = 0;
  instance.flags =
      VK_GEOMETRY_INSTANCE_FORCE_OPAQUE_BIT_KHR | VK_GEOMETRY_INSTANCE_TRIANGLE_FACING_CULL_DISABLE_BIT_KHR;
  instance.accelerationStructureReference = address_of(blas_);
  const vk::Buffer instances =
      vk::upload_vector(ctx, std::vector<VkAccelerationStructureInstanceKHR>{instance}, kBuildInput);

  VkAccelerationStructureGeometryKHR tgeom{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_KHR};
  tgeom.geometryType = VK_GEOMETRY_TYPE_INSTANCES_KHR;
  tgeom.geometry.instances.sType = VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_GEOMETRY_INSTANCES_DATA_KHR;
  tgeom.geometry.instances.arrayOfPointers = VK_FALSE;
  tgeom.geometry.instances.data.deviceAddress = instances.device_address();
  VkAccelerationStructureBuildGeometryInfoKHR tlas_info{
      VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_GEOMETRY_INFO_KHR};
  tlas_info.type = VK_ACCELERATION_STRUCTURE_TYPE_TOP_LEVEL_KHR;
  tlas_info.flags = VK_BUILD_ACCELERATION_STRUCTURE_PREFER_FAST_TRACE_BIT_KHR;
  tlas_info.mode = VK_BUILD_ACCELERATION_STRUCTURE_MODE_BUILD_KHR;
  tlas_info.geometryCount = 1;
  tlas_info.pGeometries = &tgeom;
  const uint32_t one = 1;
  VkAccelerationStructureBuildSizesInfoKHR tlas_sizes{VK_STRUCTURE_TYPE_ACCELERATION_STRUCTURE_BUILD_SIZES_INFO_KHR};
  fn.get_build_sizes(device_, VK_ACCELERATION_STRUCTURE_BUILD_TYPE_DEVICE_KHR, &tlas_info, &one, &tlas_sizes);
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
    const VkAccelerationStructureBuildRangeInfoKHR range{1, 0, 0, 0};
    const VkAccelerationStructureBuildRangeInfoKHR* ranges = &range;
    fn.cmd_build(cmd, 1, &tlas_info, &ranges);
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

AccelStructure::~AccelStructure() {
  if (tlas_) destroy_(device_, tlas_, nullptr);
  if (blas_) destroy_(device_, blas_, nullptr);
}

}  // namespace hp
