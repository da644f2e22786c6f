// glTF loader fuzz target: the bytes as a .glb and as a .gltf file, each through hp::load_scene.
// Loading either succeeds or throws hp::InputError; any other exception escapes and is a bug (libFuzzer
// reports the abort; the replay driver names the input).
#include <cstddef>
#include <cstdint>

#include "error.hpp"
#include "fuzz_common.hpp"
#include "scene/load.hpp"

namespace {

void load(const std::string& path) {
  try {
    hp::Scene scene = hp::load_scene(path);
    (void)scene;
  } catch (const hp::InputError&) {
    // The expected outcome for nearly every mutated input.
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // The .glb extension selects the binary container, .gltf the JSON one (which also sniffs a "glTF"
  // magic), so the same bytes exercise both parsers. Relative buffer URIs resolve inside the scratch dir.
  load(hp::fuzz::write_input("input.glb", data, size));
  load(hp::fuzz::write_input("input.gltf", data, size));
  return 0;
}
