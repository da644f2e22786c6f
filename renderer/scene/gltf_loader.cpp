#include "scene/gltf_loader.hpp"

#include "error.hpp"
#include "json_depth.hpp"

#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string_view>

namespace hp {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

/// Several messages (tinygltf's, nlohmann's) span lines; the contract is one line per error.
std::string one_line(std::string_view text) {
  std::string out;
  for (char c : text) {
    if (c == '\n' || c == '\r') {
      if (!out.empty() && out.back() != ' ' && !out.ends_with("; ")) out += "; ";
    } else if ((c >= 0 && c < 0x20) || c == 0x7f) {
      out += '?';  // parser messages quote raw input bytes; keep the terminal sane
    } else {
      out += c;
    }
  }
  while (!out.empty() && (out.back() == ' ' || out.back() == ';')) out.pop_back();
  return out;
}

[[noreturn]] void fail(const std::string& file, const std::string& field, const std::string& reason) {
  throw InputError(one_line(file + ": " + field + ": " + reason));
}

std::string idx(const char* array, std::size_t i) { return std::string(array) + "[" + std::to_string(i) + "]"; }

// ---------------------------------------------------------------------------------------------------------
// Reading the file and checking the container before tinygltf sees it: tinygltf reports these with
// multi-line strings that do not name the field, and trusts indices in places (it would read out of bounds).

std::vector<unsigned char> read_bytes(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) fail(path, "file", "no such file");
  if (fs::is_directory(path, ec)) fail(path, "file", "is a directory, not a .gltf or .glb file");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "file", "cannot be opened for reading");
  std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) fail(path, "file", "read error");
  return bytes;
}

uint32_t read_u32(const std::vector<unsigned char>& b, std::size_t at) {
  uint32_t v;
  std::memcpy(&v, b.data() + at, 4);  // GLB is little-endian, like every platform this builds for
  return v;
}

/// Validates the GLB container and returns its JSON chunk.
std::string_view glb_json_chunk(const std::string& path, const std::vector<unsigned char>& b) {
  constexpr uint32_t kMagic = 0x46546C67, kJson = 0x4E4F534A, kBin = 0x004E4942;
  if (b.size() < 12) fail(path, "GLB header", "file is " + std::to_string(b.size()) + " bytes, a header needs 12");
  if (read_u32(b, 0) != kMagic) fail(path, "GLB header.magic", "not 'glTF'");
  if (const uint32_t v = read_u32(b, 4); v != 2) fail(path, "GLB header.version", std::to_string(v) + ", expected 2");
  if (const uint32_t len = read_u32(b, 8); len != b.size())
    fail(path, "GLB header.length", std::to_string(len) + " does not match the file size " + std::to_string(b.size()));
  if (b.size() < 20) fail(path, "GLB chunks[0]", "missing (the JSON chunk must follow the header)");
  const uint32_t json_len = read_u32(b, 12);
  if (read_u32(b, 16) != kJson) fail(path, "GLB chunks[0].chunkType", "not JSON");
  if (std::size_t(json_len) > b.size() - 20)
    fail(path, "GLB chunks[0].chunkLength",
         std::to_string(json_len) + " runs past the end of the file (" + std::to_string(b.size() - 20) +
             " bytes left)");
  const std::size_t bin_at = 20 + std::size_t(json_len);
  if (b.size() - bin_at >= 8) {
    const uint32_t bin_len = read_u32(b, bin_at);
    if (read_u32(b, bin_at + 4) == kBin && std::size_t(bin_len) > b.size() - bin_at - 8)
      fail(path, "GLB chunks[1].chunkLength",
           std::to_string(bin_len) + " runs past the end of the file (" + std::to_string(b.size() - bin_at - 8) +
               " bytes left)");
  }
  return {reinterpret_cast<const char*>(b.data()) + 20, json_len};
}

/// Percent-decoding for relative buffer URIs ("my%20model.bin").
std::string decode_uri(const std::string& uri) {
  std::string out;
  for (std::size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
        std::isxdigit(static_cast<unsigned char>(uri[i + 2]))) {
      out += static_cast<char>(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

/// Every index from one glTF object into another, checked on the JSON so that the error names the exact
/// field. tinygltf checks some of these too, but not all, and without saying where.
class ReferenceChecker {
 public:
  ReferenceChecker(const std::string& path, const json& root) : path_(path), root_(root) {}

  void run() {
    if (!root_.is_object()) fail(path_, "JSON", "the top level is not an object");
    ref(root_, "scene", "scene", "scenes");
    each("scenes", [&](const json& s, const std::string& f) { refs(s, "nodes", f + ".nodes", "nodes"); });
    // tinygltf drops a field of the wrong type without a word (a rotation of "abc" became the identity,
    // a byteOffset of -100 was read as 0): the fields this loader uses are type-checked here.
    if (const auto a = root_.find("asset"); a != root_.end()) {
      if (!a->is_object()) fail(path_, "asset", "expected an object");
      const auto v = a->find("version");
      if (v == a->end() || !v->is_string()) fail(path_, "asset.version", "missing or not a string");
      if (!v->get<std::string>().starts_with("2.")) {
        fail(path_, "asset.version", "'" + v->get<std::string>() + "': only glTF 2.x is supported");
      }
    }
    each("nodes", [&](const json& n, const std::string& f) {
      for (const char* k : {"matrix", "translation", "rotation", "scale"}) numbers(n, k, f);
    });
    each("bufferViews", [&](const json& v, const std::string& f) {
      for (const char* k : {"byteOffset", "byteLength", "byteStride"}) count(v, k, f);
    });
    each("accessors", [&](const json& a, const std::string& f) {
      for (const char* k : {"byteOffset", "count", "componentType"}) count(a, k, f);
    });
    each("materials", [&](const json& m, const std::string& f) {
      if (const auto p = m.find("pbrMetallicRoughness"); p != m.end()) {
        if (!p->is_object()) fail(path_, f + ".pbrMetallicRoughness", "expected an object");
        numbers(*p, "baseColorFactor", f + ".pbrMetallicRoughness");
        for (const char* k : {"metallicFactor", "roughnessFactor"}) number(*p, k, f + ".pbrMetallicRoughness");
      }
      numbers(m, "emissiveFactor", f);
    });
    each("nodes", [&](const json& n, const std::string& f) {
      refs(n, "children", f + ".children", "nodes");
      ref(n, "mesh", f + ".mesh", "meshes");
      ref(n, "camera", f + ".camera", "cameras");
      ref(n, "skin", f + ".skin", "skins");
    });
    each("meshes", [&](const json& m, const std::string& f) {
      const auto prims = m.find("primitives");
      if (prims == m.end() || !prims->is_array()) return;  // tinygltf reports a missing "primitives"
      for (std::size_t p = 0; p < prims->size(); ++p) {
        const json& prim = (*prims)[p];
        const std::string pf = f + ".primitives[" + std::to_string(p) + "]";
        if (!prim.is_object()) continue;
        ref(prim, "indices", pf + ".indices", "accessors");
        ref(prim, "material", pf + ".material", "materials");
        if (const auto a = prim.find("attributes"); a != prim.end() && a->is_object())
          for (const auto& [name, value] : a->items()) check(value, pf + ".attributes." + name, "accessors");
        if (const auto t = prim.find("targets"); t != prim.end() && t->is_array())
          for (std::size_t k = 0; k < t->size(); ++k)
            if ((*t)[k].is_object())
              for (const auto& [name, value] : (*t)[k].items())
                check(value, pf + ".targets[" + std::to_string(k) + "]." + name, "accessors");
      }
    });
    each("accessors", [&](const json& a, const std::string& f) {
      ref(a, "bufferView", f + ".bufferView", "bufferViews");
      if (const auto s = a.find("sparse"); s != a.end() && s->is_object()) {
        if (const auto i = s->find("indices"); i != s->end())
          ref(*i, "bufferView", f + ".sparse.indices.bufferView", "bufferViews");
        if (const auto v = s->find("values"); v != s->end())
          ref(*v, "bufferView", f + ".sparse.values.bufferView", "bufferViews");
      }
    });
    each("bufferViews", [&](const json& v, const std::string& f) { ref(v, "buffer", f + ".buffer", "buffers"); });
    each("textures", [&](const json& t, const std::string& f) { ref(t, "source", f + ".source", "images"); });
    each("images",
         [&](const json& im, const std::string& f) { ref(im, "bufferView", f + ".bufferView", "bufferViews"); });
  }

 private:
  std::size_t size_of(const char* array) const {
    const auto it = root_.find(array);
    return it != root_.end() && it->is_array() ? it->size() : 0;
  }
  template <class F>
  void each(const char* array, F&& f) const {
    const auto it = root_.find(array);
    if (it == root_.end()) return;
    if (!it->is_array()) fail(path_, array, "expected an array");
    for (std::size_t i = 0; i < it->size(); ++i)
      if ((*it)[i].is_object()) f((*it)[i], idx(array, i));
  }
  void check(const json& value, const std::string& field, const char* target) const {
    if (!value.is_number_integer()) fail(path_, field, "expected an index into " + std::string(target));
    const std::size_t n = size_of(target);
    const auto i = value.get<int64_t>();
    if (i < 0 || static_cast<uint64_t>(i) >= n)
      fail(path_, field,
           "index " + std::to_string(i) + " out of range (" + target + " has " + std::to_string(n) + " entries)");
  }
  void numbers(const json& obj, const char* key, const std::string& f) const {
    const auto it = obj.find(key);
    if (it == obj.end()) return;
    if (!it->is_array() || !std::all_of(it->begin(), it->end(), [](const json& x) { return x.is_number(); }))
      fail(path_, f + "." + key, "expected an array of numbers");
  }
  void number(const json& obj, const char* key, const std::string& f) const {
    if (const auto it = obj.find(key); it != obj.end() && !it->is_number())
      fail(path_, f + "." + key, "expected a number");
  }
  void count(const json& obj, const char* key, const std::string& f) const {
    const auto it = obj.find(key);
    if (it == obj.end() || it->is_number_unsigned()) return;
    // JSON Schema counts 0.0 as an integer: a whole, non-negative float is one too.
    if (it->is_number_float()) {
      const double v = it->get<double>();
      if (v >= 0.0 && v == std::floor(v)) return;
    }
    fail(path_, f + "." + key, "expected a non-negative integer, got " + it->dump());
  }
  void ref(const json& obj, const char* key, const std::string& field, const char* target) const {
    if (const auto it = obj.find(key); it != obj.end()) check(*it, field, target);
  }
  void refs(const json& obj, const char* key, const std::string& field, const char* target) const {
    const auto it = obj.find(key);
    if (it == obj.end()) return;
    if (!it->is_array()) fail(path_, field, "expected an array of indices");
    for (std::size_t i = 0; i < it->size(); ++i) check((*it)[i], field + "[" + std::to_string(i) + "]", target);
  }

  const std::string& path_;
  const json& root_;
};

/// tinygltf's own FileExists accepts a directory (or a FIFO, a device), and its ReadWholeFile then sizes its
/// buffer by tellg(), which is 2^63 - 1 for a directory on ext4 and overlayfs: a buffer or image URI of "."
/// asked for an 8 EiB allocation. Only regular files exist for tinygltf; a missing image stays a warning.
bool regular_file_exists(const std::string& path, void*) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

/// Textures are never decoded: the renderer uses material factors only. Accepting every image also means
/// a referenced image file that is missing (the shared scenes ship without textures) is not an error.
bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;
}

/// Required extensions the loader can honour: all of them only change how textures are stored or
/// add shading the factors do not cover, never the geometry.
bool extension_supported(const std::string& name) {
  static const char* const kSupported[] = {"KHR_texture_transform", "KHR_texture_basisu", "EXT_texture_webp",
                                           "KHR_materials_emissive_strength", "KHR_materials_unlit"};
  return std::any_of(std::begin(kSupported), std::end(kSupported), [&](const char* s) { return name == s; });
}

// ---------------------------------------------------------------------------------------------------------
// Accessors: every one is bounds-checked against its bufferView and buffer before a byte is read.

struct AccessorView {
  const unsigned char* data = nullptr;  ///< null: no bufferView, all elements are zero (glTF 3.6.2.4)
  std::size_t stride = 0;
  std::size_t count = 0;
};

int component_size(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

int component_count(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    case TINYGLTF_TYPE_MAT2: return 4;
    case TINYGLTF_TYPE_MAT3: return 9;
    case TINYGLTF_TYPE_MAT4: return 16;
    default: return 0;
  }
}

const char* type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT2: return "MAT2";
    case TINYGLTF_TYPE_MAT3: return "MAT3";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
    default: return "unknown";
  }
}

const char* component_name(int ct) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT: return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return "FLOAT";
    default: return "unknown";
  }
}

class Converter {
 public:
  Converter(const std::string& path, const tinygltf::Model& model) : path_(path), model_(model) {}

  Scene run() {
    Scene scene;
    scene.name = path_;
    for (std::size_t i = 0; i < model_.extensionsRequired.size(); ++i) {
      const std::string& ext = model_.extensionsRequired[i];
      if (!extension_supported(ext))
        fail(path_, idx("extensionsRequired", i), "unsupported required extension '" + ext + "'");
    }
    convert_materials(scene);
    mesh_cache_.assign(model_.meshes.size(), std::nullopt);

    std::vector<int> roots;
    std::string where;
    if (model_.defaultScene >= 0) {
      if (std::size_t(model_.defaultScene) >= model_.scenes.size())
        fail(path_, "scene", "index " + std::to_string(model_.defaultScene) + " out of range");
      roots = model_.scenes[model_.defaultScene].nodes;
      where = idx("scenes", model_.defaultScene);
    } else {
      // No default scene: every node that is nobody's child is a root (glTF leaves the choice to the
      // client; showing everything beats showing nothing).
      std::vector<char> is_child(model_.nodes.size(), 0);
      for (const auto& n : model_.nodes)
        for (int c : n.children)
          if (c >= 0 && std::size_t(c) < is_child.size()) is_child[c] = 1;
      for (std::size_t i = 0; i < model_.nodes.size(); ++i)
        if (!is_child[i]) roots.push_back(static_cast<int>(i));
      where = "nodes";
    }
    traverse(scene, roots, where);

    if (triangle_count(scene) == 0) fail(path_, where, "the scene has no triangles");
    return scene;
  }

 private:
  void convert_materials(Scene& scene) {
    for (std::size_t i = 0; i < model_.materials.size(); ++i) {
      const auto& src = model_.materials[i];
      const auto& pbr = src.pbrMetallicRoughness;
      const std::string f = idx("materials", i) + ".pbrMetallicRoughness";
      Material m;
      m.name = src.name.empty() ? idx("materials", i) : src.name;
      if (pbr.baseColorFactor.size() != 4)
        fail(path_, f + ".baseColorFactor", "expected 4 numbers, got " + std::to_string(pbr.baseColorFactor.size()));
      for (int c = 0; c < 3; ++c) m.base_color[c] = unit_factor(pbr.baseColorFactor[c], f + ".baseColorFactor");
      m.metallic = unit_factor(pbr.metallicFactor, f + ".metallicFactor");
      m.roughness = unit_factor(pbr.roughnessFactor, f + ".roughnessFactor");
      scene.materials.push_back(std::move(m));
    }
  }

  float unit_factor(double v, const std::string& field) const {
    if (!std::isfinite(v)) fail(path_, field, "not a finite number");
    // The spec requires [0, 1]; slightly out-of-range exporters exist, and clamping is what viewers do.
    return static_cast<float>(std::clamp(v, 0.0, 1.0));
  }

  uint32_t default_material(Scene& scene) {
    if (!default_material_) {
      // Not the spec's default (white, fully metallic, fully rough), which renders black under a sky-only
      // ambient; the header's neutral grey dielectric reads better for a profiler's images.
      Material m;
      m.name = "default";
      scene.materials.push_back(m);
      default_material_ = static_cast<uint32_t>(scene.materials.size() - 1);
    }
    return *default_material_;
  }

  glm::dmat4 local_transform(std::size_t n) const {
    const auto& node = model_.nodes[n];
    const std::string f = idx("nodes", n);
    auto check = [&](const std::vector<double>& v, std::size_t want, const char* key) {
      if (!v.empty() && v.size() != want)
        fail(path_, f + "." + key, "expected " + std::to_string(want) + " numbers, got " + std::to_string(v.size()));
      for (double x : v)
        if (!std::isfinite(x)) fail(path_, f + "." + key, "not a finite number");
    };
    check(node.matrix, 16, "matrix");
    check(node.translation, 3, "translation");
    check(node.rotation, 4, "rotation");
    check(node.scale, 3, "scale");
    if (!node.matrix.empty()) return glm::make_mat4(node.matrix.data());  // column-major, as glTF stores it
    glm::dmat4 m(1.0);
    if (!node.translation.empty())
      m[3] = glm::dvec4(node.translation[0], node.translation[1], node.translation[2], 1.0);
    if (!node.rotation.empty()) {
      // glTF stores x, y, z, w; glm's constructor takes w first.
      glm::dquat q(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
      const double len = glm::length(q);
      if (!(len > 0.0)) fail(path_, f + ".rotation", "zero quaternion");
      m = m * glm::mat4_cast(q / len);
    }
    if (!node.scale.empty())
      m = m * glm::scale(glm::dmat4(1.0), glm::dvec3(node.scale[0], node.scale[1], node.scale[2]));
    return m;
  }

  void traverse(Scene& scene, const std::vector<int>& roots, const std::string& where) {
    // Iterative, so a deep hierarchy cannot overflow the stack; `seen` turns a cycle (or a node with two
    // parents, which glTF forbids too) into an error instead of an endless loop.
    std::vector<char> seen(model_.nodes.size(), 0);
    struct Item {
      int node;
      glm::dmat4 parent;
    };
    std::vector<Item> stack;
    for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.push_back({*it, glm::dmat4(1.0)});
    while (!stack.empty()) {
      const Item item = stack.back();
      stack.pop_back();
      if (item.node < 0 || std::size_t(item.node) >= model_.nodes.size())
        fail(path_, where, "node index " + std::to_string(item.node) + " out of range");
      if (seen[item.node]) fail(path_, idx("nodes", item.node), "reached twice: the node hierarchy is not a tree");
      seen[item.node] = 1;
      const auto& node = model_.nodes[item.node];
      const glm::dmat4 world = item.parent * local_transform(item.node);
      if (node.mesh >= 0) {
        if (std::size_t(node.mesh) >= model_.meshes.size())
          fail(path_, idx("nodes", item.node) + ".mesh", "index " + std::to_string(node.mesh) + " out of range");
        for (uint32_t mesh : meshes_of(scene, node.mesh)) {
          check_world_bounds(scene.meshes[mesh], mesh, world, idx("nodes", item.node));
          scene.instances.push_back(Instance{mesh, glm::mat4(world)});
        }
      }
      for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.push_back({*c, world});
    }
  }

  /// World positions past +-1e18 (a scale of 1e300, a translation of 1e38) overflow the BVH's surface areas
  /// (float) or the positions themselves: the node that puts them there is named instead of building a tree
  /// of NaN costs. The mesh's bounding box corners are transformed in double.
  void check_world_bounds(const Mesh& mesh, uint32_t mesh_index, const glm::dmat4& world, const std::string& node) {
    constexpr double kLimit = 1e18;
    if (mesh.positions.empty()) return;
    // The mesh's box once per mesh, however many nodes instance it.
    auto [box, fresh] = mesh_bounds_.try_emplace(mesh_index);
    if (fresh) {
      box->second = {glm::dvec3(mesh.positions[0]), glm::dvec3(mesh.positions[0])};
      for (const glm::vec3& p : mesh.positions) {
        box->second.first = glm::min(box->second.first, glm::dvec3(p));
        box->second.second = glm::max(box->second.second, glm::dvec3(p));
      }
    }
    const glm::dvec3 lo = box->second.first, hi = box->second.second;
    for (int c = 0; c < 8; ++c) {
      const glm::dvec3 corner((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
      const glm::dvec4 w = world * glm::dvec4(corner, 1.0);
      for (int k = 0; k < 3; ++k) {
        if (!(std::abs(w[k]) <= kLimit)) {
          char at[32];
          std::snprintf(at, sizeof at, "%.3g", w[k]);
          fail(path_, node,
               "its world transform puts mesh '" + mesh.name + "' at " + at + " (positions must stay within +-1e18)");
        }
      }
    }
  }

  /// The hp meshes of one glTF mesh (one per triangle primitive), converted on first use.
  const std::vector<uint32_t>& meshes_of(Scene& scene, int mesh) {
    auto& cached = mesh_cache_[mesh];
    if (cached) return *cached;
    cached.emplace();
    const auto& src = model_.meshes[mesh];
    for (std::size_t p = 0; p < src.primitives.size(); ++p) {
      const std::string f = idx("meshes", mesh) + ".primitives[" + std::to_string(p) + "]";
      std::optional<Mesh> m = convert_primitive(scene, src.primitives[p], f);
      if (!m) continue;
      m->name = (src.name.empty() ? idx("meshes", mesh) : src.name) + "/" + std::to_string(p);
      scene.meshes.push_back(std::move(*m));
      cached->push_back(static_cast<uint32_t>(scene.meshes.size() - 1));
    }
    return *cached;
  }

  AccessorView view(int accessor, const std::string& field, int want_type, std::initializer_list<int> want_ct) const {
    if (accessor < 0 || std::size_t(accessor) >= model_.accessors.size())
      fail(path_, field,
           "accessor index " + std::to_string(accessor) + " out of range (accessors has " +
               std::to_string(model_.accessors.size()) + " entries)");
    const auto& acc = model_.accessors[accessor];
    const std::string af = idx("accessors", accessor);
    if (acc.type != want_type || std::find(want_ct.begin(), want_ct.end(), acc.componentType) == want_ct.end()) {
      std::string want;
      for (int ct : want_ct) want += std::string(want.empty() ? "" : " or ") + component_name(ct);
      fail(path_, field,
           af + " is " + type_name(acc.type) + " of " + component_name(acc.componentType) + ", expected " +
               type_name(want_type) + " of " + want);
    }
    if (acc.sparse.isSparse) fail(path_, field, af + " is sparse, which is not supported");
    const std::size_t elem = std::size_t(component_size(acc.componentType)) * component_count(acc.type);
    AccessorView v;
    v.count = acc.count;
    v.stride = elem;
    if (acc.count == 0) return v;
    if (acc.bufferView < 0) {
      // No bufferView means all zeros (glTF 3.6.2.4): nothing bounds the count, so cap it before allocating.
      constexpr std::size_t kMaxImplicit = std::size_t(1) << 24;
      if (acc.count > kMaxImplicit)
        fail(path_, field,
             af + " has no bufferView and " + std::to_string(acc.count) + " elements (at most " +
                 std::to_string(kMaxImplicit) + " implicit zeros are accepted)");
      return v;
    }
    if (std::size_t(acc.bufferView) >= model_.bufferViews.size())
      fail(path_, af + ".bufferView", "index " + std::to_string(acc.bufferView) + " out of range");
    const auto& bv = model_.bufferViews[acc.bufferView];
    const std::string bf = idx("bufferViews", acc.bufferView);
    if (bv.buffer < 0 || std::size_t(bv.buffer) >= model_.buffers.size())
      fail(path_, bf + ".buffer", "index " + std::to_string(bv.buffer) + " out of range");
    const auto& buf = model_.buffers[bv.buffer];
    std::size_t view_end;
    if (__builtin_add_overflow(bv.byteOffset, bv.byteLength, &view_end) || view_end > buf.data.size())
      fail(path_, bf,
           "byteOffset " + std::to_string(bv.byteOffset) + " + byteLength " + std::to_string(bv.byteLength) +
               " runs past the end of " + idx("buffers", bv.buffer) + " (" + std::to_string(buf.data.size()) +
               " bytes)");
    if (bv.byteStride != 0) {
      if (bv.byteStride < elem)
        fail(path_, bf + ".byteStride",
             std::to_string(bv.byteStride) + " is smaller than an element of " + af + " (" + std::to_string(elem) +
                 " bytes)");
      v.stride = bv.byteStride;
    }
    // Last byte read: byteOffset + stride * (count - 1) + elem, which must fit in the view.
    std::size_t need;
    if (__builtin_mul_overflow(v.stride, acc.count - 1, &need) || __builtin_add_overflow(need, elem, &need) ||
        __builtin_add_overflow(need, acc.byteOffset, &need) || need > bv.byteLength)
      fail(path_, field,
           af + " (" + std::to_string(acc.count) + " x " + std::to_string(elem) + " bytes at byteOffset " +
               std::to_string(acc.byteOffset) + ", stride " + std::to_string(v.stride) + ") runs past the end of " +
               bf + " (" + std::to_string(bv.byteLength) + " bytes)");
    v.data = buf.data.data() + bv.byteOffset + acc.byteOffset;
    return v;
  }

  std::vector<glm::vec3> read_vec3(const AccessorView& v) const {
    std::vector<glm::vec3> out(v.count, glm::vec3(0.0f));
    if (v.data)
      for (std::size_t i = 0; i < v.count; ++i) std::memcpy(&out[i], v.data + i * v.stride, sizeof(glm::vec3));
    return out;
  }

  std::optional<Mesh> convert_primitive(Scene& scene, const tinygltf::Primitive& prim, const std::string& f) {
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES) {
      static const char* const kModes[] = {"POINTS",    "LINES",          "LINE_LOOP",   "LINE_STRIP",
                                           "TRIANGLES", "TRIANGLE_STRIP", "TRIANGLE_FAN"};
      std::cerr << "warning: " << path_ << ": " << f << ".mode: " << mode << " ("
                << (mode >= 0 && mode <= 6 ? kModes[mode] : "unknown") << ") is not TRIANGLES; primitive skipped\n";
      return std::nullopt;
    }
    const auto pos_it = prim.attributes.find("POSITION");
    if (pos_it == prim.attributes.end()) fail(path_, f + ".attributes.POSITION", "missing");
    const std::string pf = f + ".attributes.POSITION";
    Mesh m;
    m.positions = read_vec3(view(pos_it->second, pf, TINYGLTF_TYPE_VEC3, {TINYGLTF_COMPONENT_TYPE_FLOAT}));
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
      const glm::vec3& p = m.positions[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        fail(path_, pf,
             idx("accessors", pos_it->second) + " element " + std::to_string(i) + " is " +
                 (std::isnan(p.x) || std::isnan(p.y) || std::isnan(p.z) ? "NaN" : "Inf") + " (" + std::to_string(p.x) +
                 ", " + std::to_string(p.y) + ", " + std::to_string(p.z) + ")");
    }
    const std::size_t vertex_count = m.positions.size();

    if (prim.indices >= 0) {
      const std::string inf = f + ".indices";
      const AccessorView iv = view(prim.indices, inf, TINYGLTF_TYPE_SCALAR,
                                   {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                    TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT});
      const int ct = model_.accessors[prim.indices].componentType;
      m.indices.resize(iv.count, 0);
      if (iv.data) {
        for (std::size_t i = 0; i < iv.count; ++i) {
          const unsigned char* at = iv.data + i * iv.stride;
          if (ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) {
            m.indices[i] = *at;
          } else if (ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
            uint16_t s;
            std::memcpy(&s, at, 2);
            m.indices[i] = s;
          } else {
            std::memcpy(&m.indices[i], at, 4);
          }
        }
      }
      for (std::size_t i = 0; i < m.indices.size(); ++i)
        if (m.indices[i] >= vertex_count)
          fail(path_, inf,
               idx("accessors", prim.indices) + " element " + std::to_string(i) + " is vertex " +
                   std::to_string(m.indices[i]) + ", but POSITION has " + std::to_string(vertex_count) + " vertices");
    } else {
      if (vertex_count > std::numeric_limits<uint32_t>::max()) fail(path_, pf, "more than 2^32 vertices");
      m.indices.resize(vertex_count);
      for (std::size_t i = 0; i < vertex_count; ++i) m.indices[i] = static_cast<uint32_t>(i);
    }
    if (m.indices.size() % 3 != 0)
      fail(path_, prim.indices >= 0 ? f + ".indices" : pf,
           std::to_string(m.indices.size()) + " vertices is not a whole number of triangles");
    if (m.indices.empty()) return std::nullopt;  // an empty primitive adds nothing; the scene total is checked

    const auto nrm_it = prim.attributes.find("NORMAL");
    if (nrm_it != prim.attributes.end()) {
      const std::string nf = f + ".attributes.NORMAL";
      m.normals = read_vec3(view(nrm_it->second, nf, TINYGLTF_TYPE_VEC3, {TINYGLTF_COMPONENT_TYPE_FLOAT}));
      if (m.normals.size() != vertex_count)
        fail(path_, nf,
             idx("accessors", nrm_it->second) + " has " + std::to_string(m.normals.size()) +
                 " elements, POSITION has " + std::to_string(vertex_count));
    }
    fill_normals(m);

    m.material = prim.material >= 0 ? static_cast<uint32_t>(prim.material) : default_material(scene);
    if (m.material >= scene.materials.size()) fail(path_, f + ".material", "index out of range");
    return m;
  }

  /// Computes area-weighted vertex normals where the file has none, and repairs unusable ones (zero,
  /// NaN) so that downstream code can trust every normal to be unit length.
  static void fill_normals(Mesh& m) {
    const bool have = m.normals.size() == m.positions.size();
    auto usable = [](const glm::vec3& n) {
      const float l = glm::length(n);
      return std::isfinite(l) && l > 1e-12f;
    };
    if (have && std::all_of(m.normals.begin(), m.normals.end(), usable)) {
      for (auto& n : m.normals) n = glm::normalize(n);
      return;
    }
    // The unnormalised cross product is twice the triangle's area times its normal: summing it weights
    // each face by its area.
    std::vector<glm::vec3> computed(m.positions.size(), glm::vec3(0.0f));
    for (std::size_t t = 0; t + 2 < m.indices.size(); t += 3) {
      const uint32_t a = m.indices[t], b = m.indices[t + 1], c = m.indices[t + 2];
      const glm::vec3 n = glm::cross(m.positions[b] - m.positions[a], m.positions[c] - m.positions[a]);
      computed[a] += n;
      computed[b] += n;
      computed[c] += n;
    }
    if (!have) m.normals.assign(m.positions.size(), glm::vec3(0.0f));
    for (std::size_t i = 0; i < m.normals.size(); ++i) {
      if (have && usable(m.normals[i])) {
        m.normals[i] = glm::normalize(m.normals[i]);
      } else {
        m.normals[i] = usable(computed[i]) ? glm::normalize(computed[i]) : glm::vec3(0.0f, 1.0f, 0.0f);
      }
    }
  }

  const std::string& path_;
  const tinygltf::Model& model_;
  std::vector<std::optional<std::vector<uint32_t>>> mesh_cache_;
  std::map<uint32_t, std::pair<glm::dvec3, glm::dvec3>> mesh_bounds_;  ///< hp mesh -> local box (check_world_bounds)
  std::optional<uint32_t> default_material_;
};

bool ends_with_ci(const std::string& s, std::string_view suffix) {
  if (s.size() < suffix.size()) return false;
  return std::equal(suffix.begin(), suffix.end(), s.end() - suffix.size(),
                    [](unsigned char a, unsigned char b) { return std::tolower(a) == std::tolower(b); });
}

}  // namespace

Scene load_gltf(const std::string& path) {
  const std::vector<unsigned char> bytes = read_bytes(path);
  // tinygltf takes the length as unsigned int.
  if (bytes.size() > std::numeric_limits<unsigned int>::max()) fail(path, "file", "larger than 4 GiB");
  const bool binary = ends_with_ci(path, ".glb") || (bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0);
  std::string_view text = binary ? glb_json_chunk(path, bytes)
                                 : std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size());

  check_json_depth(text, path);
  json root;
  try {
    root = json::parse(text);
  } catch (const json::exception& e) {
    // Not only parse_error: a number too large for a double (1e400) is out_of_range.406 (fuzzer find).
    std::string what = e.what();
    // "[json.exception.parse_error.101] parse error at line 3, column 5: ..." -> drop the library's tag.
    if (const auto close = what.find("] "); what.starts_with("[json.exception") && close != std::string::npos)
      what = what.substr(close + 2);
    fail(path, "JSON", what);
  }
  ReferenceChecker(path, root).run();

  const std::string base_dir = fs::path(path).parent_path().string();
  if (const auto buffers = root.find("buffers"); buffers != root.end() && buffers->is_array()) {
    for (std::size_t i = 0; i < buffers->size(); ++i) {
      const json& b = (*buffers)[i];
      if (!b.is_object() || !b.contains("uri") || !b["uri"].is_string()) continue;
      const std::string uri = b["uri"].get<std::string>();
      if (uri.starts_with("data:")) continue;
      const fs::path file = fs::path(base_dir) / decode_uri(uri);
      std::error_code ec;
      const fs::file_status st = fs::status(file, ec);
      if (!fs::exists(st)) fail(path, idx("buffers", i) + ".uri", "'" + uri + "' not found (" + file.string() + ")");
      if (!fs::is_regular_file(st))
        fail(path, idx("buffers", i) + ".uri",
             "'" + uri + "' is " + (fs::is_directory(st) ? "a directory" : "not a regular file") + " (" +
                 file.string() + ")");
    }
  }

  tinygltf::TinyGLTF gltf;
  gltf.SetImageLoader(skip_image, nullptr);
  gltf.SetFsCallbacks(tinygltf::FsCallbacks{regular_file_exists, tinygltf::ExpandFilePath, tinygltf::ReadWholeFile,
                                            tinygltf::WriteWholeFile, nullptr});
  tinygltf::Model model;
  std::string err, warn;  // warnings are only about textures that are not there, which we never need
  const bool ok = binary ? gltf.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(),
                                                     static_cast<unsigned int>(bytes.size()), base_dir)
                         : gltf.LoadASCIIFromString(&model, &err, &warn, text.data(),
                                                    static_cast<unsigned int>(text.size()), base_dir);
  if (!ok) fail(path, "glTF", "tinygltf: " + (err.empty() ? std::string("failed without a message") : err));
  return Converter(path, model).run();
}

}  // namespace hp
