#include "bvh/ray_io.hpp"

#include "atomic_file.hpp"
#include "error.hpp"

#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

namespace hp::bvh {
namespace {

// The records are written as the in-memory structs (packed 32-bit fields, static_asserted in geometry.hpp),
// which is the file's byte order only on a little-endian machine.
static_assert(std::endian::native == std::endian::little, "ray_io assumes a little-endian host");

template <class T>
std::vector<T> read_records(const std::string& path, const char* what) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(path + ": cannot read " + what + " file: " + ec.message());
  if (size % sizeof(T) != 0) {
    throw InputError(path + ": size " + std::to_string(size) + " bytes is not a multiple of the " +
                     std::to_string(sizeof(T)) + "-byte " + what + " record");
  }
  std::vector<T> out(size / sizeof(T));
  std::ifstream in(path, std::ios::binary);
  if (!in || !in.read(reinterpret_cast<char*>(out.data()), static_cast<std::streamsize>(size))) {
    throw InputError(path + ": cannot read " + what + " file");
  }
  return out;
}

template <class T>
void write_records(const std::string& path, std::span<const T> records, const char* what) {
  AtomicFile file(path, std::string(what) + " file");
  file.stream().write(reinterpret_cast<const char*>(records.data()),
                      static_cast<std::streamsize>(records.size_bytes()));
  file.commit();
}

}  // namespace

void write_triangles(const std::string& path, std::span<const Triangle> triangles) {
  write_records(path, triangles, "triangle");
}
std::vector<Triangle> read_triangles(const std::string& path) { return read_records<Triangle>(path, "triangle"); }

void write_rays(const std::string& path, std::span<const Ray> rays) { write_records(path, rays, "ray"); }
std::vector<Ray> read_rays(const std::string& path) { return read_records<Ray>(path, "ray"); }

void write_hits(const std::string& path, std::span<const Hit> hits) { write_records(path, hits, "hit"); }
std::vector<Hit> read_hits(const std::string& path) { return read_records<Hit>(path, "hit"); }

}  // namespace hp::bvh
