// The CPU reference renderer: the converged image of the hybrid frame's shading model, traced entirely on
// the CPU with the reference traversal (bvh/traverse.hpp), in parallel on all cores.
//
// What it renders, per pixel centre (the same samples the raster pass takes):
//  - primary visibility by a ray cast (no depth buffer): the closest hit's exact position (barycentric
//    interpolation of the triangle, in double), its geometric normal and interpolated shading normal,
//    oriented toward the camera the way the G-buffer pass orients them;
//  - exact shadows: one occlusion ray per lit-facing pixel from the exact hit point, moved off the
//    triangle's plane along the geometric normal on the light's side by 2^-20 of the scene's extent plus
//    128 ULPs of the point's largest coordinate: scale-invariant (Wächter & Binder's offset is absolute
//    near the origin, which this project measures as a shortcut) and far below a pixel's footprint;
//  - converged reflections where roughness < the threshold: the mean over `samples` GGX-sampled directions
//    (stratified: a Halton (2, 3) sequence with a per-pixel Cranley-Patterson rotation) of the same
//    estimator the GPU runs once per frame (hit shading with its widened lobe, shadow rays at the hit),
//    at full resolution;
//  - the composite's formulas (shading.hpp mirrors the GLSL).
// The passes follow the scenario: a frame without shadows (reflections) is compared with a reference
// without them, so each sweep measures its own shortcut.
#pragma once

#include "bvh/bvh.hpp"
#include "image/image.hpp"
#include "scene/scene.hpp"

#include <cstdint>
#include <string>

namespace hp {

struct ReferenceSettings {
  uint32_t width = 1280, height = 720;
  bool shadows = true;
  bool reflections = true;
  bool reflection_shadows = true;  ///< shadow rays at reflection hits
  float roughness_threshold = 0.35f;
  uint32_t samples = 256;  ///< reflection directions per reflective pixel
  int threads = 0;         ///< 0 = all cores
};

/// What the reference knows per pixel.
struct ReferenceImage {
  Image4f color;  ///< linear radiance, alpha 1
  /// r: shadow visibility of the light (1 lit, 0 shadowed; 0 for surfaces facing away; -1 background);
  /// gba: the shading normal (world, unit, toward the camera).
  Image4f shading;
  /// rgb: the exact hit position relative to the camera (world units); a: 1 foreground, 0 background.
  Image4f position;
  double render_s = 0.0;
  uint64_t rays = 0;  ///< primary + shadow + reflection rays cast
};

/// Renders the reference of `scene` seen by `camera` (light and sky from the scene). The BVH is built with
/// the default binned SAH (the answer does not depend on the tree: the traversal's hit semantics are
/// tree-independent up to the coplanar ties of bvh/traverse.hpp). Throws hp::InputError for an absurd size
/// or zero samples.
ReferenceImage render_reference(const Scene& scene, const Camera& camera, const ReferenceSettings& settings);

/// The cache key of a reference: 16 hex digits hashing everything the image depends on (scene spec, camera,
/// light, sky, size, passes, threshold, samples) and a version number of the reference's shading model.
std::string reference_id(const std::string& scene_spec, const Scene& scene, const Camera& camera,
                         const ReferenceSettings& settings);

/// Writes the three layers as `<dir>/<id>.{color,shading,position}.exr` (each written atomically);
/// reads them back. load returns false when any layer is missing or has the wrong size.
void save_reference(const std::string& dir, const std::string& id, const ReferenceImage& ref);
bool load_reference(const std::string& dir, const std::string& id, uint32_t width, uint32_t height,
                    ReferenceImage& out);

}  // namespace hp
