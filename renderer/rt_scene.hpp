// The scene as the ray-tracing passes read it: a BVH built on the CPU and the geometry uploaded in BVH
// leaf order, in one of two layouts. Only what the passes read is uploaded.
#pragma once

#include "frame_settings.hpp"
#include "rt_geometry.hpp"
#include "vk/pipeline.hpp"
#include "vk/resources.hpp"

#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include <string>

namespace hp {


class RtScene {
 public:
  /// `shading`: also upload normals, per-slot material ids and materials (reflections shade their hits).
  /// `allow_geometry_texels`: false forces the storage loads (to compare the two paths).
  /// `slot_map`: upload the slot -> scene triangle map, which only closest-hit ties and ray dumps read (a
  /// frame of any-hit shadow rays without dumps leaves it out: 4 bytes a triangle).
  /// `bvh_nodes`: upload the BVH nodes (false for the driver traversals, which read the driver's structure:
  /// the node bindings then hold a small dummy).
  /// `spread_levels`: the passes' dispatch order (spread_levels()); by default the device's
  /// (dispatch_spread_levels). The traversal's division is the device's (exact_traversal_division).
  RtScene(vk::Context& ctx, const Scene& scene, const RtGeometry& geometry, GeometryLayout layout, bool shading,
          bool allow_geometry_texels = true, bool slot_map = true, bool bvh_nodes = true,
          std::optional<uint32_t> spread_levels = std::nullopt);

  GeometryLayout layout() const { return layout_; }
  bool object_leaves() const { return object_leaves_; }
  /// The nodes are the wide4 layout (RtGeometry::node_layout; specialization constant 5), not the binary.
  bool wide_nodes() const { return wide_nodes_; }
  /// Levels of the order in which the traced passes' workgroups take their tiles and rays
  /// (shaders/common/dispatch_order.glsl; specialization constant 6).
  uint32_t spread_levels() const { return spread_levels_; }
  /// The traversal divides in double precision and rounds once (specialization constant 7).
  bool exact_division() const { return exact_division_; }
  /// The traversal reads the node and geometry texels through storage texel buffers (imageLoad, bindings 39-42)
  /// rather than uniform ones (texelFetch, 26 and 29-31): specialization constant 8, storage_texel_reads.
  bool storage_texels() const { return storage_texels_; }
  /// The traversal fetches the geometry through texel views (positions(), indices(), soup() seen as
  /// R32G32B32A32_UINT, a vertex or a triangle's three indices per texel: bindings 29-31) rather than storage
  /// loads. Off where the device cannot read that format as a uniform texel buffer, a buffer exceeds
  /// maxTexelBufferElements (or in that layout maxStorageBufferRange), or the constructor was asked not to.
  bool geometry_texels() const { return geometry_texels_; }
  VkBufferView position_texels() const { return position_texels_.handle(); }
  VkBufferView index_texels() const { return index_texels_.handle(); }
  VkBufferView soup_texels() const { return soup_texels_.handle(); }
  /// With geometry_texels(): the shading normals the same way (bindings 32, 33) and the slot -> scene
  /// triangle map as R32_UINT (binding 34, the closest hit's tie-break).
  VkBufferView normal_texels() const { return normal_texels_.handle(); }
  VkBufferView soup_normal_texels() const { return soup_normal_texels_.handle(); }
  VkBufferView slot_scene_texels() const { return slot_scene_texels_.handle(); }
  /// With geometry_texels(): the per-slot material ids as R32_UINT (binding 35) and the materials as
  /// RGBA32_UINT, two texels each (binding 36), for the reflection hits' shading.
  VkBufferView slot_material_texels() const { return slot_material_texels_.handle(); }
  VkBufferView material_texels() const { return material_texels_.handle(); }
  /// Every binding of shaders/common/rt_bindings.glsl 2..11; a buffer the configuration does not read is
  /// a small dummy (4 bytes, 48 where it is also seen as texels).
  const vk::Buffer& nodes() const { return nodes_; }
  /// The node buffer as RGBA32UI texels, two per binary node or four per wide node (binding 26: the
  /// traversal's fetches).
  VkBufferView node_texels() const { return node_texels_.handle(); }
  /// The geometry's buffers: 12 bytes a vertex, index triple or normal, or 16 (a fourth word, unused) where
  /// the shaders read them as texels (geometry_texels()). The *_bytes sizes are those of the 12-byte layout,
  /// as the shaders address and trace them.
  const vk::Buffer& positions() const { return positions_; }
  const vk::Buffer& indices() const { return indices_; }
  const vk::Buffer& soup() const { return soup_; }
  const vk::Buffer& object_first() const { return object_first_; }
  const vk::Buffer& slot_scene() const { return slot_scene_; }
  const vk::Buffer& normals() const { return normals_; }
  const vk::Buffer& soup_normals() const { return soup_normals_; }
  const vk::Buffer& slot_material() const { return slot_material_; }
  uint64_t positions_bytes() const { return positions_bytes_; }
  uint64_t indices_bytes() const { return indices_bytes_; }
  uint64_t soup_bytes() const { return soup_bytes_; }
  uint64_t normals_bytes() const { return normals_bytes_; }
  uint64_t soup_normals_bytes() const { return soup_normals_bytes_; }
  const vk::Buffer& materials() const { return materials_; }
  /// The bindings the traversal reads (shaders/common/traversal.glsl; gpu::kTraversalBindings of
  /// core/gpu/bindings.h): their layout entries (compute stage), and writing this scene's buffers into them.
  static void add_traversal_bindings(std::vector<VkDescriptorSetLayoutBinding>& bindings,
                                     VkShaderStageFlags stages = VK_SHADER_STAGE_COMPUTE_BIT);
  void write_traversal_bindings(vk::DescriptorSet& ds) const;
  /// Bytes uploaded for the traversal and shading (dummies excluded).
  uint64_t uploaded_bytes() const { return uploaded_bytes_; }

 private:
  GeometryLayout layout_;
  bool object_leaves_;
  bool wide_nodes_;
  uint32_t spread_levels_;
  bool exact_division_;
  bool storage_texels_;
  uint64_t uploaded_bytes_ = 0;
  uint64_t positions_bytes_ = 0, indices_bytes_ = 0, soup_bytes_ = 0, normals_bytes_ = 0, soup_normals_bytes_ = 0;
  vk::Buffer nodes_, positions_, indices_, soup_, object_first_, slot_scene_, normals_, soup_normals_, slot_material_,
      materials_, texel_dummy_;
  bool geometry_texels_ = false;
  vk::BufferView node_texels_;  // after the buffers: destroyed before them
  vk::BufferView position_texels_, index_texels_, soup_texels_, normal_texels_, soup_normal_texels_, slot_scene_texels_,
      slot_material_texels_, material_texels_;
};

/// How many CPU threads `ctx`'s device computes on: 0 on a GPU; on a CPU device (lavapipe) LP_NUM_THREADS
/// where set, else one per online CPU.
unsigned device_cpu_threads(const vk::Context& ctx);

/// How many levels of hp_spread (shaders/common/dispatch_order.glsl) the traced passes of `ctx`'s device use:
/// on a CPU device, which splits a dispatch into one contiguous block of workgroups per thread (lavapipe:
/// LP_NUM_THREADS where set, else one thread per online CPU), ceil(log2(threads)), so that every block
/// covers the whole image; on a GPU 0, the image order.
uint32_t dispatch_spread_levels(const vk::Context& ctx);

/// Whether the compute traversal on `ctx`'s device takes its quotients in double precision, rounded once to
/// float (hp_div in shaders/common/traversal.glsl), so that they are the correctly rounded quotients of the C++
/// reference: on every device but lavapipe, whose float division is IEEE's (LLVM's fdiv on the host CPU). Vulkan
/// allows a 32-bit division 2.5 ulp of error, and NVIDIA's uses it. HP_EXACT_DIVISION=1 (or 0) in the
/// environment forces it on (off): the tests check the double-precision path on lavapipe with it.
bool exact_traversal_division(const vk::Context& ctx);
/// The same decision for a driver by its name (VkPhysicalDeviceDriverProperties::driverName), as `devices` shows it.
bool exact_traversal_division(std::string_view driver_name);

/// Whether the compute traversal on `ctx`'s device reads its node and geometry texels with imageLoad from storage
/// texel buffers rather than texelFetch from uniform ones (the same views, the same bytes): on lavapipe, where it
/// is the faster of the two (docs/gpu-passes.md); GPUs keep texelFetch, the path measured on them.
/// HP_STORAGE_TEXELS=1 (or 0) in the environment forces it on (off), for the tests and A/B runs.
bool storage_texel_reads(const vk::Context& ctx);
/// The same decision for a driver by its name, as `devices` shows it.
bool storage_texel_reads(std::string_view driver_name);

/// The specialization of a ray-tracing shader for `scene` (shaders/common/rt_bindings.glsl: constant_id 0 =
/// soup layout, 1 = object leaves, 2 = geometry fetched as texels), for what a frame records (constant_id 3 =
/// `rt_flags`, HP_RT_COUNTERS | HP_RT_DUMP_RAYS | HP_RT_REFLECTION_SHADOWS ...), for the driver traversal's
/// primitive -> slot table (constant_id 4, common/driver_traversal.glsl), for the node layout (constant_id 5 =
/// wide4 nodes), for the dispatch order (constant_id 6 = spread levels), for the division (constant_id 7 =
/// exact_traversal_division) and for the texel reads (constant_id 8 = storage_texel_reads). Not copyable: `info`
/// points into it.
struct RtSpecialization {
  RtSpecialization(const RtScene& scene, uint32_t rt_flags, bool as_remap);
  RtSpecialization(const RtSpecialization&) = delete;
  RtSpecialization& operator=(const RtSpecialization&) = delete;
  uint32_t values[9];
  VkSpecializationMapEntry entries[9];
  VkSpecializationInfo info;
};

/// A ray-tracing compute pipeline specialized as RtSpecialization says.
vk::Pipeline create_rt_pipeline(vk::Context& ctx, std::span<const uint32_t> spirv, VkPipelineLayout layout,
                                const RtScene& scene, uint32_t rt_flags = 0, bool as_remap = false);

}  // namespace hp
