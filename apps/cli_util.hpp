// Small helpers shared by the subcommands: parsing "x,y,z" vectors, camera and light options.
#pragma once

#include "scene/scene.hpp"

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <vector>

namespace hp::cli {

/// Parses "x,y,z" into a vector; throws hp::InputError naming the option.
glm::vec3 parse_vec3(const std::string& option, const std::string& text);

/// Camera and light overrides from the command line, applied on top of the scene's own.
struct ViewOptions {
  std::string camera_pos, camera_target, light_dir;
  float fov_deg = 0.0f;  // 0 = keep
  void add_to(CLI::App* cmd);
  /// The camera to render with: the scene's (or auto-framed) with the overrides applied.
  Camera camera_for(const Scene& scene, float aspect) const;
  /// Applies the light override to the scene.
  void apply_light(Scene& scene) const;
};

}  // namespace hp::cli
