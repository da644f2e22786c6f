// Dinero IV text traces ("-informat D"): one access per line, `<r|w> <hex address> <hex size>`, so the
// classic trace-driven simulator can replay what ours did and ours can replay its inputs.
// Only reads (r) and writes (w) are meaningful for a GPU data cache; other Dinero labels are rejected.
// Blank lines and lines starting with '#' are skipped (comments are ours; Dinero itself has none, so
// write_din never emits them).
#pragma once

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

namespace hp::trace {

struct DinAccess {
  bool write = false;
  uint64_t address = 0;
  uint32_t size = 0;  // bytes, >= 1
};

// Throws hp::InputError "FILE:LINE: reason" on the first malformed line.
std::vector<DinAccess> read_din(const std::filesystem::path& path);
std::vector<DinAccess> parse_din(std::istream& in, const std::string& name);
void write_din(std::ostream& out, const std::vector<DinAccess>& accesses);
void write_din_line(std::ostream& out, const DinAccess& a);

}  // namespace hp::trace
