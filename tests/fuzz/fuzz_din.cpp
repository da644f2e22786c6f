// Dinero text fuzz target: the bytes through hp::trace::parse_din. Success or hp::InputError only; a
// parsed access must satisfy the reader's contract (size >= 1).
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "error.hpp"
#include "trace/din.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    for (const hp::trace::DinAccess& a : hp::trace::parse_din(in, "fuzz.din"))
      if (a.size == 0) __builtin_trap();
  } catch (const hp::InputError&) {
  }
  return 0;
}
