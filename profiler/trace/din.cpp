#include "trace/din.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <ostream>

#include "error.hpp"

namespace hp::trace {

namespace {

// Parses one hexadecimal field (optional 0x prefix) of at most 64 bits.
bool parse_hex(std::string_view field, uint64_t& out) {
  if (field.size() > 2 && field[0] == '0' && (field[1] == 'x' || field[1] == 'X')) field.remove_prefix(2);
  if (field.empty()) return false;
  auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), out, 16);
  return ec == std::errc() && end == field.data() + field.size();
}

std::string_view next_field(std::string_view& line) {
  size_t b = line.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) {
    line = {};
    return {};
  }
  size_t e = line.find_first_of(" \t\r", b);
  if (e == std::string_view::npos) e = line.size();
  std::string_view f = line.substr(b, e - b);
  line.remove_prefix(e);
  return f;
}

// One line (without its '\n'): false for a blank or comment line, else the access in `a`.
bool parse_line(std::string_view line, DinAccess& a, const std::string& name, uint64_t line_no) {
  auto fail = [&](const std::string& why) { throw InputError(name + ":" + std::to_string(line_no) + ": " + why); };
  std::string_view label = next_field(line);
  if (label.empty() || label[0] == '#') return false;
  if (label == "r" || label == "0")
    a.write = false;
  else if (label == "w" || label == "1")
    a.write = true;
  else
    fail("unsupported access label '" + std::string(label) + "' (expected r or w)");
  std::string_view addr = next_field(line), size = next_field(line);
  if (addr.empty()) fail("missing address");
  if (!parse_hex(addr, a.address)) fail("bad hexadecimal address '" + std::string(addr) + "'");
  if (size.empty()) fail("missing size");
  uint64_t s = 0;
  if (!parse_hex(size, s) || s == 0 || s > 0xFFFFFFFFull) fail("bad size '" + std::string(size) + "'");
  if (!next_field(line).empty()) fail("extra field after the size");
  a.size = uint32_t(s);
  return true;
}

// Hex digit values, 16 for anything else.
constexpr std::array<uint8_t, 256> kHex = [] {
  std::array<uint8_t, 256> t{};
  for (auto& v : t) v = 16;
  for (int c = 0; c < 10; ++c) t['0' + c] = uint8_t(c);
  for (int c = 0; c < 6; ++c) t['a' + c] = t['A' + c] = uint8_t(10 + c);
  return t;
}();

// The common line "L ADDR SIZE\n" (L one of r w 0 1; ADDR 1..16 hex digits; SIZE 1..8 hex digits, not
// zero; single spaces; "\r\n" allowed): the bytes it took, or 0 when the line needs the full parser.
// Reads at most 31 bytes from p.
inline size_t parse_fast(const unsigned char* p, DinAccess& a) {
  const unsigned char c = p[0];
  if (c == 'r' || c == '0')
    a.write = false;
  else if (c == 'w' || c == '1')
    a.write = true;
  else
    return 0;
  if (p[1] != ' ') return 0;
  const unsigned char* q = p + 2;
  uint64_t addr = 0;
  size_t k = 0;
  for (uint32_t d; k < 17 && (d = kHex[q[k]]) < 16; ++k) addr = addr << 4 | d;
  if (k == 0 || k == 17 || q[k] != ' ') return 0;
  q += k + 1;
  uint64_t size = 0;
  k = 0;
  for (uint32_t d; k < 9 && (d = kHex[q[k]]) < 16; ++k) size = size << 4 | d;
  if (k == 0 || k == 9 || size == 0) return 0;
  q += k;
  if (*q == '\r') ++q;
  if (*q != '\n') return 0;
  a.address = addr;
  a.size = uint32_t(size);
  return size_t(q + 1 - p);
}

}  // namespace

std::vector<DinAccess> parse_din(std::istream& in, const std::string& name) {
  std::vector<DinAccess> out;
  std::string text;
  uint64_t line_no = 0;
  while (std::getline(in, text)) {
    DinAccess a;
    if (parse_line(text, a, name, ++line_no)) out.push_back(a);
  }
  return out;
}

std::vector<DinAccess> read_din(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(path.string() + ": is a directory, not a Dinero trace");
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open Dinero trace");
  return parse_din(in, path.string());
}

DinReader::DinReader(const std::filesystem::path& path) : name_(path.string()) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(name_ + ": is a directory, not a Dinero trace");
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) throw InputError(name_ + ": cannot open Dinero trace: " + std::strerror(errno));
#ifdef POSIX_FADV_SEQUENTIAL
  ::posix_fadvise(fd_, 0, 0, POSIX_FADV_SEQUENTIAL);
#endif
  buf_.reset(new char[kBufferBytes + 64]);  // 64 spare bytes: the fast parser may look past a line's end
}

DinReader::~DinReader() {
  if (fd_ >= 0) ::close(fd_);
}

bool DinReader::refill() {
  if (eof_) return false;
  char* b = buf_.get();
  size_t len = end_ - pos_;
  if (pos_ && len) std::memmove(b, b + pos_, len);
  pos_ = 0;
  end_ = len;
  if (len == kBufferBytes) {
    // A line as long as the buffer. Leading blanks do not change how a line parses: drop them. A
    // comment is skipped to its end whatever its length; anything else this long is an error.
    size_t k = 0;
    while (k < len && (b[k] == ' ' || b[k] == '\t' || b[k] == '\r')) ++k;
    if (k < len && b[k] == '#') {
      while (true) {
        const ssize_t r = ::read(fd_, b, kBufferBytes);
        if (r < 0 && errno == EINTR) continue;
        if (r < 0) throw InputError(name_ + ": read failed: " + std::strerror(errno));
        if (r == 0) {  // the comment was the last line
          ++line_no_;
          pos_ = end_ = 0;
          eof_ = true;
          return false;
        }
        if (const void* nl = std::memchr(b, '\n', size_t(r))) {
          ++line_no_;
          pos_ = size_t(static_cast<const char*>(nl) - b) + 1;
          end_ = size_t(r);
          return true;
        }
      }
    }
    if (k == 0)
      throw InputError(name_ + ":" + std::to_string(line_no_ + 1) + ": line longer than " +
                       std::to_string(kBufferBytes) + " bytes");
    std::memmove(b, b + k, len - k);
    end_ = len - k;
  }
  while (true) {
    const ssize_t r = ::read(fd_, b + end_, kBufferBytes - end_);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) throw InputError(name_ + ": read failed: " + std::strerror(errno));
    if (r == 0) {
      eof_ = true;
      return false;
    }
    end_ += size_t(r);
    return true;
  }
}

size_t DinReader::read(std::span<DinAccess> out) {
  size_t n = 0;
  char* b = buf_.get();
  while (n < out.size()) {
    // Lines of the common shape while a whole one surely fits in what is buffered.
    while (n < out.size() && end_ - pos_ >= 64) {
      const size_t used = parse_fast(reinterpret_cast<const unsigned char*>(b + pos_), out[n]);
      if (!used) break;
      pos_ += used;
      ++line_no_;
      ++n;
    }
    if (n == out.size()) break;
    const char* nl = static_cast<const char*>(std::memchr(b + pos_, '\n', end_ - pos_));
    if (!nl) {
      if (refill()) continue;
      if (pos_ == end_) break;  // end of the file
      nl = b + end_;            // the last line has no '\n'
    }
    const std::string_view line(b + pos_, size_t(nl - (b + pos_)));
    pos_ = std::min(end_, size_t(nl - b) + 1);
    if (parse_line(line, out[n], name_, ++line_no_)) ++n;
  }
  return n;
}

void write_din_line(std::ostream& out, const DinAccess& a) {
  char buf[48];
  char* p = buf;
  *p++ = a.write ? 'w' : 'r';
  *p++ = ' ';
  p = std::to_chars(p, buf + sizeof buf, a.address, 16).ptr;
  *p++ = ' ';
  p = std::to_chars(p, buf + sizeof buf, a.size, 16).ptr;
  *p++ = '\n';
  out.write(buf, p - buf);
}

void write_din(std::ostream& out, const std::vector<DinAccess>& accesses) {
  for (const DinAccess& a : accesses) write_din_line(out, a);
}

}  // namespace hp::trace
