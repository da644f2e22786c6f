// The driver's acceleration structure of the ray-traced scene (VK_KHR_acceleration_structure), for the
// ray-query and ray-tracing-pipeline traversals. AsLayout::flat: one bottom-level structure of the
// world-space triangles (opaque, one geometry) under a top-level structure of one identity instance.
// AsLayout::instances: a bottom level per mesh (object space, its index buffer) under a top level of the
// scene's instances, as an engine builds it (the study's object granularity's counterpart). Built on the device
// (lavapipe runs the build on the CPU when the command executes), timed by timestamps, optionally compacted.
//
// The triangles go to the driver in a chosen order (AsOrder): the compute BVH's leaf order, where the
// driver's primitive index is the passes' slot, or another order with a primitive -> slot table that the
// shaders read (as_slot()), so that shading, dumps and counters see the same slots in every traversal.
#pragma once

#include "frame_settings.hpp"
#include "rt_geometry.hpp"
#include "vk/pipeline.hpp"
#include "vk/resources.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace hp {

/// What the build cost and holds.
struct AsBuildStats {
  uint32_t triangles = 0;  ///< in the bottom levels (each mesh once in the instances layout)
  uint32_t blas_count = 0, instances = 0;
  uint64_t blas_bytes = 0;        ///< the bottom level as kept (after compaction, when asked)
  uint64_t blas_built_bytes = 0;  ///< the bottom level as built
  uint64_t tlas_bytes = 0;
  uint64_t scratch_bytes = 0;  ///< the largest build's scratch (freed after the build)
  double build_ms = 0.0;       ///< device time of the builds and the compaction copy (timestamps), else host
  bool build_timed_on_device = false;
  double host_ms = 0.0;  ///< host wall time of the whole construction (inputs, submissions, waits)
  bool compacted = false;
};

/// Why `ctx` cannot trace with `t` ("'NAME' has no ray queries (...)": its device lacks ray queries or
/// ray-tracing pipelines with acceleration structures), or "" when it can (always for the compute traversal).
/// The one check the frame, `bvh --gpu`, the runner's unsupported cells and the tests share.
std::string traversal_unsupported(const vk::Context& ctx, Traversal t);
/// Throws DeviceError("Vulkan device <why>: --traversal T needs them") where traversal_unsupported says why.
void require_traversal(const vk::Context& ctx, Traversal t);

/// The order of the triangles handed to the build: slots (leaf order) listed in AS primitive order.
/// leaf: 0..n-1; scene: by scene triangle index; morton: by the 30-bit Morton code of the centroid in the
/// scene's bounds (ties by slot). Vulkan-free, for tests.
std::vector<uint32_t> as_primitive_slots(const RtGeometry& g, AsOrder order);

class AccelStructure {
 public:
  /// Throws DeviceError when the device has no acceleration structures (Context::buffer_device_address_enabled).
  /// AsLayout::instances needs `scene` (its meshes and instances, from which `g` was built) and the leaf order.
  AccelStructure(vk::Context& ctx, const RtGeometry& g, AsOrder order, bool compaction,
                 AsLayout layout = AsLayout::flat, const Scene* scene = nullptr);
  ~AccelStructure();
  AccelStructure(const AccelStructure&) = delete;
  AccelStructure& operator=(const AccelStructure&) = delete;

  VkAccelerationStructureKHR tlas() const { return tlas_; }
  /// The primitive -> slot table is read (the order is not the leaf order).
  bool remapped() const { return remapped_; }
  /// AS primitive index -> leaf-order slot (a 4-byte dummy where remapped() is false).
  const vk::Buffer& as_slot() const { return as_slot_; }
  AsOrder order() const { return order_; }
  AsLayout layout() const { return layout_; }
  const AsBuildStats& stats() const { return stats_; }
  /// The driver traversal's bindings (gpu::kDriverTraversalBindings: the top level, the primitive -> slot
  /// table) and writing them.
  static void add_bindings(std::vector<VkDescriptorSetLayoutBinding>& bindings, VkShaderStageFlags stages);
  void write_bindings(vk::DescriptorSet& ds) const;

 private:
  void build(vk::Context& ctx, const RtGeometry& g, const Scene* scene, bool compaction);
  void release();

  VkDevice device_;
  PFN_vkDestroyAccelerationStructureKHR destroy_;
  AsOrder order_;
  AsLayout layout_;
  bool remapped_ = false;
  std::vector<vk::Buffer> blas_buffers_;
  vk::Buffer tlas_buffer_, as_slot_;
  std::vector<VkAccelerationStructureKHR> blas_;
  VkAccelerationStructureKHR tlas_ = VK_NULL_HANDLE;
  AsBuildStats stats_;
};

}  // namespace hp
