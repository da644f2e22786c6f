// Dinero text fuzz target: the bytes through both Dinero readers, hp::trace::parse_din (whole input) and
// the streamed hp::trace::DinReader that `cachesim --din` uses (bounded buffer, its own fast line scan).
// Success or hp::InputError only; a parsed access must satisfy the reader's contract (size >= 1); and the two
// readers must agree: the same accesses in the same order, or both reject the input.
#include <sys/mman.h>
#include <unistd.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "error.hpp"
#include "trace/din.hpp"

namespace {

// The streamed reader opens a path: the bytes go into an anonymous in-memory file, named through /proc.
std::vector<hp::trace::DinAccess> read_streamed(const uint8_t* data, size_t size, bool& rejected) {
  std::vector<hp::trace::DinAccess> out;
  const int fd = ::memfd_create("fuzz.din", 0);
  if (fd < 0) __builtin_trap();
  for (size_t done = 0; done < size;) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n <= 0) __builtin_trap();
    done += size_t(n);
  }
  try {
    hp::trace::DinReader reader("/proc/self/fd/" + std::to_string(fd));
    std::array<hp::trace::DinAccess, 64> chunk;
    while (const size_t n = reader.read(chunk)) out.insert(out.end(), chunk.begin(), chunk.begin() + long(n));
  } catch (const hp::InputError&) {
    rejected = true;
  }
  ::close(fd);
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  std::vector<hp::trace::DinAccess> whole;
  bool whole_rejected = false;
  try {
    whole = hp::trace::parse_din(in, "fuzz.din");
    for (const hp::trace::DinAccess& a : whole)
      if (a.size == 0) __builtin_trap();
  } catch (const hp::InputError&) {
    whole_rejected = true;
  }
  bool streamed_rejected = false;
  const std::vector<hp::trace::DinAccess> streamed = read_streamed(data, size, streamed_rejected);
  if (whole_rejected != streamed_rejected) __builtin_trap();
  if (whole_rejected) return 0;
  if (streamed.size() != whole.size()) __builtin_trap();
  for (size_t i = 0; i < whole.size(); ++i) {
    const hp::trace::DinAccess &a = whole[i], &b = streamed[i];
    if (a.address != b.address || a.size != b.size || a.write != b.write) __builtin_trap();
  }
  return 0;
}
