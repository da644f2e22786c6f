// Trace file fuzz target: the bytes as a trace file (format version 1 or 2: the corpus holds both;
// compact_v2.hptrace seeds the compact record decoder's coding 1, capture_coding2.hptrace, an 8x8 capture,
// its coding 2), opened with hp::trace::TraceReader, then every pass read whole (which validates each
// record) and slice by slice, and small passes replayed slice by slice through the cache simulator (the
// streamed path of `hybridprof cachesim`, which builds a coding-2 slice straight from its coding) with
// wavefronts of 16 and 64 lanes (workgroups of several wavefronts, and of one). Success or hp::InputError
// only: a coded slice the simulator rejects but the reader reads cleanly is a std::logic_error, a crash.
#include <cstddef>
#include <cstdint>
#include <span>

#include "cachesim/simulator.hpp"
#include "error.hpp"
#include "fuzz_common.hpp"
#include "trace/trace_file.hpp"

namespace {

hp::cachesim::Preset small_preset(uint32_t wave_width) {
  hp::cachesim::Preset p;
  p.name = "fuzz";
  p.compute_units = 3;
  p.wave_width = wave_width;
  p.max_waves_per_cu = 4;
  p.l1 = hp::cachesim::CacheConfig{1024, 64, 64, 4};
  p.l2 = hp::cachesim::CacheConfig{8192, 64, 64, 8};
  return p;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = hp::fuzz::write_input("input.hptrace", data, size);
  try {
    hp::trace::TraceReader reader(path);
    hp::cachesim::SimOptions so;
    so.l2_mrc = true;
    hp::cachesim::Simulator narrow(small_preset(16), reader.header(), so), wide(small_preset(64), reader.header(), so);
    for (uint32_t p = 0; p < reader.passes().size(); ++p) {
      const auto records = reader.read_pass(p);
      // read_pass must return what the directory promised, and the slices must add up to it.
      if (records.size() != reader.record_count(p)) __builtin_trap();
      uint64_t sliced = 0;
      reader.read_slices(p, [&](std::span<const hp::trace::TraceRecord> r, uint64_t, uint64_t) { sliced += r.size(); });
      if (sliced != records.size()) __builtin_trap();
      // Replay only dispatches small enough to keep an input fast (the fuzzer's timeout is 5 s).
      const auto& d = reader.passes()[p].dispatch;
      if (d.invocations() > (1u << 16) || d.workgroups() > (1u << 12) || d.invocations_per_workgroup() > 1024) continue;
      for (hp::cachesim::Simulator* sim : {&narrow, &wide}) {
        sim->begin_pass(reader.passes()[p]);
        hp::cachesim::feed_slices(*sim, reader, p);
        const hp::cachesim::PassResult res = sim->end_pass();
        if (res.lane_accesses != records.size() || res.stats.l1.hits + res.stats.l1.misses != res.stats.l1.requests)
          __builtin_trap();
      }
    }
  } catch (const hp::InputError&) {
  }
  return 0;
}
