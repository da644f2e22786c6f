#include "cachesim/simulator.hpp"

#include "cachesim/address_map.hpp"

#include <algorithm>
#include <bit>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <ostream>
#include <stdexcept>
#include <thread>

#include "error.hpp"
#include "trace/din.hpp"

namespace hp::cachesim {

namespace {


// Merges one wavefront step's lane accesses into requests. A small open-addressed table keyed by
// (line, kind) with generation stamps: no clearing, no allocation per step.
class Coalescer {
 public:
  Coalescer(uint32_t wave_width, uint32_t line_shift, uint32_t sector_shift, uint32_t full_mask, bool sectors)
      : line_shift_(line_shift), sector_shift_(sector_shift), full_mask_(full_mask), sectors_(sectors) {
    size_t size = std::bit_ceil(size_t(wave_width) * 8);
    keys_.resize(size);
    stamp_.assign(size, 0);
    slot_req_.resize(size);
    mask_ = size - 1;
    requests.reserve(size_t(wave_width) * 2);
    lanes.reserve(size_t(wave_width) * 2);
    quarters.reserve(size_t(wave_width) * 2);
    lane_request.reserve(size_t(wave_width) * 2);
    // Quarter-waves of ceil(wave_width / 4) lanes (HitCounting::quarter_wave): a lane's bit of 4.
    const uint32_t q = (wave_width + 3) / 4;
    quarter_bit_.resize(wave_width);
    for (uint32_t l = 0; l < wave_width; ++l) quarter_bit_[l] = uint8_t(1u << (l / q));
  }

  void begin() {
    ++gen_;
    requests.clear();
    lanes.clear();
    quarters.clear();
    lane_request.clear();
    last_key_ = ~uint64_t(0);  // no key: a line number is below 2^62
  }

  // Adds one access of lane `lane` of the wavefront (global invocation `invocation`); remembers
  // (invocation, request) pairs when per_invocation.
  [[gnu::always_inline]] void add(uint64_t address, uint32_t info, uint32_t invocation, uint32_t lane,
                                  bool per_invocation) {
    const uint8_t quarter = quarter_bit_[lane];
    const uint32_t size = gpu::trace_size(info);
    const auto kind = AccessKind(gpu::trace_kind(info));
    const uint64_t last_byte = address + size - 1;
    const uint64_t first_line = address >> line_shift_, last_line = last_byte >> line_shift_;
    last_single_ = first_line == last_line;
    for (uint64_t line = first_line; line <= last_line; ++line) {
      uint32_t mask = full_mask_;
      if (sectors_) {
        const uint64_t lo = line == first_line ? address : line << line_shift_;
        const uint64_t hi = line == last_line ? last_byte : ((line + 1) << line_shift_) - 1;
        const uint64_t in_line = (uint64_t(1) << line_shift_) - 1;
        const uint32_t s0 = uint32_t((lo & in_line) >> sector_shift_), s1 = uint32_t((hi & in_line) >> sector_shift_);
        mask = uint32_t(((uint64_t(2) << s1) - 1) & ~((uint64_t(1) << s0) - 1));
      }
      const uint64_t key = (line << 2) | uint64_t(kind);
      uint32_t req;
      // Neighbouring lanes usually touch the line the previous lane did: no hashing then.
      if (key == last_key_) {
        req = last_req_;
        requests[req].sectors |= mask;
        ++lanes[req];
        quarters[req] |= quarter;
        if (per_invocation) lane_request.push_back({invocation, req});
        continue;
      }
      uint64_t h = (key * 0x9E3779B97F4A7C15ull) >> 40 & mask_;
      while (true) {
        if (stamp_[h] != gen_) {
          stamp_[h] = gen_;
          keys_[h] = key;
          req = uint32_t(requests.size());
          slot_req_[h] = req;
          requests.push_back(Request{line, mask, kind, uint8_t(gpu::trace_buffer(info))});
          lanes.push_back(1);
          quarters.push_back(quarter);
          break;
        }
        if (keys_[h] == key) {
          req = slot_req_[h];
          requests[req].sectors |= mask;
          ++lanes[req];
          quarters[req] |= quarter;
          break;
        }
        h = (h + 1) & mask_;
      }
      last_key_ = key;
      last_req_ = req;
      if (per_invocation) lane_request.push_back({invocation, req});
    }
  }

  // The same access as the previous add() of this step, by other lanes: where that access lay in one line
  // (last_single()), adding it again changes only its request's lane count and quarter-waves, so a caller
  // may count such lanes itself (quarter_of each, note_lane each when per_invocation) and add them with
  // count_again(lanes, their quarter-waves) before the next add() or the step's end.
  bool last_single() const { return last_single_; }
  uint8_t quarter_of(uint32_t lane) const { return quarter_bit_[lane]; }
  void note_lane(uint32_t invocation) { lane_request.push_back({invocation, last_req_}); }
  void count_again(uint32_t n, uint8_t quarter_mask) {
    lanes[last_req_] += n;
    quarters[last_req_] |= quarter_mask;
  }

  std::vector<Request> requests;
  // Per request: the lane accesses it serves, and the quarter-waves they are in (a bit each).
  std::vector<uint32_t> lanes;
  std::vector<uint8_t> quarters;
  std::vector<std::pair<uint32_t, uint32_t>> lane_request;

 private:
  std::vector<uint8_t> quarter_bit_;  // per lane of a wavefront
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> stamp_, slot_req_;
  uint64_t mask_ = 0;
  uint64_t last_key_ = ~uint64_t(0);  // the previous lane access's key and request, this step
  uint32_t last_req_ = 0;
  bool last_single_ = false;  // whether the previous lane access lay in one line
  uint32_t gen_ = 0;
  uint32_t line_shift_, sector_shift_, full_mask_;
  bool sectors_;
};

// One workgroup's wave steps, coalesced: per wavefront its lockstep steps (each step: the lanes whose
// next access has the lowest pending sequence number, in lane order), each step already merged into its
// requests. A step's requests depend on its own lanes' records only, never on the caches or on the
// scheduling, so they are computed once, while the workgroup's records are hot in the host's caches and
// on the feeding thread; the scheduler then only interleaves steps. Freed when the workgroup retires.
struct GroupRequests {
  uint64_t records = 0;                  // lane accesses (resident-record accounting)
  std::vector<Request> requests;         // in issue order
  std::vector<uint32_t> step_end;        // per step (all wavefronts' steps in order): end of its requests
  std::vector<uint32_t> wave_steps_end;  // per wavefront: end of its steps in step_end
  // per_invocation only: (invocation, index in requests) for each lane access's request, and per step
  // the end of its entries.
  std::vector<std::pair<uint32_t, uint32_t>> lanes;
  std::vector<uint32_t> step_lanes_end;
  void clear() {
    records = 0;
    requests.clear();
    step_end.clear();
    wave_steps_end.clear();
    lanes.clear();
    step_lanes_end.clear();
  }
};

// Retired workgroups' GroupRequests, kept with their arrays' capacity for the next workgroups to be built:
// allocating them afresh for each workgroup (and growing them step by step) cost a third of the builders'
// time in malloc, reallocation copies and the page faults of memory the allocator had given back.
// Bounded by the workgroups alive at once (resident and queued), as the GroupRequests themselves are.
class GroupPool {
 public:
  std::unique_ptr<GroupRequests> take() {
    {
      std::lock_guard lk(m_);
      if (!free_.empty()) {
        std::unique_ptr<GroupRequests> g = std::move(free_.back());
        free_.pop_back();
        return g;
      }
    }
    return std::make_unique<GroupRequests>();
  }
  void give(std::unique_ptr<GroupRequests> g) {
    g->clear();
    std::lock_guard lk(m_);
    free_.push_back(std::move(g));
  }

 private:
  std::mutex m_;
  std::vector<std::unique_ptr<GroupRequests>> free_;
};

// Part of a fed slice, handed from the feeding thread to the scheduler: its workgroups become known.
struct Piece {
  uint64_t first_group = 0, end_group = 0;
  std::vector<std::unique_ptr<GroupRequests>> groups;  // by workgroup - first_group; null: no accesses
  bool first_of_feed = false;
  uint64_t feed_records = 0;  // first piece of a feed: the feed's records
};

// A slice's records bucketed by workgroup, stably. Captures write a workgroup's records in a few runs
// (the GPU runs it on one core), so the buckets are usually lists of runs in the caller's records, no
// copy; records in workgroup order are one run per workgroup; records in no order at all (many short
// runs) are copied into workgroup order. Filled by the feeding thread, then read by every builder until
// the slice is built.
class Buckets {
 public:
  explicit Buckets(const trace::BufferInfo* const* buffers) : buffers_(buffers) {}

  // Checks each record lies in the slice and names a known buffer; false on a bad record.
  bool fill(std::span<const trace::TraceRecord> records, uint64_t first_group, uint64_t end_group, uint64_t per_group) {
    per_group_ = per_group;
    first_group_ = first_group;
    const uint64_t groups = end_group - first_group;
    const uint64_t first_inv = first_group * per_group, span_inv = groups * per_group;
    const bool pow2 = std::has_single_bit(per_group);
    const uint32_t shift = uint32_t(std::countr_zero(per_group));
    auto group_of = [&](uint32_t inv) { return pow2 ? (inv - first_inv) >> shift : (inv - first_inv) / per_group; };
    begin_.assign(groups + 1, 0);
    runs_.clear();
    bool in_order = true;
    uint64_t prev = ~uint64_t(0);
    const trace::TraceRecord* data = records.data();
    for (size_t i = 0; i < records.size(); ++i) {
      const trace::TraceRecord& r = data[i];
      if (!buffers_[gpu::trace_buffer(r.info)] || r.invocation < first_inv || r.invocation - first_inv >= span_inv)
        return false;
      const uint64_t g = group_of(r.invocation);
      ++begin_[g + 1];
      if (g != prev) {
        in_order &= prev == ~uint64_t(0) || g > prev;
        runs_.push_back(Run{i, 0, g});
        prev = g;
      }
      ++runs_.back().count;
    }
    for (uint64_t g = 0; g < groups; ++g) begin_[g + 1] += begin_[g];
    data_ = records.data();
    if (in_order) {
      mode_ = Mode::in_place;
    } else if (runs_.size() <= records.size() / 8) {
      // Runs by workgroup (stable): group g's runs are run_order_[run_begin_[g] .. run_begin_[g + 1]).
      mode_ = Mode::runs;
      run_begin_.assign(groups + 1, 0);
      for (const Run& r : runs_) ++run_begin_[r.group + 1];
      for (uint64_t g = 0; g < groups; ++g) run_begin_[g + 1] += run_begin_[g];
      cursor_.assign(run_begin_.begin(), run_begin_.end() - 1);
      run_order_.resize(runs_.size());
      for (size_t k = 0; k < runs_.size(); ++k) run_order_[cursor_[runs_[k].group]++] = uint32_t(k);
    } else {
      mode_ = Mode::copied;
      sorted_.resize(records.size());
      cursor_.assign(begin_.begin(), begin_.end() - 1);
      for (const trace::TraceRecord& r : records) sorted_[cursor_[group_of(r.invocation)]++] = r;
      data_ = sorted_.data();
    }
    return true;
  }
  // Records already validated against the buffer table and in workgroup order, with where each
  // workgroup's records start (a decoded version-2 slice): no pass over the records. False when the index
  // cannot describe them.
  bool fill_indexed(std::span<const trace::TraceRecord> records, uint64_t first_group, uint64_t end_group,
                    uint64_t per_group, const uint32_t* group_begin) {
    per_group_ = per_group;
    first_group_ = first_group;
    const uint64_t groups = end_group - first_group;
    if (group_begin[0] != 0 || group_begin[groups] != records.size()) return false;
    begin_.assign(group_begin, group_begin + groups + 1);
    for (uint64_t g = 0; g < groups; ++g)
      if (begin_[g] > begin_[g + 1]) return false;
    data_ = records.data();
    mode_ = Mode::in_place;
    return true;
  }
  // A coding-2 slice (Simulator::feed_coded): each workgroup's body, decoded by the builders.
  void fill_coded(const trace::CodedSlice& slice, uint64_t first_group, uint64_t per_group) {
    per_group_ = per_group;
    first_group_ = first_group;
    coded_ = slice.bytes.data();
    bodies_ = slice.bodies.data();
    mode_ = Mode::coded;
  }
  bool coded() const { return mode_ == Mode::coded; }
  // Group g's body in the coded slice.
  std::pair<const uint8_t*, const uint8_t*> body(uint64_t g) const {
    return {coded_ + bodies_[g].first, coded_ + bodies_[g].second};
  }
  // About how many records group g has, to size the pieces (a coded record takes about 2 bytes).
  uint64_t weight(uint64_t g) const {
    return mode_ == Mode::coded ? (bodies_[g].second - bodies_[g].first) / 2 : records(g);
  }
  uint64_t records(uint64_t g) const { return begin_[g + 1] - begin_[g]; }
  // Calls f(pointer, count) for each run of group g's records, in record order.
  template <typename F>
  void for_each_run(uint64_t g, F&& f) const {
    if (mode_ != Mode::runs) {
      f(data_ + begin_[g], begin_[g + 1] - begin_[g]);
      return;
    }
    for (uint64_t k = run_begin_[g]; k < run_begin_[g + 1]; ++k) {
      const Run& r = runs_[run_order_[k]];
      f(data_ + r.first, r.count);
    }
  }
  uint64_t first_group() const { return first_group_; }
  uint64_t per_group() const { return per_group_; }
  // Group g's records when they lie in one run (null otherwise).
  const trace::TraceRecord* single_run(uint64_t g) const { return mode_ == Mode::runs ? nullptr : data_ + begin_[g]; }

 private:
  struct Run {
    uint64_t first, count, group;
  };
  enum class Mode : uint8_t { in_place, runs, copied, coded };
  const trace::BufferInfo* const* buffers_;
  const uint8_t* coded_ = nullptr;
  const std::pair<uint64_t, uint64_t>* bodies_ = nullptr;
  uint64_t per_group_ = 1, first_group_ = 0;
  const trace::TraceRecord* data_ = nullptr;
  Mode mode_ = Mode::in_place;
  std::vector<uint64_t> begin_, cursor_, run_begin_;
  std::vector<Run> runs_;
  std::vector<uint32_t> run_order_;
  std::vector<trace::TraceRecord> sorted_;
};

// Turns bucketed workgroups into GroupRequests; one per building thread (its scratch and coalescer).
class Builder {
 public:
  Builder(const Preset& preset, const Cache& l1, const trace::BufferInfo* const* buffers, bool per_invocation,
          GroupPool& pool)
      : pool_(pool),
        co_(preset.wave_width, l1.line_shift(), l1.sector_shift(), l1.full_mask(),
            preset.coalescing == Coalescing::sector),
        buffers_(buffers),
        width_(preset.wave_width),
        per_inv_(per_invocation) {
    for (size_t id = 0; id < maps_.size(); ++id) maps_[id] = AddressMap(buffers[id]);
  }

  // Workgroup first_group + g's requests (null: no accesses).
  std::unique_ptr<GroupRequests> build(const Buckets& buckets, uint64_t g) {
    const uint64_t per_group = buckets.per_group();
    const uint64_t first_invocation = (buckets.first_group() + g) * per_group;
    if (buckets.coded()) {
      const auto [p, end] = buckets.body(g);
      return build_coded(p, end, first_invocation, per_group);
    }
    const uint64_t n = buckets.records(g);
    if (n == 0) return nullptr;
    if (const trace::TraceRecord* in = buckets.single_run(g); in && in_issue_order(in, n))
      return build_in_order(in, n, first_invocation, per_group);
    return build_general([&](auto&& f) { buckets.for_each_run(g, f); }, n, first_invocation, per_group);
  }

  // A workgroup's requests from its coding-2 body [p, end) (trace_codec.hpp; kRecordReadBytes readable past
  // `end`), every record checked as TraceReader checks a decoded one: known buffer, access kind, reserved
  // bits, offset + size inside the buffer, lane inside the workgroup, seq below 2^32. A defect throws
  // CodedSliceRejected (the caller reads the slice again the careful way for the error's words). Where a
  // workgroup is one wavefront and no lane comes twice in a step (as a capture writes), each coded step is
  // a wave step, coalesced as it is decoded: no record is stored. Otherwise the body is decoded into
  // records first and built as records are.
  std::unique_ptr<GroupRequests> build_coded(const uint8_t* p, const uint8_t* end, uint64_t first_invocation,
                                             uint64_t per_group) {
    if (p == end) return nullptr;
    if (per_group <= width_) {
      std::unique_ptr<GroupRequests> ga = pool_.take();
      ga->requests.reserve(size_t(end - p) / 8 + 8);  // as the records path: a record takes about 2 bytes
      // Lanes repeating the previous access, counted here (in registers) and into its request at once.
      uint32_t again = 0;
      uint8_t again_quarters = 0;
      const auto flush_again = [&] {
        co_.count_again(again, again_quarters);
        again = 0;
        again_quarters = 0;
      };
      const bool whole = walk_coded(
          p, end, per_group, true, [&] { co_.begin(); },
          [&](uint32_t lane, uint32_t, uint32_t info, uint64_t address, uint32_t, bool same) {
            const uint32_t invocation = uint32_t(first_invocation + lane);
            if (same && co_.last_single()) {
              ++again;
              again_quarters |= co_.quarter_of(lane);
              if (per_inv_) co_.note_lane(invocation);
              return;
            }
            if (again) flush_again();
            co_.add(address, info, invocation, lane, per_inv_);
          },
          [&](uint64_t n) {
            if (again) flush_again();
            ga->records += n;
            end_step(*ga, pending_.data(), pending_touched_.data());
          });
      // The workgroup's lookups count once it is whole (a lane twice in a step: none of them).
      for (size_t w = 0; w < pending_touched_.size(); ++w) {
        for (uint64_t m = pending_touched_[w]; m; m &= m - 1) {
          const size_t b = w * 64 + size_t(std::countr_zero(m));
          if (whole) lookups[b].add(pending_[b]);
          pending_[b] = L1Lookups{};
        }
        pending_touched_[w] = 0;
      }
      if (whole) {
        ga->wave_steps_end.push_back(uint32_t(ga->step_end.size()));
        return ga;
      }
      pool_.give(std::move(ga));
    }
    scratch_.clear();
    walk_coded(
        p, end, per_group, false, [] {},
        [&](uint32_t lane, uint32_t seq, uint32_t info, uint64_t, uint32_t offset, bool) {
          scratch_.push_back(trace::TraceRecord{uint32_t(first_invocation + lane), seq, info, offset});
        },
        [](uint64_t) {});
    const trace::TraceRecord* in = scratch_.data();
    const uint64_t n = scratch_.size();
    if (in_issue_order(in, n)) return build_in_order(in, n, first_invocation, per_group);
    return build_general([&](auto&& f) { f(in, n); }, n, first_invocation, per_group);
  }

  // The general build: `for_each_run(f)` calls f(pointer, count) on each run of the workgroup's n records.
  template <typename ForEachRun>
  std::unique_ptr<GroupRequests> build_general(ForEachRun&& for_each_run, uint64_t n, uint64_t first_invocation,
                                               uint64_t per_group) {
    // This workgroup's records by invocation (stable: one invocation's keep their order), each
    // invocation's sorted by seq where needed (GPU atomics usually hand out indices in program order).
    at_.assign(per_group + 1, 0);
    for_each_run([&](const trace::TraceRecord* in, uint64_t count) {
      for (uint64_t k = 0; k < count; ++k) ++at_[in[k].invocation - first_invocation + 1];
    });
    for (uint64_t i = 0; i < per_group; ++i) at_[i + 1] += at_[i];
    // Addresses are resolved here, in record order: plain buffers inline (most records), images by
    // their declared layout.
    recs_.resize(n);
    cursor32_.assign(at_.begin(), at_.end() - 1);
    for_each_run([&](const trace::TraceRecord* in, uint64_t count) {
      for (uint64_t k = 0; k < count; ++k) {
        const trace::TraceRecord& r = in[k];
        const trace::BufferInfo& b = *buffers_[gpu::trace_buffer(r.info)];
        recs_[cursor32_[r.invocation - first_invocation]++] =
            LaneAccess{b.kind == trace::BufferKind::buffer ? b.base_address + r.offset
                                                           : maps_[gpu::trace_buffer(r.info)](r.offset),
                       r.seq, r.info};
      }
    });
    auto by_seq = [](const LaneAccess& x, const LaneAccess& y) { return x.seq < y.seq; };
    // Whether every lane's seqs strictly increase (dense 0, 1, 2, ... from a capture): then the steps are
    // exactly the distinct seqs in ascending order, each the lanes holding it in lane order.
    strict_.assign(per_group, 1);
    for (uint64_t i = 0; i < per_group; ++i) {
      auto first = recs_.begin() + at_[i], last = recs_.begin() + at_[i + 1];
      if (!std::is_sorted(first, last, by_seq)) std::stable_sort(first, last, by_seq);
      for (auto it = first; it != last && it + 1 != last; ++it)
        if (it->seq == (it + 1)->seq) {
          strict_[i] = 0;
          break;
        }
    }
    std::unique_ptr<GroupRequests> ga = pool_.take();
    ga->records = n;
    ga->requests.reserve(n / 4 + 8);
    const uint32_t waves = uint32_t((per_group + width_ - 1) / width_);
    const LaneAccess* recs = recs_.data();
    for (uint32_t w = 0; w < waves; ++w) {
      const uint32_t l0 = w * width_;
      const uint32_t lanes = uint32_t(std::min<uint64_t>(width_, per_group - l0));
      const uint32_t lane_base = uint32_t(first_invocation + l0);
      const uint32_t e0 = at_[l0], e1 = at_[l0 + lanes];
      if (e0 == e1) {
        ga->wave_steps_end.push_back(uint32_t(ga->step_end.size()));
        continue;
      }
      bool strict = true;
      uint32_t lo = ~0u, hi = 0;
      for (uint32_t l = 0; l < lanes; ++l) {
        strict &= strict_[l0 + l] != 0;
        if (at_[l0 + l] < at_[l0 + l + 1]) {
          lo = std::min(lo, recs[at_[l0 + l]].seq);
          hi = std::max(hi, recs[at_[l0 + l + 1] - 1].seq);
        }
      }
      const uint64_t range = uint64_t(hi) - lo + 1;
      if (strict && range <= 4 * uint64_t(e1 - e0) + 64) {
        // Counting sort of the wavefront's accesses by seq, lanes in order within each seq.
        seq_count_.assign(range + 1, 0);
        for (uint32_t k = e0; k < e1; ++k) ++seq_count_[recs[k].seq - lo + 1];
        for (uint64_t q = 0; q < range; ++q) seq_count_[q + 1] += seq_count_[q];
        step_recs_.resize(e1 - e0);
        seq_cursor_.assign(seq_count_.begin(), seq_count_.end() - 1);
        for (uint32_t l = 0; l < lanes; ++l)
          for (uint32_t k = at_[l0 + l]; k < at_[l0 + l + 1]; ++k) {
            // The seq field is not needed past this point: it carries the lane.
            step_recs_[seq_cursor_[recs[k].seq - lo]++] = LaneAccess{recs[k].address, l, recs[k].info};
          }
        const LaneAccess* steps = step_recs_.data();
        for (uint64_t q = 0; q < range; ++q) {
          const uint32_t s0 = seq_count_[q], s1 = seq_count_[q + 1];
          if (s0 == s1) continue;
          co_.begin();
          for (uint32_t j = s0; j < s1; ++j)
            co_.add(steps[j].address, steps[j].info, lane_base + steps[j].seq, steps[j].seq, per_inv_);
          end_step(*ga);
        }
        ga->wave_steps_end.push_back(uint32_t(ga->step_end.size()));
        continue;
      }
      // General case (repeated seqs, sparse seqs): each step takes the lanes whose next access has the
      // lowest pending seq.
      uint32_t* c = at_.data() + l0;  // at_[] becomes each lane's cursor; at_[l0 + l + 1] is still its end
      end_.assign(at_.begin() + l0 + 1, at_.begin() + l0 + lanes + 1);
      const uint32_t* end = end_.data();
      // The lowest pending seq; 2^32: no access left. Each step finds the next one as it goes.
      uint64_t step_seq = uint64_t(1) << 32;
      for (uint32_t l = 0; l < lanes; ++l)
        if (c[l] < end[l]) step_seq = std::min<uint64_t>(step_seq, recs[c[l]].seq);
      while (step_seq >> 32 == 0) {
        uint64_t next = uint64_t(1) << 32;
        co_.begin();
        for (uint32_t l = 0; l < lanes; ++l) {
          if (c[l] == end[l]) continue;
          const LaneAccess& a = recs[c[l]];
          if (a.seq != step_seq) {
            next = std::min<uint64_t>(next, a.seq);
            continue;
          }
          co_.add(a.address, a.info, lane_base + l, l, per_inv_);
          if (++c[l] < end[l]) next = std::min<uint64_t>(next, recs[c[l]].seq);
        }
        end_step(*ga);
        step_seq = next;
      }
      ga->wave_steps_end.push_back(uint32_t(ga->step_end.size()));
    }
    return ga;
  }

  // The L1 load lookups of every step this builder coalesced, by buffer.
  std::array<L1Lookups, 256> lookups{};

 private:
  // Whether a workgroup's records come in issue order: by seq, then by invocation, no (invocation, seq)
  // twice. A version-2 trace decodes to that order (trace_codec.hpp), and then every lane's seqs strictly
  // increase, so a wavefront's steps are its lanes' records of each seq in turn, taken as they come:
  // no per-lane gather and no sort.
  static bool in_issue_order(const trace::TraceRecord* in, uint64_t n) {
    uint64_t prev = 0;
    for (uint64_t k = 0; k < n; ++k) {
      const uint64_t key = uint64_t(in[k].seq) << 32 | in[k].invocation;
      if (k && key <= prev) return false;
      prev = key;
    }
    return true;
  }

  // The wave steps of a workgroup whose records are in issue order (in_issue_order): the same steps, in
  // the same order, as the general path below makes of them.
  std::unique_ptr<GroupRequests> build_in_order(const trace::TraceRecord* in, uint64_t n, uint64_t first_invocation,
                                                uint64_t per_group) {
    std::unique_ptr<GroupRequests> ga = pool_.take();
    ga->records = n;
    ga->requests.reserve(n / 4 + 8);
    // Where each seq's records start (and, as `cursor_`, how far each wave has taken them).
    seq_start_.clear();
    for (uint64_t k = 0; k < n; ++k)
      if (k == 0 || in[k].seq != in[k - 1].seq) seq_start_.push_back(uint32_t(k));
    seq_start_.push_back(uint32_t(n));
    const size_t seqs = seq_start_.size() - 1;
    seq_cursor_.assign(seq_start_.begin(), seq_start_.end() - 1);
    const uint32_t waves = uint32_t((per_group + width_ - 1) / width_);
    for (uint32_t w = 0; w < waves; ++w) {
      const uint32_t l0 = w * width_;
      const uint64_t lane_end = first_invocation + std::min<uint64_t>(per_group, uint64_t(l0) + width_);
      const uint32_t lane_base = uint32_t(first_invocation + l0);
      for (size_t q = 0; q < seqs; ++q) {
        uint32_t k = seq_cursor_[q];
        const uint32_t end = seq_start_[q + 1];
        if (k == end || in[k].invocation >= lane_end) continue;  // no lane of this wave has this seq
        co_.begin();
        for (; k < end && in[k].invocation < lane_end; ++k) {
          const trace::TraceRecord& r = in[k];
          const trace::BufferInfo& b = *buffers_[gpu::trace_buffer(r.info)];
          const uint64_t address = b.kind == trace::BufferKind::buffer ? b.base_address + r.offset
                                                                       : maps_[gpu::trace_buffer(r.info)](r.offset);
          co_.add(address, r.info, r.invocation, r.invocation - lane_base, per_inv_);
        }
        seq_cursor_[q] = k;
        end_step(*ga);
      }
      ga->wave_steps_end.push_back(uint32_t(ga->step_end.size()));
    }
    return ga;
  }

  // Closes the coalescer's current step: appends its requests (and lane entries) to `ga` and counts its
  // L1 lookups under every HitCounting (they do not depend on the caches' state) into `into` (by buffer;
  // null: `lookups`), marking each buffer counted in `touched` (a bit per buffer) when given.
  void end_step(GroupRequests& ga, L1Lookups* into = nullptr, uint64_t* touched = nullptr) {
    if (!into) into = lookups.data();
    const uint32_t base = uint32_t(ga.requests.size());
    for (size_t k = 0; k < co_.requests.size(); ++k) {
      const Request& q = co_.requests[k];
      if (q.kind != AccessKind::load) continue;  // stores and atomics do not look the L1 up
      if (touched) touched[q.buffer >> 6] |= uint64_t(1) << (q.buffer & 63);
      L1Lookups& l = into[q.buffer];
      ++l.request;
      l.quarter_wave += count_bits(uint32_t(co_.quarters[k]));
      l.lane += co_.lanes[k];
    }
    ga.requests.insert(ga.requests.end(), co_.requests.begin(), co_.requests.end());
    ga.step_end.push_back(uint32_t(ga.requests.size()));
    if (per_inv_) {
      for (const auto& [inv, req] : co_.lane_request) ga.lanes.emplace_back(inv, base + req);
      ga.step_lanes_end.push_back(uint32_t(ga.lanes.size()));
    }
  }

  // Walks a coding-2 workgroup body [p, end): begin_step() at each step, record(lane, seq, info, address,
  // offset, same) for each record, checked, in coded order (same: the step's previous record has the same
  // info word and offset), end_step(records of the step) after it. With
  // `stop_at_repeat`, returns false as soon as a lane comes twice in a step (the walk is then incomplete);
  // true once the whole body is walked. Throws CodedSliceRejected on any defect.
  template <typename BeginStep, typename Record, typename EndStep>
  bool walk_coded(const uint8_t* p, const uint8_t* end, uint64_t per_group, bool stop_at_repeat, BeginStep&& begin_step,
                  Record&& record, EndStep&& end_step) {
    const auto reject = [] { throw CodedSliceRejected(); };
    uint64_t steps = 0;
    p = trace::read_varint(p, steps);
    if (!p || p > end || steps == 0) reject();
    trace::CodedState state;
    // The info word last checked, and what it names: its buffer, the access size, whether offsets map to
    // addresses directly.
    uint32_t info = ~0u;
    const trace::BufferInfo* buffer = nullptr;
    uint32_t size = 0;
    bool plain = true;
    const AddressMap* map = nullptr;
    // The previous record's access (info word, offset) and its address.
    uint32_t record_info = 0, offset = 0;
    uint64_t address = 0;
    uint64_t seq = 0;
    for (uint64_t st = 0; st < steps; ++st) {
      uint64_t delta = 0, n = 0;
      p = trace::read_varint(p, delta);
      if (p) p = trace::read_varint(p, n);
      if (!p || p > end) reject();
      seq = st == 0 ? delta : seq + delta + 1;
      if (seq > 0xFFFFFFFFu) reject();
      ++n;
      begin_step();
      int64_t lane = -1;
      for (uint64_t k = 0; k < n; ++k) {
        uint64_t d = 0;
        p = trace::decode_record(p, state, d);
        if (!p) reject();
        if (d == 0 && k > 0 && stop_at_repeat) return false;
        lane += int64_t(d);
        if (uint64_t(lane) >= per_group) reject();
        if (state.info != info) {
          info = state.info;
          if ((info & HP_TRACE_RESERVED_MASK) || gpu::trace_kind(info) > HP_TRACE_ATOMIC) reject();
          buffer = buffers_[gpu::trace_buffer(info)];
          if (!buffer) reject();
          size = gpu::trace_size(info);
          plain = buffer->kind == trace::BufferKind::buffer;
          map = &maps_[gpu::trace_buffer(info)];
        }
        // A record repeating the previous one's access (another lane reading the same bytes, the usual case
        // in a coherent step) was checked and mapped with it.
        if (k == 0 || state.offset != offset || state.info != record_info) {
          if (uint64_t(state.offset) + size > buffer->size_bytes) reject();  // as the reader compares
          offset = state.offset;
          record_info = info;
          address = plain ? buffer->base_address + offset : (*map)(offset);
          record(uint32_t(lane), uint32_t(seq), info, address, offset, false);
        } else {
          record(uint32_t(lane), uint32_t(seq), info, address, offset, true);
        }
        if (p > end) reject();
      }
      end_step(n);
    }
    if (p != end) reject();
    return true;
  }

  GroupPool& pool_;
  Coalescer co_;
  const trace::BufferInfo* const* buffers_;
  uint32_t width_;
  bool per_inv_;
  struct LaneAccess {
    uint64_t address;
    uint32_t seq, info;
  };
  std::vector<LaneAccess> recs_, step_recs_;
  std::vector<uint32_t> at_, cursor32_, end_, seq_count_, seq_cursor_, seq_start_;
  std::vector<uint8_t> strict_;
  std::array<AddressMap, 256> maps_;         // by buffer id
  std::vector<trace::TraceRecord> scratch_;  // a coded workgroup decoded (build_coded's general way)
  std::array<L1Lookups, 256> pending_{};     // a coded workgroup's lookups until it is whole
  std::array<uint64_t, 4> pending_touched_{};
};

// A resident wavefront. It reads its workgroup's arrays (laid out in issue order and not changed once
// built; owned by the resident workgroup until it retires) through its own copies of their data
// pointers and where its next step starts, so that issuing a step does not first chase the workgroup's
// object and step table.
struct Wave {
  const Request* requests;
  const uint32_t* step_end;
  const std::pair<uint32_t, uint32_t>* lanes;
  const uint32_t* step_lanes_end;
  uint64_t workgroup;
  uint32_t next_step, end_step;  // its steps in step_end
  uint32_t next_request;         // where its next step's requests start
  uint32_t next_lane;            // where its next step's lane entries start (per_invocation)
};

struct ResidentGroup {
  uint64_t workgroup;
  std::unique_ptr<GroupRequests> data;
  uint32_t waves_left;
};

struct ComputeUnit {
  std::vector<Wave> waves;
  std::vector<ResidentGroup> groups;
  uint32_t resident_waves = 0;
  size_t next = 0;  // round-robin position in waves
};

// Thrown inside the scheduler thread when the simulator is destroyed mid-pass.
struct Abandoned {};

constexpr size_t kPieceRecords = 1 << 16;  // records per piece handed to the scheduler (about)
constexpr size_t kQueuedPieces = 8;        // pieces built ahead of the scheduler at most
constexpr size_t kIssueBatch = 4096;       // requests queued before the hierarchy takes them

}  // namespace

// One pass in flight. The calling thread (feed) checks and buckets each slice; it and a helper thread
// then build its pieces (workgroups grouped into wave steps and coalesced), which a scheduler thread
// takes in workgroup order to run the SIMT schedule and the caches. The scheduler waits where it would
// dispatch a workgroup no piece has brought yet, so every decision is the one a single-threaded replay
// makes, whatever the threads' timing; the resident-record count is kept in the scheduler's logical
// time (a feed's records count from the moment the scheduler needs its first workgroup), so it does not
// depend on the timing either.
struct Simulator::PassState {
  trace::PassInfo info;
  PassResult res;
  uint64_t per_group = 0, groups = 0, invocations = 0;
  uint32_t waves_per_group = 0;
  // Caller side.
  uint64_t fed_end = 0;  // workgroups below this were fed or are empty
  bool ended = false;
  uint64_t lane_accesses = 0;
  uint32_t slices = 0;
  Buckets buckets;
  GroupPool pool;
  Builder builder, helper_builder;
  // The slice being built: pieces [g0, g1) of workgroups (relative to the slice), claimed in order.
  std::vector<std::pair<uint64_t, uint64_t>> jobs;
  std::vector<std::unique_ptr<Piece>> built;
  size_t next_job = 0, published = 0, jobs_done = 0;
  uint64_t feed_records = 0;
  uint64_t built_records = 0;   // lane accesses of the slice's workgroups built so far
  uint64_t job_generation = 0;  // bumped per slice: wakes the helper
  std::exception_ptr build_error;
  bool stop_helper = false;
  std::condition_variable cv_jobs, cv_built;
  std::thread helper;
  // Shared, under m.
  std::mutex m;
  std::condition_variable cv_fed, cv_space;
  std::deque<std::unique_ptr<Piece>> queue;
  bool final = false, abandon = false, sched_done = false;
  std::exception_ptr error;
  // Scheduler side.
  std::vector<ComputeUnit> cu;
  std::deque<std::unique_ptr<Piece>> pieces;  // taken from the queue, not yet fully dispatched
  uint64_t known_end = 0;                     // workgroups below this are known to the scheduler
  bool all_known = false;
  uint64_t next_group = 0;
  uint64_t resident_records = 0;
  std::vector<Request> batch;
  std::vector<uint32_t> batch_cu;
  std::vector<std::pair<uint32_t, uint32_t>> batch_lanes;
  std::vector<IssueResult> outcome;
  std::thread thread;

  PassState(const Preset& preset, const Cache& l1, const trace::BufferInfo* const* buffers, bool per_invocation)
      : buckets(buffers),
        builder(preset, l1, buffers, per_invocation, pool),
        helper_builder(preset, l1, buffers, per_invocation, pool) {}

  // Hands a piece to the scheduler (under m).
  void publish_locked(std::unique_ptr<Piece> p) {
    queue.push_back(std::move(p));
    cv_fed.notify_one();
  }

  // Builds pieces of the current slice until none is left unclaimed. Both builders run it.
  void run_jobs(Builder& b) {
    std::unique_lock lk(m);
    while (next_job < jobs.size()) {
      const size_t k = next_job++;
      const auto [g0, g1] = jobs[k];
      lk.unlock();
      auto p = std::make_unique<Piece>();
      const uint64_t first = buckets.first_group();
      p->first_group = first + g0;
      p->end_group = first + g1;
      p->first_of_feed = k == 0;
      p->feed_records = k == 0 ? feed_records : 0;
      uint64_t records = 0;
      try {
        p->groups.reserve(g1 - g0);
        for (uint64_t g = g0; g < g1; ++g) {
          p->groups.push_back(b.build(buckets, g));
          if (p->groups.back()) records += p->groups.back()->records;
        }
      } catch (...) {  // out of memory: feed() rethrows it once every job of the slice has ended
        lk.lock();
        if (!build_error) build_error = std::current_exception();
        if (++jobs_done == jobs.size()) cv_built.notify_all();
        continue;
      }
      lk.lock();
      built_records += records;
      built[k] = std::move(p);
      while (published < built.size() && built[published]) publish_locked(std::move(built[published++]));
      if (++jobs_done == jobs.size()) cv_built.notify_all();
    }
  }

  void helper_loop() {
    uint64_t seen = 0;
    std::unique_lock lk(m);
    while (true) {
      cv_jobs.wait(lk, [&] { return stop_helper || job_generation != seen; });
      if (stop_helper) return;
      seen = job_generation;
      lk.unlock();
      run_jobs(helper_builder);
      lk.lock();
    }
  }

  void stop_helper_thread() {
    if (!helper.joinable()) return;
    {
      std::lock_guard lk(m);
      stop_helper = true;
    }
    cv_jobs.notify_all();
    helper.join();
  }

  // Scheduler: takes pieces until workgroup g is known or no more will come.
  void await(uint64_t g) {
    while (g >= known_end && !all_known) {
      std::unique_lock lk(m);
      cv_fed.wait(lk, [&] { return !queue.empty() || final || abandon; });
      if (abandon) throw Abandoned{};
      if (queue.empty()) {
        all_known = true;
        break;
      }
      std::unique_ptr<Piece> p = std::move(queue.front());
      queue.pop_front();
      lk.unlock();
      cv_space.notify_one();
      if (p->first_of_feed) {
        resident_records += p->feed_records;
        res.peak_resident_records = std::max(res.peak_resident_records, resident_records);
      }
      known_end = p->end_group;
      pieces.push_back(std::move(p));
    }
  }

  // Takes workgroup g's requests out of its piece (null: none); drops pieces fully handed out.
  std::unique_ptr<GroupRequests> take(uint64_t g) {
    await(g);
    std::unique_ptr<GroupRequests> out;
    for (auto& p : pieces)
      if (g >= p->first_group && g < p->end_group) {
        out = std::move(p->groups[g - p->first_group]);
        break;
      }
    while (!pieces.empty() && pieces.front()->end_group <= g + 1) pieces.pop_front();
    return out;
  }
};

Simulator::Simulator(const Preset& preset, const trace::TraceHeader& header, SimOptions options)
    : preset_(preset),
      buffer_storage_(header.buffers),
      options_(std::move(options)),
      hierarchy_(preset.l1, preset.compute_units, preset.l2) {
  for (const auto& b : buffer_storage_) buffers_[b.id & 0xFF] = &b;
  if (options_.l1_mrc || options_.l2_mrc)
    hierarchy_.enable_mrc(options_.l1_mrc, options_.l2_mrc, options_.mrc_sampling_rate);
}

Simulator::~Simulator() { stop(); }

void Simulator::stop() {
  if (!pass_) return;
  pass_->stop_helper_thread();
  if (!pass_->thread.joinable()) return;
  {
    std::lock_guard lk(pass_->m);
    pass_->abandon = true;
  }
  pass_->cv_fed.notify_all();
  pass_->thread.join();
}

PassResult Simulator::run_pass(const trace::PassInfo& pass, std::span<const trace::TraceRecord> records) {
  begin_pass(pass);
  feed(records, 0, pass.dispatch.workgroups());
  return end_pass();
}

void Simulator::begin_pass(const trace::PassInfo& pass) {
  const auto& d = pass.dispatch;
  if (d.invocations() > 0xFFFFFFFFull) throw InputError("pass '" + pass.name + "': 2^32 invocations or more");
  stop();
  pass_.reset();
  pass_ = std::make_unique<PassState>(preset_, hierarchy_.l1(0), buffers_, options_.per_invocation);
  PassState& ps = *pass_;
  ps.info = pass;
  ps.per_group = d.invocations_per_workgroup();
  ps.groups = d.workgroups();
  ps.invocations = d.invocations();
  ps.waves_per_group = uint32_t((ps.per_group + preset_.wave_width - 1) / preset_.wave_width);
  ps.cu.resize(preset_.compute_units);
  ps.res.name = pass.name;
  ps.res.workgroups = ps.groups;
  if (options_.per_invocation) {
    ps.res.l1_misses.assign(ps.invocations, 0);
    ps.res.l2_misses.assign(ps.invocations, 0);
  }
  hierarchy_.begin_pass();
  if (std::thread::hardware_concurrency() > 1) ps.helper = std::thread([&ps] { ps.helper_loop(); });
  ps.thread = std::thread([this] {
    PassState& s = *pass_;
    try {
      schedule();
      issue_batch();
    } catch (const Abandoned&) {
    } catch (...) {
      s.error = std::current_exception();
    }
    {
      std::lock_guard lk(s.m);
      s.sched_done = true;
    }
    s.cv_space.notify_all();
  });
}

void Simulator::feed(std::span<const trace::TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup,
                     const uint32_t* group_begin) {
  feed_slice(first_workgroup, end_workgroup, records.size(), [&](PassState& ps) {
    const bool filled =
        group_begin ? ps.buckets.fill_indexed(records, first_workgroup, end_workgroup, ps.per_group, group_begin)
                    : ps.buckets.fill(records, first_workgroup, end_workgroup, ps.per_group);
    if (!filled)
      throw InputError("pass '" + ps.info.name + "': record outside its slice's workgroups or the buffer table");
  });
}

void Simulator::feed_coded(const trace::CodedSlice& slice, uint64_t first_workgroup, uint64_t end_workgroup) {
  if (slice.bodies.size() != end_workgroup - first_workgroup)
    throw std::logic_error("Simulator::feed_coded: the slice's index does not match its workgroups");
  if (first_workgroup == end_workgroup && slice.count != 0) throw CodedSliceRejected();
  feed_slice(first_workgroup, end_workgroup, slice.count,
             [&](PassState& ps) { ps.buckets.fill_coded(slice, first_workgroup, ps.per_group); });
  // Every record of the slice was built, no more and no fewer (a record count the coding does not hold
  // is a defect like any other).
  if (pass_->built_records != slice.count) {
    pass_->build_error = std::make_exception_ptr(CodedSliceRejected());
    throw CodedSliceRejected();
  }
}

template <typename Fill>
void Simulator::feed_slice(uint64_t first_workgroup, uint64_t end_workgroup, uint64_t count, Fill&& fill) {
  if (!pass_ || pass_->ended) throw std::logic_error("Simulator::feed outside begin_pass / end_pass");
  PassState& ps = *pass_;
  const std::string& name = ps.info.name;
  if (first_workgroup > end_workgroup || end_workgroup > ps.groups)
    throw InputError("pass '" + name + "': slice of workgroups [" + std::to_string(first_workgroup) + ", " +
                     std::to_string(end_workgroup) + ") outside the dispatch of " + std::to_string(ps.groups));
  if (first_workgroup < ps.fed_end)
    throw InputError("pass '" + name + "': slice [" + std::to_string(first_workgroup) + ", " +
                     std::to_string(end_workgroup) + ") overlaps or precedes workgroup " + std::to_string(ps.fed_end) +
                     " (slices must come in dispatch order)");
  if (end_workgroup == first_workgroup) {
    if (count != 0) throw InputError("pass '" + name + "': record outside its slice's workgroups or the buffer table");
    // Nothing fed, but the workgroups before it are known to be empty now.
    ps.fed_end = end_workgroup;
    auto p = std::make_unique<Piece>();
    p->first_group = p->end_group = end_workgroup;
    std::lock_guard lk(ps.m);
    ps.publish_locked(std::move(p));
    return;
  }
  fill(ps);
  ps.fed_end = end_workgroup;
  ps.lane_accesses += count;
  ps.slices += count != 0;
  // Pieces of about kPieceRecords records (and at least one workgroup); the last ends at the slice's end
  // so that the workgroups after its records become known too.
  const uint64_t groups = end_workgroup - first_workgroup;
  std::unique_lock lk(ps.m);
  // At most kQueuedPieces pieces wait for the scheduler before a new slice is built: bounded memory.
  ps.cv_space.wait(lk, [&] { return ps.queue.size() < kQueuedPieces || ps.sched_done; });
  ps.jobs.clear();
  for (uint64_t g = 0; g < groups;) {
    const uint64_t g0 = g;
    uint64_t taken = 0;
    while (g < groups && (taken < kPieceRecords || g == g0)) taken += ps.buckets.weight(g++);
    ps.jobs.emplace_back(g0, g);
  }
  ps.built.clear();
  ps.built.resize(ps.jobs.size());
  ps.next_job = ps.published = ps.jobs_done = 0;
  ps.built_records = 0;
  ps.feed_records = count;
  ++ps.job_generation;
  lk.unlock();
  ps.cv_jobs.notify_all();
  ps.run_jobs(ps.builder);
  // The records and buckets must outlive every build of this slice: wait for the helper's last one.
  lk.lock();
  ps.cv_built.wait(lk, [&] { return ps.jobs_done == ps.jobs.size(); });
  if (ps.build_error) std::rethrow_exception(ps.build_error);
}

PassResult Simulator::end_pass() {
  if (!pass_ || pass_->ended) throw std::logic_error("Simulator::end_pass without begin_pass");
  PassState& ps = *pass_;
  ps.ended = true;
  {
    std::lock_guard lk(ps.m);
    ps.final = true;
  }
  ps.cv_fed.notify_all();
  ps.thread.join();
  ps.stop_helper_thread();
  if (ps.error || ps.build_error) {  // a failed build leaves workgroups out: no result for this pass
    std::exception_ptr e = ps.error ? ps.error : ps.build_error;
    pass_.reset();
    std::rethrow_exception(e);
  }
  PassResult res = std::move(ps.res);
  res.lane_accesses = ps.lane_accesses;
  res.slices = ps.slices;
  // Every fed workgroup was built by one of the two builders and issued by the scheduler.
  for (size_t b = 0; b < res.buffer_l1_lookups.size(); ++b) {
    L1Lookups& l = res.buffer_l1_lookups[b];
    l = ps.builder.lookups[b];
    l.add(ps.helper_builder.lookups[b]);
    res.l1_lookups.add(l);
  }
  pass_.reset();
  res.stats = hierarchy_.stats();
  res.buffers = hierarchy_.buffers();
  // The preset's counting: lookups and hits change, misses do not (the first lookup of a request is
  // the one that misses).
  const HitCounting counting = preset_.l1_hit_counting;
  res.l1_hit_counting = counting;
  if (counting != HitCounting::request) {
    res.stats.l1.requests = res.l1_lookups.of(counting);
    res.stats.l1.hits = res.stats.l1.requests - res.stats.l1.misses;
    for (size_t b = 0; b < res.buffers.size(); ++b) res.buffers[b].l1_requests = res.buffer_l1_lookups[b].of(counting);
  }
  if (options_.l1_mrc) res.l1_curve = hierarchy_.l1_curve();
  if (options_.l2_mrc) res.l2_curve = hierarchy_.l2_curve();
  return res;
}

void Simulator::issue_batch() {
  PassState& ps = *pass_;
  if (ps.batch.empty()) return;
  const bool per_inv = options_.per_invocation;
  if (per_inv && ps.outcome.size() < ps.batch.size()) ps.outcome.resize(ps.batch.size());
  hierarchy_.issue(std::span<const Request>(ps.batch), std::span<const uint32_t>(ps.batch_cu),
                   per_inv ? ps.outcome.data() : nullptr);
  if (per_inv) {
    PassResult& res = ps.res;
    const IssueResult* o = ps.outcome.data();
    for (const auto& [inv, r] : ps.batch_lanes) {
      res.l1_misses[inv] += o[r].l1_miss;
      res.l2_misses[inv] += o[r].l2_miss;
    }
  }
  ps.batch.clear();
  ps.batch_cu.clear();
  ps.batch_lanes.clear();
}

// Runs the whole pass on the scheduler thread, waiting for pieces as it needs them.
void Simulator::schedule() {
  PassState& ps = *pass_;
  PassResult& res = ps.res;
  const bool per_inv = options_.per_invocation;
  const uint32_t cus = preset_.compute_units;

  // Places workgroup next_group's wavefronts on a CU; wavefronts without accesses never become
  // resident, and a workgroup without any never does.
  auto dispatch = [&](ComputeUnit& c) {
    const uint64_t g = ps.next_group++;
    res.waves += ps.waves_per_group;
    std::unique_ptr<GroupRequests> ga = ps.take(g);
    if (!ga) return;  // a workgroup without accesses
    uint32_t placed = 0;
    for (uint32_t w = 0; w < ps.waves_per_group; ++w) {
      const uint32_t s0 = w ? ga->wave_steps_end[w - 1] : 0, s1 = ga->wave_steps_end[w];
      if (s0 == s1) continue;  // a wavefront without accesses
      c.waves.push_back(Wave{ga->requests.data(), ga->step_end.data(), ga->lanes.data(), ga->step_lanes_end.data(), g,
                             s0, s1, s0 ? ga->step_end[s0 - 1] : 0, per_inv && s0 ? ga->step_lanes_end[s0 - 1] : 0});
      ++placed;
    }
    c.groups.push_back(ResidentGroup{g, std::move(ga), placed});
    c.resident_waves += placed;
  };
  auto has_room = [&](const ComputeUnit& c) {
    return c.resident_waves == 0 || c.resident_waves + ps.waves_per_group <= preset_.max_waves_per_cu;
  };
  // Sweeps the CUs round-robin, one workgroup to each with room, until a sweep places nothing or no
  // workgroup is left.
  auto refill = [&] {
    bool progress = true;
    while (progress && ps.next_group < ps.groups) {
      progress = false;
      for (uint32_t i = 0; i < cus && ps.next_group < ps.groups; ++i)
        if (has_room(ps.cu[i])) {
          dispatch(ps.cu[i]);
          progress = true;
        }
    }
  };

  refill();
  while (true) {
    bool any = false, freed = false;
    for (uint32_t i = 0; i < cus; ++i) {
      ComputeUnit& c = ps.cu[i];
      if (c.waves.empty()) continue;
      any = true;
      if (c.next >= c.waves.size()) c.next = 0;
      Wave& w = c.waves[c.next];
      const uint32_t r0 = w.next_request, r1 = w.step_end[w.next_step];
      w.next_request = r1;
      ++res.wave_steps;
      if (options_.observer)
        for (uint32_t k = r0; k < r1; ++k) options_.observer(i, w.requests[k]);
      // Queued for the hierarchy, which takes them in batches (the same results: nothing the
      // scheduler does depends on them).
      const uint32_t base = uint32_t(ps.batch.size());
      ps.batch.insert(ps.batch.end(), w.requests + r0, w.requests + r1);
      ps.batch_cu.insert(ps.batch_cu.end(), r1 - r0, i);
      if (per_inv) {
        const uint32_t l1 = w.step_lanes_end[w.next_step];
        for (uint32_t k = w.next_lane; k < l1; ++k)
          ps.batch_lanes.emplace_back(w.lanes[k].first, base + (w.lanes[k].second - r0));
        w.next_lane = l1;
      }
      if (ps.batch.size() >= kIssueBatch) issue_batch();
      if (++w.next_step == w.end_step) {
        const uint64_t g = w.workgroup;
        c.waves.erase(c.waves.begin() + int64_t(c.next));  // next now points at the following wave
        --c.resident_waves;
        for (size_t k = 0; k < c.groups.size(); ++k)
          if (c.groups[k].workgroup == g && --c.groups[k].waves_left == 0) {
            ps.resident_records -= c.groups[k].data->records;
            ps.pool.give(std::move(c.groups[k].data));
            c.groups.erase(c.groups.begin() + int64_t(k));
            freed = true;
            break;
          }
      } else {
        ++c.next;
      }
    }
    if (!any && ps.next_group >= ps.groups) return;
    ++res.cycles;
    if (freed || !any) refill();
  }
}

bool Simulator::buffers_match(const std::vector<trace::BufferInfo>& buffers) const {
  if (buffers.size() != buffer_storage_.size()) return false;
  for (const trace::BufferInfo& b : buffers) {
    if (b.id >= 256 || !buffers_[b.id]) return false;
    const trace::BufferInfo& o = *buffers_[b.id];
    if (o.base_address != b.base_address || o.size_bytes != b.size_bytes || o.kind != b.kind ||
        o.texel_bytes != b.texel_bytes || o.width != b.width || o.height != b.height ||
        o.row_pitch_bytes != b.row_pitch_bytes || o.tile_width != b.tile_width || o.tile_height != b.tile_height)
      return false;
  }
  return true;
}

void feed_slices(Simulator& sim, const trace::TraceReader& reader, uint32_t pass,
                 const std::function<void(uint64_t records_done)>& on_slice) {
  uint64_t done = 0;
  // The reader validates each record against its header's buffer table. Where the simulator's table is the
  // same, the simulator checks records itself: it takes a coding-2 slice as coded (built straight from the
  // coding, checked as it is decoded) and a decoded version-2 slice with its workgroup index instead of
  // scanning the records again.
  if (sim.buffers_match(reader.header().buffers)) {
    try {
      reader.read_slices_coded(pass, [&](std::span<const trace::TraceRecord> records, const trace::CodedSlice* coded,
                                         uint64_t first, uint64_t end, const uint32_t* group_begin) {
        if (coded) {
          sim.feed_coded(*coded, first, end);
          done += coded->count;
        } else {
          sim.feed(records, first, end, group_begin);
          done += records.size();
        }
        if (on_slice) on_slice(done);
      });
    } catch (const CodedSliceRejected&) {
      // The careful read of the pass names the first defect (and throws it).
      reader.read_slices(pass, [](std::span<const trace::TraceRecord>, uint64_t, uint64_t) {});
      throw std::logic_error("a coded slice of pass " + std::to_string(pass) +
                             " was rejected, but reads without error when decoded");
    }
    return;
  }
  const bool trusted = std::all_of(reader.header().buffers.begin(), reader.header().buffers.end(),
                                   [&](const trace::BufferInfo& b) { return sim.knows_buffer(b.id); });
  reader.read_slices_indexed(pass, [&](std::span<const trace::TraceRecord> records, uint64_t first, uint64_t end,
                                       const uint32_t* group_begin) {
    sim.feed(records, first, end, trusted ? group_begin : nullptr);
    done += records.size();
    if (on_slice) on_slice(done);
  });
}

uint64_t Simulator::finish() {
  const uint64_t before = hierarchy_.stats().dram_write_bytes;
  hierarchy_.flush();
  return hierarchy_.stats().dram_write_bytes - before;
}

uint64_t export_din(std::ostream& out, const Preset& preset, const trace::TraceHeader& header,
                    const trace::PassInfo& pass, std::span<const trace::TraceRecord> records, uint32_t cu,
                    bool include_stores) {
  return export_din(
      out, preset, header, pass, [&](Simulator& sim) { sim.feed(records, 0, pass.dispatch.workgroups()); }, cu,
      include_stores);
}

std::function<void(uint32_t, const Request&)> din_observer(std::ostream& out, const Preset& preset, uint32_t cu,
                                                           bool include_stores, uint64_t& lines) {
  if (cu >= preset.compute_units)
    throw InputError("--export-din: compute unit " + std::to_string(cu) + " does not exist (preset '" + preset.name +
                     "' has " + std::to_string(preset.compute_units) + ")");
  const uint32_t line_shift = uint32_t(std::countr_zero(preset.l1.line_bytes));
  const uint32_t sector_bytes = preset.l1.sector_bytes;
  return [&out, &lines, cu, include_stores, line_shift, sector_bytes](uint32_t c, const Request& r) {
    if (c != cu || r.kind == AccessKind::atomic) return;  // atomics bypass the L1
    if (r.kind == AccessKind::store && !include_stores) return;
    // One Dinero access per contiguous run of sectors: it covers exactly what the L1 was asked for.
    uint32_t m = r.sectors;
    while (m) {
      const uint32_t s0 = uint32_t(std::countr_zero(m));
      const uint32_t run = uint32_t(std::countr_one(m >> s0));
      trace::write_din_line(out, trace::DinAccess{r.kind == AccessKind::store,
                                                  (r.line << line_shift) + s0 * sector_bytes, run * sector_bytes});
      ++lines;
      m &= run == 32 ? 0u : ~(((1u << run) - 1) << s0);
    }
  };
}

uint64_t export_din(std::ostream& out, const Preset& preset, const trace::TraceHeader& header,
                    const trace::PassInfo& pass, const std::function<void(Simulator&)>& feed, uint32_t cu,
                    bool include_stores) {
  uint64_t lines = 0;
  SimOptions opt;
  opt.per_invocation = false;
  opt.observer = din_observer(out, preset, cu, include_stores, lines);
  Simulator sim(preset, header, std::move(opt));
  sim.begin_pass(pass);
  feed(sim);
  sim.end_pass();
  return lines;
}

}  // namespace hp::cachesim
