#include "gpu_scene.hpp"

#include <glm/gtc/matrix_inverse.hpp>

namespace hp {

GpuScene::GpuScene(vk::Context& ctx, const Scene& scene) {
  std::vector<RasterVertex> vertices;
  std::vector<uint32_t> indices;
  for (const Mesh& m : scene.meshes) {
    MeshRange r;
    r.first_index = static_cast<uint32_t>(indices.size());
    r.index_count = static_cast<uint32_t>(m.indices.size());
    r.vertex_offset = static_cast<int32_t>(vertices.size());
    for (size_t i = 0; i < m.positions.size(); ++i) {
      vertices.push_back({m.positions[i], i < m.normals.size() ? m.normals[i] : glm::vec3(0.0f)});
    }
    indices.insert(indices.end(), m.indices.begin(), m.indices.end());
    meshes_.push_back(r);
  }
  vertices_ = vk::upload_vector(ctx, vertices, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
  indices_ = vk::upload_vector(ctx, indices, VK_BUFFER_USAGE_INDEX_BUFFER_BIT);

  for (const Instance& inst : scene.instances) {
    const Mesh& mesh = scene.meshes[inst.mesh];
    const Material& mat = scene.materials.at(mesh.material);
    const glm::mat3 nm = glm::inverseTranspose(glm::mat3(inst.world));
    Draw d;
    d.mesh = inst.mesh;
    d.push.world = inst.world;
    // glm is column-major: row r of nm is (nm[0][r], nm[1][r], nm[2][r]).
    d.push.normal_row0 = glm::vec4(nm[0][0], nm[1][0], nm[2][0], mat.base_color.r);
    d.push.normal_row1 = glm::vec4(nm[0][1], nm[1][1], nm[2][1], mat.base_color.g);
    d.push.normal_row2 = glm::vec4(nm[0][2], nm[1][2], nm[2][2], mat.base_color.b);
    d.push.material = glm::vec4(mat.metallic, mat.roughness, float(mesh.material), 0.0f);
    draws_.push_back(d);
  }
}

}  // namespace hp
