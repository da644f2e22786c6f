// Every descriptor binding, defined once for the shaders (layout(binding = HP_BIND_...)) and for the C++
// descriptor set layouts and writes; grouped by descriptor set. All sets are set 0 of their pipelines.
// C++: static_asserts below check that the bindings of each set are distinct.
#ifndef HP_BINDINGS_H
#define HP_BINDINGS_H

// ---- the ray-tracing set (shaders/common/rt_bindings.glsl): every ray-tracing pass, one set --------------
#define HP_BIND_RT_FRAME 0                  // FrameUniforms (uniform buffer)
#define HP_BIND_RT_PARAMS 1                 // RayParams (uniform buffer)
#define HP_BIND_RT_NODES 2                  // BVH nodes (storage; also seen as texels at HP_BIND_RT_NODE_TEXELS)
#define HP_BIND_RT_POSITIONS 3              // vertex positions, 3 floats each (storage; traversal: 64-bit words)
#define HP_BIND_RT_INDICES 4                // 3 indices per slot (storage; traversal: 64-bit words)
#define HP_BIND_RT_SOUP 5                   // 9 floats per slot, de-indexed layout (storage; traversal: words)
#define HP_BIND_RT_OBJECT_FIRST 6           // first slot of each object (object leaves)
#define HP_BIND_RT_SLOT_SCENE 7             // slot -> scene triangle (closest-hit tie-break)
#define HP_BIND_RT_NORMALS 8                // shading normals, 3 floats per vertex
#define HP_BIND_RT_SOUP_NORMALS 9           // shading normals, 9 floats per slot (soup)
#define HP_BIND_RT_SLOT_MATERIAL 10         // slot -> material id
#define HP_BIND_RT_MATERIALS 11             // GpuMaterial per material
#define HP_BIND_RT_COUNTERS 12              // 64-bit work counters as 32-bit word pairs (HP_RT_COUNTERS)
#define HP_BIND_RT_SHADOW_DUMP 13           // RayDump per shadow ray (HP_RT_DUMP_RAYS)
#define HP_BIND_RT_REFLECTION_DUMP 14       // RayDump per reflection ray (HP_RT_DUMP_RAYS)
#define HP_BIND_RT_GBUF_DEPTH 15            // G-buffer depth (combined image sampler)
#define HP_BIND_RT_GBUF_NORMAL 16           // G-buffer normal + roughness (combined image sampler)
#define HP_BIND_RT_GBUF_ALBEDO 17           // G-buffer albedo + metalness (combined image sampler)
#define HP_BIND_RT_SHADOW_MASK 18           // shadow mask, r32f (storage image)
#define HP_BIND_RT_REFLECTION 19            // this frame's reflection grid, rgba32f (storage image)
#define HP_BIND_RT_REFLECTION_ACCUM 20      // running mean of the reflections, rgba32f (storage image)
#define HP_BIND_TRACE_RECORDS 21            // trace buffer of the instrumented variants (also the sort's set)
#define HP_BIND_RT_COMPACT_RAYS 22          // CompactRay per appended reflection ray (compaction path)
#define HP_BIND_RT_SORT_KEYS 23             // sort key per compacted ray
#define HP_BIND_RT_SORT_VALUES 24           // compacted ray index per key
#define HP_BIND_RT_RAY_COUNT 25             // appended ray count, then the consume pass's indirect dispatch
#define HP_BIND_RT_NODE_TEXELS 26           // BVH nodes as RGBA32UI texels, two per node
#define HP_BIND_BATCH_RAYS 27               // RayBatchTracer's set only: the rays (BatchRay), RGBA32UI texels
#define HP_BIND_BATCH_RESULTS 28            // RayBatchTracer's set only: the answers (BatchResult)
#define HP_BIND_RT_POSITION_TEXELS 29       // positions as R32G32B32A32_UINT texels (HP_GEOMETRY_TEXELS)
#define HP_BIND_RT_INDEX_TEXELS 30          // a slot's three indices per R32G32B32A32_UINT texel
#define HP_BIND_RT_SOUP_TEXELS 31           // soup vertices as R32G32B32A32_UINT texels
#define HP_BIND_RT_NORMAL_TEXELS 32         // shading normals as R32G32B32A32_UINT texels
#define HP_BIND_RT_SOUP_NORMAL_TEXELS 33    // soup shading normals as R32G32B32A32_UINT texels
#define HP_BIND_RT_SLOT_SCENE_TEXELS 34     // slot -> scene triangle as R32_UINT texels
#define HP_BIND_RT_SLOT_MATERIAL_TEXELS 35  // slot -> material id as R32_UINT texels
#define HP_BIND_RT_MATERIAL_TEXELS 36       // materials as RGBA32_UINT texels, two per material
#define HP_BIND_RT_TLAS 37                  // the driver's top-level acceleration structure (ray-query, pipeline)
#define HP_BIND_RT_AS_SLOT 38               // AS primitive index -> leaf-order slot (AsOrder other than leaf)
#define HP_BIND_RT_NODE_IMAGE 39            // the views of 26, 29, 30 and 31 as storage texel buffers, read where
#define HP_BIND_RT_POSITION_IMAGE 40        // HP_STORAGE_TEXELS (RtScene::storage_texels)
#define HP_BIND_RT_INDEX_IMAGE 41
#define HP_BIND_RT_SOUP_IMAGE 42

// ---- the radix sort's set (shaders/sort/radix_common.glsl, RadixSort), plus HP_BIND_TRACE_RECORDS -------
#define HP_BIND_SORT_KEYS_IN 0              // keys read by a digit pass
#define HP_BIND_SORT_VALUES_IN 1            // values read by a digit pass
#define HP_BIND_SORT_KEYS_OUT 2             // keys written by a digit pass
#define HP_BIND_SORT_VALUES_OUT 3           // values written by a digit pass
#define HP_BIND_SORT_HISTOGRAMS 4           // per-block digit counts, scanned into offsets in place
#define HP_BIND_SORT_COUNT 5                // the live element count (uint at offset 0)

// ---- the composite's set (shaders/composite.comp, CompositePass) ----------------------------------------
#define HP_BIND_COMPOSITE_FRAME 0           // FrameUniforms (uniform buffer)
#define HP_BIND_COMPOSITE_GBUF_DEPTH 1      // G-buffer depth (combined image sampler)
#define HP_BIND_COMPOSITE_GBUF_NORMAL 2     // G-buffer normal + roughness (combined image sampler)
#define HP_BIND_COMPOSITE_GBUF_ALBEDO 3     // G-buffer albedo + metalness (combined image sampler)
#define HP_BIND_COMPOSITE_OUTPUT 4          // the frame's colour, rgba32f (storage image, written)
#define HP_BIND_COMPOSITE_SHADOW_MASK 5     // shadow mask, r32f (storage image, read)
#define HP_BIND_COMPOSITE_REFLECTION 6      // accumulated reflections, rgba32f (storage image, read)

// ---- the G-buffer's set (shaders/gbuffer.vert / .frag, GBufferPass) -------------------------------------
#define HP_BIND_GBUFFER_FRAME 0             // FrameUniforms (uniform buffer, vertex + fragment)

#ifdef __cplusplus
#include <array>
#include <cstdint>
namespace hp::gpu {

template <size_t N>
constexpr bool bindings_distinct(const std::array<uint32_t, N>& b) {
  for (size_t i = 0; i < N; ++i) {
    for (size_t j = i + 1; j < N; ++j) {
      if (b[i] == b[j]) return false;
    }
  }
  return true;
}

/// The bindings the traversal reads (common/traversal.glsl; RtScene::add_traversal_bindings), in both sets
/// that hold it.
inline constexpr std::array<uint32_t, 14> kTraversalBindings = {
    HP_BIND_RT_POSITIONS,       HP_BIND_RT_INDICES,       HP_BIND_RT_SOUP,         HP_BIND_RT_OBJECT_FIRST,
    HP_BIND_RT_SLOT_SCENE,      HP_BIND_RT_NODE_TEXELS,   HP_BIND_RT_POSITION_TEXELS, HP_BIND_RT_INDEX_TEXELS,
    HP_BIND_RT_SOUP_TEXELS,     HP_BIND_RT_SLOT_SCENE_TEXELS, HP_BIND_RT_NODE_IMAGE,  HP_BIND_RT_POSITION_IMAGE,
    HP_BIND_RT_INDEX_IMAGE,     HP_BIND_RT_SOUP_IMAGE};
/// The driver traversal's bindings (common/driver_traversal.glsl), in both sets that hold it, where the
/// traversal is the driver's.
inline constexpr std::array<uint32_t, 2> kDriverTraversalBindings = {HP_BIND_RT_TLAS, HP_BIND_RT_AS_SLOT};
/// 0..42 but the ray batch's 27 and 28.
inline constexpr std::array<uint32_t, 41> kRtSetBindings = {
    HP_BIND_RT_FRAME,           HP_BIND_RT_PARAMS,           HP_BIND_RT_NODES,
    HP_BIND_RT_POSITIONS,       HP_BIND_RT_INDICES,          HP_BIND_RT_SOUP,
    HP_BIND_RT_OBJECT_FIRST,    HP_BIND_RT_SLOT_SCENE,       HP_BIND_RT_NORMALS,
    HP_BIND_RT_SOUP_NORMALS,    HP_BIND_RT_SLOT_MATERIAL,    HP_BIND_RT_MATERIALS,
    HP_BIND_RT_COUNTERS,        HP_BIND_RT_SHADOW_DUMP,      HP_BIND_RT_REFLECTION_DUMP,
    HP_BIND_RT_GBUF_DEPTH,      HP_BIND_RT_GBUF_NORMAL,      HP_BIND_RT_GBUF_ALBEDO,
    HP_BIND_RT_SHADOW_MASK,     HP_BIND_RT_REFLECTION,       HP_BIND_RT_REFLECTION_ACCUM,
    HP_BIND_TRACE_RECORDS,      HP_BIND_RT_COMPACT_RAYS,     HP_BIND_RT_SORT_KEYS,
    HP_BIND_RT_SORT_VALUES,     HP_BIND_RT_RAY_COUNT,        HP_BIND_RT_NODE_TEXELS,
    HP_BIND_RT_POSITION_TEXELS, HP_BIND_RT_INDEX_TEXELS,     HP_BIND_RT_SOUP_TEXELS,
    HP_BIND_RT_NORMAL_TEXELS,   HP_BIND_RT_SOUP_NORMAL_TEXELS, HP_BIND_RT_SLOT_SCENE_TEXELS,
    HP_BIND_RT_SLOT_MATERIAL_TEXELS, HP_BIND_RT_MATERIAL_TEXELS, HP_BIND_RT_TLAS,
    HP_BIND_RT_AS_SLOT,         HP_BIND_RT_NODE_IMAGE,       HP_BIND_RT_POSITION_IMAGE,
    HP_BIND_RT_INDEX_IMAGE,     HP_BIND_RT_SOUP_IMAGE};
inline constexpr std::array<uint32_t, 18> kBatchSetBindings = {
    HP_BIND_RT_POSITIONS,   HP_BIND_RT_INDICES,         HP_BIND_RT_SOUP,            HP_BIND_RT_OBJECT_FIRST,
    HP_BIND_RT_SLOT_SCENE,  HP_BIND_RT_NODE_TEXELS,     HP_BIND_RT_POSITION_TEXELS, HP_BIND_RT_INDEX_TEXELS,
    HP_BIND_RT_SOUP_TEXELS, HP_BIND_RT_SLOT_SCENE_TEXELS, HP_BIND_BATCH_RAYS,       HP_BIND_BATCH_RESULTS,
    HP_BIND_RT_TLAS,        HP_BIND_RT_AS_SLOT,         HP_BIND_RT_NODE_IMAGE,      HP_BIND_RT_POSITION_IMAGE,
    HP_BIND_RT_INDEX_IMAGE, HP_BIND_RT_SOUP_IMAGE};
inline constexpr std::array<uint32_t, 7> kSortSetBindings = {
    HP_BIND_SORT_KEYS_IN,    HP_BIND_SORT_VALUES_IN, HP_BIND_SORT_KEYS_OUT, HP_BIND_SORT_VALUES_OUT,
    HP_BIND_SORT_HISTOGRAMS, HP_BIND_SORT_COUNT,     HP_BIND_TRACE_RECORDS};
inline constexpr std::array<uint32_t, 7> kCompositeSetBindings = {
    HP_BIND_COMPOSITE_FRAME,  HP_BIND_COMPOSITE_GBUF_DEPTH,  HP_BIND_COMPOSITE_GBUF_NORMAL,
    HP_BIND_COMPOSITE_GBUF_ALBEDO, HP_BIND_COMPOSITE_OUTPUT, HP_BIND_COMPOSITE_SHADOW_MASK,
    HP_BIND_COMPOSITE_REFLECTION};

static_assert(bindings_distinct(kTraversalBindings), "traversal bindings collide");
static_assert(bindings_distinct(kDriverTraversalBindings), "driver traversal bindings collide");
static_assert(bindings_distinct(kRtSetBindings), "ray-tracing set bindings collide");
static_assert(bindings_distinct(kBatchSetBindings), "ray batch set bindings collide");
static_assert(bindings_distinct(kSortSetBindings), "radix sort set bindings collide");
static_assert(bindings_distinct(kCompositeSetBindings), "composite set bindings collide");

}  // namespace hp::gpu
#endif

#endif
