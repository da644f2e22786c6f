// Scenario parser fuzz target: the bytes as JSON text, then hp::parse_matrix. Text that is not JSON, or
// holds a number no double can hold, is an expected rejection (load_matrix turns it into an InputError
// with line and column); a document that parses must give a Matrix or an hp::InputError, never a
// nlohmann type_error, out_of_range or a crash.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "error.hpp"
#include "scenario.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(data, data + size);
  } catch (const nlohmann::json::exception&) {
    // parse_error, or out_of_range.406 for a number past a double's range (1e400): both rejections of
    // the text, which load_matrix must turn into an InputError too.
    return 0;
  }
  try {
    hp::Matrix m = hp::parse_matrix(doc, "fuzz.json");
    // canonical() and id() run on every cell in the runner; exercise them too.
    for (const hp::Scenario& s : m.cells) (void)s.id();
  } catch (const hp::InputError&) {
  }
  return 0;
}
