// A test process's own scratch folder under the system's temporary folder: named after the process (ctest
// runs tests of one binary side by side, each in its own process), (re)created on every call and removed
// with everything in it when the process exits, so a test run leaves nothing behind.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace hp::test {

inline const std::filesystem::path& scratch_dir() {
  static const struct Dir {
    std::filesystem::path path = std::filesystem::temp_directory_path() / ("hp_tests_" + std::to_string(::getpid()));
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  } dir;
  std::filesystem::create_directories(dir.path);
  return dir.path;
}

}  // namespace hp::test
