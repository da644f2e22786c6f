// The SIMT replay as it was before the grouped, coalesced-ahead and two-threaded Simulator: one thread,
// lane accesses grouped into wave steps per workgroup and coalesced as each step issues. Kept for the
// tests only, as the straightforward path the Simulator's counts, request streams and per-invocation
// misses are compared against (baseline_simulator.cpp is the former simulator.cpp, unchanged but for
// the class name).
#pragma once

#include "cachesim/simulator.hpp"

namespace hp::cachesim::baseline {

class BaselineSimulator {
 public:
  BaselineSimulator(const Preset& preset, const trace::TraceHeader& header, SimOptions options = {});
  ~BaselineSimulator();
  BaselineSimulator(const BaselineSimulator&) = delete;
  BaselineSimulator& operator=(const BaselineSimulator&) = delete;
  PassResult run_pass(const trace::PassInfo& pass, std::span<const trace::TraceRecord> records);
  void begin_pass(const trace::PassInfo& pass);
  void feed(std::span<const trace::TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup);
  PassResult end_pass();
  uint64_t finish();

 private:
  struct PassState;
  void advance();
  void schedule();
  void issue_batch();
  Preset preset_;
  const trace::BufferInfo* buffers_[256] = {};
  std::vector<trace::BufferInfo> buffer_storage_;
  SimOptions options_;
  Hierarchy hierarchy_;
  std::unique_ptr<PassState> pass_;
};

}  // namespace hp::cachesim::baseline
