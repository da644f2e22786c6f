// What a frame renders and measures, as plain values: the settings that the renderer takes and that
// scenario files, the runner and the reports name. No Vulkan here (scenario parsing and the reports link
// none); the renderer's passes take these structs as they are.
#pragma once

#include "bvh_options.hpp"

#include <cstdint>
#include <string>

namespace hp {

enum class GeometryLayout {
  indexed,  ///< "EBO": world-space vertex positions + an index buffer whose triangles are in leaf order
  soup,     ///< "no EBO": de-indexed triangles, three vertices each, in leaf order
};
GeometryLayout parse_geometry_layout(const std::string& name);  // throws InputError
const char* to_string(GeometryLayout g);
bvh::NodeLayout parse_node_layout(const std::string& name);  // throws InputError
const char* to_string(bvh::NodeLayout l);

enum class ShadowOffset { normal_bias, robust };
enum class JitterMode { shared, per_thread };
/// How reflection rays reach the traversal: `direct` (one thread per grid cell) or `compact` (valid rays
/// appended to a buffer, optionally sorted, consumed by an indirectly sized dispatch: the study's 4.2).
enum class ReflectionPath { direct, compact };
enum class SortKey { none, octant, direction, origin };
enum class Writeback { index, reproject };
ShadowOffset parse_shadow_offset(const std::string& name);
JitterMode parse_jitter_mode(const std::string& name);
ReflectionPath parse_reflection_path(const std::string& name);
SortKey parse_sort_key(const std::string& name);
Writeback parse_writeback(const std::string& name);
const char* to_string(ShadowOffset o);
const char* to_string(JitterMode j);
const char* to_string(ReflectionPath p);
const char* to_string(SortKey k);
const char* to_string(Writeback w);
/// Who walks the rays through the scene: the compute shaders' own BVH traversal (the study's), the driver's
/// acceleration structure through ray queries in the same compute shaders (VK_KHR_ray_query), or through a
/// ray-tracing pipeline (VK_KHR_ray_tracing_pipeline: ray generation, miss and closest-hit shaders).
enum class Traversal { compute, ray_query, pipeline };
/// The triangle order handed to the driver's acceleration-structure build (driver BVHs follow their input
/// order): the compute BVH's leaf order, the scene's order, or the Morton order of the triangle centroids.
enum class AsOrder { leaf, scene, morton };
/// How the scene is handed to the driver: one bottom-level structure of its world-space triangles under one
/// instance, or a bottom level per mesh under a top level of the scene's instances.
enum class AsLayout { flat, instances };
AsLayout parse_as_layout(const std::string& name);  // throws InputError
const char* to_string(AsLayout l);
Traversal parse_traversal(const std::string& name);  // throws InputError
AsOrder parse_as_order(const std::string& name);     // throws InputError
const char* to_string(Traversal t);
const char* to_string(AsOrder o);

/// Significant bits of a sort key mode (the radix sort's passes follow: 4 bits each).
uint32_t sort_key_bits(SortKey k);

struct RayTracingOptions {
  bool shadows = true;
  bool reflections = true;
  ShadowOffset offset = ShadowOffset::normal_bias;
  float bias = 0.1f;  ///< world units, for ShadowOffset::normal_bias (the study's 0.1)
  JitterMode jitter = JitterMode::per_thread;
  uint32_t reflection_divisor = 1;    ///< 1, 2 or 4: reflection grid = ceil(extent / divisor) per axis
  float roughness_threshold = 0.35f;  ///< reflective where roughness < this
  bool reflection_shadows = true;     ///< shadow rays from reflection hits
  bool counters = false;              ///< count rays, nodes visited, triangles tested (deterministic)
  bool dump_rays = false;             ///< record every ray and its result (tests, cross-checks)
  uint32_t seed = 1;
  /// Gate-validation knob: the shadow pass re-traces the first fraction of the image rows (same results,
  /// more work). 0 = off.
  float inject_shadow_fraction = 0.0f;
  ReflectionPath reflection_path = ReflectionPath::direct;
  SortKey sort = SortKey::none;            ///< compact path only
  Writeback writeback = Writeback::index;  ///< compact path only
  Traversal traversal = Traversal::compute;
  AsOrder as_order = AsOrder::leaf;     ///< driver traversals only (flat layout)
  AsLayout as_layout = AsLayout::flat;  ///< driver traversals only
  bool as_compaction = false;           ///< driver traversals: compact the bottom-level structure after its build
};

struct FrameSettings {
  uint32_t width = 1280;
  uint32_t height = 720;
  bool reversed_z = false;
  GeometryLayout geometry = GeometryLayout::indexed;
  RayTracingOptions rt{.shadows = false, .reflections = false};
  bvh::BuildOptions bvh;
  /// Time the passes on the host (one submission each, "cpu-wall") even where the queue has timestamps:
  /// what a queue without timestamp support gets, selectable so that path can be run and compared anywhere.
  bool host_timing = false;
};

/// Largest image side accepted (Vulkan guarantees 4096 for 2D images; lavapipe and GPUs allow 16384).
constexpr uint32_t kMaxImageSide = 16384;

/// Throws hp::InputError naming the limit when width/height are zero or too large for the device.
void validate_extent(uint32_t width, uint32_t height, uint32_t device_max_side);

}  // namespace hp
