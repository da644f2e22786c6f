#include "rt_scene.hpp"

#include "common/shared_types.h"
#include "error.hpp"


namespace hp {

GeometryLayout parse_geometry_layout(const std::string& name) {
  if (name == "indexed" || name == "ebo") return GeometryLayout::indexed;
  if (name == "soup" || name == "no-ebo") return GeometryLayout::soup;
  throw InputError("--geometry " + name + ": unknown layout (choose indexed or soup)");
}

const char* to_string(GeometryLayout g) { return g == GeometryLayout::indexed ? "indexed" : "soup"; }

namespace {

constexpr VkBufferUsageFlags kStorage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;

vk::Buffer dummy(vk::Context& ctx) { return vk::Buffer(ctx, 4, kStorage, false); }

template <typename T>
vk::Buffer upload(vk::Context& ctx, const std::vector<T>& v, uint64_t& total) {
  if (v.empty()) return dummy(ctx);
  total += v.size() * sizeof(T);
  return vk::upload_vector(ctx, v, kStorage);
}

}  // namespace

RtScene::RtScene(vk::Context& ctx, const Scene& scene, const RtGeometry& g, GeometryLayout layout, bool shading)
    : layout_(layout), object_leaves_(g.bvh.granularity == bvh::Granularity::object) {
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
  check_range("BVH node", g.bvh.nodes.size() * sizeof(gpu::BvhNode));
  // The traversal fetches nodes as texels (traversal.glsl says why): two 16-byte texels per node.
  const uint64_t max_texels = ctx.properties().limits.maxTexelBufferElements;
  if (g.bvh.nodes.size() * 2 > max_texels) {
    throw InputError("scene '" + scene.name + "': the BVH's " + std::to_string(g.bvh.nodes.size()) +
                     " nodes need " + std::to_string(g.bvh.nodes.size() * 2) +
                     " texels, over this device's maxTexelBufferElements of " + std::to_string(max_texels));
  }
  uploaded_bytes_ += g.bvh.nodes.size() * sizeof(gpu::BvhNode);
  nodes_ = vk::upload_vector(ctx, g.bvh.nodes, kStorage | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT);
  node_texels_ = vk::BufferView(ctx, nodes_, VK_FORMAT_R32G32B32A32_UINT);
  object_first_ = object_leaves_ ? upload(ctx, leaf.object_first, uploaded_bytes_) : dummy(ctx);
  slot_scene_ = upload(ctx, leaf.scene_index, uploaded_bytes_);

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
  positions_ = upload(ctx, positions, uploaded_bytes_);
  indices_ = upload(ctx, indices, uploaded_bytes_);
  soup_ = upload(ctx, soup, uploaded_bytes_);
  normals_ = upload(ctx, normals, uploaded_bytes_);
  soup_normals_ = upload(ctx, soup_normals, uploaded_bytes_);

  std::vector<uint32_t> slot_material;
  std::vector<gpu::GpuMaterial> materials;
  if (shading) {
    slot_material.reserve(slots);
    for (uint32_t t : leaf.scene_index) slot_material.push_back(g.world.material[t]);
    for (const Material& m : scene.materials) {
      materials.push_back({glm::vec4(m.base_color, m.metallic), glm::vec4(m.roughness, 0.0f, 0.0f, 0.0f)});
    }
  }
  slot_material_ = upload(ctx, slot_material, uploaded_bytes_);
  materials_ = upload(ctx, materials, uploaded_bytes_);
}

vk::Pipeline create_rt_pipeline(vk::Context& ctx, std::span<const uint32_t> spirv, VkPipelineLayout layout, bool soup,
                                bool object_leaves) {
  const uint32_t values[2] = {soup ? 1u : 0u, object_leaves ? 1u : 0u};
  const VkSpecializationMapEntry entries[2] = {{0, 0, 4}, {1, 4, 4}};
  const VkSpecializationInfo spec{2, entries, sizeof(values), values};
  return vk::create_compute_pipeline(ctx, spirv, layout, &spec);
}

vk::Pipeline create_rt_pipeline(vk::Context& ctx, std::span<const uint32_t> spirv, VkPipelineLayout layout,
                                const RtScene& scene) {
  return create_rt_pipeline(ctx, spirv, layout, scene.layout() == GeometryLayout::soup, scene.object_leaves());
}

}  // namespace hp
