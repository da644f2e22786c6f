// The Simulator (workgroups grouped and coalesced on the feeding thread, scheduled and cached on a
// second one) against the former single-threaded replay kept in baseline_simulator.cpp: the same
// request stream in the same order, the same counts per level and buffer, per invocation and in the
// miss-ratio curves, the same wave steps, waves, cycles and resident-record peaks, on generated
// traces and on awkward hand-made ones, whole and sliced.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>

#include "baseline_simulator.hpp"
#include "cachesim/preset.hpp"
#include "cachesim/simulator.hpp"
#include "cachesim/synthetic.hpp"
#include "error.hpp"

namespace hp::cachesim {
namespace {

using trace::TraceRecord;

struct Seen {
  uint32_t cu;
  uint64_t line;
  uint32_t sectors;
  AccessKind kind;
  uint8_t buffer;
  bool operator==(const Seen&) const = default;
};

struct Replay {
  PassResult result;
  std::vector<Seen> requests;
  uint64_t flushed = 0;
};

// One feed per slice: slices[k] = [cuts[k], cuts[k+1]) with the records of those workgroups.
template <typename Sim>
std::vector<Replay> replay(const Preset& p, const trace::Trace& t, SimOptions so,
                           const std::vector<std::vector<uint64_t>>& cuts, uint32_t shuffle_seed) {
  std::vector<Replay> out(t.passes.size());
  size_t pass = 0;
  so.observer = [&](uint32_t cu, const Request& r) {
    out[pass].requests.push_back({cu, r.line, r.sectors, r.kind, r.buffer});
  };
  Sim sim(p, t.header, so);
  std::mt19937 rng(shuffle_seed);
  for (pass = 0; pass < t.passes.size(); ++pass) {
    const trace::PassInfo& info = t.passes[pass];
    const uint64_t per_group = info.dispatch.invocations_per_workgroup();
    sim.begin_pass(info);
    const std::vector<uint64_t>& c = cuts[pass];
    for (size_t k = 0; k + 1 < c.size(); ++k) {
      std::vector<TraceRecord> part;
      for (const TraceRecord& r : t.records[pass])
        if (r.invocation >= c[k] * per_group && r.invocation < c[k + 1] * per_group) part.push_back(r);
      if (shuffle_seed) std::shuffle(part.begin(), part.end(), rng);
      sim.feed(part, c[k], c[k + 1]);
    }
    out[pass].result = sim.end_pass();
  }
  out.back().flushed = sim.finish();
  return out;
}

// The file's slices as `cachesim TRACE` feeds them (feed_slices: a version-2 slice with its decoded
// workgroup index, so that the simulator does not scan its records).
std::vector<Replay> replay_file(const Preset& p, const std::filesystem::path& path, SimOptions so) {
  const trace::TraceReader reader(path);
  std::vector<Replay> out(reader.passes().size());
  size_t pass = 0;
  so.observer = [&](uint32_t cu, const Request& r) {
    out[pass].requests.push_back({cu, r.line, r.sectors, r.kind, r.buffer});
  };
  Simulator sim(p, reader.header(), so);
  for (pass = 0; pass < reader.passes().size(); ++pass) {
    sim.begin_pass(reader.passes()[pass]);
    feed_slices(sim, reader, uint32_t(pass));
    out[pass].result = sim.end_pass();
  }
  out.back().flushed = sim.finish();
  return out;
}

void expect_equal(const Replay& a, const Replay& b) {
  const PassResult &x = a.result, &y = b.result;
  ASSERT_EQ(a.requests.size(), b.requests.size());
  EXPECT_TRUE(a.requests == b.requests);
  for (auto [l, m] : {std::pair{&x.stats.l1, &y.stats.l1}, std::pair{&x.stats.l2, &y.stats.l2}}) {
    EXPECT_EQ(l->requests, m->requests);
    EXPECT_EQ(l->hits, m->hits);
    EXPECT_EQ(l->misses, m->misses);
    EXPECT_EQ(l->line_hits, m->line_hits);
    EXPECT_EQ(l->line_misses, m->line_misses);
    EXPECT_EQ(l->sectors, m->sectors);
    EXPECT_EQ(l->sector_hits, m->sector_hits);
    EXPECT_EQ(l->sector_misses, m->sector_misses);
  }
  EXPECT_EQ(x.stats.stores, y.stats.stores);
  EXPECT_EQ(x.stats.atomics, y.stats.atomics);
  EXPECT_EQ(x.stats.dram_read_bytes, y.stats.dram_read_bytes);
  EXPECT_EQ(x.stats.dram_write_bytes, y.stats.dram_write_bytes);
  for (size_t i = 0; i < x.buffers.size(); ++i) {
    EXPECT_EQ(x.buffers[i].l1_requests, y.buffers[i].l1_requests) << i;
    EXPECT_EQ(x.buffers[i].l1_misses, y.buffers[i].l1_misses) << i;
    EXPECT_EQ(x.buffers[i].l2_requests, y.buffers[i].l2_requests) << i;
    EXPECT_EQ(x.buffers[i].l2_misses, y.buffers[i].l2_misses) << i;
    EXPECT_EQ(x.buffers[i].dram_read_bytes, y.buffers[i].dram_read_bytes) << i;
  }
  EXPECT_EQ(x.l1_misses, y.l1_misses);
  EXPECT_EQ(x.l2_misses, y.l2_misses);
  EXPECT_EQ(x.lane_accesses, y.lane_accesses);
  EXPECT_EQ(x.wave_steps, y.wave_steps);
  EXPECT_EQ(x.waves, y.waves);
  EXPECT_EQ(x.workgroups, y.workgroups);
  EXPECT_EQ(x.cycles, y.cycles);
  EXPECT_EQ(x.slices, y.slices);
  EXPECT_EQ(x.peak_resident_records, y.peak_resident_records);
  EXPECT_EQ(x.l1_curve.accesses, y.l1_curve.accesses);
  EXPECT_EQ(x.l2_curve.accesses, y.l2_curve.accesses);
  for (uint64_t lines = 1; lines <= (1u << 20); lines *= 4) {
    EXPECT_EQ(x.l1_curve.misses(lines), y.l1_curve.misses(lines));
    EXPECT_EQ(x.l2_curve.misses(lines), y.l2_curve.misses(lines));
  }
  EXPECT_EQ(a.flushed, b.flushed);
}

void expect_same_replays(const Preset& p, const trace::Trace& t, const SimOptions& so,
                         const std::vector<std::vector<uint64_t>>& cuts, uint32_t shuffle_seed) {
  const auto fast = replay<Simulator>(p, t, so, cuts, shuffle_seed);
  const auto base = replay<baseline::BaselineSimulator>(p, t, so, cuts, shuffle_seed);
  ASSERT_EQ(fast.size(), base.size());
  for (size_t i = 0; i < fast.size(); ++i) {
    SCOPED_TRACE("pass " + t.passes[i].name);
    expect_equal(fast[i], base[i]);
    EXPECT_GT(base[i].requests.size(), 0u);
  }
}

std::vector<std::vector<uint64_t>> whole(const trace::Trace& t) {
  std::vector<std::vector<uint64_t>> c;
  for (const auto& p : t.passes) c.push_back({0, p.dispatch.workgroups()});
  return c;
}

// Random cut points (repeated ones give empty slices) and, with `gaps`, slices that leave workgroups out.
std::vector<std::vector<uint64_t>> random_cuts(const trace::Trace& t, uint32_t seed, int cuts) {
  std::mt19937 rng(seed);
  std::vector<std::vector<uint64_t>> out;
  for (const auto& p : t.passes) {
    const uint64_t groups = p.dispatch.workgroups();
    std::vector<uint64_t> c = {0, groups};
    for (int k = 0; k < cuts; ++k) c.push_back(rng() % (groups + 1));
    std::sort(c.begin(), c.end());
    out.push_back(c);
  }
  return out;
}

Preset preset_named(const std::string& name) { return find_preset(name); }

TEST(SimulatorEquivalence, GeneratedBvhTraceOnTheShippedPresets) {
  SyntheticBvhOptions o;
  o.width = 96;
  o.height = 80;
  o.tree_depth = 12;
  o.incoherent_fraction = 0.3;
  const trace::Trace t = make_bvh_like_trace(o);
  ASSERT_GT(t.records[0].size(), 100000u);
  for (const std::string name : {"vega56", "ga102", "h100"}) {
    SCOPED_TRACE(name);
    SimOptions so;
    so.per_invocation = true;
    so.l1_mrc = so.l2_mrc = true;
    expect_same_replays(preset_named(name), t, so, whole(t), 0);
    so.l1_mrc = so.l2_mrc = false;
    so.per_invocation = false;
    expect_same_replays(preset_named(name), t, so, random_cuts(t, 5, 12), 9);
  }
}

// Hand-made: several passes (the L2 stays warm between them), workgroups that are not a multiple of the
// wave width, lanes that diverge and realign by seq, seq 0xFFFFFFFF, duplicate seqs, accesses that span
// two lines, all three kinds, plain buffers and both image layouts, empty workgroups and wavefronts.
trace::Trace awkward_trace(uint32_t seed) {
  trace::Trace t;
  auto buffer = [&](uint32_t id, trace::BufferKind kind, uint64_t base, uint64_t size) {
    trace::BufferInfo b;
    b.id = id;
    b.name = "b" + std::to_string(id);
    b.kind = kind;
    b.base_address = base;
    b.size_bytes = size;
    if (kind != trace::BufferKind::buffer) {
      b.texel_bytes = 8;
      b.width = 100;
      b.height = 64;
      b.size_bytes = uint64_t(b.width) * b.height * b.texel_bytes;
      b.row_pitch_bytes = 1024;
      b.tile_width = b.tile_height = 8;
    }
    t.header.buffers.push_back(b);
  };
  buffer(0, trace::BufferKind::buffer, 0x100000, 1 << 20);
  buffer(7, trace::BufferKind::image_linear, 0x400000, 0);
  buffer(200, trace::BufferKind::image_tiled, 0x800000, 0);
  buffer(3, trace::BufferKind::buffer, 0x1000003, 1 << 16);  // unaligned base: accesses straddle lines
  std::mt19937 rng(seed);
  for (uint32_t pass = 0; pass < 3; ++pass) {
    trace::PassInfo info;
    info.name = "pass" + std::to_string(pass);
    const uint32_t sizes[3][3] = {{80, 1, 1}, {7, 5, 3}, {64, 2, 1}};
    const uint32_t counts[3][3] = {{23, 1, 1}, {4, 3, 2}, {5, 1, 3}};
    for (int k = 0; k < 3; ++k) {
      info.dispatch.workgroup_size[k] = sizes[pass][k];
      info.dispatch.workgroup_count[k] = counts[pass][k];
    }
    std::vector<TraceRecord> recs;
    const uint64_t per_group = info.dispatch.invocations_per_workgroup();
    for (uint32_t inv = 0; inv < info.dispatch.invocations(); ++inv) {
      const uint64_t g = inv / per_group;
      if (g % 5 == 3) continue;                          // an empty workgroup
      if (pass == 2 && inv % per_group >= 64) continue;  // its second wavefront (wave64) empty
      const uint32_t n = rng() % 9;                      // some lanes without accesses
      uint32_t seq = rng() % 3;
      for (uint32_t k = 0; k < n; ++k) {
        const uint32_t which = rng() % 4;
        const uint32_t ids[4] = {0, 7, 200, 3};
        const uint32_t kind = rng() % 10 == 0 ? HP_TRACE_STORE : rng() % 20 == 0 ? HP_TRACE_ATOMIC : HP_TRACE_LOAD;
        const uint32_t size = 1 + rng() % 16;
        uint32_t offset;
        if (which == 0)
          offset = (rng() % 2 ? (inv * 16) : uint32_t(rng() % 4096) * 64 + 60) % ((1 << 20) - 16);
        else if (which == 3)
          offset = uint32_t(rng() % 1000) * 61;
        else
          offset = uint32_t(rng() % (100 * 64)) * 8 + uint32_t(rng() % (9 - std::min<uint32_t>(size, 8)));
        const uint32_t sz = which == 1 || which == 2 ? std::min<uint32_t>(size, 8) : size;
        recs.push_back(TraceRecord{inv, seq, HP_TRACE_INFO(ids[which], kind, sz), offset});
        const uint32_t step = rng() % 6;
        seq += step == 0 ? 0 : step == 5 ? 3 : 1;  // duplicates, gaps (divergence), realignment
      }
      if (inv % 97 == 5) recs.push_back(TraceRecord{inv, 0xFFFFFFFFu, HP_TRACE_INFO(0u, HP_TRACE_LOAD, 4u), 64});
    }
    std::shuffle(recs.begin(), recs.end(), rng);  // records in no particular order, as GPU atomics give them
    t.passes.push_back(info);
    t.records.push_back(std::move(recs));
  }
  return t;
}

TEST(SimulatorEquivalence, AwkwardTracesWholeAndSliced) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    const trace::Trace t = awkward_trace(seed);
    Preset small = preset_named("vega56");
    small.compute_units = 3;
    small.max_waves_per_cu = 2;  // occupancy limits dispatch
    Preset sectors = preset_named("ga102");
    sectors.compute_units = 5;
    sectors.wave_width = 16;
    for (const Preset& p : {small, sectors, preset_named("h100")}) {
      SCOPED_TRACE(p.name + " seed " + std::to_string(seed));
      SimOptions so;
      so.per_invocation = true;
      so.l2_mrc = true;
      expect_same_replays(p, t, so, whole(t), 0);
      expect_same_replays(p, t, so, random_cuts(t, seed, 6), seed);
    }
  }
}

TEST(SimulatorEquivalence, RecordsAlreadyInWorkgroupOrderAndOneRecordSlices) {
  // In workgroup order the grouping uses the records in place: the same results as shuffled.
  trace::Trace t = awkward_trace(4);
  for (auto& recs : t.records)
    std::stable_sort(recs.begin(), recs.end(),
                     [](const TraceRecord& a, const TraceRecord& b) { return a.invocation / 80 < b.invocation / 80; });
  SimOptions so;
  so.per_invocation = true;
  expect_same_replays(preset_named("vega56"), t, so, whole(t), 0);
  // One slice per workgroup.
  std::vector<std::vector<uint64_t>> cuts;
  for (const auto& p : t.passes) {
    std::vector<uint64_t> c;
    for (uint64_t g = 0; g <= p.dispatch.workgroups(); ++g) c.push_back(g);
    cuts.push_back(c);
  }
  expect_same_replays(preset_named("ga102"), t, so, cuts, 0);
}

// The trace with a lane of every third workgroup accessing twice at its third step (the coding keeps both;
// a capture never writes that): workgroups with and without repeated lanes, one after the other.
trace::Trace with_some_repeats(trace::Trace t) {
  for (size_t p = 0; p < t.passes.size(); ++p) {
    const uint64_t per_group = t.passes[p].dispatch.invocations_per_workgroup();
    const size_t n = t.records[p].size();
    for (size_t i = 0; i < n; ++i) {
      const TraceRecord r = t.records[p][i];
      if ((r.invocation / per_group) % 3 == 1 && r.invocation % per_group == 5 && r.seq == 2) {
        TraceRecord again = r;
        again.offset = r.offset >= 64 ? r.offset - 64 : r.offset + 64;
        t.records[p].push_back(again);
      }
    }
  }
  return t;
}

// A trace written to a file and read back, in either format version and either coding of version 2: the
// file's records (version 2 gives them back reordered by workgroup, seq and invocation, which the grouping
// takes without sorting) replay exactly as the original records do through the former single-threaded
// replay. Streamed from the file, a coding-2 slice is built straight from its coding: a wavefront per
// workgroup coalesced as it is decoded (vega56, h100), several per workgroup and lanes repeated in a step
// (the awkward traces) decoded to records first.
TEST(SimulatorEquivalence, TraceFilesOfBothVersionsReplayLikeTheirRecords) {
  SyntheticBvhOptions o;
  o.width = 48;
  o.height = 40;
  o.tree_depth = 10;
  o.incoherent_fraction = 0.3;
  Preset small = preset_named("vega56");
  small.compute_units = 3;
  small.max_waves_per_cu = 2;
  Preset narrow = preset_named("ga102");  // wave32, and 16: several wavefronts per workgroup
  narrow.compute_units = 5;
  narrow.wave_width = 16;
  Preset wide = preset_named("vega56");  // wave128: every workgroup of the awkward traces one wavefront
  wide.compute_units = 4;
  wide.wave_width = 128;
  const auto path = std::filesystem::temp_directory_path() / "hp_equivalence_trace_file.hptrace";
  for (const trace::Trace& t :
       {make_bvh_like_trace(o), with_some_repeats(make_bvh_like_trace(o)), awkward_trace(6), awkward_trace(7)}) {
    for (const auto& [version, coding] : {std::pair{trace::kTraceVersionRaw, trace::kCodingSizedGroups},
                                          std::pair{trace::kTraceVersion, trace::kCodingDeltaVarint},
                                          std::pair{trace::kTraceVersion, trace::kCodingSizedGroups}}) {
      {
        // Three slices per pass, as a capture streams them.
        trace::TraceWriter w(path, t.header, version, coding);
        for (size_t p = 0; p < t.passes.size(); ++p) {
          const uint32_t index = w.begin_pass(t.passes[p]);
          const uint64_t groups = t.passes[p].dispatch.workgroups(),
                         per = t.passes[p].dispatch.invocations_per_workgroup();
          for (uint64_t g0 = 0; g0 < groups; g0 += groups / 3 + 1) {
            const uint64_t g1 = std::min(groups, g0 + groups / 3 + 1);
            std::vector<TraceRecord> part;
            for (const TraceRecord& r : t.records[p])
              if (r.invocation >= g0 * per && r.invocation < g1 * per) part.push_back(r);
            w.write_records(index, part, g0, g1);
          }
        }
        w.finish();
      }
      const trace::Trace read = trace::read_trace(path);
      EXPECT_EQ(trace::TraceReader(path).version(), version);
      for (const Preset& p : {small, narrow, wide, preset_named("h100")}) {
        SCOPED_TRACE(p.name + " version " + std::to_string(version) + " coding " + std::to_string(coding));
        SimOptions so;
        so.per_invocation = true;
        so.l2_mrc = true;
        const auto from_file = replay<Simulator>(p, read, so, whole(read), 0);
        const auto base = replay<baseline::BaselineSimulator>(p, t, so, whole(t), 0);
        ASSERT_EQ(from_file.size(), base.size());
        for (size_t i = 0; i < base.size(); ++i) expect_equal(from_file[i], base[i]);
        // Streamed from the file slice by slice: the same as the records fed in the file's slices.
        std::vector<std::vector<uint64_t>> file_cuts;
        for (const trace::PassInfo& info : t.passes) {
          const uint64_t groups = info.dispatch.workgroups();
          file_cuts.emplace_back();
          for (uint64_t g0 = 0; g0 < groups; g0 += groups / 3 + 1) file_cuts.back().push_back(g0);
          file_cuts.back().push_back(groups);
        }
        const auto streamed = replay_file(p, path, so);
        const auto sliced = replay<baseline::BaselineSimulator>(p, t, so, file_cuts, 0);
        ASSERT_EQ(streamed.size(), sliced.size());
        for (size_t i = 0; i < sliced.size(); ++i) expect_equal(streamed[i], sliced[i]);
        // The L1 lookups under every counting (the baseline has none): as the records' replay counts them.
        for (size_t i = 0; i < sliced.size(); ++i) {
          const auto same = [](const L1Lookups& a, const L1Lookups& b) {
            return a.request == b.request && a.quarter_wave == b.quarter_wave && a.lane == b.lane;
          };
          EXPECT_TRUE(same(streamed[i].result.l1_lookups, from_file[i].result.l1_lookups)) << "pass " << i;
          for (size_t b = 0; b < streamed[i].result.buffer_l1_lookups.size(); ++b)
            EXPECT_TRUE(same(streamed[i].result.buffer_l1_lookups[b], from_file[i].result.buffer_l1_lookups[b]))
                << "pass " << i << " buffer " << b;
        }
      }
    }
  }
  std::filesystem::remove(path);
}

// A coding-2 slice is checked as the simulator builds it from its coding; a defect there ends the replay
// with the very error a careful read of the file gives (the same words, naming the file, pass and record).
TEST(SimulatorEquivalence, DefectsInCodedSlicesAreNamedAsTheReaderNamesThem) {
  const auto path = std::filesystem::temp_directory_path() / "hp_equivalence_coded_defect.hptrace";
  // Workgroups of several wavefronts (decoded to records first) and of one (coalesced as decoded).
  Preset wide = preset_named("vega56");
  wide.wave_width = 128;
  for (const Preset& p : {preset_named("vega56"), wide}) {
    SCOPED_TRACE("wave" + std::to_string(p.wave_width));
    const trace::Trace good = awkward_trace(3);
    // The careful reader's error, and the replay's.
    auto errors = [&](const std::filesystem::path& file) {
      std::string read, replayed;
      try {
        trace::read_trace(file);
      } catch (const InputError& e) {
        read = e.what();
      }
      try {
        replay_file(p, file, SimOptions{});
      } catch (const InputError& e) {
        replayed = e.what();
      }
      return std::pair{read, replayed};
    };
    struct Defect {
      const char* what;
      uint32_t info;
      uint32_t offset;
    };
    const uint32_t size = 1u << 20;  // buffer 0's
    for (const Defect& d : {Defect{"past the end of buffer 'b0'", HP_TRACE_INFO(0u, HP_TRACE_LOAD, 4u), size - 2},
                            Defect{"unknown buffer id 9", HP_TRACE_INFO(9u, HP_TRACE_LOAD, 4u), 0},
                            Defect{"unknown access kind", HP_TRACE_INFO(0u, 3u, 4u), 0},
                            Defect{"reserved info bits set", HP_TRACE_INFO(0u, HP_TRACE_LOAD, 4u) | 0x40u, 0}}) {
      SCOPED_TRACE(d.what);
      trace::Trace t = good;
      // In the second pass (the first replays cleanly first), an invocation's next access.
      TraceRecord bad = t.records[1][t.records[1].size() / 2];
      bad.seq += 1000;
      bad.info = d.info;
      bad.offset = d.offset;
      t.records[1].push_back(bad);
      trace::write_trace(path, t);
      const auto [read, replayed] = errors(path);
      EXPECT_NE(read.find(d.what), std::string::npos) << read;
      EXPECT_NE(read.find(path.string() + ": pass 'pass1': record "), std::string::npos) << read;
      EXPECT_EQ(replayed, read);
    }
    // A chunk that declares one record more than its coding holds (and an END chunk that agrees).
    trace::write_trace(path, good);
    std::vector<char> bytes(std::filesystem::file_size(path));
    {
      std::FILE* f = std::fopen(path.c_str(), "rb");
      ASSERT_EQ(std::fread(bytes.data(), 1, bytes.size(), f), bytes.size());
      std::fclose(f);
    }
    const std::string tag = "RECV";
    const size_t at = size_t(std::search(bytes.begin(), bytes.end(), tag.begin(), tag.end()) - bytes.begin());
    ASSERT_LT(at, bytes.size());
    for (const size_t pos : {at + 16 + 24, bytes.size() - 16}) {  // the chunk's count, the END chunk's total
      uint64_t v = 0;
      std::memcpy(&v, bytes.data() + pos, 8);
      ++v;
      std::memcpy(bytes.data() + pos, &v, 8);
    }
    {
      std::FILE* f = std::fopen(path.c_str(), "wb");
      ASSERT_EQ(std::fwrite(bytes.data(), 1, bytes.size(), f), bytes.size());
      std::fclose(f);
    }
    const auto [read, replayed] = errors(path);
    EXPECT_NE(read.find("records, the chunk declares"), std::string::npos) << read;
    EXPECT_EQ(replayed, read);
  }
  std::filesystem::remove(path);
}

TEST(SimulatorEquivalence, DestroyedMidPassAndRestartedPassesAreClean) {
  const trace::Trace t = awkward_trace(5);
  Simulator sim(preset_named("vega56"), t.header);
  sim.begin_pass(t.passes[0]);
  sim.feed(t.records[0], 0, t.passes[0].dispatch.workgroups());
  // A new pass without end_pass abandons the one in flight; the pass after it replays normally.
  sim.begin_pass(t.passes[1]);
  sim.feed(t.records[1], 0, t.passes[1].dispatch.workgroups());
  const PassResult r = sim.end_pass();
  EXPECT_EQ(r.lane_accesses, t.records[1].size());
  EXPECT_GT(r.stats.l1.requests + r.stats.stores + r.stats.atomics, 0u);
  {
    Simulator abandoned(preset_named("vega56"), t.header);
    abandoned.begin_pass(t.passes[0]);
    abandoned.feed(t.records[0], 0, t.passes[0].dispatch.workgroups());
  }  // destroyed mid-pass: joins its scheduler thread
  EXPECT_THROW(sim.end_pass(), std::logic_error);
}

}  // namespace
}  // namespace hp::cachesim
