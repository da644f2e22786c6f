#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <tuple>

#include "cachesim/din_replay.hpp"
#include "cachesim/simulator.hpp"
#include "cachesim/synthetic.hpp"
#include "error.hpp"
#include "trace/din.hpp"

namespace hp::cachesim {
namespace {

using trace::TraceRecord;

Preset small_preset(uint32_t cus, uint32_t width, uint32_t max_waves, Coalescing co = Coalescing::line) {
  Preset p;
  p.name = "test";
  p.compute_units = cus;
  p.wave_width = width;
  p.max_waves_per_cu = max_waves;
  p.coalescing = co;
  const uint32_t line = co == Coalescing::line ? 64 : 128, sector = co == Coalescing::line ? 64 : 32;
  p.l1 = CacheConfig{4096, line, sector, 4};
  p.l2 = CacheConfig{65536, line, sector, 16};
  return p;
}

trace::TraceHeader one_buffer() {
  trace::TraceHeader h;
  trace::BufferInfo b;
  b.id = 0;
  b.name = "buf";
  b.base_address = 0x10000;
  b.size_bytes = 1 << 20;
  h.buffers.push_back(b);
  return h;
}

trace::PassInfo pass_of(uint32_t per_group, uint32_t groups) {
  trace::PassInfo p{std::string("p"), {}};
  p.dispatch.workgroup_size[0] = per_group;
  p.dispatch.workgroup_count[0] = groups;
  return p;
}

TraceRecord load(uint32_t inv, uint32_t seq, uint32_t offset, uint32_t size = 4, uint32_t kind = HP_TRACE_LOAD) {
  return TraceRecord{inv, seq, HP_TRACE_INFO(0u, kind, size), offset};
}

struct Seen {
  uint32_t cu;
  uint64_t line;
  uint32_t sectors;
  AccessKind kind;
  bool operator==(const Seen&) const = default;
};

std::vector<Seen> observe(const Preset& p, const trace::PassInfo& pass, const std::vector<TraceRecord>& recs,
                          PassResult* out = nullptr) {
  std::vector<Seen> seen;
  SimOptions o;
  o.observer = [&](uint32_t cu, const Request& r) { seen.push_back({cu, r.line, r.sectors, r.kind}); };
  Simulator sim(p, one_buffer(), o);
  PassResult res = sim.run_pass(pass, recs);
  if (out) *out = res;
  return seen;
}

constexpr uint64_t kBaseLine64 = 0x10000 / 64, kBaseLine128 = 0x10000 / 128;

TEST(Simulator, CoalescesLanesIntoUniqueLines) {
  auto seen =
      observe(small_preset(1, 4, 8), pass_of(4, 1), {load(0, 0, 0), load(1, 0, 4), load(2, 0, 8), load(3, 0, 64)});
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].line, kBaseLine64);
  EXPECT_EQ(seen[1].line, kBaseLine64 + 1);
}

TEST(Simulator, CoalescesIntoSectorsGroupedByLine) {
  auto seen = observe(small_preset(1, 4, 8, Coalescing::sector), pass_of(4, 1),
                      {load(0, 0, 0), load(1, 0, 32), load(2, 0, 100), load(3, 0, 200)});
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].line, kBaseLine128);
  EXPECT_EQ(seen[0].sectors, 0b1011u);
  EXPECT_EQ(seen[1].line, kBaseLine128 + 1);
  EXPECT_EQ(seen[1].sectors, 0b0100u);
}

TEST(Simulator, LineCrossingAccessRequestsBothLines) {
  PassResult r;
  auto seen = observe(small_preset(1, 1, 8), pass_of(1, 1), {load(0, 0, 60, 8)}, &r);
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[1].line, seen[0].line + 1);
  EXPECT_EQ(r.l1_misses[0], 2u);  // the lane saw both misses
  auto sec = observe(small_preset(1, 1, 8, Coalescing::sector), pass_of(1, 1), {load(0, 0, 124, 16)});
  ASSERT_EQ(sec.size(), 2u);
  EXPECT_EQ(sec[0].sectors, 0b1000u);
  EXPECT_EQ(sec[1].sectors, 0b0001u);
}

TEST(Simulator, KindsAreNotMerged) {
  auto seen = observe(small_preset(1, 2, 8), pass_of(2, 1), {load(0, 0, 0), load(1, 0, 8, 4, HP_TRACE_STORE)});
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].kind, AccessKind::load);
  EXPECT_EQ(seen[1].kind, AccessKind::store);
}

TEST(Simulator, LanesIssueTheirKthAccessesTogetherRegardlessOfRecordOrder) {
  // Lane 0: A then B; lane 1: A then C; records shuffled as GPU atomics may deliver them.
  std::vector<TraceRecord> recs = {load(1, 1, 128), load(0, 1, 64), load(1, 0, 0), load(0, 0, 0)};
  auto seen = observe(small_preset(1, 2, 8), pass_of(2, 1), recs);
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_EQ(seen[0].line, kBaseLine64);
  EXPECT_EQ(seen[1].line, kBaseLine64 + 1);  // lane 0's B first: lane order within a step
  EXPECT_EQ(seen[2].line, kBaseLine64 + 2);
}

TEST(Simulator, SequenceNumbersRealignDivergedLanes) {
  // Lane 0 makes three accesses, lane 1 one, then both store at seq 9 (the same line): the stores
  // issue together in one request after lane 0's extra accesses.
  std::vector<TraceRecord> recs = {load(0, 0, 0),
                                   load(0, 1, 128),
                                   load(0, 2, 256),
                                   load(1, 0, 0),
                                   load(0, 9, 512, 4, HP_TRACE_STORE),
                                   load(1, 9, 516, 4, HP_TRACE_STORE)};
  PassResult r;
  auto seen = observe(small_preset(1, 2, 8), pass_of(2, 1), recs, &r);
  ASSERT_EQ(seen.size(), 4u);
  EXPECT_EQ(seen[3].kind, AccessKind::store);
  EXPECT_EQ(seen[3].line, kBaseLine64 + 8);
  EXPECT_EQ(r.wave_steps, 4u);
}

TEST(Simulator, WorkgroupsGoToComputeUnitsInDispatchOrder) {
  // 2 CUs, one wave per CU; workgroup 0 has two accesses, the others one (line = 1 + workgroup).
  std::vector<TraceRecord> recs = {load(0, 0, 64), load(0, 1, 64 * 10), load(1, 0, 128), load(2, 0, 192),
                                   load(3, 0, 256)};
  auto seen = observe(small_preset(2, 1, 1), pass_of(1, 4), recs);
  std::vector<Seen> want = {{0, kBaseLine64 + 1, 1, AccessKind::load},
                            {1, kBaseLine64 + 2, 1, AccessKind::load},
                            {0, kBaseLine64 + 10, 1, AccessKind::load},
                            {1, kBaseLine64 + 3, 1, AccessKind::load},
                            {0, kBaseLine64 + 4, 1, AccessKind::load}};
  EXPECT_EQ(seen, want);
}

TEST(Simulator, ResidentWavesInterleaveRoundRobin) {
  // One CU, wave width 1, a workgroup of 2 lanes = 2 waves, each with 2 accesses.
  std::vector<TraceRecord> recs = {load(0, 0, 0), load(0, 1, 64), load(1, 0, 128), load(1, 1, 192)};
  auto seen = observe(small_preset(1, 1, 4), pass_of(2, 1), recs);
  ASSERT_EQ(seen.size(), 4u);
  EXPECT_EQ(seen[0].line, kBaseLine64 + 0);
  EXPECT_EQ(seen[1].line, kBaseLine64 + 2);
  EXPECT_EQ(seen[2].line, kBaseLine64 + 1);
  EXPECT_EQ(seen[3].line, kBaseLine64 + 3);
}

TEST(Simulator, OccupancyLimitDelaysWorkgroups) {
  // 2 CUs. Workgroup 0 loads A then B, workgroup 1 loads C, workgroup 2 loads A. With one resident
  // workgroup per CU, workgroup 2 waits for CU 1 and misses there; with two it joins workgroup 0 on
  // CU 0 and hits the line workgroup 0 brought in.
  std::vector<TraceRecord> recs = {load(0, 0, 0), load(0, 1, 64), load(1, 0, 128), load(2, 0, 0)};
  PassResult one, two;
  auto seen_one = observe(small_preset(2, 1, 1), pass_of(1, 3), recs, &one);
  auto seen_two = observe(small_preset(2, 1, 2), pass_of(1, 3), recs, &two);
  EXPECT_EQ(one.l1_misses[2], 1u);
  EXPECT_EQ(seen_one.back().cu, 1u);
  EXPECT_EQ(two.l1_misses[2], 0u);
}

TEST(Simulator, PerInvocationMissesAndConservation) {
  PassResult r;
  observe(small_preset(1, 2, 8), pass_of(2, 1), {load(0, 0, 0), load(1, 0, 4), load(0, 1, 0)}, &r);
  EXPECT_EQ(r.l1_misses[0], 1u);
  EXPECT_EQ(r.l1_misses[1], 1u);  // shared request: both lanes saw the miss
  EXPECT_EQ(r.stats.l1.requests, 2u);
  EXPECT_EQ(r.stats.l1.hits, 1u);
  EXPECT_EQ(r.lane_accesses, 3u);
  EXPECT_EQ(r.wave_steps, 2u);
}

TEST(Simulator, SyntheticTraceCountsAreConsistentAndDeterministic) {
  SyntheticBvhOptions o;
  o.width = o.height = 32;
  o.tree_depth = 10;
  trace::Trace t = make_bvh_like_trace(o);
  trace::validate_records("synthetic", t.header, t.passes[0], t.records[0]);
  Preset p = small_preset(4, 16, 8);
  SimOptions so;
  so.l2_mrc = true;
  Simulator a(p, t.header, so), b(p, t.header, so);
  PassResult ra = a.run_pass(t.passes[0], t.records[0]);
  std::vector<TraceRecord> shuffled = t.records[0];
  std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(3));
  PassResult rb = b.run_pass(t.passes[0], shuffled);
  EXPECT_EQ(ra.stats.l1.misses, rb.stats.l1.misses);
  EXPECT_EQ(ra.stats.l2.misses, rb.stats.l2.misses);
  EXPECT_EQ(ra.stats.l1.hits + ra.stats.l1.misses, ra.stats.l1.requests);
  EXPECT_EQ(ra.stats.l2.requests, ra.stats.l1.misses + ra.stats.stores + ra.stats.atomics);
  // The epilogue stores share one seq: a 16-lane wave covers 2 rows of 8 pixels, 32 bytes in each
  // row's 64-byte line, so 2 store requests per wave.
  EXPECT_EQ(ra.stats.stores, 32u * 32u / 16u * 2u);
  uint64_t inv_l1 = 0;
  for (uint32_t m : ra.l1_misses) inv_l1 += m;
  EXPECT_GE(inv_l1, ra.stats.l1.misses);
  EXPECT_EQ(ra.l2_curve.accesses, ra.stats.l2.requests);
  EXPECT_GT(ra.stats.l1.hits, 0u);
  EXPECT_GT(ra.stats.l2.misses, 0u);
}

// Everything a replay counts, for comparing two replays of the same pass.
void expect_same(const PassResult& a, const PassResult& b) {
  EXPECT_EQ(a.stats.l1.requests, b.stats.l1.requests);
  EXPECT_EQ(a.stats.l1.misses, b.stats.l1.misses);
  EXPECT_EQ(a.stats.l1.sector_misses, b.stats.l1.sector_misses);
  EXPECT_EQ(a.stats.l2.requests, b.stats.l2.requests);
  EXPECT_EQ(a.stats.l2.misses, b.stats.l2.misses);
  EXPECT_EQ(a.stats.l2.sector_misses, b.stats.l2.sector_misses);
  EXPECT_EQ(a.stats.dram_read_bytes, b.stats.dram_read_bytes);
  EXPECT_EQ(a.stats.stores, b.stats.stores);
  EXPECT_EQ(a.lane_accesses, b.lane_accesses);
  EXPECT_EQ(a.wave_steps, b.wave_steps);
  EXPECT_EQ(a.waves, b.waves);
  EXPECT_EQ(a.cycles, b.cycles);
  EXPECT_EQ(a.l1_misses, b.l1_misses);
  EXPECT_EQ(a.l2_misses, b.l2_misses);
  for (uint64_t lines : {1u, 16u, 256u, 4096u, 65536u}) EXPECT_EQ(a.l2_curve.misses(lines), b.l2_curve.misses(lines));
  for (size_t i = 0; i < a.buffers.size(); ++i) EXPECT_EQ(a.buffers[i].l2_misses, b.buffers[i].l2_misses);
}

TEST(Simulator, SlicedReplayEqualsWholeReplayAndHoldsOnlyAFewSlices) {
  SyntheticBvhOptions o;
  o.width = 64;
  o.height = 48;
  o.tree_depth = 10;
  o.incoherent_fraction = 0.3;
  trace::Trace t = make_bvh_like_trace(o);
  const trace::PassInfo& pass = t.passes[0];
  const uint64_t groups = pass.dispatch.workgroups(), per_group = pass.dispatch.invocations_per_workgroup();
  std::mt19937 rng(11);
  for (Preset p : {small_preset(4, 16, 8), small_preset(3, 32, 2, Coalescing::sector), small_preset(7, 64, 64)}) {
    SimOptions so;
    so.l2_mrc = true;
    Simulator whole(p, t.header, so);
    const PassResult ref = whole.run_pass(pass, t.records[0]);
    for (int trial = 0; trial < 4; ++trial) {
      // Random cut points, some slices empty, records shuffled inside each slice.
      std::vector<uint64_t> cuts = {0, groups};
      for (int k = 0; k < 1 + trial * 5; ++k) cuts.push_back(rng() % (groups + 1));
      std::sort(cuts.begin(), cuts.end());
      Simulator sliced(p, t.header, so);
      sliced.begin_pass(pass);
      for (size_t c = 0; c + 1 < cuts.size(); ++c) {
        std::vector<TraceRecord> part;
        for (const TraceRecord& r : t.records[0])
          if (r.invocation >= cuts[c] * per_group && r.invocation < cuts[c + 1] * per_group) part.push_back(r);
        std::shuffle(part.begin(), part.end(), rng);
        sliced.feed(part, cuts[c], cuts[c + 1]);
      }
      const PassResult r = sliced.end_pass();
      SCOPED_TRACE("preset wave" + std::to_string(p.wave_width) + ", trial " + std::to_string(trial));
      expect_same(ref, r);
      EXPECT_LE(r.peak_resident_records, t.records[0].size());
      const uint64_t waves_per_group = (per_group + p.wave_width - 1) / p.wave_width;
      const uint64_t resident_groups =
          uint64_t(p.compute_units) * std::max<uint64_t>(1, p.max_waves_per_cu / waves_per_group);
      if (trial == 3 && resident_groups * 4 < groups) {
        // Many slices on a machine that holds a fraction of the dispatch: the replay never held it all.
        EXPECT_LT(r.peak_resident_records, t.records[0].size() * 3 / 4) << r.slices << " slices";
      }
    }
  }
}

TEST(Simulator, WorkgroupsNoSliceCoversHaveNoAccesses) {
  // Workgroups 1 and 3 of 4 fed as slices; 0 and 2 never: the replay equals a whole pass without them.
  const trace::PassInfo pass = pass_of(64, 4);
  std::vector<TraceRecord> g1, g3, both;
  for (uint32_t i = 0; i < 64; ++i) {
    g1.push_back(load(64 + i, 0, i * 4));
    g3.push_back(load(192 + i, 0, 4096 + i * 8));
  }
  both = g1;
  both.insert(both.end(), g3.begin(), g3.end());
  const Preset p = small_preset(2, 16, 8);
  Simulator whole(p, one_buffer()), sliced(p, one_buffer());
  const PassResult ref = whole.run_pass(pass, both);
  sliced.begin_pass(pass);
  sliced.feed(g1, 1, 2);
  sliced.feed(g3, 3, 4);
  const PassResult r = sliced.end_pass();
  expect_same(ref, r);
  EXPECT_EQ(r.slices, 2u);
  EXPECT_EQ(r.waves, 16u);  // every workgroup's 4 waves are counted, empty or not
}

TEST(Simulator, SlicesOutOfOrderOrOutsideTheirRangeAreRejected) {
  const trace::PassInfo pass = pass_of(64, 4);
  Simulator sim(small_preset(2, 16, 8), one_buffer());
  sim.begin_pass(pass);
  sim.feed(std::vector<TraceRecord>{load(130, 0, 0)}, 2, 3);
  EXPECT_THROW(sim.feed(std::vector<TraceRecord>{load(10, 0, 0)}, 0, 1), InputError);  // before the last slice
  EXPECT_THROW(sim.feed(std::vector<TraceRecord>{load(10, 0, 0)}, 3, 4), InputError);  // record not in [3, 4)
  EXPECT_THROW(sim.feed(std::vector<TraceRecord>{}, 3, 5), InputError);                // past the dispatch
  sim.feed(std::vector<TraceRecord>{load(200, 0, 64)}, 3, 4);
  const PassResult r = sim.end_pass();
  EXPECT_EQ(r.lane_accesses, 2u);
  EXPECT_EQ(r.stats.l1.requests, 2u);
}

TEST(Simulator, DineroExportReplaysToTheSameL1Counts) {
  SyntheticBvhOptions o;
  o.width = o.height = 32;
  o.tree_depth = 9;
  trace::Trace t = make_bvh_like_trace(o);
  for (Coalescing co : {Coalescing::line, Coalescing::sector}) {
    Preset p = small_preset(1, 16, 4, co);
    if (co == Coalescing::sector) {  // Dinero has no sectors: compare a sector-less L1 of 32 B lines
      p.l1 = CacheConfig{4096, 32, 32, 4};
      p.l2 = CacheConfig{65536, 32, 32, 16};
    }
    std::stringstream din;
    const uint64_t lines = export_din(din, p, t.header, t.passes[0], t.records[0], 0);
    auto accesses = trace::parse_din(din, "export");
    ASSERT_EQ(accesses.size(), lines);
    SimOptions so;
    so.per_invocation = false;
    Simulator sim(p, t.header, so);
    PassResult r = sim.run_pass(t.passes[0], t.records[0]);
    DinResult d = replay_din(accesses, p.l1, p.l2);
    EXPECT_EQ(d.l1.fetches, r.stats.l1.requests);
    EXPECT_EQ(d.l1.misses, r.stats.l1.misses);
  }
  EXPECT_THROW(
      {
        std::stringstream s;
        export_din(s, small_preset(1, 16, 4), t.header, t.passes[0], t.records[0], 3);
      },
      hp::InputError);
}

constexpr HitCounting kCountings[] = {HitCounting::request, HitCounting::quarter_wave, HitCounting::lane};

PassResult replay_counting(Preset p, HitCounting c, const trace::PassInfo& pass, const std::vector<TraceRecord>& recs) {
  p.l1_hit_counting = c;
  Simulator sim(p, one_buffer());
  return sim.run_pass(pass, recs);
}

TEST(Simulator, L1HitCountingsOfOneWaveReadingOneLine) {
  // 64 lanes read 4 bytes each of one 64-byte line: one request, which misses.
  std::vector<TraceRecord> recs;
  for (uint32_t l = 0; l < 64; ++l) recs.push_back(load(l, 0, (l % 16) * 4));
  const uint64_t lookups[] = {1, 4, 64}, hits[] = {0, 3, 63};
  for (size_t k = 0; k < 3; ++k) {
    const PassResult r = replay_counting(small_preset(1, 64, 8), kCountings[k], pass_of(64, 1), recs);
    SCOPED_TRACE(to_string(kCountings[k]));
    EXPECT_EQ(r.l1_hit_counting, kCountings[k]);
    EXPECT_EQ(r.stats.l1.misses, 1u);
    EXPECT_EQ(r.stats.l1.requests, lookups[k]);
    EXPECT_EQ(r.stats.l1.hits, hits[k]);
    EXPECT_EQ(r.buffers[0].l1_requests, lookups[k]);
    EXPECT_EQ(r.buffers[0].l1_misses, 1u);
    // Every counting is there whichever the preset picks.
    EXPECT_EQ(r.l1_lookups.request, 1u);
    EXPECT_EQ(r.l1_lookups.quarter_wave, 4u);
    EXPECT_EQ(r.l1_lookups.lane, 64u);
    EXPECT_EQ(r.buffer_l1_lookups[0].lane, 64u);
    // Below the L1 nothing changes: one L2 request, one L2 miss.
    EXPECT_EQ(r.stats.l2.requests, 1u);
    EXPECT_EQ(r.stats.l2.misses, 1u);
  }
}

TEST(Simulator, L1HitCountingsFollowTheLanesAndQuarterWavesOfEachRequest) {
  std::vector<TraceRecord> recs;
  for (uint32_t l = 0; l < 64; ++l) {
    // Step 0: lanes 0-15 (quarter 0) read line A, lanes 16-63 (quarters 1-3) line B: two misses.
    recs.push_back(load(l, 0, l < 16 ? l * 4 : 64 + (l % 16) * 4));
    // Step 1: every lane reads A again: a hit.
    recs.push_back(load(l, 1, 0));
    // Step 3: stores are not L1 lookups.
    recs.push_back(load(l, 3, 1024 + l * 4, 4, HP_TRACE_STORE));
  }
  // Step 2: lane 40 alone reads 8 bytes across A and B: two requests of one lane each, both hits.
  recs.push_back(load(40, 2, 60, 8));
  std::shuffle(recs.begin(), recs.end(), std::mt19937(5));
  for (HitCounting c : kCountings) {
    const PassResult r = replay_counting(small_preset(1, 64, 8), c, pass_of(64, 1), recs);
    SCOPED_TRACE(to_string(c));
    EXPECT_EQ(r.stats.l1.misses, 2u);
    EXPECT_EQ(r.l1_lookups.request, 5u);
    EXPECT_EQ(r.l1_lookups.quarter_wave, 1u + 3u + 4u + 1u + 1u);
    EXPECT_EQ(r.l1_lookups.lane, 16u + 48u + 64u + 1u + 1u);
    EXPECT_EQ(r.stats.l1.requests, r.l1_lookups.of(c));
    EXPECT_EQ(r.stats.l1.hits, r.l1_lookups.of(c) - 2u);
    EXPECT_EQ(r.stats.stores, 4u);  // 256 bytes of stores: four lines
  }
  // A wave of 32 has quarters of 8 lanes; one of 6, quarters of 2 lanes (the last one short).
  std::vector<TraceRecord> narrow;
  for (uint32_t l = 0; l < 6; ++l) narrow.push_back(load(l, 0, 0));
  EXPECT_EQ(
      replay_counting(small_preset(1, 6, 8), HitCounting::quarter_wave, pass_of(6, 1), narrow).l1_lookups.quarter_wave,
      3u);
  EXPECT_EQ(
      replay_counting(small_preset(1, 32, 8), HitCounting::quarter_wave, pass_of(6, 1), narrow).l1_lookups.quarter_wave,
      1u);
}

// A random trace: workgroups of 128 on waves of 64, each lane a random number of accesses with strictly
// increasing seqs (dense in some lanes, with large gaps in others), loads, stores and atomics, some
// crossing a line, some lanes sharing lines. The lookups each counting expects are counted here from the
// records alone: per wave and seq (one step), per line touched by loads, its lanes and quarter-waves.
struct RandomTrace {
  trace::PassInfo pass = pass_of(128, 24);
  std::vector<TraceRecord> records;
  L1Lookups expected;
};

RandomTrace random_trace(uint32_t seed) {
  RandomTrace t;
  std::mt19937 rng(seed);
  std::map<std::tuple<uint32_t, uint32_t, uint64_t>, std::pair<std::set<uint32_t>, std::set<uint32_t>>> steps;
  const uint32_t invocations = 128 * 24;
  for (uint32_t inv = 0; inv < invocations; ++inv) {
    const uint32_t n = rng() % 12;
    const bool sparse = (inv / 64) % 3 == 0;  // these waves take the general (non-dense) step path
    uint32_t seq = rng() % 3;
    for (uint32_t k = 0; k < n; ++k) {
      seq += sparse ? 1 + rng() % 700 : 1 + rng() % 2;
      // Neighbouring lanes often share a line; a few accesses spread over 256 KiB.
      const uint32_t offset = rng() % 8 == 0 ? (rng() % 65536) * 4 : ((inv / 8) * 64 + seq * 128 + rng() % 64) % 65536;
      const uint32_t size = rng() % 6 == 0 ? 16 : 4;
      const uint32_t r = rng() % 20;
      const uint32_t kind = r == 0 ? HP_TRACE_ATOMIC : r < 4 ? HP_TRACE_STORE : HP_TRACE_LOAD;
      t.records.push_back(load(inv, seq, offset, size, kind));
      if (kind != HP_TRACE_LOAD) continue;
      const uint32_t wave = inv / 64, lane = inv % 64;
      const uint64_t a = 0x10000 + offset;
      for (uint64_t line = a / 64; line <= (a + size - 1) / 64; ++line) {
        auto& [lanes, quarters] = steps[{wave, seq, line}];
        lanes.insert(lane);
        quarters.insert(lane / 16);
      }
    }
  }
  for (const auto& [key, v] : steps) {
    ++t.expected.request;
    t.expected.lane += v.first.size();
    t.expected.quarter_wave += v.second.size();
  }
  std::shuffle(t.records.begin(), t.records.end(), rng);
  return t;
}

TEST(Simulator, MissesAreTheSameUnderEveryHitCounting) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    const RandomTrace t = random_trace(seed);
    for (Preset p : {small_preset(3, 64, 4), small_preset(2, 64, 8, Coalescing::sector)}) {
      SCOPED_TRACE("seed " + std::to_string(seed) + (p.coalescing == Coalescing::sector ? ", sectors" : ", lines"));
      std::vector<PassResult> r;
      for (HitCounting c : kCountings) {
        p.l1_hit_counting = c;
        SimOptions so;
        so.l2_mrc = true;
        Simulator sim(p, one_buffer(), so);
        r.push_back(sim.run_pass(t.pass, t.records));
      }
      const PassResult& ref = r[0];
      if (p.coalescing == Coalescing::line) {  // the records' lines are 64-byte lines
        EXPECT_EQ(ref.l1_lookups.request, t.expected.request);
        EXPECT_EQ(ref.l1_lookups.quarter_wave, t.expected.quarter_wave);
        EXPECT_EQ(ref.l1_lookups.lane, t.expected.lane);
      }
      EXPECT_GT(ref.stats.l1.misses, 0u);
      EXPECT_GT(ref.stats.l1.hits, 0u);
      EXPECT_LT(ref.l1_lookups.request, ref.l1_lookups.quarter_wave);
      EXPECT_LT(ref.l1_lookups.quarter_wave, ref.l1_lookups.lane);
      for (size_t k = 0; k < r.size(); ++k) {
        const PassResult& x = r[k];
        SCOPED_TRACE(to_string(kCountings[k]));
        EXPECT_EQ(x.l1_lookups.request, ref.stats.l1.requests);  // the request counting is the hierarchy's
        EXPECT_EQ(x.l1_lookups.request, ref.l1_lookups.request);
        EXPECT_EQ(x.l1_lookups.quarter_wave, ref.l1_lookups.quarter_wave);
        EXPECT_EQ(x.l1_lookups.lane, ref.l1_lookups.lane);
        EXPECT_EQ(x.stats.l1.requests, x.l1_lookups.of(kCountings[k]));
        EXPECT_EQ(x.stats.l1.hits + x.stats.l1.misses, x.stats.l1.requests);
        // Misses, sectors, the L2, DRAM, per-invocation counts and curves: identical.
        EXPECT_EQ(x.stats.l1.misses, ref.stats.l1.misses);
        EXPECT_EQ(x.stats.l1.sector_misses, ref.stats.l1.sector_misses);
        EXPECT_EQ(x.stats.l2.requests, ref.stats.l2.requests);
        EXPECT_EQ(x.stats.l2.hits, ref.stats.l2.hits);
        EXPECT_EQ(x.stats.l2.misses, ref.stats.l2.misses);
        EXPECT_EQ(x.stats.dram_read_bytes, ref.stats.dram_read_bytes);
        EXPECT_EQ(x.l1_misses, ref.l1_misses);
        EXPECT_EQ(x.l2_misses, ref.l2_misses);
        EXPECT_EQ(x.l2_curve.misses(64), ref.l2_curve.misses(64));
        EXPECT_EQ(x.buffers[0].l1_misses, ref.buffers[0].l1_misses);
        EXPECT_EQ(x.buffers[0].l2_misses, ref.buffers[0].l2_misses);
        EXPECT_EQ(x.buffers[0].l1_requests, x.buffer_l1_lookups[0].of(kCountings[k]));
      }
    }
  }
}

TEST(BufferLayout, ImagesMapLogicalOffsetsByDeclaredLayout) {
  trace::BufferInfo tiled;
  tiled.kind = trace::BufferKind::image_tiled;
  tiled.base_address = 1000;
  tiled.texel_bytes = 4;
  tiled.width = 16;
  tiled.height = 16;
  tiled.tile_width = 8;
  tiled.tile_height = 8;
  const uint32_t texel = 1 * 16 + 9;  // x = 9, y = 1: tile 1, position 1 * 8 + 1 within it
  EXPECT_EQ(tiled.address(texel * 4 + 2), 1000u + (64 + 9) * 4 + 2);
  trace::BufferInfo linear = tiled;
  linear.kind = trace::BufferKind::image_linear;
  linear.row_pitch_bytes = 256;
  EXPECT_EQ(linear.address(texel * 4), 1000u + 256 + 36);
}

}  // namespace
}  // namespace hp::cachesim
