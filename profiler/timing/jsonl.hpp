// JSON-lines files (results.jsonl, rounds.jsonl): one JSON value per line, appended and synced one line at a
// time, so an interrupted write leaves at most a partial last line.
#pragma once

#include "error.hpp"
#include "json_depth.hpp"

#include <nlohmann/json.hpp>

#include <string>

namespace hp {

/// Calls f(value, where) for each complete line of `content` (the text of `file`), parsed, with `where` =
/// "FILE:LINE". Empty lines are skipped; an unterminated last line is not parsed, and the return value says
/// whether there was one. A line nested deeper than kMaxJsonDepth or not JSON is an InputError naming
/// FILE:LINE and "corrupt `what` line".
template <class F>
bool for_each_jsonl_line(const std::string& content, const std::string& file, const char* what, F&& f) {
  size_t start = 0, line_no = 0;
  while (start < content.size()) {
    const size_t end = content.find('\n', start);
    if (end == std::string::npos) return true;
    ++line_no;
    const std::string text = content.substr(start, end - start);
    start = end + 1;
    if (text.empty()) continue;
    const std::string where = file + ":" + std::to_string(line_no);
    check_json_depth(text, where);
    nlohmann::json value;
    try {
      value = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
      throw InputError(where + ": corrupt " + what + " line (" + std::string(e.what()).substr(0, 120) + ")");
    }
    f(std::move(value), where);
  }
  return false;
}

}  // namespace hp
