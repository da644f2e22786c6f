#include "apps/cli_util.hpp"

#include "error.hpp"

#include <cmath>
#include <sstream>

namespace hp::cli {

glm::vec3 parse_vec3(const std::string& option, const std::string& text) {
  std::vector<float> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      float f = std::stof(item, &used);
      if (used != item.size() || !std::isfinite(f)) throw std::invalid_argument(item);
      v.push_back(f);
    } catch (const std::exception&) {
      throw InputError(option + " '" + text + "': '" + item + "' is not a finite number");
    }
  }
  if (v.size() != 3) throw InputError(option + " '" + text + "': expected three numbers x,y,z");
  return {v[0], v[1], v[2]};
}

void ViewOptions::add_to(CLI::App* cmd) {
  cmd->add_option("--camera-pos", camera_pos, "camera position x,y,z (default: the scene's, or auto-framed)");
  cmd->add_option("--camera-target", camera_target, "point the camera looks at, x,y,z");
  cmd->add_option("--fov", fov_deg, "vertical field of view in degrees")->check(CLI::Range(1.0f, 179.0f));
  cmd->add_option("--light-dir", light_dir, "direction toward the directional light, x,y,z");
}

Camera ViewOptions::camera_for(const Scene& scene, float aspect) const {
  Camera cam = scene.has_camera ? scene.camera : auto_frame(scene, aspect);
  if (!camera_pos.empty()) cam.position = parse_vec3("--camera-pos", camera_pos);
  if (!camera_target.empty()) cam.target = parse_vec3("--camera-target", camera_target);
  if (fov_deg > 0.0f) cam.vfov_deg = fov_deg;
  if (glm::length(cam.target - cam.position) == 0.0f) {
    throw InputError("--camera-pos and --camera-target are the same point");
  }
  return cam;
}

void ViewOptions::apply_light(Scene& scene) const {
  if (light_dir.empty()) return;
  glm::vec3 d = parse_vec3("--light-dir", light_dir);
  if (glm::length(d) == 0.0f) throw InputError("--light-dir '" + light_dir + "': zero vector");
  scene.light.direction = glm::normalize(d);
}

}  // namespace hp::cli
