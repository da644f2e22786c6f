// Camera matrices in Vulkan conventions: right-handed world, clip z in [0, 1], framebuffer y down.
// Shared by the raster pass, the compute passes (world position from depth) and the CPU reference.
#pragma once

#include "scene/scene.hpp"

#include <glm/glm.hpp>

namespace hp {

/// Camera-relative: the matrices project a position taken relative to the eye (the view has no translation;
/// built in double), so a world far from the origin keeps its precision near the camera (docs/speed-vs-error.md,
/// "Shadows"). The GPU passes get exactly these.
struct View {
  glm::vec3 eye{0.0f};
  glm::mat4 view_proj_rel{1.0f};      ///< (world - eye) -> clip
  glm::mat4 inv_view_proj_rel{1.0f};  ///< (ndc, depth) -> world - eye
  bool reversed_z = false;
  /// The depth-buffer value of the background (the clear value).
  float far_depth() const { return reversed_z ? 0.0f : 1.0f; }
};

/// The up vector the view is built with: the camera's, or, when the camera looks along it (straight down
/// at its target, say) and no side axis follows, the world axis least aligned with the view direction.
/// Shared by make_view and the CPU reference's primary rays.
glm::dvec3 view_up(const Camera& camera);

/// Perspective view of `camera` for an image of width/height `aspect`. Standard depth maps near -> 0 and
/// far -> 1; reversed-Z maps near -> 1 and far -> 0 (better float precision far away).
View make_view(const Camera& camera, float aspect, bool reversed_z);

/// The world-space point of pixel centre (px + 0.5, py + 0.5) at depth-buffer value `depth`, computed as the
/// GPU passes do (hp_world_position): camera-relative, then plus the eye.
glm::vec3 unproject(const View& view, float px, float py, uint32_t width, uint32_t height, float depth);

/// The depth-buffer value of a world-space point (what the raster pass writes there).
float project_depth(const View& view, const glm::vec3& world);

}  // namespace hp
