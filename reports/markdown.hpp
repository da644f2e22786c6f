// Text helpers that every report section shares, so that a number or a name reads the same in each.
#pragma once

#include <string>
#include <vector>

namespace hp::md {

/// A table cell's text: '|' escaped.
std::string escape(const std::string& s);
/// A count with thousands separators ("6,251,450"), as the study's tables print them.
std::string count(double v);
/// Whole numbers as count(), others to four significant digits.
std::string general(double v);
/// "a", "a and b", "a, b and c".
std::string list(const std::vector<std::string>& items);

}  // namespace hp::md
