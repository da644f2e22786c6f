#include "cachesim/simulator.hpp"

#include <algorithm>
#include <bit>
#include <ostream>
#include <stdexcept>

#include "error.hpp"
#include "trace/din.hpp"

namespace hp::cachesim {

namespace {

// A pass's accesses grouped by invocation and ordered by sequence number, with addresses resolved.
struct LaneAccesses {
  std::vector<uint64_t> begin;    // begin[inv] .. begin[inv + 1]: that invocation's accesses
  std::vector<uint64_t> address;  // byte address
  std::vector<uint32_t> info;     // the record's info word (size, kind, buffer)
  std::vector<uint32_t> seq;      // the record's sequence number
};

LaneAccesses group(std::span<const trace::TraceRecord> records, uint64_t invocations,
                   const trace::BufferInfo* const* buffers) {
  LaneAccesses a;
  a.begin.assign(invocations + 1, 0);
  for (const auto& r : records) ++a.begin[r.invocation + 1];
  for (uint64_t i = 0; i < invocations; ++i) a.begin[i + 1] += a.begin[i];
  // Counting sort by invocation, stable, so one invocation's records keep their buffer order, then
  // a per-invocation sort by seq where needed (GPU atomics usually hand out indices in program order).
  std::vector<uint64_t> fill(a.begin.begin(), a.begin.end() - 1);
  std::vector<trace::TraceRecord> sorted(records.size());
  for (const auto& r : records) sorted[fill[r.invocation]++] = r;
  for (uint64_t i = 0; i < invocations; ++i) {
    auto first = sorted.begin() + int64_t(a.begin[i]), last = sorted.begin() + int64_t(a.begin[i + 1]);
    auto by_seq = [](const trace::TraceRecord& x, const trace::TraceRecord& y) { return x.seq < y.seq; };
    if (!std::is_sorted(first, last, by_seq)) std::stable_sort(first, last, by_seq);
  }
  a.address.resize(sorted.size());
  a.info.resize(sorted.size());
  a.seq.resize(sorted.size());
  for (size_t i = 0; i < sorted.size(); ++i) {
    a.seq[i] = sorted[i].seq;
    a.address[i] = buffers[gpu::trace_buffer(sorted[i].info)]->address(sorted[i].offset);
    a.info[i] = sorted[i].info;
  }
  return a;
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
      uint64_t h = (key * 0x9E3779B97F4A7C15ull) >> 40 & mask_;
      uint32_t req;
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
      if (per_invocation) lane_request.push_back({invocation, req});
    }
  }

  std::vector<Request> requests;
  std::vector<std::pair<uint32_t, uint32_t>> lane_request;

 private:
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> stamp_, slot_req_;
  uint64_t mask_ = 0;
  uint32_t gen_ = 0;
  uint32_t line_shift_, sector_shift_, full_mask_;
  bool sectors_;
};

struct Wave {
  uint64_t first_invocation;
  uint32_t lanes;
  uint64_t remaining;  // accesses not yet issued
  uint64_t workgroup;
};

struct ResidentGroup {
  uint64_t workgroup;
  uint32_t waves_left;
  uint32_t waves;
};

struct ComputeUnit {
  std::vector<Wave> waves;
  std::vector<ResidentGroup> groups;
  uint32_t resident_waves = 0;
  size_t next = 0;  // round-robin position in waves
};

}  // namespace

Simulator::Simulator(const Preset& preset, const trace::TraceHeader& header, SimOptions options)
    : preset_(preset), buffer_storage_(header.buffers), options_(std::move(options)),
      hierarchy_(preset.l1, preset.compute_units, preset.l2) {
  for (const auto& b : buffer_storage_) buffers_[b.id & 0xFF] = &b;
  if (options_.l1_mrc || options_.l2_mrc) hierarchy_.enable_mrc(options_.l1_mrc, options_.l2_mrc, options_.mrc_sampling_rate);
}

PassResult Simulator::run_pass(const trace::PassInfo& pass, std::span<const trace::TraceRecord> records) {
  const auto& d = pass.dispatch;
  const uint64_t per_group = d.invocations_per_workgroup();
  const uint64_t groups = d.workgroups();
  const uint64_t invocations = d.invocations();
  if (invocations > 0xFFFFFFFFull)
    throw InputError("pass '" + pass.name + "': more than 2^32 invocations");
  for (const auto& r : records)
    if (!buffers_[gpu::trace_buffer(r.info)] || r.invocation >= invocations)
      throw InputError("pass '" + pass.name + "': record outside the dispatch or its buffer table");

  const LaneAccesses acc = group(records, invocations, buffers_);
  hierarchy_.begin_pass();

  PassResult res;
  res.name = pass.name;
  res.lane_accesses = records.size();
  res.workgroups = groups;
  const bool per_inv = options_.per_invocation;
  if (per_inv) {
    res.l1_misses.assign(invocations, 0);
    res.l2_misses.assign(invocations, 0);
  }

  const uint32_t width = preset_.wave_width;
  const uint32_t waves_per_group = uint32_t((per_group + width - 1) / width);
  const uint32_t cus = preset_.compute_units;
  const Cache& l1 = hierarchy_.l1(0);
  Coalescer co(width, l1.line_shift(), l1.sector_shift(), l1.full_mask(), preset_.coalescing == Coalescing::sector);
  std::vector<ComputeUnit> cu(cus);
  uint64_t next_group = 0;
  std::vector<IssueResult> outcome;
  std::vector<uint64_t> cursor(acc.begin.begin(), acc.begin.end() - 1);  // next access per invocation

  // Places a workgroup's wavefronts on a CU; wavefronts without accesses never become resident.
  auto dispatch = [&](ComputeUnit& c) {
    const uint64_t g = next_group++;
    uint32_t placed = 0;
    for (uint32_t w = 0; w < waves_per_group; ++w) {
      const uint64_t first = g * per_group + uint64_t(w) * width;
      const uint32_t lanes = uint32_t(std::min<uint64_t>(width, per_group - uint64_t(w) * width));
      const uint64_t accesses = acc.begin[first + lanes] - acc.begin[first];
      ++res.waves;
      if (accesses == 0) continue;
      c.waves.push_back(Wave{first, lanes, accesses, g});
      ++placed;
    }
    if (placed) {
      c.groups.push_back(ResidentGroup{g, placed, placed});
      c.resident_waves += placed;
    }
  };
  auto has_room = [&](const ComputeUnit& c) {
    return c.resident_waves == 0 || c.resident_waves + waves_per_group <= preset_.max_waves_per_cu;
  };
  // Round-robin over CUs until no CU has room or no workgroup is left.
  auto refill = [&] {
    bool progress = true;
    while (progress && next_group < groups) {
      progress = false;
      for (uint32_t i = 0; i < cus && next_group < groups; ++i)
        if (has_room(cu[i])) {
          dispatch(cu[i]);
          progress = true;
        }
    }
  };

  refill();
  while (true) {
    bool any = false, freed = false;
    for (uint32_t i = 0; i < cus; ++i) {
      ComputeUnit& c = cu[i];
      if (c.waves.empty()) continue;
      any = true;
      if (c.next >= c.waves.size()) c.next = 0;
      Wave& w = c.waves[c.next];
      // The step issues every lane whose next access has the lowest pending sequence number:
      // lanes stay in lockstep by seq, and a capture can realign lanes after divergence by giving
      // the accesses after a reconvergence point a common seq.
      uint32_t step_seq = ~0u;
      for (uint32_t l = 0; l < w.lanes; ++l) {
        const uint64_t inv = w.first_invocation + l;
        if (cursor[inv] < acc.begin[inv + 1]) step_seq = std::min(step_seq, acc.seq[cursor[inv]]);
      }
      co.begin();
      uint32_t issued = 0;
      for (uint32_t l = 0; l < w.lanes; ++l) {
        const uint64_t inv = w.first_invocation + l;
        const uint64_t idx = cursor[inv];
        if (idx < acc.begin[inv + 1] && acc.seq[idx] == step_seq) {
          co.add(acc.address[idx], acc.info[idx], uint32_t(inv), per_inv);
          ++cursor[inv];
          ++issued;
        }
      }
      ++res.wave_steps;
      for (const Request& r : co.requests) hierarchy_.prefetch(i, r.line);
      if (options_.observer)
        for (const Request& r : co.requests) options_.observer(i, r);
      if (per_inv) {
        if (outcome.size() < co.requests.size()) outcome.resize(co.requests.size());
        IssueResult* o = outcome.data();
        hierarchy_.issue(i, std::span<const Request>(co.requests), o);
        for (const auto& [inv, r] : co.lane_request) {
          res.l1_misses[inv] += o[r].l1_miss;
          res.l2_misses[inv] += o[r].l2_miss;
        }
      } else {
        hierarchy_.issue(i, std::span<const Request>(co.requests), nullptr);
      }
      w.remaining -= issued;
      if (w.remaining == 0) {
        const uint64_t g = w.workgroup;
        c.waves.erase(c.waves.begin() + int64_t(c.next));  // next now points at the following wave
        --c.resident_waves;
        for (size_t k = 0; k < c.groups.size(); ++k)
          if (c.groups[k].workgroup == g && --c.groups[k].waves_left == 0) {
            c.groups.erase(c.groups.begin() + int64_t(k));
            freed = true;
            break;
          }
      } else {
        ++c.next;
      }
    }
    if (!any && next_group >= groups) break;
    ++res.cycles;
    if (freed || !any) refill();
  }

  res.stats = hierarchy_.stats();
  res.buffers = hierarchy_.buffers();
  if (options_.l1_mrc) res.l1_curve = hierarchy_.l1_curve();
  if (options_.l2_mrc) res.l2_curve = hierarchy_.l2_curve();
  return res;
}

uint64_t Simulator::finish() {
  const uint64_t before = hierarchy_.stats().dram_write_bytes;
  hierarchy_.flush();
  return hierarchy_.stats().dram_write_bytes - before;
}

uint64_t export_din(std::ostream& out, const Preset& preset, const trace::TraceHeader& header,
                    const trace::PassInfo& pass, std::span<const trace::TraceRecord> records, uint32_t cu,
                    bool include_stores) {
  if (cu >= preset.compute_units)
    throw InputError("--export-din: compute unit " + std::to_string(cu) + " does not exist (preset '" +
                     preset.name + "' has " + std::to_string(preset.compute_units) + ")");
  uint64_t lines = 0;
  const uint32_t line_shift = uint32_t(std::countr_zero(preset.l1.line_bytes));
  const uint32_t sector_bytes = preset.l1.sector_bytes;
  SimOptions opt;
  opt.per_invocation = false;
  opt.observer = [&](uint32_t c, const Request& r) {
    if (c != cu || r.kind == AccessKind::atomic) return;  // atomics bypass the L1
    if (r.kind == AccessKind::store && !include_stores) return;
    // One Dinero access per contiguous run of sectors: it covers exactly what the L1 was asked for.
    uint32_t m = r.sectors;
    while (m) {
      const uint32_t s0 = uint32_t(std::countr_zero(m));
      const uint32_t run = uint32_t(std::countr_one(m >> s0));
      trace::write_din_line(out, trace::DinAccess{r.kind == AccessKind::store, (r.line << line_shift) + s0 * sector_bytes,
                                                  run * sector_bytes});
      ++lines;
      m &= run == 32 ? 0u : ~(((1u << run) - 1) << s0);
    }
  };
  Simulator sim(preset, header, std::move(opt));
  sim.run_pass(pass, records);
  return lines;
}

}  // namespace hp::cachesim
