// Reading a whole file a user names (scenario, preset, policy, results, timing result): a missing
// file, a directory or an unreadable file is an InputError naming the path and what was expected, not the
// standard library's "basic_filebuf::underflow" escaping as an internal error.
#pragma once

#include "error.hpp"

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace hp {

/// The bytes of `path`. `what` names the expected kind of file in the errors ("scenario file").
inline std::string read_input_file(const std::filesystem::path& path, const std::string& what) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(st)) throw InputError(path.string() + ": no such " + what);
  if (std::filesystem::is_directory(st)) throw InputError(path.string() + ": is a directory, not a " + what);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open the " + what);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path.string() + ": read error in the " + what);
  return text;
}

}  // namespace hp
