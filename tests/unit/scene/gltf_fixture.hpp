// Writes small glTF files for the loader tests: a valid document that each test bends into one defect.
#pragma once

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

namespace hp::test {

/// A fresh directory per test under the system temp dir, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() / ("hp_scene_" + std::string(info->test_suite_name()) + "_" +
                                                      info->name() + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

inline void write_bytes(const std::string& path, const std::vector<unsigned char>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

/// One buffer under construction: each append is 4-byte aligned, as glTF requires for floats.
struct BufferBuilder {
  std::vector<unsigned char> bytes;

  template <class T>
  std::size_t append(const std::vector<T>& values) {
    while (bytes.size() % 4 != 0) bytes.push_back(0);
    const std::size_t at = bytes.size();
    bytes.resize(at + values.size() * sizeof(T));
    std::memcpy(bytes.data() + at, values.data(), values.size() * sizeof(T));
    return at;
  }
};

/// The base document: one quad (4 vertices, 6 u16 indices) in the z = 0 plane, x and y in [0, 1], one node,
/// one scene. Buffer: indices at byte 0 (12 bytes), positions at byte 12 (48 bytes).
///   accessors[0] = indices (SCALAR u16, 6), accessors[1] = POSITION (VEC3 float, 4)
///   bufferViews[0] = indices, bufferViews[1] = positions, buffers[0] = "quad.bin"
struct QuadGltf {
  std::vector<uint16_t> indices{0, 1, 2, 0, 2, 3};
  std::vector<float> positions{0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  nlohmann::json doc;

  QuadGltf() { rebuild(); }

  /// Re-creates `doc` from `indices` and `positions` (call after changing them).
  void rebuild() {
    BufferBuilder b;
    const std::size_t io = b.append(indices);
    const std::size_t po = b.append(positions);
    bin = b.bytes;
    doc = {
        {"asset", {{"version", "2.0"}}},
        {"scene", 0},
        {"scenes", {{{"nodes", {0}}}}},
        {"nodes", {{{"mesh", 0}}}},
        {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 1}}}, {"indices", 0}}}}}}},
        {"accessors",
         {{{"bufferView", 0}, {"componentType", 5123}, {"count", indices.size()}, {"type", "SCALAR"}},
          {{"bufferView", 1}, {"componentType", 5126}, {"count", positions.size() / 3}, {"type", "VEC3"}}}},
        {"bufferViews",
         {{{"buffer", 0}, {"byteOffset", io}, {"byteLength", indices.size() * 2}},
          {{"buffer", 0}, {"byteOffset", po}, {"byteLength", positions.size() * 4}}}},
        {"buffers", {{{"uri", "quad.bin"}, {"byteLength", bin.size()}}}},
    };
  }

  /// Writes `<dir>/<name>` and the buffer beside it; returns the .gltf path.
  std::string write(const TempDir& dir, const std::string& name = "quad.gltf") const {
    write_bytes(dir.file(doc["buffers"][0].value("uri", "quad.bin")), bin);
    const std::string path = dir.file(name);
    write_text(path, doc.dump(1));
    return path;
  }

  /// The same document as a .glb with the buffer in its BIN chunk.
  std::vector<unsigned char> glb() const {
    nlohmann::json d = doc;
    d["buffers"][0].erase("uri");
    std::string json = d.dump();
    while (json.size() % 4 != 0) json += ' ';
    std::vector<unsigned char> data = bin;
    while (data.size() % 4 != 0) data.push_back(0);
    std::vector<unsigned char> out;
    auto u32 = [&](uint32_t v) {
      for (int i = 0; i < 4; ++i) out.push_back(static_cast<unsigned char>(v >> (8 * i)));
    };
    u32(0x46546C67);  // "glTF"
    u32(2);
    u32(static_cast<uint32_t>(12 + 8 + json.size() + 8 + data.size()));
    u32(static_cast<uint32_t>(json.size()));
    u32(0x4E4F534A);  // "JSON"
    out.insert(out.end(), json.begin(), json.end());
    u32(static_cast<uint32_t>(data.size()));
    u32(0x004E4942);  // "BIN\0"
    out.insert(out.end(), data.begin(), data.end());
    return out;
  }

  std::vector<unsigned char> bin;
};

}  // namespace hp::test
