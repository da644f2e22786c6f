// A bound on the nesting of JSON a user hands us (scenario files, cache presets, result lines, gate
// policies, glTF). nlohmann::json copies a value recursively and tinygltf converts `extras` recursively, so
// a file of a few hundred kilobytes of '[' would overflow the stack; the text is scanned first instead, in
// one pass without recursion, and a deeper file is an InputError naming it.
#pragma once

#include "error.hpp"

#include <string>
#include <string_view>

namespace hp {

/// Far deeper than any file this project reads legitimately needs (scenarios and presets nest 4 levels,
/// glTF about 6 plus whatever `extras` hold).
inline constexpr int kMaxJsonDepth = 256;

/// The deepest nesting of arrays and objects in `text`, brackets inside strings not counted. Malformed
/// text gets a number too (the parser reports what is wrong with it).
inline int json_nesting_depth(std::string_view text) {
  int depth = 0, deepest = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;  // the escaped character, whatever it is
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > deepest) deepest = depth;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}

/// Throws InputError("<origin>: JSON nested deeper than 256 levels") when `text` nests deeper.
inline void check_json_depth(std::string_view text, const std::string& origin) {
  if (json_nesting_depth(text) > kMaxJsonDepth) {
    throw InputError(origin + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  }
}

}  // namespace hp
