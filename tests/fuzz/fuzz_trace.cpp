// Trace file fuzz target: the bytes as a trace file, opened with hp::trace::TraceReader, then every pass
// read (which validates each record). Success or hp::InputError only.
#include <cstddef>
#include <cstdint>

#include "error.hpp"
#include "fuzz_common.hpp"
#include "trace/trace_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = hp::fuzz::write_input("input.hptrace", data, size);
  try {
    hp::trace::TraceReader reader(path);
    for (uint32_t p = 0; p < reader.passes().size(); ++p) {
      const auto records = reader.read_pass(p);
      // read_pass must return what the directory promised.
      if (records.size() != reader.record_count(p)) __builtin_trap();
    }
  } catch (const hp::InputError&) {
  }
  return 0;
}
