// Binary files for cross-checking the traversal against another ray tracer. All little-endian, no header:
//   triangles: float32 x 9 per triangle (v0, v1, v2), in scene order
//   rays:      float32 x 8 per ray: ox oy oz tmin dx dy dz tmax
//   hits:      per ray: int32 prim (-1 = miss; index in the triangle file's order), float32 t, u, v
//              (barycentrics: point = (1 - u - v) v0 + u v1 + v v2)
// Readers throw hp::InputError with one line naming the file (missing, unreadable, or a size that is not a
// whole number of records). Writers write a temporary file beside the target and rename it, so a reader
// never sees half a file; they throw hp::InputError when the file cannot be written.
#pragma once

#include "bvh/geometry.hpp"

#include <span>
#include <string>
#include <vector>

namespace hp::bvh {

void write_triangles(const std::string& path, std::span<const Triangle> triangles);
std::vector<Triangle> read_triangles(const std::string& path);

void write_rays(const std::string& path, std::span<const Ray> rays);
std::vector<Ray> read_rays(const std::string& path);

void write_hits(const std::string& path, std::span<const Hit> hits);
std::vector<Hit> read_hits(const std::string& path);

}  // namespace hp::bvh
