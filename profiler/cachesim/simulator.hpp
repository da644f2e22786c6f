// The SIMT execution model that turns a pass's per-invocation access records into the request stream
// a GPU's caches would see, and replays it through a Hierarchy (docs/cache-model.md states every
// approximation):
//   - workgroups go to compute units in dispatch order: first round-robin over the CUs, then each
//     freed slot takes the next workgroup; a CU holds at most max_waves_per_cu wavefronts (at least
//     one workgroup);
//   - a workgroup is cut into wavefronts of wave_width lanes by local invocation index;
//   - a wavefront issues together the lanes' next accesses that share the lowest pending sequence
//     number (lockstep by seq: with dense 0, 1, 2, ... numbering, the lanes' k-th accesses);
//   - the coalescer merges one step's lane accesses into unique lines (Coalescing::line) or unique
//     sectors grouped by line (Coalescing::sector), separately per access kind, in lane order;
//   - the L1 counts lookups and hits per request, per quarter-wave or per lane (HitCounting, the
//     preset's l1_hit_counting); all three are counted on every replay (L1Lookups), misses are the same;
//   - each cycle every CU with resident wavefronts issues one step of its next wavefront in
//     round-robin order, CUs in index order, so CUs interleave at the L2 step by step.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "cachesim/hierarchy.hpp"
#include "cachesim/preset.hpp"
#include "trace/trace_file.hpp"

namespace hp::cachesim {

struct SimOptions {
  bool per_invocation = true;  // per-invocation L1/L2 miss counts (heatmaps)
  bool l1_mrc = false, l2_mrc = false;
  double mrc_sampling_rate = 1.0;  // < 1: SHARDS
  // Sees every coalesced request, in issue order, before the caches do (Dinero export, debugging).
  std::function<void(uint32_t cu, const Request&)> observer;
};

// L1 load lookups under each HitCounting, of a pass or of one buffer. They follow from the coalesced
// requests and the lanes each serves, not from the caches' state; misses are the same under every
// counting, so hits under counting c are of(c) - the L1 misses.
struct L1Lookups {
  uint64_t request = 0;       // L1 load requests (= HierarchyStats::l1.requests under HitCounting::request)
  uint64_t quarter_wave = 0;  // per request, the quarter-waves that have a lane in it
  uint64_t lane = 0;          // per request, the lane accesses it serves
  uint64_t of(HitCounting c) const {
    return c == HitCounting::lane ? lane : c == HitCounting::quarter_wave ? quarter_wave : request;
  }
  void add(const L1Lookups& o) {
    request += o.request;
    quarter_wave += o.quarter_wave;
    lane += o.lane;
  }
};

struct PassResult {
  std::string name;
  // stats.l1.requests and .hits, and buffers[].l1_requests, count lookups the preset's way
  // (Preset::l1_hit_counting); every other count, the L1's misses, line and sector counts included, is
  // per request.
  HierarchyStats stats;
  std::array<BufferStats, 256> buffers{};              // by buffer id
  HitCounting l1_hit_counting = HitCounting::request;  // the counting stats.l1 and buffers[] use
  L1Lookups l1_lookups;                                // under every counting (stats.l1.misses: the misses)
  std::array<L1Lookups, 256> buffer_l1_lookups{};      // by buffer id (buffers[].l1_misses: the misses)
  // Per global invocation: requests of its accesses that missed the L1 / the L2 (an access spanning
  // two lines counts for both; lanes sharing a request all see its outcome).
  std::vector<uint32_t> l1_misses, l2_misses;
  uint64_t lane_accesses = 0, wave_steps = 0, waves = 0, workgroups = 0, cycles = 0;
  uint32_t slices = 0;                 // feed() calls that brought records
  uint64_t peak_resident_records = 0;  // most records held at once (streaming keeps this bounded)
  MissRatioCurve l1_curve, l2_curve;   // filled when requested
};

// What Simulator::feed_coded throws on a defect in a coded slice.
struct CodedSliceRejected : std::runtime_error {
  CodedSliceRejected() : std::runtime_error("a defect in a coded slice of records") {}
};

class Simulator {
 public:
  // Throws InputError when the preset and trace cannot work together.
  Simulator(const Preset& preset, const trace::TraceHeader& header, SimOptions options = {});
  ~Simulator();
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  // Replays one pass. Records must be validated (TraceReader::read_pass does it); any order.
  // L1s start empty (barrier between dispatches), the L2 stays warm from earlier passes.
  // Equivalent to begin_pass, one feed of the whole dispatch, end_pass.
  PassResult run_pass(const trace::PassInfo& pass, std::span<const trace::TraceRecord> records);

  // Streaming replay of one pass, slice by slice as a capture produces them, in bounded memory:
  // feed() takes the records of workgroups [first_workgroup, end_workgroup) (any order inside; every
  // record's invocation must lie in that range) and simulates as far as those workgroups allow; slices
  // come in increasing, non-overlapping workgroup order, and workgroups no slice covers have no accesses.
  // feed() groups and coalesces the slice on the calling thread and returns while a scheduler thread
  // replays it (it may block while that thread is a few pieces behind): the slice's records are not
  // used after feed() returns, and what is kept of them (the coalesced requests) is freed as their
  // workgroups retire. The counts equal run_pass's whatever the slicing and the threads' timing. Throws InputError on a record outside its slice or buffer table, or on slices
  // out of order.
  void begin_pass(const trace::PassInfo& pass);
  // `group_begin` (optional): the records are already validated against this simulator's buffer table
  // and in workgroup order, group_begin[g] .. group_begin[g + 1] being workgroup first_workgroup + g's
  // (TraceReader::read_slices_indexed gives it for a version-2 slice): they are then not scanned again.
  void feed(std::span<const trace::TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup,
            const uint32_t* group_begin = nullptr);
  PassResult end_pass();
  // A coding-2 slice straight from a trace file (TraceReader::read_slices_coded), built from its coding
  // without decoding it to records first; the results are feed()'s of the decoded records. Each record is
  // checked against this simulator's buffer table as TraceReader checks it against its header's (the
  // caller makes sure the two tables are the same: buffers_match). Throws CodedSliceRejected on any defect,
  // without words: the caller reads the slice again the careful way to name it. The pass gives no result
  // after that.
  void feed_coded(const trace::CodedSlice& slice, uint64_t first_workgroup, uint64_t end_workgroup);

  // End of the frame: dirty L2 sectors written back, in bytes.
  uint64_t finish();

  // Replaces SimOptions::observer from the next pass on (empty: none); call it between passes.
  void set_observer(std::function<void(uint32_t cu, const Request&)> observer) {
    options_.observer = std::move(observer);
  }

  const Preset& preset() const { return preset_; }
  // Whether the trace header this simulator was made with has a buffer of this id.
  bool knows_buffer(uint32_t id) const { return id < 256 && buffers_[id] != nullptr; }
  // Whether this simulator's buffer table is `buffers`: the same ids, kinds, addresses, sizes and layouts.
  bool buffers_match(const std::vector<trace::BufferInfo>& buffers) const;

 private:
  struct PassState;
  // The scheduler thread's body: the whole pass, waiting for fed workgroups as it needs them.
  void schedule();
  // Ends a pass in flight without finishing it (destructor, a new begin_pass).
  void stop();
  // feed()'s and feed_coded()'s common part; `fill(PassState&)` hands the slice to the builders.
  template <typename Fill>
  void feed_slice(uint64_t first_workgroup, uint64_t end_workgroup, uint64_t count, Fill&& fill);
  // Issues the queued requests to the hierarchy and adds their misses to per-invocation counts.
  void issue_batch();
  Preset preset_;
  const trace::BufferInfo* buffers_[256] = {};
  std::vector<trace::BufferInfo> buffer_storage_;
  SimOptions options_;
  Hierarchy hierarchy_;
  std::unique_ptr<PassState> pass_;
};

// Feeds pass `pass` of a trace file to `sim` (between its begin_pass and end_pass), one validated slice at
// a time in workgroup order (TraceReader::read_slices). `on_slice`, if set, gets the pass's records fed so far
// after each slice (a progress line).
void feed_slices(Simulator& sim, const trace::TraceReader& reader, uint32_t pass,
                 const std::function<void(uint64_t records_done)>& on_slice = {});

// Writes the coalesced request stream that compute unit `cu` sends to its L1 during one pass, in
// Dinero IV text ("r ADDR SIZE", one line per contiguous run of sectors), loads only unless
// include_stores (stores as "w": replay them in Dinero with -l1-dwalloc n to mirror our L1).
// Returns the number of lines written.
uint64_t export_din(std::ostream& out, const Preset& preset, const trace::TraceHeader& header,
                    const trace::PassInfo& pass, std::span<const trace::TraceRecord> records, uint32_t cu,
                    bool include_stores = false);
// The observer export_din attaches: writes compute unit `cu`'s L1 requests to `out` as Dinero lines and
// counts them in `lines`. Attach it to a simulator that replays anyway (Simulator::set_observer) to export
// without a second replay: the request stream does not depend on the caches' state.
std::function<void(uint32_t cu, const Request&)> din_observer(std::ostream& out, const Preset& preset, uint32_t cu,
                                                              bool include_stores, uint64_t& lines);

// The same, streamed: `feed` hands the pass's slices to the simulator (Simulator::feed), e.g. from
// TraceReader::read_slices, so a frame of any size exports in bounded memory.
uint64_t export_din(std::ostream& out, const Preset& preset, const trace::TraceHeader& header,
                    const trace::PassInfo& pass, const std::function<void(Simulator&)>& feed, uint32_t cu,
                    bool include_stores = false);

}  // namespace hp::cachesim
