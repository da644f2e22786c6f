#include "markdown.hpp"

#include "cell_result.hpp"

#include <cmath>

namespace hp::md {

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '|') out += '\\';
    out += c;
  }
  return out;
}

std::string count(double v) {
  const std::string s = format_number("%.0f", v);
  std::string out;
  const size_t lead = s[0] == '-' ? 1 : 0;
  for (size_t i = 0; i < s.size(); ++i) {
    if (i > lead && (s.size() - i) % 3 == 0) out += ',';
    out += s[i];
  }
  return out;
}

std::string general(double v) {
  if (std::isfinite(v) && v == std::floor(v) && std::abs(v) < 1e15) return count(v);
  return format_number("%.4g", v);
}

std::string list(const std::vector<std::string>& items) {
  std::string s;
  for (size_t i = 0; i < items.size(); ++i) s += (i == 0 ? "" : i + 1 == items.size() ? " and " : ", ") + items[i];
  return s;
}

}  // namespace hp::md
