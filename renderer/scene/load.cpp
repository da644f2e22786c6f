#include "scene/load.hpp"

#include "error.hpp"
#include "scene/builtin_scenes.hpp"
#include "scene/gltf_loader.hpp"

#include <cctype>
#include <filesystem>

namespace hp {

Scene load_scene(const std::string& spec) {
  constexpr std::string_view kPrefix = "builtin:";
  if (spec.empty()) throw InputError("scene: empty spec (expected builtin:NAME or a .gltf/.glb path)");
  if (spec.starts_with(kPrefix)) {
    const std::string name = spec.substr(kPrefix.size());
    if (auto scene = make_builtin_scene(name)) return std::move(*scene);
    std::string known;
    for (const std::string& n : builtin_names()) known += (known.empty() ? "builtin:" : ", builtin:") + n;
    throw InputError(spec + ": scene: unknown built-in scene '" + name + "' (known: " + known + ")");
  }
  // glTF only: a file of another format would otherwise reach the JSON parser ("parse error at line 1").
  const std::string ext = std::filesystem::path(spec).extension().string();
  std::string lower;
  for (char c : ext) lower += char(std::tolower(static_cast<unsigned char>(c)));
  if (lower != ".gltf" && lower != ".glb") {
    throw InputError(spec + ": scene: unsupported format '" + (ext.empty() ? std::string("(no extension)") : ext) +
                     "' (hybridprof reads glTF 2.0: .gltf or .glb, or builtin:NAME)");
  }
  return load_gltf(spec);
}

std::vector<std::string> builtin_scene_names() { return builtin_names(); }

}  // namespace hp
