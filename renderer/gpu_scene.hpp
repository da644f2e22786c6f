// The scene's raster geometry on the GPU: one interleaved vertex buffer (position, normal) and one index
// buffer for all meshes, and per-instance draw parameters. (The ray-tracing passes upload their own,
// BVH-ordered copies: what the raster pass reads is not what the traversal reads.)
#pragma once

#include "gpu/shared_types.h"
#include "scene/scene.hpp"
#include "vk/resources.hpp"

#include <vector>

namespace hp {

struct RasterVertex {
  glm::vec3 position;
  glm::vec3 normal;
};
static_assert(sizeof(RasterVertex) == 24);

struct MeshRange {
  uint32_t first_index = 0;
  uint32_t index_count = 0;
  int32_t vertex_offset = 0;
};

struct Draw {
  uint32_t mesh = 0;
  gpu::GBufferPush push{};
};

class GpuScene {
 public:
  GpuScene(vk::Context& ctx, const Scene& scene);

  const vk::Buffer& vertices() const { return vertices_; }
  const vk::Buffer& indices() const { return indices_; }
  const std::vector<MeshRange>& meshes() const { return meshes_; }
  const std::vector<Draw>& draws() const { return draws_; }

 private:
  vk::Buffer vertices_;
  vk::Buffer indices_;
  std::vector<MeshRange> meshes_;
  std::vector<Draw> draws_;
};

}  // namespace hp
