// Stable content ids: 16 hex digits of a 64-bit FNV-1a hash. Scenario ids and reference-image cache keys
// use it on a canonical JSON dump, so the same configuration gets the same id on every machine and run.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>

namespace hp {

inline uint64_t stable_hash64(const std::string& text) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

inline std::string stable_id(const std::string& text) {
  const uint64_t h = stable_hash64(text);
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

}  // namespace hp
