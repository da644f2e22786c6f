// The binary triangle, ray and hit files: exact round trips, the documented byte layout, clear errors.
#include "atomic_file.hpp"
#include "bvh/ray_io.hpp"
#include "error.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace hp::bvh {
namespace {

std::string temp_path(const char* name) {
  return (std::filesystem::temp_directory_path() /
          (std::string("hp_bvh_io_") + std::to_string(::getpid()) + "_" + name))
      .string();
}

std::vector<unsigned char> bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(BvhRayIo, RoundTripsBitExactly) {
  const std::vector<Triangle> tris{{{1, 2, 3}, {-4, 5.5f, 6}, {7, 8, -0.0f}},
                                   {{1e-30f, 1e30f, 0}, {0, 0, 0}, {1, 1, 1}}};
  std::vector<Ray> rays(3);
  rays[1].origin = glm::vec3(1, -2, 3);
  rays[1].tmin = 0.5f;
  rays[1].dir = glm::vec3(-0.0f, 0.0f, 1.0f);
  rays[1].tmax = 9.0f;
  rays[2].tmax = std::numeric_limits<float>::infinity();
  const std::vector<Hit> hits{{-1, 0, 0, 0}, {12345, 2.5f, 0.25f, 0.5f}};

  const std::string tp = temp_path("t.bin"), rp = temp_path("r.bin"), hp_ = temp_path("h.bin");
  write_triangles(tp, tris);
  write_rays(rp, rays);
  write_hits(hp_, hits);
  const auto t2 = read_triangles(tp);
  const auto r2 = read_rays(rp);
  const auto h2 = read_hits(hp_);
  ASSERT_EQ(t2.size(), tris.size());
  ASSERT_EQ(r2.size(), rays.size());
  ASSERT_EQ(h2.size(), hits.size());
  EXPECT_EQ(std::memcmp(t2.data(), tris.data(), tris.size() * sizeof(Triangle)), 0);
  EXPECT_EQ(std::memcmp(r2.data(), rays.data(), rays.size() * sizeof(Ray)), 0);
  EXPECT_EQ(std::memcmp(h2.data(), hits.data(), hits.size() * sizeof(Hit)), 0);
  EXPECT_TRUE(std::signbit(r2[1].dir.x));

  // The documented layout: sizes without header, fields in order, little-endian.
  const auto tb = bytes_of(tp), rb = bytes_of(rp), hb = bytes_of(hp_);
  EXPECT_EQ(tb.size(), 2u * 36u);
  EXPECT_EQ(rb.size(), 3u * 32u);
  EXPECT_EQ(hb.size(), 2u * 16u);
  // Ray 1: ox = 1.0f = 0x3f800000 at byte 32, tmin = 0.5f = 0x3f000000 at byte 44, tmax = 9.0f at byte 60.
  EXPECT_EQ(rb[32 + 3], 0x3f);
  EXPECT_EQ(rb[32 + 2], 0x80);
  EXPECT_EQ(rb[44 + 3], 0x3f);
  EXPECT_EQ(rb[44 + 2], 0x00);
  float f;
  std::memcpy(&f, rb.data() + 60, 4);
  EXPECT_EQ(f, 9.0f);
  // Hit 0: prim -1 = ff ff ff ff; hit 1: prim 12345 = 0x3039 little-endian.
  EXPECT_EQ(hb[0], 0xff);
  EXPECT_EQ(hb[16], 0x39);
  EXPECT_EQ(hb[17], 0x30);
  // Triangle 0: v1.y = 5.5f at byte 16.
  std::memcpy(&f, tb.data() + 16, 4);
  EXPECT_EQ(f, 5.5f);

  // No temporary file is left behind.
  EXPECT_FALSE(atomic_temporary_exists(hp_));
  for (const auto& p : {tp, rp, hp_}) std::filesystem::remove(p);
}

TEST(BvhRayIo, EmptyFilesAreEmptyLists) {
  const std::string p = temp_path("empty.bin");
  write_rays(p, {});
  EXPECT_TRUE(read_rays(p).empty());
  std::filesystem::remove(p);
}

/// Expects an InputError whose message is one line that names the file.
template <class F>
void expect_error_naming(const std::string& path, F&& f) {
  try {
    f();
    ADD_FAILURE() << "no error for " << path;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

TEST(BvhRayIo, ErrorsNameTheFile) {
  const std::string missing = temp_path("does_not_exist.bin");
  expect_error_naming(missing, [&] { read_rays(missing); });
  expect_error_naming(missing, [&] { read_triangles(missing); });
  expect_error_naming(missing, [&] { read_hits(missing); });

  const std::string odd = temp_path("odd.bin");
  {
    std::ofstream out(odd, std::ios::binary);
    const char junk[40] = {};
    out.write(junk, sizeof junk);  // 40 bytes: not a multiple of 32 (rays) nor 36 (triangles) nor 16 (hits)
  }
  expect_error_naming(odd, [&] { read_rays(odd); });
  expect_error_naming(odd, [&] { read_triangles(odd); });
  expect_error_naming(odd, [&] { read_hits(odd); });
  std::filesystem::remove(odd);

  const std::string unwritable = "/nonexistent_dir_hp/out.bin";
  expect_error_naming(unwritable, [&] { write_hits(unwritable, {}); });
}

}  // namespace
}  // namespace hp::bvh
