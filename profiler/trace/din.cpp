#include "trace/din.hpp"

#include <charconv>
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

}  // namespace

std::vector<DinAccess> parse_din(std::istream& in, const std::string& name) {
  std::vector<DinAccess> out;
  std::string text;
  uint64_t line_no = 0;
  while (std::getline(in, text)) {
    ++line_no;
    auto fail = [&](const std::string& why) {
      throw InputError(name + ":" + std::to_string(line_no) + ": " + why);
    };
    std::string_view line = text;
    std::string_view label = next_field(line);
    if (label.empty() || label[0] == '#') continue;
    DinAccess a;
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
    out.push_back(a);
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
