// The glTF loader: valid files (hierarchy, index types, strides, materials, .glb) and one generated file per
// kind of defect, each of which must give a one-line hp::InputError naming the file and the field.
#include "error.hpp"
#include "gltf_fixture.hpp"
#include "scene/load.hpp"

#include <glm/gtc/constants.hpp>
#include <gtest/gtest.h>

#include <functional>

#include <cmath>
#include <limits>

namespace hp {
namespace {

using test::QuadGltf;
using test::TempDir;

/// Loads `path`, expecting an InputError whose single line contains the path, `field` and `reason`.
void expect_input_error(const std::string& path, const std::string& field, const std::string& reason) {
  try {
    (void)load_scene(path);
    ADD_FAILURE() << "no InputError for " << path << " (expected field " << field << ")";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "more than one line: " << msg;
    EXPECT_EQ(msg.find('\r'), std::string::npos) << msg;
    EXPECT_NE(msg.find(path), std::string::npos) << "file not named: " << msg;
    EXPECT_NE(msg.find(field), std::string::npos) << "field '" << field << "' not named: " << msg;
    EXPECT_NE(msg.find(reason), std::string::npos) << "reason '" << reason << "' not given: " << msg;
  }
}

void expect_near(const glm::vec3& a, const glm::vec3& b, float tol = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

TEST(GltfLoader, LoadsTheBaseQuad) {
  TempDir dir;
  QuadGltf q;
  const Scene s = load_scene(q.write(dir));
  ASSERT_EQ(s.meshes.size(), 1u);
  ASSERT_EQ(s.instances.size(), 1u);
  EXPECT_EQ(triangle_count(s), 2u);
  EXPECT_EQ(s.meshes[0].indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
  const Aabb b = world_bounds(s);
  expect_near(b.min, {0, 0, 0});
  expect_near(b.max, {1, 1, 0});
  EXPECT_FALSE(s.has_camera);
  // No NORMAL attribute: computed from the (counter-clockwise, facing +z) triangles.
  ASSERT_EQ(s.meshes[0].normals.size(), 4u);
  for (const glm::vec3& n : s.meshes[0].normals) expect_near(n, {0, 0, 1});
  // No material on the primitive: a default one is added.
  ASSERT_EQ(s.materials.size(), 1u);
  EXPECT_EQ(s.meshes[0].material, 0u);
}

TEST(GltfLoader, NodeHierarchyComposesTranslationRotationScaleParentToChild) {
  TempDir dir;
  QuadGltf q;
  const double h = std::sqrt(0.5);
  // nodes[0]: T(1,2,3) * Ry(90 deg) * S(2), child nodes[1]: T(0,0,1) * S(1,0.5,1) with the quad.
  // nodes[2]: a matrix (column-major) translating by (10,0,0), with the quad too.
  q.doc["nodes"] = {
      {{"translation", {1, 2, 3}}, {"rotation", {0, h, 0, h}}, {"scale", {2, 2, 2}}, {"children", {1}}},
      {{"translation", {0, 0, 1}}, {"scale", {1, 0.5, 1}}, {"mesh", 0}},
      {{"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 10, 0, 0, 1}}, {"mesh", 0}},
  };
  q.doc["scenes"][0]["nodes"] = {0, 2};
  const Scene s = load_scene(q.write(dir));
  ASSERT_EQ(s.instances.size(), 2u);
  EXPECT_EQ(s.meshes.size(), 1u) << "one glTF mesh used twice is one hp mesh instanced twice";
  EXPECT_EQ(triangle_count(s), 4u);

  // By hand: the quad's corner (x, y, 0) -> child (x, y/2, 1) -> S(2) (2x, y, 2) -> Ry(90): (a,b,c) ->
  // (c, b, -a) = (2, y, -2x) -> + (1,2,3) = (3, 2+y, 3-2x): x = 3, y in [2,3], z in [1,3].
  const WorldGeometry g = world_geometry(s);
  expect_near(g.positions[0], {3, 2, 3});
  expect_near(g.positions[1], {3, 2, 1});
  expect_near(g.positions[2], {3, 3, 1});
  expect_near(g.positions[3], {3, 3, 3});
  // The quad faces +z in object space; Ry(90) turns +z into +x.
  for (int v = 0; v < 4; ++v) expect_near(g.normals[v], {1, 0, 0});
  expect_near(g.positions[4], {10, 0, 0});
  expect_near(g.positions[6], {11, 1, 0});

  const Aabb b = world_bounds(s);
  expect_near(b.min, {3, 0, 0});
  expect_near(b.max, {11, 3, 3});
}

TEST(GltfLoader, WithoutDefaultSceneAllRootNodesAreShown) {
  TempDir dir;
  QuadGltf q;
  q.doc["nodes"] = {{{"children", {1}}, {"translation", {0, 5, 0}}},
                    {{"mesh", 0}},
                    {{"mesh", 0}, {"translation", {-4, 0, 0}}}};
  q.doc.erase("scene");
  q.doc.erase("scenes");
  const Scene s = load_scene(q.write(dir));
  ASSERT_EQ(s.instances.size(), 2u) << "roots are nodes 0 and 2; node 1 is a child, not a root";
  const Aabb b = world_bounds(s);
  expect_near(b.min, {-4, 0, 0});
  expect_near(b.max, {1, 6, 0});
}

TEST(GltfLoader, NonTrianglePrimitiveIsSkippedWithOneWarningLine) {
  TempDir dir;
  QuadGltf q;
  auto lines = q.doc["meshes"][0]["primitives"][0];
  lines["mode"] = 1;  // LINES
  q.doc["meshes"][0]["primitives"].push_back(lines);
  const std::string path = q.write(dir);
  testing::internal::CaptureStderr();
  const Scene s = load_scene(path);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(s.meshes.size(), 1u);
  EXPECT_EQ(triangle_count(s), 2u);
  EXPECT_NE(err.find("meshes[0].primitives[1].mode"), std::string::npos) << err;
  EXPECT_NE(err.find("LINES"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
}

TEST(GltfLoader, ReadsInterleavedStridesU8IndicesAndFileNormals) {
  TempDir dir;
  QuadGltf q;
  // Interleaved position + normal, 24-byte stride; normals deliberately not +z (and one unnormalised) so
  // that we can tell file normals from computed ones.
  // clang-format off: two vertices a row
  const std::vector<float> interleaved = {0, 0, 0, 0, 1, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 0, 1, 0, 0, 1, 0};
  // clang-format on
  const std::vector<uint8_t> idx8 = {0, 1, 2, 0, 2, 3};
  test::BufferBuilder b;
  const std::size_t vo = b.append(interleaved);
  const std::size_t io = b.append(idx8);
  q.bin = b.bytes;
  q.doc["buffers"][0]["byteLength"] = q.bin.size();
  q.doc["bufferViews"] = {{{"buffer", 0}, {"byteOffset", io}, {"byteLength", 6}},
                          {{"buffer", 0}, {"byteOffset", vo}, {"byteLength", 96}, {"byteStride", 24}}};
  q.doc["accessors"][0]["componentType"] = 5121;
  q.doc["accessors"][1]["byteOffset"] = 0;
  q.doc["accessors"].push_back(
      {{"bufferView", 1}, {"byteOffset", 12}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}});
  q.doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 2;
  const Scene s = load_scene(q.write(dir));
  const Mesh& m = s.meshes.at(0);
  ASSERT_EQ(m.positions.size(), 4u);
  expect_near(m.positions[2], {1, 1, 0});
  expect_near(m.positions[3], {0, 1, 0});
  for (const glm::vec3& n : m.normals) expect_near(n, {0, 1, 0});
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
}

TEST(GltfLoader, ReadsU32IndicesAndNonIndexedPrimitives) {
  TempDir dir;
  QuadGltf q;
  const std::vector<uint32_t> idx32 = {2, 1, 0};
  test::BufferBuilder b;
  const std::size_t po = b.append(q.positions);
  const std::size_t io = b.append(idx32);
  q.bin = b.bytes;
  q.doc["buffers"][0]["byteLength"] = q.bin.size();
  q.doc["bufferViews"] = {{{"buffer", 0}, {"byteOffset", io}, {"byteLength", 12}},
                          {{"buffer", 0}, {"byteOffset", po}, {"byteLength", 48}}};
  q.doc["accessors"][0] = {{"bufferView", 0}, {"componentType", 5125}, {"count", 3}, {"type", "SCALAR"}};
  // Second primitive: no indices, the first three positions as one triangle.
  q.doc["accessors"].push_back({{"bufferView", 1}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}});
  q.doc["meshes"][0]["primitives"].push_back({{"attributes", {{"POSITION", 2}}}});
  const Scene s = load_scene(q.write(dir));
  ASSERT_EQ(s.meshes.size(), 2u);
  EXPECT_EQ(s.meshes[0].indices, (std::vector<uint32_t>{2, 1, 0}));
  EXPECT_EQ(s.meshes[1].indices, (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_EQ(s.meshes[1].positions.size(), 3u);
  // Reversed winding: the computed normal faces -z.
  expect_near(s.meshes[0].normals[0], {0, 0, -1});
}

TEST(GltfLoader, MaterialFactorsAndDefaultMaterial) {
  TempDir dir;
  QuadGltf q;
  q.doc["materials"] = {{{"name", "paint"},
                         {"pbrMetallicRoughness",
                          {{"baseColorFactor", {0.1, 0.2, 0.3, 1.0}},
                           {"metallicFactor", 0.25},
                           {"roughnessFactor", 0.75},
                           {"baseColorTexture", {{"index", 0}}}}}}};
  // The texture's image is not shipped: a missing image must not be an error.
  q.doc["textures"] = {{{"source", 0}}};
  q.doc["images"] = {{{"uri", "missing_texture.png"}}};
  auto second = q.doc["meshes"][0]["primitives"][0];
  q.doc["meshes"][0]["primitives"][0]["material"] = 0;
  q.doc["meshes"][0]["primitives"].push_back(second);
  const Scene s = load_scene(q.write(dir));
  ASSERT_EQ(s.meshes.size(), 2u);
  ASSERT_EQ(s.materials.size(), 2u);
  const Material& m = s.materials[s.meshes[0].material];
  EXPECT_EQ(m.name, "paint");
  expect_near(m.base_color, {0.1f, 0.2f, 0.3f});
  EXPECT_FLOAT_EQ(m.metallic, 0.25f);
  EXPECT_FLOAT_EQ(m.roughness, 0.75f);
  EXPECT_EQ(s.materials[s.meshes[1].material].name, "default");
}

TEST(GltfLoader, LoadsGlb) {
  TempDir dir;
  QuadGltf q;
  const std::string path = dir.file("quad.glb");
  test::write_bytes(path, q.glb());
  const Scene s = load_scene(path);
  EXPECT_EQ(triangle_count(s), 2u);
  expect_near(world_bounds(s).max, {1, 1, 0});
}

// ---- malformed input: one defect each ------------------------------------------------------------------

TEST(GltfErrors, MissingFile) {
  TempDir dir;
  expect_input_error(dir.file("does_not_exist.gltf"), "file", "no such file");
}

TEST(GltfErrors, BrokenJson) {
  TempDir dir;
  QuadGltf q;
  const std::string path = q.write(dir);
  std::string text = q.doc.dump(1);
  test::write_text(path, text.substr(0, text.size() / 2));  // cut mid-document
  expect_input_error(path, "JSON", "parse error");
}

// Fuzzer find (2026-11-29): a number past a double's range is nlohmann's out_of_range.406, not a
// parse_error, and escaped the loader as a library exception.
TEST(GltfErrors, NumberTooLargeForADouble) {
  TempDir dir;
  QuadGltf q;
  const std::string path = q.write(dir);
  std::string text = q.doc.dump(1);
  text.insert(text.find('{') + 1, "\"extras\": 1e400,");
  test::write_text(path, text);
  expect_input_error(path, "JSON", "number overflow");
}

// Audit find (2026-11-30): 20,000 levels of '[' in `extras` (40 KB) overflowed the stack in tinygltf.
TEST(GltfErrors, DeeplyNestedJsonIsNamedNotACrash) {
  TempDir dir;
  QuadGltf q;
  const std::string path = q.write(dir);
  std::string text = q.doc.dump(1);
  text.insert(text.find('{') + 1, "\"extras\": " + std::string(20000, '[') + std::string(20000, ']') + ",");
  test::write_text(path, text);
  expect_input_error(path, "", "JSON nested deeper than 256 levels");
  // Brackets inside strings do not count, and a legitimately nested `extras` loads.
  text = q.doc.dump(1);
  text.insert(text.find('{') + 1, "\"extras\": {\"s\": \"" + std::string(1000, '[') + "\\\"\", \"a\": [[[[1]]]]},");
  test::write_text(path, text);
  EXPECT_NO_THROW((void)load_scene(path));
}

// Audit finds (2026-11-30): tinygltf drops a field of the wrong type silently, and a huge scale or
// translation gave a BVH of NaN costs and an empty image.
TEST(GltfErrors, WrongTypesAndWorldsOutOfRangeAreNamed) {
  struct Case {
    std::function<void(nlohmann::json&)> edit;
    std::string field, reason;
  };
  const std::vector<Case> cases = {
      {[](nlohmann::json& d) { d["nodes"][0]["rotation"] = "abc"; }, "nodes[0].rotation",
       "expected an array of numbers"},
      {[](nlohmann::json& d) {
         d["nodes"][0]["scale"] = {1, "x", 1};
       },
       "nodes[0].scale", "expected an array of numbers"},
      {[](nlohmann::json& d) { d["bufferViews"][0]["byteOffset"] = -100; }, "bufferViews[0].byteOffset",
       "non-negative integer"},
      {[](nlohmann::json& d) { d["accessors"][0]["count"] = 2.5; }, "accessors[0].count", "non-negative integer"},
      {[](nlohmann::json& d) { d["asset"]["version"] = "1.0"; }, "asset.version", "only glTF 2.x"},
      {[](nlohmann::json& d) {
         d["materials"] = {{{"pbrMetallicRoughness", {{"roughnessFactor", "x"}}}}};
       },
       "materials[0].pbrMetallicRoughness.roughnessFactor", "expected a number"},
      {[](nlohmann::json& d) {
         d["nodes"][0]["scale"] = {1e300, 1e300, 1e300};
       },
       "nodes[0]", "within +-1e18"},
      {[](nlohmann::json& d) {
         d["nodes"][0]["translation"] = {0, 1e38, 0};
       },
       "nodes[0]", "within +-1e18"},
  };
  for (const Case& c : cases) {
    TempDir dir;
    QuadGltf q;
    c.edit(q.doc);
    SCOPED_TRACE(c.field);
    expect_input_error(q.write(dir), c.field, c.reason);
  }
  // A large world that fits (1e6 units from the origin) still loads, and so does a whole number written as
  // a float (JSON Schema's integer).
  TempDir dir;
  QuadGltf q;
  q.doc["nodes"][0]["translation"] = {1e6, 0, 0};
  q.doc["bufferViews"][0]["byteOffset"] = 0.0;
  EXPECT_NO_THROW((void)load_scene(q.write(dir)));
}

TEST(GltfErrors, OutOfRangeAccessorIndex) {
  TempDir dir;
  QuadGltf q;
  q.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 7;
  expect_input_error(q.write(dir), "meshes[0].primitives[0].attributes.POSITION", "out of range");
}

TEST(GltfErrors, OutOfRangeIndicesAccessor) {
  TempDir dir;
  QuadGltf q;
  q.doc["meshes"][0]["primitives"][0]["indices"] = 2;
  expect_input_error(q.write(dir), "meshes[0].primitives[0].indices", "out of range");
}

TEST(GltfErrors, OutOfRangeBufferViewBufferMeshNodeMaterial) {
  {
    TempDir dir;
    QuadGltf q;
    q.doc["accessors"][1]["bufferView"] = 5;
    expect_input_error(q.write(dir), "accessors[1].bufferView", "out of range");
  }
  {
    TempDir dir;
    QuadGltf q;
    q.doc["bufferViews"][0]["buffer"] = 1;
    expect_input_error(q.write(dir), "bufferViews[0].buffer", "out of range");
  }
  {
    TempDir dir;
    QuadGltf q;
    q.doc["nodes"][0]["mesh"] = 3;
    expect_input_error(q.write(dir), "nodes[0].mesh", "out of range");
  }
  {
    TempDir dir;
    QuadGltf q;
    q.doc["scenes"][0]["nodes"] = {0, 4};
    expect_input_error(q.write(dir), "scenes[0].nodes[1]", "out of range");
  }
  {
    TempDir dir;
    QuadGltf q;
    q.doc["meshes"][0]["primitives"][0]["material"] = 0;  // there are no materials
    expect_input_error(q.write(dir), "meshes[0].primitives[0].material", "out of range");
  }
}

TEST(GltfErrors, IndicesPastTheEndOfTheBuffer) {
  TempDir dir;
  QuadGltf q;
  q.doc["accessors"][0]["count"] = 600;
  expect_input_error(q.write(dir), "meshes[0].primitives[0].indices", "runs past the end of bufferViews[0]");
}

TEST(GltfErrors, BufferViewPastTheEndOfTheBuffer) {
  TempDir dir;
  QuadGltf q;
  q.doc["bufferViews"][1]["byteLength"] = 4800;
  expect_input_error(q.write(dir), "bufferViews[1]", "runs past the end of buffers[0]");
}

TEST(GltfErrors, PositionsPastTheEndViaByteOffset) {
  TempDir dir;
  QuadGltf q;
  q.doc["accessors"][1]["byteOffset"] = 4;  // 4 x 12 bytes from byte 4 needs 52 of the view's 48
  expect_input_error(q.write(dir), "meshes[0].primitives[0].attributes.POSITION", "runs past the end");
}

TEST(GltfErrors, VertexIndexOutOfRange) {
  TempDir dir;
  QuadGltf q;
  q.indices = {0, 1, 2, 0, 2, 9};
  q.rebuild();
  expect_input_error(q.write(dir), "meshes[0].primitives[0].indices", "vertex 9");
}

TEST(GltfErrors, NanPosition) {
  TempDir dir;
  QuadGltf q;
  q.positions[4] = std::numeric_limits<float>::quiet_NaN();
  q.rebuild();
  expect_input_error(q.write(dir), "meshes[0].primitives[0].attributes.POSITION", "NaN");
}

TEST(GltfErrors, InfPosition) {
  TempDir dir;
  QuadGltf q;
  q.positions[9] = -std::numeric_limits<float>::infinity();
  q.rebuild();
  expect_input_error(q.write(dir), "meshes[0].primitives[0].attributes.POSITION", "Inf");
}

TEST(GltfErrors, ZeroTriangles) {
  TempDir dir;
  QuadGltf q;
  q.doc["meshes"][0]["primitives"][0]["mode"] = 0;  // POINTS: skipped, leaving nothing
  testing::internal::CaptureStderr();
  expect_input_error(q.write(dir), "scenes[0]", "no triangles");
  (void)testing::internal::GetCapturedStderr();
}

TEST(GltfErrors, ZeroTrianglesWhenNoNodeHasAMesh) {
  TempDir dir;
  QuadGltf q;
  q.doc["nodes"][0].erase("mesh");
  expect_input_error(q.write(dir), "scenes[0]", "no triangles");
}

TEST(GltfErrors, UnsupportedRequiredExtension) {
  TempDir dir;
  QuadGltf q;
  q.doc["extensionsUsed"] = {"KHR_texture_transform", "KHR_draco_mesh_compression"};
  q.doc["extensionsRequired"] = {"KHR_texture_transform", "KHR_draco_mesh_compression"};
  expect_input_error(q.write(dir), "extensionsRequired[1]", "KHR_draco_mesh_compression");
}

TEST(GltfErrors, GlbWithBadMagic) {
  TempDir dir;
  QuadGltf q;
  auto bytes = q.glb();
  bytes[0] = 'X';
  const std::string path = dir.file("bad_magic.glb");
  test::write_bytes(path, bytes);
  expect_input_error(path, "GLB header.magic", "not 'glTF'");
}

TEST(GltfErrors, GlbWithBadLengthAndTruncatedHeader) {
  TempDir dir;
  QuadGltf q;
  auto bytes = q.glb();
  bytes[8] = static_cast<unsigned char>(bytes[8] + 16);  // header.length no longer the file size
  const std::string path = dir.file("bad_length.glb");
  test::write_bytes(path, bytes);
  expect_input_error(path, "GLB header.length", "does not match the file size");

  const std::string tiny = dir.file("tiny.glb");
  test::write_bytes(tiny, {'g', 'l', 'T', 'F', 2, 0});
  expect_input_error(tiny, "GLB header", "a header needs 12");
}

TEST(GltfErrors, GlbWithJsonChunkPastTheEnd) {
  TempDir dir;
  QuadGltf q;
  auto bytes = q.glb();
  bytes[13] = 0x7f;  // chunkLength becomes more than 32,000 bytes, the file has about 700
  const std::string path = dir.file("bad_chunk.glb");
  test::write_bytes(path, bytes);
  expect_input_error(path, "GLB chunks[0].chunkLength", "runs past the end of the file");
}

TEST(GltfErrors, WrongAccessorTypes) {
  {
    TempDir dir;
    QuadGltf q;
    q.doc["accessors"][1]["type"] = "VEC2";
    expect_input_error(q.write(dir), "meshes[0].primitives[0].attributes.POSITION", "expected VEC3 of FLOAT");
  }
  {
    TempDir dir;
    QuadGltf q;
    q.doc["accessors"][0]["componentType"] = 5126;  // float indices
    expect_input_error(q.write(dir), "meshes[0].primitives[0].indices", "expected SCALAR of UNSIGNED_BYTE");
  }
}

TEST(GltfErrors, AccessorWithoutBufferViewAndAHugeCount) {
  TempDir dir;
  QuadGltf q;
  // Without a bufferView an accessor is all zeros, so nothing in the file bounds its count.
  q.doc["accessors"][1].erase("bufferView");
  q.doc["accessors"][1]["count"] = 4000000000ull;
  expect_input_error(q.write(dir), "meshes[0].primitives[0].attributes.POSITION", "no bufferView");
}

TEST(GltfErrors, MissingBufferFile) {
  TempDir dir;
  QuadGltf q;
  const std::string path = q.write(dir);
  std::filesystem::remove(dir.file("quad.bin"));
  expect_input_error(path, "buffers[0].uri", "not found");
}

// Fuzzer find (2026-11-29): tinygltf reads a directory as a file of 2^63 - 1 bytes (its tellg() on ext4 and
// overlayfs), so a buffer URI of "." threw std::bad_alloc (an 8 EiB allocation under ASan).
TEST(GltfErrors, BufferUriThatIsADirectory) {
  TempDir dir;
  QuadGltf q;
  std::filesystem::create_directories(dir.file("sub"));
  for (const char* uri : {".", "sub", "sub/"}) {
    QuadGltf d = q;
    const std::string path = d.write(dir);
    d.doc["buffers"][0]["uri"] = uri;
    test::write_text(path, d.doc.dump(1));
    expect_input_error(path, "buffers[0].uri", "is a directory");
  }
}

TEST(GltfLoader, ImageUriThatIsADirectoryIsAMissingImageNotAnError) {
  TempDir dir;
  QuadGltf q;
  q.doc["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}};
  q.doc["textures"] = {{{"source", 0}}};
  q.doc["images"] = {{{"uri", "."}}};
  q.doc["meshes"][0]["primitives"][0]["material"] = 0;
  EXPECT_EQ(triangle_count(load_scene(q.write(dir))), 2u);
}

TEST(GltfErrors, NodeCycle) {
  TempDir dir;
  QuadGltf q;
  q.doc["nodes"] = {{{"mesh", 0}, {"children", {1}}}, {{"children", {0}}}};
  expect_input_error(q.write(dir), "nodes[0]", "not a tree");
}

TEST(GltfErrors, TinygltfErrorsAreFoldedIntoOneLine) {
  TempDir dir;
  QuadGltf q;
  q.doc["accessors"][1].erase("componentType");  // required: only tinygltf checks this one
  q.doc["accessors"][0].erase("type");
  expect_input_error(q.write(dir), "glTF", "tinygltf");
}

}  // namespace
}  // namespace hp
