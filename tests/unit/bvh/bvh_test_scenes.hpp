// Procedural triangle sets and rays for the BVH tests and benchmarks (header-only, deterministic seeds).
#pragma once

#include "bvh/geometry.hpp"

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace hp::bvh::testing {

/// An indexed mesh; triangles() expands it in index order.
struct IndexedMesh {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;

  std::vector<Triangle> triangles() const { return make_triangles(positions, indices); }
};

/// Closed UV sphere: `stacks` rings, `slices` segments, pole caps as triangle fans (no zero-area triangles).
/// Triangles: 2 * slices * (stacks - 1).
inline IndexedMesh uv_sphere(int stacks, int slices, float radius = 1.0f, glm::vec3 center = glm::vec3(0.0f)) {
  IndexedMesh m;
  const float pi = 3.14159265358979f;
  m.positions.push_back(center + glm::vec3(0, radius, 0));
  for (int i = 1; i < stacks; ++i) {
    const float phi = pi * static_cast<float>(i) / static_cast<float>(stacks);
    for (int j = 0; j < slices; ++j) {
      const float theta = 2.0f * pi * static_cast<float>(j) / static_cast<float>(slices);
      m.positions.push_back(
          center + radius * glm::vec3(std::sin(phi) * std::cos(theta), std::cos(phi), std::sin(phi) * std::sin(theta)));
    }
  }
  m.positions.push_back(center + glm::vec3(0, -radius, 0));
  const uint32_t south = static_cast<uint32_t>(m.positions.size() - 1);
  const auto ring = [&](int i, int j) { return 1u + static_cast<uint32_t>((i - 1) * slices + (j % slices)); };
  for (int j = 0; j < slices; ++j) m.indices.insert(m.indices.end(), {0u, ring(1, j + 1), ring(1, j)});
  for (int i = 1; i + 1 < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      const uint32_t a = ring(i, j), b = ring(i, j + 1), c = ring(i + 1, j), d = ring(i + 1, j + 1);
      m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
    }
  }
  for (int j = 0; j < slices; ++j)
    m.indices.insert(m.indices.end(), {south, ring(stacks - 1, j), ring(stacks - 1, j + 1)});
  return m;
}

/// Height field over [0, size]^2 in xz: n x n quads, two triangles each, heights from a few sines.
inline IndexedMesh terrain(int n, float size = 100.0f, float height = 10.0f) {
  IndexedMesh m;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const float x = size * static_cast<float>(i) / static_cast<float>(n);
      const float z = size * static_cast<float>(j) / static_cast<float>(n);
      const float y = height * (0.5f * std::sin(x * 0.11f) * std::cos(z * 0.07f) +
                                0.3f * std::sin(x * 0.37f + z * 0.23f) + 0.2f * std::sin(z * 0.91f));
      m.positions.emplace_back(x, y, z);
    }
  }
  const auto at = [&](int i, int j) { return static_cast<uint32_t>(i * (n + 1) + j); };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      m.indices.insert(m.indices.end(),
                       {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  return m;
}

/// Random small triangles in a box: the "random scene".
inline std::vector<Triangle> random_soup(std::size_t n, uint32_t seed, float extent = 10.0f, float size = 0.5f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-extent, extent), off(-size, size);
  std::vector<Triangle> tris(n);
  for (auto& t : tris) {
    const glm::vec3 c(pos(rng), pos(rng), pos(rng));
    t.v0 = c + glm::vec3(off(rng), off(rng), off(rng));
    t.v1 = c + glm::vec3(off(rng), off(rng), off(rng));
    t.v2 = c + glm::vec3(off(rng), off(rng), off(rng));
  }
  return tris;
}

/// Clusters of `per` tiny triangles at x = 2^k for k = kmin..kmax, along a line: an exponential
/// distribution. Uniform bins over the centroid range can only peel the few largest clusters off per level,
/// so a greedy binned SAH builds a tree as deep as there are cluster groups, past any fixed stack.
/// Triangle size is 1e-3 * min(2^k, 1), so areas stay finite in float over the whole range.
inline std::vector<Triangle> exponential_clusters(int kmin, int kmax, int per, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Triangle> tris;
  tris.reserve(static_cast<std::size_t>(kmax - kmin + 1) * per);
  for (int k = kmin; k <= kmax; ++k) {
    const float s = std::ldexp(1.0f, k);
    const float w = std::min(s, 1.0f) * 1e-3f;
    for (int i = 0; i < per; ++i) {
      const glm::vec3 c(s * (1.0f + 0.01f * u(rng)), w * u(rng), w * u(rng));
      tris.push_back({c, c + glm::vec3(w, 0, 0), c + glm::vec3(0, w, w)});
    }
  }
  return tris;
}

/// Uniform random direction.
inline glm::vec3 random_dir(std::mt19937& rng) {
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (;;) {
    const glm::vec3 d(g(rng), g(rng), g(rng));
    const float l = glm::length(d);
    if (l > 1e-3f) return d / l;
  }
}

/// Random rays: origins uniform in [-extent, extent]^3, directions uniform.
inline std::vector<Ray> random_rays(std::size_t n, uint32_t seed, float extent) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-extent, extent);
  std::vector<Ray> rays(n);
  for (auto& r : rays) {
    r.origin = glm::vec3(pos(rng), pos(rng), pos(rng));
    r.dir = random_dir(rng);
  }
  return rays;
}

/// Coherent primary rays of a pinhole camera (width x height, vertical field of view in degrees).
inline std::vector<Ray> pinhole_rays(glm::vec3 eye, glm::vec3 target, int width, int height, float vfov_deg) {
  const glm::vec3 fwd = glm::normalize(target - eye);
  const glm::vec3 right = glm::normalize(glm::cross(fwd, glm::vec3(0, 1, 0)));
  const glm::vec3 up = glm::cross(right, fwd);
  const float h = std::tan(glm::radians(vfov_deg) * 0.5f);
  const float w = h * static_cast<float>(width) / static_cast<float>(height);
  std::vector<Ray> rays;
  rays.reserve(static_cast<std::size_t>(width) * height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const float sx = (2.0f * (static_cast<float>(x) + 0.5f) / static_cast<float>(width) - 1.0f) * w;
      const float sy = (1.0f - 2.0f * (static_cast<float>(y) + 0.5f) / static_cast<float>(height)) * h;
      Ray r;
      r.origin = eye;
      r.dir = glm::normalize(fwd + sx * right + sy * up);
      rays.push_back(r);
    }
  }
  return rays;
}

}  // namespace hp::bvh::testing
