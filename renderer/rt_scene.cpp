#include "rt_scene.hpp"

#include "error.hpp"
#include "gpu/bindings.h"
#include "gpu/shared_types.h"

#include <algorithm>
#include <cstdlib>
#include <string_view>
#include <thread>


namespace hp {

namespace {

constexpr VkBufferUsageFlags kStorage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;

vk::Buffer dummy(vk::Context& ctx) { return vk::Buffer(ctx, 4, kStorage, false); }

// A dummy seen as texels holds whole texels of every format used here (4 to 16 bytes: 48 bytes).
uint64_t dummy_bytes(VkBufferUsageFlags extra_usage) { return extra_usage ? 48 : 4; }

template <typename T>
vk::Buffer upload(vk::Context& ctx, const std::vector<T>& v, uint64_t& total, VkBufferUsageFlags extra_usage = 0) {
  if (v.empty()) return vk::Buffer(ctx, dummy_bytes(extra_usage), kStorage | extra_usage, false);
  total += v.size() * sizeof(T);
  return vk::upload_vector(ctx, v, kStorage | extra_usage);
}

// A vertex, a normal or a triangle's three indices as a texel: 16 bytes, the fourth word unused.
constexpr VkFormat kQuad = VK_FORMAT_R32G32B32A32_UINT;

// Three-word items as four-word ones (the fourth 0): the texel layout of the geometry.
template <typename T>
std::vector<T> quads(const std::vector<T>& triples) {
  std::vector<T> q;
  q.reserve(triples.size() / 3 * 4);
  for (size_t i = 0; i + 2 < triples.size(); i += 3)
    q.insert(q.end(), {triples[i], triples[i + 1], triples[i + 2], T(0)});
  return q;
}

}  // namespace

unsigned device_cpu_threads(const vk::Context& ctx) {
  if (ctx.properties().deviceType != VK_PHYSICAL_DEVICE_TYPE_CPU) return 0;
  unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  if (const char* env = std::getenv("LP_NUM_THREADS"); env != nullptr && *env != '\0') {
    char* end = nullptr;
    const unsigned long n = std::strtoul(env, &end, 10);
    if (*end == '\0') threads = static_cast<unsigned>(std::min(n, 1024ul));
  }
  return threads;
}

uint32_t dispatch_spread_levels(const vk::Context& ctx) {
  const unsigned threads = device_cpu_threads(ctx);
  if (threads == 0) return 0;
  uint32_t levels = 0;
  while ((1u << levels) < threads) ++levels;
  return levels;
}

namespace {

// A per-driver choice of the traversal's code, which `variable` (=1 or =0) in the environment overrides.
bool driver_choice(const char* variable, bool by_driver) {
  if (const char* env = std::getenv(variable); env != nullptr && *env != '\0') return std::string_view(env) != "0";
  return by_driver;
}

}  // namespace

bool exact_traversal_division(std::string_view driver_name) {
  return driver_choice("HP_EXACT_DIVISION", driver_name != "llvmpipe");
}

bool exact_traversal_division(const vk::Context& ctx) { return exact_traversal_division(ctx.info().driver_name); }

bool storage_texel_reads(std::string_view driver_name) {
  return driver_choice("HP_STORAGE_TEXELS", driver_name == "llvmpipe");
}

bool storage_texel_reads(const vk::Context& ctx) { return storage_texel_reads(ctx.info().driver_name); }

RtScene::RtScene(vk::Context& ctx, const Scene& scene, const RtGeometry& g, GeometryLayout layout, bool shading,
                 bool allow_geometry_texels, bool slot_map, bool bvh_nodes, std::optional<uint32_t> spread_levels)
    : layout_(layout),
      object_leaves_(g.bvh.granularity == bvh::Granularity::object),
      wide_nodes_(bvh_nodes && g.node_layout == bvh::NodeLayout::wide4),
      spread_levels_(spread_levels ? *spread_levels : dispatch_spread_levels(ctx)),
      exact_division_(exact_traversal_division(ctx)),
      storage_texels_(storage_texel_reads(ctx)) {
  const auto& leaf = g.leaf;
  const size_t slots = leaf.triangles.size();
  const uint64_t max_range = ctx.properties().limits.maxStorageBufferRange;
  const auto check_range = [&](const char* what, uint64_t bytes) {
    if (bytes > max_range) {
      throw InputError(std::string("scene '") + scene.name + "': the " + what + " buffer needs " +
                       std::to_string(bytes >> 20) + " MiB, over this device's maxStorageBufferRange of " +
                       std::to_string(max_range >> 20) + " MiB");
    }
  };
  // The node layout the traversal reads (a specialization constant): the study's binary nodes, or wide4.
  const bool wide = wide_nodes_;
  const uint64_t node_bytes =
      wide ? g.wide.nodes.size() * sizeof(gpu::WideNode) : g.bvh.nodes.size() * sizeof(gpu::BvhNode);
  check_range("BVH node", node_bytes);
  // The traversal fetches nodes as texels (traversal.glsl says why): 16 bytes each.
  const uint64_t max_texels = ctx.properties().limits.maxTexelBufferElements;
  if (node_bytes / 16 > max_texels) {
    const size_t count = wide ? g.wide.nodes.size() : g.bvh.nodes.size();
    throw InputError("scene '" + scene.name + "': the BVH's " + std::to_string(count) + " nodes need " +
                     std::to_string(node_bytes / 16) + " texels, over this device's maxTexelBufferElements of " +
                     std::to_string(max_texels));
  }
  // Every view the traversal reads as texels is bound both ways, a uniform and a storage texel buffer
  // (bindings 26 and 39, ...; R32G32B32A32_UINT supports both on every Vulkan device): which one the shader
  // reads is a specialization constant (storage_texels()).
  constexpr VkBufferUsageFlags kTexelUsage =
      VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT | VK_BUFFER_USAGE_STORAGE_TEXEL_BUFFER_BIT;
  constexpr VkBufferUsageFlags kNodeUsage = kStorage | kTexelUsage;
  if (bvh_nodes) {
    uploaded_bytes_ += node_bytes;
    nodes_ = wide ? vk::upload_vector(ctx, g.wide.nodes, kNodeUsage) : vk::upload_vector(ctx, g.bvh.nodes, kNodeUsage);
  } else {
    nodes_ = vk::Buffer(ctx, 48, kNodeUsage, false);  // never read
  }
  node_texels_ = vk::BufferView(ctx, nodes_, VK_FORMAT_R32G32B32A32_UINT);
  object_first_ = object_leaves_ ? upload(ctx, leaf.object_first, uploaded_bytes_) : dummy(ctx);

  std::vector<float> positions, soup, normals, soup_normals;
  std::vector<uint32_t> indices;
  if (layout == GeometryLayout::indexed) {
    positions.reserve(g.world.positions.size() * 3);
    for (const glm::vec3& p : g.world.positions) positions.insert(positions.end(), {p.x, p.y, p.z});
    indices.reserve(slots * 3);
    for (size_t k = 0; k < slots; ++k) {
      const uint32_t t = leaf.scene_index[k];
      const uint32_t* idx = &g.world.indices[size_t(t) * 3];
      // Degenerate triangles kept inside objects are collapsed to their first vertex, exactly as the
      // leaf-order triangles the reference traversal reads (so both layouts test the same values).
      if (bvh::is_degenerate(g.triangles[t])) {
        indices.insert(indices.end(), {idx[0], idx[0], idx[0]});
      } else {
        indices.insert(indices.end(), {idx[0], idx[1], idx[2]});
      }
    }
    if (shading) {
      for (const glm::vec3& n : g.world.normals) normals.insert(normals.end(), {n.x, n.y, n.z});
    }
  } else {
    soup.reserve(slots * 9);
    for (const bvh::Triangle& t : leaf.triangles) {
      soup.insert(soup.end(), {t.v0.x, t.v0.y, t.v0.z, t.v1.x, t.v1.y, t.v1.z, t.v2.x, t.v2.y, t.v2.z});
    }
    if (shading) {
      soup_normals.reserve(slots * 9);
      for (size_t k = 0; k < slots; ++k) {
        const uint32_t* idx = &g.world.indices[size_t(leaf.scene_index[k]) * 3];
        for (int c = 0; c < 3; ++c) {
          const glm::vec3& n = g.world.normals[idx[c]];
          soup_normals.insert(soup_normals.end(), {n.x, n.y, n.z});
        }
      }
    }
  }
  check_range("vertex", positions.size() * 4);
  check_range("index", indices.size() * 4);
  check_range("triangle soup", soup.size() * 4);
  // The geometry as R32G32B32A32_UINT texels: a triangle's fetch is one texel per vertex (and one for its
  // indices) instead of llvmpipe's loops over the lanes for storage loads, and a 16-byte texel is one
  // 16-byte load per lane where a 12-byte R32G32B32_UINT one took an 8- and a 4-byte load and inserts
  // (docs/gpu-passes.md, "Geometry as texels"). UINT keeps the float bits exactly. The buffers are then
  // uploaded in that layout, a fourth word per item; the storage bindings, which the shaders do not read
  // with texels, see the same buffers. The storage path (12 bytes an item) stays for devices without the
  // format or past their limits.
  VkFormatProperties quad{};
  vkGetPhysicalDeviceFormatProperties(ctx.physical_device(), kQuad, &quad);
  // Every buffer seen as texels stays within maxTexelBufferElements (R32_UINT: the slot map is 1 per slot),
  // and in the texel layout within maxStorageBufferRange.
  const uint64_t most_texels =
      std::max({positions.size() / 3, indices.size() / 3, soup.size() / 3, normals.size() / 3, soup_normals.size() / 3,
                uint64_t(slots), uint64_t(scene.materials.size()) * 2});
  geometry_texels_ = allow_geometry_texels && (quad.bufferFeatures & VK_FORMAT_FEATURE_UNIFORM_TEXEL_BUFFER_BIT) != 0 &&
                     most_texels <= max_texels && most_texels * 16 <= max_range;
  const VkBufferUsageFlags texel_usage = geometry_texels_ ? VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT : 0;
  // The traversal's geometry (positions, indices, soup) is also bound as storage texel buffers (bindings 40-42).
  const VkBufferUsageFlags traversal_texel_usage = geometry_texels_ ? kTexelUsage : 0;
  // The sizes of the geometry as the shaders address it (12 bytes a vertex, index triple or normal; an
  // unused buffer's dummy): the trace's buffer table, whatever the layout uploaded.
  const auto addressed_bytes = [&](const auto& triples) {  // float or uint32_t items
    return triples.empty() ? dummy_bytes(texel_usage) : triples.size() * 4;
  };
  positions_bytes_ = addressed_bytes(positions);
  indices_bytes_ = addressed_bytes(indices);
  soup_bytes_ = addressed_bytes(soup);
  normals_bytes_ = addressed_bytes(normals);
  soup_normals_bytes_ = addressed_bytes(soup_normals);
  const auto geometry = [&](const auto& triples, VkBufferUsageFlags usage) {
    if (geometry_texels_) return upload(ctx, quads(triples), uploaded_bytes_, usage);
    return upload(ctx, triples, uploaded_bytes_);
  };
  positions_ = geometry(positions, traversal_texel_usage);
  indices_ = geometry(indices, traversal_texel_usage);
  soup_ = geometry(soup, traversal_texel_usage);
  normals_ = geometry(normals, texel_usage);
  soup_normals_ = geometry(soup_normals, texel_usage);
  slot_scene_ = upload(ctx, slot_map ? leaf.scene_index : std::vector<uint32_t>{}, uploaded_bytes_, texel_usage);
  // Without texels, the texel bindings (HP_BIND_RT_*_TEXELS and *_IMAGE) still need valid views: any small texel
  // buffer does (never read).
  if (!geometry_texels_) texel_dummy_ = vk::Buffer(ctx, 48, kTexelUsage, false);
  const auto view = [&](const vk::Buffer& b, VkFormat f) {
    return vk::BufferView(ctx, geometry_texels_ ? b : texel_dummy_, f);
  };
  position_texels_ = view(positions_, kQuad);
  index_texels_ = view(indices_, kQuad);
  soup_texels_ = view(soup_, kQuad);
  normal_texels_ = view(normals_, kQuad);
  soup_normal_texels_ = view(soup_normals_, kQuad);
  slot_scene_texels_ = view(slot_scene_, VK_FORMAT_R32_UINT);

  std::vector<uint32_t> slot_material;
  std::vector<gpu::GpuMaterial> materials;
  if (shading) {
    slot_material.reserve(slots);
    for (uint32_t t : leaf.scene_index) slot_material.push_back(g.world.material[t]);
    for (const Material& m : scene.materials) {
      materials.push_back({glm::vec4(m.base_color, m.metallic), glm::vec4(m.roughness, 0.0f, 0.0f, 0.0f)});
    }
  }
  slot_material_ = upload(ctx, slot_material, uploaded_bytes_, texel_usage);
  materials_ = upload(ctx, materials, uploaded_bytes_, texel_usage);
  slot_material_texels_ = view(slot_material_, VK_FORMAT_R32_UINT);
  material_texels_ = view(materials_, VK_FORMAT_R32G32B32A32_UINT);  // two texels per material
}

void RtScene::add_traversal_bindings(std::vector<VkDescriptorSetLayoutBinding>& b, VkShaderStageFlags cs) {
  for (uint32_t i :
       {HP_BIND_RT_POSITIONS, HP_BIND_RT_INDICES, HP_BIND_RT_SOUP, HP_BIND_RT_OBJECT_FIRST, HP_BIND_RT_SLOT_SCENE}) {
    b.push_back({i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, cs, nullptr});
  }
  for (uint32_t i : {HP_BIND_RT_NODE_TEXELS, HP_BIND_RT_POSITION_TEXELS, HP_BIND_RT_INDEX_TEXELS,
                     HP_BIND_RT_SOUP_TEXELS, HP_BIND_RT_SLOT_SCENE_TEXELS}) {
    b.push_back({i, VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, 1, cs, nullptr});
  }
  for (uint32_t i : {HP_BIND_RT_NODE_IMAGE, HP_BIND_RT_POSITION_IMAGE, HP_BIND_RT_INDEX_IMAGE, HP_BIND_RT_SOUP_IMAGE}) {
    b.push_back({i, VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER, 1, cs, nullptr});
  }
}

void RtScene::write_traversal_bindings(vk::DescriptorSet& ds) const {
  const VkDescriptorType sb = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  const VkDescriptorType tb = VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
  ds.write_buffer(HP_BIND_RT_POSITIONS, sb, positions_.handle());
  ds.write_buffer(HP_BIND_RT_INDICES, sb, indices_.handle());
  ds.write_buffer(HP_BIND_RT_SOUP, sb, soup_.handle());
  ds.write_buffer(HP_BIND_RT_OBJECT_FIRST, sb, object_first_.handle());
  ds.write_buffer(HP_BIND_RT_SLOT_SCENE, sb, slot_scene_.handle());
  ds.write_texel_buffer(HP_BIND_RT_NODE_TEXELS, tb, node_texels());
  ds.write_texel_buffer(HP_BIND_RT_POSITION_TEXELS, tb, position_texels());
  ds.write_texel_buffer(HP_BIND_RT_INDEX_TEXELS, tb, index_texels());
  ds.write_texel_buffer(HP_BIND_RT_SOUP_TEXELS, tb, soup_texels());
  ds.write_texel_buffer(HP_BIND_RT_SLOT_SCENE_TEXELS, tb, slot_scene_texels());
  const VkDescriptorType si = VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER;
  ds.write_texel_buffer(HP_BIND_RT_NODE_IMAGE, si, node_texels());
  ds.write_texel_buffer(HP_BIND_RT_POSITION_IMAGE, si, position_texels());
  ds.write_texel_buffer(HP_BIND_RT_INDEX_IMAGE, si, index_texels());
  ds.write_texel_buffer(HP_BIND_RT_SOUP_IMAGE, si, soup_texels());
}

RtSpecialization::RtSpecialization(const RtScene& scene, uint32_t rt_flags, bool as_remap)
    : values{scene.layout() == GeometryLayout::soup ? 1u : 0u,
             scene.object_leaves() ? 1u : 0u,
             scene.geometry_texels() ? 1u : 0u,
             rt_flags,
             as_remap ? 1u : 0u,
             scene.wide_nodes() ? 1u : 0u,
             scene.spread_levels(),
             scene.exact_division() ? 1u : 0u,
             scene.storage_texels() ? 1u : 0u},
      entries{{0, 0, 4}, {1, 4, 4}, {2, 8, 4}, {3, 12, 4}, {4, 16, 4}, {5, 20, 4}, {6, 24, 4}, {7, 28, 4}, {8, 32, 4}},
      info{9, entries, sizeof(values), values} {}

vk::Pipeline create_rt_pipeline(vk::Context& ctx, std::span<const uint32_t> spirv, VkPipelineLayout layout,
                                const RtScene& scene, uint32_t rt_flags, bool as_remap) {
  const RtSpecialization spec(scene, rt_flags, as_remap);
  return vk::create_compute_pipeline(ctx, spirv, layout, &spec.info);
}

}  // namespace hp
