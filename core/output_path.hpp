// Checks an output path before any work is done for it, so that a command fails at once, with the path
// named, instead of after minutes of rendering or tracing with other outputs already written. AtomicFile
// calls it too: it writes a temporary beside PATH and renames it over PATH, which would replace a device
// node such as /dev/null (as root) or fail late on a folder.
#pragma once

#include "error.hpp"

#include <filesystem>
#include <string>

namespace hp {

/// Throws InputError("<what> <path>: ...") when `path` is a folder or an existing non-regular file, when its
/// folder does not exist (`parent_must_exist`: no folder is created that was not asked for; false for a
/// writer that makes its own folders, as the runner's cell images), or when its nearest existing ancestor
/// is not a folder. `what` names the option or the kind of file ("--timings").
inline void check_output_path(const std::filesystem::path& path, const std::string& what,
                              bool parent_must_exist = true) {
  namespace fs = std::filesystem;
  const std::string name = (what.empty() ? "" : what + " ") + path.string();
  if (path.empty()) throw InputError(what + ": an empty path");
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (fs::exists(st)) {
    if (fs::is_directory(st)) throw InputError(name + ": is a directory, not a file");
    if (!fs::is_regular_file(st)) {
      throw InputError(name + ": exists and is not a regular file (writing would replace it)");
    }
    return;
  }
  for (fs::path p = path.parent_path(); !p.empty(); p = p.parent_path()) {
    const fs::file_status s = fs::status(p, ec);
    if (fs::exists(s)) {
      if (!fs::is_directory(s)) throw InputError(name + ": " + p.string() + " is not a folder");
      break;
    }
    if (parent_must_exist) throw InputError(name + ": the folder " + p.string() + " does not exist");
    if (p == p.parent_path()) break;
  }
}

}  // namespace hp
