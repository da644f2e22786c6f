// The former simulator.cpp (see baseline_simulator.hpp): the straightforward path the tests compare against.
#include "baseline_simulator.hpp"

#include <algorithm>
#include <bit>
#include <ostream>
#include <stdexcept>

#include "error.hpp"
#include "trace/din.hpp"

namespace hp::cachesim::baseline {

namespace {

// Working memory of group(), kept from slice to slice.
struct GroupScratch {
  std::vector<uint64_t> begin, cursor;
  std::vector<uint32_t> order, lane_cursor, lane_end;
  std::vector<trace::TraceRecord> group;
};

// One workgroup's accesses in the order its wavefronts will issue them: per wavefront, its lockstep steps
// (each step: the lanes whose next access has the lowest pending sequence number, in lane order), with
// addresses resolved. Lanes stay in lockstep by seq, and a capture can realign lanes after divergence by
// giving the accesses after a reconvergence point a common seq. A wavefront's steps depend on its own
// lanes' records only, so they are fixed here, once, while the workgroup's records are hot in the host's
// caches; the scheduler then streams through them. Freed when the workgroup retires.
struct GroupAccesses {
  uint64_t first_invocation = 0;         // global index of the workgroup's first invocation
  std::vector<uint64_t> address;         // byte address, in issue order
  std::vector<uint32_t> info;            // the record's info word (size, kind, buffer)
  std::vector<uint16_t> lane;            // the issuing lane within its wavefront
  std::vector<uint32_t> step_end;        // per step (all wavefronts' steps in order): end of its entries
  std::vector<uint32_t> wave_steps_end;  // per wavefront: end of its steps in step_end
};

// Splits one slice's records (already checked to lie in its workgroups) into per-workgroup issue orders;
// workgroups without records get none. `scratch` is reused from slice to slice (no fresh pages each time).
std::vector<std::unique_ptr<GroupAccesses>> group(std::span<const trace::TraceRecord> records, uint64_t first_group,
                                                  uint64_t end_group, uint64_t per_group, uint32_t wave_width,
                                                  const trace::BufferInfo* const* buffers, GroupScratch& scratch) {
  const uint64_t first_invocation = first_group * per_group;
  const uint64_t invocations = (end_group - first_group) * per_group;
  // Counting sort of record indices by invocation, stable, so one invocation's records keep their buffer
  // order; each workgroup's records are then gathered, small enough to stay in the host's caches.
  std::vector<uint64_t>& begin = scratch.begin;
  begin.assign(invocations + 1, 0);
  for (const auto& r : records) ++begin[r.invocation - first_invocation + 1];
  for (uint64_t i = 0; i < invocations; ++i) begin[i + 1] += begin[i];
  std::vector<uint64_t>& cur = scratch.cursor;
  cur.assign(begin.begin(), begin.end() - 1);
  std::vector<uint32_t>& order = scratch.order;
  order.resize(records.size());
  for (size_t k = 0; k < records.size(); ++k) order[cur[records[k].invocation - first_invocation]++] = uint32_t(k);

  std::vector<std::unique_ptr<GroupAccesses>> out(end_group - first_group);
  std::vector<trace::TraceRecord>& recs = scratch.group;
  std::vector<uint32_t>& at = scratch.lane_cursor;
  const uint32_t waves = uint32_t((per_group + wave_width - 1) / wave_width);
  auto by_seq = [](const trace::TraceRecord& x, const trace::TraceRecord& y) { return x.seq < y.seq; };
  for (uint64_t g = 0; g < out.size(); ++g) {
    const uint64_t i0 = g * per_group, r0 = begin[i0], r1 = begin[i0 + per_group];
    if (r0 == r1) continue;
    // This workgroup's records by invocation, each invocation's sorted by seq where needed (GPU atomics
    // usually hand out indices in program order).
    recs.resize(r1 - r0);
    for (uint64_t k = r0; k < r1; ++k) recs[k - r0] = records[order[k]];
    at.resize(per_group + 1);
    for (uint64_t i = 0; i <= per_group; ++i) at[i] = uint32_t(begin[i0 + i] - r0);
    for (uint64_t i = 0; i < per_group; ++i) {
      auto first = recs.begin() + at[i], last = recs.begin() + at[i + 1];
      if (!std::is_sorted(first, last, by_seq)) std::stable_sort(first, last, by_seq);
    }
    auto ga = std::make_unique<GroupAccesses>();
    ga->first_invocation = first_invocation + i0;
    ga->address.reserve(r1 - r0);
    ga->info.reserve(r1 - r0);
    ga->lane.reserve(r1 - r0);
    for (uint32_t w = 0; w < waves; ++w) {
      const uint32_t l0 = w * wave_width;
      const uint32_t lanes = uint32_t(std::min<uint64_t>(wave_width, per_group - l0));
      uint32_t* c = at.data() + l0;  // at[] becomes each lane's cursor; at[l0 + l + 1] is still its end
      std::vector<uint32_t>& end = scratch.lane_end;
      end.assign(at.begin() + l0 + 1, at.begin() + l0 + lanes + 1);
      while (true) {
        uint32_t step_seq = ~0u;
        bool any = false;
        for (uint32_t l = 0; l < lanes; ++l)
          if (c[l] < end[l]) {
            step_seq = std::min(step_seq, recs[c[l]].seq);
            any = true;
          }
        if (!any) break;
        for (uint32_t l = 0; l < lanes; ++l) {
          if (c[l] < end[l] && recs[c[l]].seq == step_seq) {
            const trace::TraceRecord& r = recs[c[l]];
            const trace::BufferInfo& b = *buffers[gpu::trace_buffer(r.info)];
            // Plain buffers inline (most records); images apply their declared layout.
            ga->address.push_back(b.kind == trace::BufferKind::buffer ? b.base_address + r.offset
                                                                      : b.address(r.offset));
            ga->info.push_back(r.info);
            ga->lane.push_back(uint16_t(l));
            ++c[l];
          }
        }
        ga->step_end.push_back(uint32_t(ga->address.size()));
      }
      ga->wave_steps_end.push_back(uint32_t(ga->step_end.size()));
    }
    out[g] = std::move(ga);
  }
  return out;
}

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
    lane_request.reserve(size_t(wave_width) * 2);
  }

  void begin() {
    ++gen_;
    requests.clear();
    lane_request.clear();
    last_key_ = ~uint64_t(0);  // no key: a line number is below 2^62
  }

  // Adds one lane access; remembers (invocation, request) pairs when per_invocation.
  void add(uint64_t address, uint32_t info, uint32_t invocation, bool per_invocation) {
    const uint32_t size = gpu::trace_size(info);
    const auto kind = AccessKind(gpu::trace_kind(info));
    const uint64_t last_byte = address + size - 1;
    const uint64_t first_line = address >> line_shift_, last_line = last_byte >> line_shift_;
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
          break;
        }
        if (keys_[h] == key) {
          req = slot_req_[h];
          requests[req].sectors |= mask;
          break;
        }
        h = (h + 1) & mask_;
      }
      last_key_ = key;
      last_req_ = req;
      if (per_invocation) lane_request.push_back({invocation, req});
    }
  }

  std::vector<Request> requests;
  std::vector<std::pair<uint32_t, uint32_t>> lane_request;

 private:
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> stamp_, slot_req_;
  uint64_t mask_ = 0;
  uint64_t last_key_ = ~uint64_t(0);  // the previous lane access's key and request, this step
  uint32_t last_req_ = 0;
  uint32_t gen_ = 0;
  uint32_t line_shift_, sector_shift_, full_mask_;
  bool sectors_;
};

// A fed slice: its workgroups' accesses until each is dispatched (the resident workgroup then owns them).
struct Slice {
  uint64_t first_group = 0, end_group = 0;
  std::vector<std::unique_ptr<GroupAccesses>> groups;  // by workgroup - first_group; null: none or dispatched
};

// A resident wavefront. It reads its workgroup's arrays (GroupAccesses, laid out in issue order and
// not changed once fed; owned by the resident workgroup until it retires) through its own copies of
// their data pointers and the start of its next step, so that issuing a step, or prefetching the one
// a few compute units ahead, does not first chase the workgroup's object and step table.
struct Wave {
  const uint64_t* address;
  const uint32_t* info;
  const uint16_t* lane;
  const uint32_t* step_end;
  uint64_t lane_base;  // global index of its first lane's invocation
  uint64_t workgroup;
  uint32_t next_step, end_step;  // its steps in step_end
  uint32_t next_entry;           // where its next step's entries start (step_end[next_step - 1], or 0)
};

struct ResidentGroup {
  uint64_t workgroup;
  std::unique_ptr<GroupAccesses> data;
  uint32_t waves_left;
};

struct ComputeUnit {
  std::vector<Wave> waves;
  std::vector<ResidentGroup> groups;
  uint32_t resident_waves = 0;
  size_t next = 0;  // round-robin position in waves
};

}  // namespace

// The scheduler's state between feeds: the replay stops where it would dispatch a workgroup no slice has
// brought yet, and resumes there, so a sliced replay makes exactly the decisions of a whole one.
struct BaselineSimulator::PassState {
  trace::PassInfo info;
  PassResult res;
  uint64_t per_group = 0, groups = 0, invocations = 0;
  uint32_t waves_per_group = 0;
  std::vector<ComputeUnit> cu;
  std::vector<std::unique_ptr<Slice>> slices;  // fed and not yet fully dispatched, in workgroup order
  uint64_t fed_end = 0;                        // workgroups below this are known (fed or empty)
  bool final = false;                          // end_pass: every workgroup is known
  uint64_t next_group = 0;
  uint64_t resident_records = 0;  // records held: fed, not yet retired
  // Refill position, kept when a refill stops for data: sweep index and whether this sweep placed work.
  uint32_t refill_cu = 0;
  bool refill_progress = false;
  bool refilling = true;  // the replay stopped inside a refill (or has not started)
  bool done = false;
  Coalescer co;
  // Coalesced requests not yet issued to the hierarchy, their compute units, and (per-invocation
  // counts) which invocation's lane each served; outcomes of the batch when it is issued.
  std::vector<Request> batch;
  std::vector<uint32_t> batch_cu;
  std::vector<std::pair<uint32_t, uint32_t>> batch_lanes;
  std::vector<IssueResult> outcome;
  GroupScratch scratch;

  PassState(uint32_t width, const Cache& l1, bool sectors)
      : co(width, l1.line_shift(), l1.sector_shift(), l1.full_mask(), sectors) {}

  // Takes workgroup g's accesses out of its slice (null: none); drops slices fully handed out.
  std::unique_ptr<GroupAccesses> take(uint64_t g) {
    std::unique_ptr<GroupAccesses> out;
    for (auto& sp : slices)
      if (g >= sp->first_group && g < sp->end_group) {
        out = std::move(sp->groups[g - sp->first_group]);
        break;
      }
    while (!slices.empty() && slices.front()->end_group <= g + 1) slices.erase(slices.begin());
    return out;
  }
  void retire(const GroupAccesses& ga) { resident_records -= ga.address.size(); }
};

BaselineSimulator::BaselineSimulator(const Preset& preset, const trace::TraceHeader& header, SimOptions options)
    : preset_(preset),
      buffer_storage_(header.buffers),
      options_(std::move(options)),
      hierarchy_(preset.l1, preset.compute_units, preset.l2) {
  for (const auto& b : buffer_storage_) buffers_[b.id & 0xFF] = &b;
  if (options_.l1_mrc || options_.l2_mrc)
    hierarchy_.enable_mrc(options_.l1_mrc, options_.l2_mrc, options_.mrc_sampling_rate);
}

BaselineSimulator::~BaselineSimulator() = default;

PassResult BaselineSimulator::run_pass(const trace::PassInfo& pass, std::span<const trace::TraceRecord> records) {
  begin_pass(pass);
  feed(records, 0, pass.dispatch.workgroups());
  return end_pass();
}

void BaselineSimulator::begin_pass(const trace::PassInfo& pass) {
  const auto& d = pass.dispatch;
  if (d.invocations() > 0xFFFFFFFFull) throw InputError("pass '" + pass.name + "': 2^32 invocations or more");
  const Cache& l1 = hierarchy_.l1(0);
  pass_ = std::make_unique<PassState>(preset_.wave_width, l1, preset_.coalescing == Coalescing::sector);
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
}

void BaselineSimulator::feed(std::span<const trace::TraceRecord> records, uint64_t first_workgroup,
                             uint64_t end_workgroup) {
  if (!pass_ || pass_->final) throw std::logic_error("BaselineSimulator::feed outside begin_pass / end_pass");
  PassState& ps = *pass_;
  const std::string& name = ps.info.name;
  if (first_workgroup > end_workgroup || end_workgroup > ps.groups)
    throw InputError("pass '" + name + "': slice of workgroups [" + std::to_string(first_workgroup) + ", " +
                     std::to_string(end_workgroup) + ") outside the dispatch of " + std::to_string(ps.groups));
  if (first_workgroup < ps.fed_end)
    throw InputError("pass '" + name + "': slice [" + std::to_string(first_workgroup) + ", " +
                     std::to_string(end_workgroup) + ") overlaps or precedes workgroup " + std::to_string(ps.fed_end) +
                     " (slices must come in dispatch order)");
  const uint64_t first_inv = first_workgroup * ps.per_group, end_inv = end_workgroup * ps.per_group;
  for (const auto& r : records)
    if (!buffers_[gpu::trace_buffer(r.info)] || r.invocation < first_inv || r.invocation >= end_inv)
      throw InputError("pass '" + name + "': record outside its slice's workgroups or the buffer table");
  ps.fed_end = end_workgroup;
  if (end_workgroup > first_workgroup) {
    auto s = std::make_unique<Slice>();
    s->first_group = first_workgroup;
    s->end_group = end_workgroup;
    s->groups = group(records, first_workgroup, end_workgroup, ps.per_group, preset_.wave_width, buffers_, ps.scratch);
    ps.resident_records += records.size();
    ps.res.peak_resident_records = std::max(ps.res.peak_resident_records, ps.resident_records);
    ps.res.lane_accesses += records.size();
    ps.res.slices += !records.empty();
    ps.slices.push_back(std::move(s));
  }
  advance();
}

PassResult BaselineSimulator::end_pass() {
  if (!pass_) throw std::logic_error("BaselineSimulator::end_pass without begin_pass");
  pass_->final = true;
  advance();
  PassResult res = std::move(pass_->res);
  pass_.reset();
  res.stats = hierarchy_.stats();
  res.buffers = hierarchy_.buffers();
  if (options_.l1_mrc) res.l1_curve = hierarchy_.l1_curve();
  if (options_.l2_mrc) res.l2_curve = hierarchy_.l2_curve();
  return res;
}

namespace {
constexpr uint32_t kPrefetchAhead = 4;
constexpr size_t kIssueBatch = 4096;  // requests queued before the hierarchy takes them
}  // namespace

void BaselineSimulator::advance() {
  schedule();
  issue_batch();
}

void BaselineSimulator::issue_batch() {
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

void BaselineSimulator::schedule() {
  PassState& ps = *pass_;
  if (ps.done) return;
  PassResult& res = ps.res;
  const bool per_inv = options_.per_invocation;
  const uint32_t width = preset_.wave_width;
  const uint32_t cus = preset_.compute_units;
  Coalescer& co = ps.co;

  // Places workgroup next_group's wavefronts on a CU; wavefronts without accesses never become
  // resident, and a workgroup without any never does.
  auto dispatch = [&](ComputeUnit& c) {
    const uint64_t g = ps.next_group++;
    res.waves += ps.waves_per_group;
    std::unique_ptr<GroupAccesses> ga = ps.take(g);
    if (!ga) return;  // a workgroup without accesses
    uint32_t placed = 0;
    for (uint32_t w = 0; w < ps.waves_per_group; ++w) {
      const uint32_t s0 = w ? ga->wave_steps_end[w - 1] : 0, s1 = ga->wave_steps_end[w];
      if (s0 == s1) continue;  // a wavefront without accesses
      c.waves.push_back(Wave{ga->address.data(), ga->info.data(), ga->lane.data(), ga->step_end.data(),
                             ga->first_invocation + uint64_t(w) * width, g, s0, s1, s0 ? ga->step_end[s0 - 1] : 0});
      ++placed;
    }
    c.groups.push_back(ResidentGroup{g, std::move(ga), placed});
    c.resident_waves += placed;
  };
  auto has_room = [&](const ComputeUnit& c) {
    return c.resident_waves == 0 || c.resident_waves + ps.waves_per_group <= preset_.max_waves_per_cu;
  };
  // Sweeps the CUs round-robin, one workgroup to each with room, until a sweep places nothing or no
  // workgroup is left. Returns false, keeping its position, where the next workgroup has not been fed.
  auto refill = [&] {
    while (ps.next_group < ps.groups) {
      if (ps.refill_cu == cus) {
        if (!ps.refill_progress) break;
        ps.refill_cu = 0;
        ps.refill_progress = false;
      }
      if (has_room(ps.cu[ps.refill_cu])) {
        if (!ps.final && ps.next_group >= ps.fed_end) return false;
        dispatch(ps.cu[ps.refill_cu]);
        ps.refill_progress = true;
      }
      ++ps.refill_cu;
    }
    ps.refill_cu = 0;
    ps.refill_progress = false;
    return true;
  };

  if (ps.refilling) {
    if (!refill()) return;
    ps.refilling = false;
  }
  while (true) {
    bool any = false, freed = false;
    for (uint32_t i = 0; i < cus; ++i) {
      ComputeUnit& c = ps.cu[i];
      // Host prefetch of the wave step a few compute units ahead: its accesses were laid out when its
      // workgroup was fed and have usually left the host's caches since (no simulated effect).
      if (const uint32_t a = i + kPrefetchAhead; a < cus) {
        const ComputeUnit& ca = ps.cu[a];
        if (!ca.waves.empty()) {
          const Wave& wa = ca.waves[ca.next < ca.waves.size() ? ca.next : 0];
          const uint32_t e = wa.next_entry;
          __builtin_prefetch(wa.address + e);
          __builtin_prefetch(wa.info + e);
          __builtin_prefetch(wa.lane + e);
          __builtin_prefetch(wa.step_end + wa.next_step);
        }
      }
      if (c.waves.empty()) continue;
      any = true;
      if (c.next >= c.waves.size()) c.next = 0;
      Wave& w = c.waves[c.next];
      const uint32_t e0 = w.next_entry, e1 = w.step_end[w.next_step];
      w.next_entry = e1;
      const uint64_t lane_base = w.lane_base;
      co.begin();
      for (uint32_t k = e0; k < e1; ++k) co.add(w.address[k], w.info[k], uint32_t(lane_base + w.lane[k]), per_inv);
      ++res.wave_steps;
      if (options_.observer)
        for (const Request& r : co.requests) options_.observer(i, r);
      // Queued for the hierarchy, which takes them in batches (the same results: nothing the
      // scheduler does depends on them).
      const uint32_t base = uint32_t(ps.batch.size());
      ps.batch.insert(ps.batch.end(), co.requests.begin(), co.requests.end());
      ps.batch_cu.insert(ps.batch_cu.end(), co.requests.size(), i);
      if (per_inv)
        for (const auto& [inv, r] : co.lane_request) ps.batch_lanes.emplace_back(inv, base + r);
      if (ps.batch.size() >= kIssueBatch) issue_batch();
      if (++w.next_step == w.end_step) {
        const uint64_t g = w.workgroup;
        c.waves.erase(c.waves.begin() + int64_t(c.next));  // next now points at the following wave
        --c.resident_waves;
        for (size_t k = 0; k < c.groups.size(); ++k)
          if (c.groups[k].workgroup == g && --c.groups[k].waves_left == 0) {
            ps.retire(*c.groups[k].data);
            c.groups.erase(c.groups.begin() + int64_t(k));
            freed = true;
            break;
          }
      } else {
        ++c.next;
      }
    }
    if (!any && ps.next_group >= ps.groups) {
      ps.done = true;
      return;
    }
    ++res.cycles;
    if (freed || !any) {
      if (!refill()) {
        ps.refilling = true;
        return;
      }
    }
  }
}

uint64_t BaselineSimulator::finish() {
  const uint64_t before = hierarchy_.stats().dram_write_bytes;
  hierarchy_.flush();
  return hierarchy_.stats().dram_write_bytes - before;
}

}  // namespace hp::cachesim::baseline
