// Loading a scene by its spec: "builtin:NAME" or a path to a .gltf / .glb file.
#pragma once

#include "scene/scene.hpp"

#include <string>
#include <vector>

namespace hp {

/// Loads a scene. Throws hp::InputError with one line naming the file, the glTF field and the reason.
Scene load_scene(const std::string& spec);

/// Names of the built-in scenes, without the "builtin:" prefix.
std::vector<std::string> builtin_scene_names();

}  // namespace hp
