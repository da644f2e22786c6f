// glTF 2.0 (.gltf and .glb) to hp::Scene, through tinygltf.
#pragma once

#include "scene/scene.hpp"

#include <string>

namespace hp {

/// Loads the default scene of a glTF 2.0 file (all root nodes when it names none): node transforms
/// (matrix or TRS), TRIANGLES primitives (one Mesh each; other modes are skipped with a one-line warning on
/// stderr), pbrMetallicRoughness factors. Textures are never decoded and may be missing.
/// Throws hp::InputError with one line "<path>: <glTF field>: <reason>" for any malformed input; every
/// accessor is checked against its buffer before it is read.
Scene load_gltf(const std::string& path);

}  // namespace hp
