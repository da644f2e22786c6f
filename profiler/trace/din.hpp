// Dinero IV text traces ("-informat D"): one access per line, `<r|w> <hex address> <hex size>`, so the
// classic trace-driven simulator can replay what ours did and ours can replay its inputs.
// Only reads (r) and writes (w) are meaningful for a GPU data cache; other Dinero labels are rejected.
// Blank lines and lines starting with '#' are skipped (comments are ours; Dinero itself has none, so
// write_din never emits them).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace hp::trace {

struct DinAccess {
  bool write = false;
  uint64_t address = 0;
  uint32_t size = 0;  // bytes, >= 1
};

// Throws hp::InputError "FILE:LINE: reason" on the first malformed line.
// read_din and parse_din hold the whole trace (16 bytes per access); DinReader streams it.
std::vector<DinAccess> read_din(const std::filesystem::path& path);
std::vector<DinAccess> parse_din(std::istream& in, const std::string& name);
// Streams a Dinero text file in bounded memory: one read buffer of kBufferBytes, refilled with read(2),
// whatever the file's size. Accepts exactly what parse_din accepts, with the same accesses and the same
// "FILE:LINE: reason" errors, with one limit of its own: a line longer than kBufferBytes that is not a
// comment is an error (comment and blank lines of any length are skipped). The common line shape
// ("r|w HEX HEX\n", no 0x prefix, single spaces) is parsed by a table-driven fast path; every other
// line goes through the same line parser as parse_din.
class DinReader {
 public:
  static constexpr size_t kBufferBytes = size_t(1) << 20;
  explicit DinReader(const std::filesystem::path& path);
  ~DinReader();
  DinReader(const DinReader&) = delete;
  DinReader& operator=(const DinReader&) = delete;

  // Parses up to out.size() accesses into `out`; returns how many (0 only at the end of the file).
  size_t read(std::span<DinAccess> out);
  uint64_t lines() const { return line_no_; }  // lines consumed so far

 private:
  bool refill();  // false at the end of the file
  std::string name_;
  int fd_ = -1;
  std::unique_ptr<char[]> buf_;
  size_t pos_ = 0, end_ = 0;
  bool eof_ = false;
  uint64_t line_no_ = 0;
};

void write_din(std::ostream& out, const std::vector<DinAccess>& accesses);
void write_din_line(std::ostream& out, const DinAccess& a);

}  // namespace hp::trace
