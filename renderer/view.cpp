#include "view.hpp"

#include <glm/gtc/matrix_transform.hpp>

#include <cmath>

namespace hp {

glm::dvec3 view_up(const Camera& camera) {
  // Looking along the up vector leaves lookAt no side axis: the view would be NaN and the image empty.
  const glm::dvec3 up(camera.up);
  const glm::dvec3 dir = glm::normalize(glm::dvec3(camera.target) - glm::dvec3(camera.position));
  if (glm::length(glm::cross(dir, glm::normalize(up))) >= 1e-9) return up;
  const glm::dvec3 a = glm::abs(dir);
  return a.x <= a.y && a.x <= a.z ? glm::dvec3(1, 0, 0) : a.y <= a.z ? glm::dvec3(0, 1, 0) : glm::dvec3(0, 0, 1);
}

View make_view(const Camera& camera, float aspect, bool reversed_z) {
  View v;
  v.reversed_z = reversed_z;
  const float f = 1.0f / std::tan(glm::radians(camera.vfov_deg) * 0.5f);
  const float n = camera.znear, fa = camera.zfar;
  // Column-major; view space looks down -z. y is negated so that world up is framebuffer up.
  glm::mat4 p(0.0f);
  p[0][0] = f / aspect;
  p[1][1] = -f;
  p[2][3] = -1.0f;
  if (!reversed_z) {  // z_ndc = fa (z + n) / ((n - fa) z) ... maps -n -> 0, -fa -> 1
    p[2][2] = fa / (n - fa);
    p[3][2] = fa * n / (n - fa);
  } else {  // maps -n -> 1, -fa -> 0
    p[2][2] = n / (fa - n);
    p[3][2] = fa * n / (fa - n);
  }
  v.eye = camera.position;
  const glm::dvec3 fwd = glm::dvec3(camera.target) - glm::dvec3(camera.position);
  const glm::dmat4 rot = glm::lookAt(glm::dvec3(0.0), fwd, view_up(camera));
  const glm::dmat4 vp_rel = glm::dmat4(p) * rot;
  v.view_proj_rel = glm::mat4(vp_rel);
  v.inv_view_proj_rel = glm::mat4(glm::inverse(vp_rel));
  return v;
}

glm::vec3 unproject(const View& view, float px, float py, uint32_t width, uint32_t height, float depth) {
  const glm::vec2 ndc((px + 0.5f) / float(width) * 2.0f - 1.0f, (py + 0.5f) / float(height) * 2.0f - 1.0f);
  const glm::vec4 h = view.inv_view_proj_rel * glm::vec4(ndc, depth, 1.0f);
  return glm::vec3(h) / h.w + view.eye;
}

float project_depth(const View& view, const glm::vec3& world) {
  const glm::vec3 rel(glm::dvec3(world) - glm::dvec3(view.eye));
  const glm::vec4 c = view.view_proj_rel * glm::vec4(rel, 1.0f);
  return c.z / c.w;
}

}  // namespace hp
