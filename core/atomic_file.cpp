#include "atomic_file.hpp"

#include "error.hpp"
#include "output_path.hpp"

#include <cerrno>
#include <cstring>
#include <unistd.h>

namespace hp {

namespace fs = std::filesystem;

namespace {

fs::path temporary_beside(const fs::path& path) {
  // Appended piece by piece, not "." + a + b: GCC 12's -Wrestrict misfires on that (PR 105651).
  std::string name = ".";
  name += path.stem().string();
  name += '.';
  name += std::to_string(::getpid());
  name += ".tmp";
  name += path.extension().string();
  return path.parent_path() / name;
}

}  // namespace

AtomicFile::AtomicFile(fs::path path, const std::string& what, bool create_folders) : path_(std::move(path)) {
  check_output_path(path_, what, /*parent_must_exist=*/!create_folders);
  temp_ = temporary_beside(path_);
  if (create_folders && path_.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(path_.parent_path(), ec);
    if (ec) throw InputError(path_.string() + ": cannot create the folder: " + ec.message());
  }
}

AtomicFile::~AtomicFile() {
  if (committed_) return;
  if (out_.is_open()) out_.close();
  std::error_code ignore;
  fs::remove(temp_, ignore);
}

std::ostream& AtomicFile::stream() {
  if (!out_.is_open()) {
    out_.open(temp_, std::ios::binary | std::ios::trunc);
    if (!out_) throw InputError(path_.string() + ": cannot write: " + std::strerror(errno));
  }
  return out_;
}

void AtomicFile::commit() {
  std::error_code ignore;
  if (out_.is_open()) {
    out_.close();
    if (!out_) {
      fs::remove(temp_, ignore);
      throw InputError(path_.string() + ": write failed (disk full?)");
    }
  }
  std::error_code ec;
  fs::rename(temp_, path_, ec);
  if (ec) {
    fs::remove(temp_, ignore);
    throw InputError(path_.string() + ": cannot rename into place: " + ec.message());
  }
  committed_ = true;
}

bool atomic_temporary_exists(const fs::path& path) {
  std::string prefix = ".";
  prefix += path.stem().string();
  prefix += '.';
  std::string suffix = ".tmp";
  suffix += path.extension().string();
  std::error_code ec;
  const fs::path folder = path.has_parent_path() ? path.parent_path() : fs::path(".");
  for (const fs::directory_entry& e : fs::directory_iterator(folder, ec)) {
    const std::string name = e.path().filename().string();
    if (name.starts_with(prefix) && name.ends_with(suffix)) return true;
  }
  return false;
}

void write_file_atomically(const fs::path& path, std::string_view content, const std::string& what) {
  AtomicFile file(path, what);
  file.stream().write(content.data(), static_cast<std::streamsize>(content.size()));
  file.commit();
}

}  // namespace hp
