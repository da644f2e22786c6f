#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <tuple>

#include "atomic_file.hpp"
#include "common/scratch_dir.hpp"
#include "error.hpp"
#include "trace/trace_codec.hpp"
#include "trace/trace_file.hpp"

namespace hp::trace {
namespace {

namespace fs = std::filesystem;

Trace sample() {
  Trace t;
  t.header.image_width = 16;
  t.header.image_height = 8;
  BufferInfo nodes;
  nodes.id = 0;
  nodes.name = "nodes";
  nodes.base_address = 0x1000;
  nodes.size_bytes = 4096;
  BufferInfo img;
  img.id = 7;
  img.name = "gbuffer_normal";
  img.kind = BufferKind::image_tiled;
  img.base_address = 0x100000;
  img.size_bytes = 16 * 8 * 8;
  img.texel_bytes = 8;
  img.width = 16;
  img.height = 8;
  img.tile_width = 8;
  img.tile_height = 8;
  t.header.buffers = {nodes, img};
  PassInfo a{"shadows", {{8, 8, 1}, {2, 1, 1}}}, b{"refl", {{64, 1, 1}, {1, 1, 1}}};
  t.passes = {a, b};
  t.records.resize(2);
  for (uint32_t i = 0; i < 128; ++i) t.records[0].push_back({i, 0, HP_TRACE_INFO(0u, HP_TRACE_LOAD, 16u), i * 32});
  t.records[0].push_back({5, 1, HP_TRACE_INFO(7u, HP_TRACE_STORE, 8u), 40});
  t.records[1].push_back({63, 0, HP_TRACE_INFO(0u, HP_TRACE_ATOMIC, 4u), 4092});
  return t;
}

fs::path tmp(const std::string& name) { return hp::test::scratch_dir() / name; }

std::string error_reading(const fs::path& p) {
  try {
    read_trace(p);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

std::vector<char> bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}
void write_bytes(const fs::path& p, const std::vector<char>& b) {
  std::ofstream(p, std::ios::binary).write(b.data(), std::streamsize(b.size()));
}

bool same(const TraceRecord& a, const TraceRecord& b) {
  return a.invocation == b.invocation && a.seq == b.seq && a.info == b.info && a.offset == b.offset;
}

TEST(TraceFile, RoundTrip) {
  const Trace t = sample();
  const auto p = tmp("round.hptrace");
  write_trace(p, t, kTraceVersionRaw);
  EXPECT_FALSE(atomic_temporary_exists(p));
  const Trace r = read_trace(p);
  EXPECT_EQ(r.header.image_width, 16u);
  ASSERT_EQ(r.header.buffers.size(), 2u);
  EXPECT_EQ(r.header.buffers[1].name, "gbuffer_normal");
  EXPECT_EQ(r.header.buffers[1].kind, BufferKind::image_tiled);
  EXPECT_EQ(r.header.buffers[1].tile_height, 8u);
  EXPECT_EQ(r.header.buffers[1].base_address, 0x100000u);
  ASSERT_EQ(r.passes.size(), 2u);
  EXPECT_EQ(r.passes[0].name, "shadows");
  EXPECT_EQ(r.passes[0].dispatch.workgroup_count[0], 2u);
  EXPECT_EQ(r.passes[1].dispatch.workgroup_size[0], 64u);
  for (int p = 0; p < 2; ++p) {
    ASSERT_EQ(r.records[p].size(), t.records[p].size());
    for (size_t i = 0; i < t.records[p].size(); ++i) EXPECT_TRUE(same(r.records[p][i], t.records[p][i]));
  }
}

// Pass 0's records by workgroup: records 0..63 and 128 (invocation 5) belong to workgroup 0, 64..127 to 1.
std::vector<TraceRecord> of_group(const Trace& t, uint32_t wg) {
  std::vector<TraceRecord> out;
  for (const TraceRecord& r : t.records[0])
    if (r.invocation / 64 == wg) out.push_back(r);
  return out;
}

TEST(TraceFile, StreamedSlicesAreConcatenatedPerPass) {
  const Trace t = sample();
  const auto p = tmp("slices.hptrace");
  const auto g0 = of_group(t, 0), g1 = of_group(t, 1);
  {
    TraceWriter w(p, t.header, kTraceVersionRaw);
    const uint32_t a = w.begin_pass(t.passes[0]);
    const uint32_t b = w.begin_pass(t.passes[1]);
    w.write_records(a, g0, 0, 1);
    w.write_records(b, t.records[1], 0, 1);
    w.write_records(a, g1, 1, 2);
    w.finish();
  }
  TraceReader r(p);
  EXPECT_EQ(r.record_count(0), t.records[0].size());
  const auto recs = r.read_pass(0);
  ASSERT_EQ(recs.size(), g0.size() + g1.size());
  for (size_t i = 0; i < recs.size(); ++i) EXPECT_TRUE(same(recs[i], i < g0.size() ? g0[i] : g1[i - g0.size()]));
}

TEST(TraceFile, ReadSlicesComesInWorkgroupOrderOneSliceAtATime) {
  const Trace t = sample();
  const auto p = tmp("slices_order.hptrace");
  const auto g0 = of_group(t, 0), g1 = of_group(t, 1);
  {
    TraceWriter w(p, t.header, kTraceVersionRaw);
    const uint32_t a = w.begin_pass(t.passes[0]);
    w.write_records(a, g1, 1, 2);  // written out of order
    w.write_records(a, g0, 0, 1);
    w.finish();
  }
  TraceReader r(p);
  std::vector<std::pair<uint64_t, uint64_t>> ranges;
  std::vector<size_t> sizes;
  const uint64_t largest = r.read_slices(0, [&](std::span<const TraceRecord> recs, uint64_t first, uint64_t end) {
    ranges.emplace_back(first, end);
    sizes.push_back(recs.size());
    for (const TraceRecord& x : recs) EXPECT_EQ(x.invocation / 64, first);
  });
  ASSERT_EQ(ranges.size(), 2u);
  EXPECT_EQ(ranges[0], std::make_pair(uint64_t(0), uint64_t(1)));
  EXPECT_EQ(ranges[1], std::make_pair(uint64_t(1), uint64_t(2)));
  EXPECT_EQ(sizes[0], g0.size());
  EXPECT_EQ(sizes[1], g1.size());
  EXPECT_EQ(largest, g0.size());
}

// A version-2 slice decodes in workgroup order, and the reader hands over where each workgroup's records
// start (workgroups without records included), so that the simulator need not scan them; a version-1
// slice, in the GPU's order, comes without.
TEST(TraceFile, CompactSlicesComeWithTheirWorkgroupIndex) {
  const Trace t = sample();
  const auto g0 = of_group(t, 0), g1 = of_group(t, 1);
  ASSERT_FALSE(g0.empty());
  ASSERT_FALSE(g1.empty());
  for (const uint32_t version : {kTraceVersion, kTraceVersionRaw}) {
    const auto p = tmp("slices_index_v" + std::to_string(version) + ".hptrace");
    {
      TraceWriter w(p, t.header, version);
      const uint32_t a = w.begin_pass(t.passes[0]);
      w.write_records(a, t.records[0], 0, 2);  // both workgroups in one slice
      w.finish();
    }
    TraceReader r(p);
    int slices = 0;
    r.read_slices_indexed(0, [&](std::span<const TraceRecord> recs, uint64_t first, uint64_t end,
                                 const uint32_t* group_begin) {
      ++slices;
      if (version == kTraceVersionRaw) {
        EXPECT_EQ(group_begin, nullptr);
        return;
      }
      ASSERT_NE(group_begin, nullptr);
      EXPECT_EQ(group_begin[0], 0u);
      EXPECT_EQ(group_begin[1], g0.size());
      EXPECT_EQ(group_begin[end - first], recs.size());
      for (uint64_t g = 0; g < end - first; ++g)
        for (uint32_t i = group_begin[g]; i < group_begin[g + 1]; ++i) EXPECT_EQ(recs[i].invocation / 64, first + g);
    });
    EXPECT_EQ(slices, 1);
  }
  // A workgroup without records in the middle of a slice: its entry equals the next one's.
  const auto gap = tmp("slices_index_gap.hptrace");
  {
    TraceWriter w(gap, t.header);
    const uint32_t a = w.begin_pass(t.passes[0]);
    w.write_records(a, g1, 0, 2);  // workgroup 0 has none
    w.finish();
  }
  TraceReader r(gap);
  r.read_slices_indexed(0, [&](std::span<const TraceRecord> recs, uint64_t, uint64_t, const uint32_t* group_begin) {
    ASSERT_NE(group_begin, nullptr);
    EXPECT_EQ(group_begin[0], 0u);
    EXPECT_EQ(group_begin[1], 0u);
    EXPECT_EQ(group_begin[2], recs.size());
  });
}

TEST(TraceFile, SlicesMustHoldTheirOwnWorkgroupsAndNotOverlap) {
  const Trace t = sample();
  const auto outside = tmp("slice_outside.hptrace"), overlap = tmp("slice_overlap.hptrace"),
             past = tmp("slice_past.hptrace");
  {
    TraceWriter w(outside, t.header, kTraceVersionRaw);
    const uint32_t a = w.begin_pass(t.passes[0]);
    w.write_records(a, t.records[0], 1, 2);  // holds workgroup 0's records too
    w.finish();
  }
  EXPECT_NE(error_reading(outside).find("outside its slice's workgroups [1, 2)"), std::string::npos)
      << error_reading(outside);
  {
    TraceWriter w(overlap, t.header, kTraceVersionRaw);
    const uint32_t a = w.begin_pass(t.passes[0]);
    w.write_records(a, of_group(t, 0), 0, 1);
    w.write_records(a, of_group(t, 1), 0, 2);
    w.finish();
  }
  EXPECT_NE(error_reading(overlap).find("overlap at workgroup 0"), std::string::npos) << error_reading(overlap);
  {
    TraceWriter w(past, t.header, kTraceVersionRaw);
    const uint32_t a = w.begin_pass(t.passes[0]);
    w.write_records(a, {}, 2, 3);
    w.finish();
  }
  EXPECT_NE(error_reading(past).find("outside the dispatch of 2"), std::string::npos) << error_reading(past);
}

TEST(TraceFile, UnfinishedWriterLeavesNoFile) {
  const auto p = tmp("unfinished.hptrace");
  fs::remove(p);
  {
    TraceWriter w(p, sample().header, kTraceVersionRaw);
    w.begin_pass(sample().passes[0]);
  }
  EXPECT_FALSE(fs::exists(p));
  EXPECT_FALSE(atomic_temporary_exists(p));
}

TEST(TraceFile, CorruptFilesGiveOneLineErrorsNamingTheFile) {
  const auto good = tmp("good.hptrace");
  write_trace(good, sample(), kTraceVersionRaw);
  const auto bytes = bytes_of(good);
  const auto bad = tmp("bad.hptrace");

  auto corrupted = bytes;
  corrupted[0] = 'X';
  write_bytes(bad, corrupted);
  EXPECT_EQ(error_reading(bad), bad.string() + ": bad magic: not a hybridprof trace file");

  corrupted = bytes;
  corrupted[8] = 9;  // version
  write_bytes(bad, corrupted);
  EXPECT_EQ(error_reading(bad), bad.string() + ": unsupported version 9 (this build reads versions 1 and 2)");

  write_bytes(bad, std::vector<char>(bytes.begin(), bytes.begin() + 20));
  EXPECT_EQ(error_reading(bad), bad.string() + ": truncated: shorter than the 32-byte header");

  write_bytes(bad, std::vector<char>(bytes.begin(), bytes.end() - 100));
  EXPECT_NE(error_reading(bad).find(bad.string() + ": truncated"), std::string::npos) << error_reading(bad);

  write_bytes(bad, std::vector<char>(bytes.begin(), bytes.end() - 32));  // the END chunk exactly
  EXPECT_EQ(error_reading(bad), bad.string() + ": truncated: no END chunk (the writer did not finish)");

  // A record naming a buffer the table lacks.
  Trace t = sample();
  t.records[0][3].info = HP_TRACE_INFO(3u, HP_TRACE_LOAD, 4u);
  write_trace(bad, t, kTraceVersionRaw);
  EXPECT_EQ(error_reading(bad), bad.string() + ": pass 'shadows': record 3: unknown buffer id 3");
  t = sample();
  t.records[1][0].invocation = 64;
  write_trace(bad, t, kTraceVersionRaw);
  EXPECT_NE(error_reading(bad).find("record 0: invocation 64 outside the dispatch"), std::string::npos);
  t = sample();
  t.records[1][0].offset = 4093;  // 4-byte atomic past the 4096-byte buffer
  write_trace(bad, t, kTraceVersionRaw);
  EXPECT_NE(error_reading(bad).find("past the end of buffer 'nodes'"), std::string::npos);

  EXPECT_NE(error_reading(tmp("does_not_exist")).find("cannot open trace file"), std::string::npos);
}

// Found by tests/fuzz/fuzz_trace (corpus/trace/oom_buffer_name_length.hptrace): a buffer name length of
// ~4 GiB was allocated before it was checked against the chunk.
TEST(TraceFile, NameLengthPastTheChunkIsAnErrorNotAnAllocation) {
  const auto good = tmp("name_len.hptrace");
  write_trace(good, sample(), kTraceVersionRaw);
  auto bytes = bytes_of(good);
  // Header 32 + chunk header 16 + count 4 = entry 0 at 52; its name_bytes field is 48 bytes in.
  ASSERT_EQ(bytes[100], 5);  // "nodes"
  bytes[103] = char(0xfb);
  write_bytes(good, bytes);
  EXPECT_EQ(error_reading(good),
            good.string() + ": malformed BUFS chunk at byte 32: name of entry 0 runs past the chunk");
}

// A RECS count of 2^60 + n wraps count * 16 to the chunk's true size; with END agreeing, read_pass then
// tried to allocate 2^64 bytes. The count must match the chunk exactly.
TEST(TraceFile, WrappingRecordCountIsAnError) {
  const auto p = tmp("wrap.hptrace");
  write_trace(p, sample(), kTraceVersionRaw);
  auto bytes = bytes_of(p);
  const std::string text(bytes.begin(), bytes.end());
  const size_t recs = text.find("RECS"), end = text.rfind("END ");
  ASSERT_NE(recs, std::string::npos);
  ASSERT_NE(end, std::string::npos);
  bytes[recs + 16 + 24 + 7] |= 0x10;  // RecordsEntry::count, top byte
  bytes[end + 16 + 7] |= 0x10;        // EndEntry::total_records, top byte
  write_bytes(p, bytes);
  EXPECT_EQ(error_reading(p), p.string() + ": malformed RECS chunk at byte " + std::to_string(recs) +
                                  ": record count does not match the chunk size");
}

size_t open_descriptors() {
  size_t n = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator("/proc/self/fd")) ++n;
  return n;
}

// Fuzzer find (2026-11-29, libFuzzer "malloc/free mismatch"): every file the reader rejected leaked its FILE
// and descriptor, because fail() throws out of the constructor and ~TraceReader never runs.
TEST(TraceFile, RejectedFilesDoNotLeakDescriptors) {
  if (!fs::exists("/proc/self/fd")) GTEST_SKIP() << "no /proc/self/fd";
  const auto good = tmp("leak.hptrace");
  write_trace(good, sample(), kTraceVersionRaw);
  const auto bytes = bytes_of(good);
  const auto bad = tmp("leak_bad.hptrace");
  write_bytes(bad, std::vector<char>(bytes.begin(), bytes.end() - 32));  // no END chunk
  const size_t before = open_descriptors();
  for (int i = 0; i < 64; ++i) EXPECT_NE(error_reading(bad).find("no END chunk"), std::string::npos);
  EXPECT_EQ(open_descriptors(), before);
}

// Names come from the file; an error quoting one stays on one line.
TEST(TraceFile, ErrorsQuotingANameStayOnOneLine) {
  Trace t = sample();
  t.passes[0].name = "sha\ndows";
  t.records[0][3].info = HP_TRACE_INFO(3u, HP_TRACE_LOAD, 4u);
  const auto p = tmp("newline.hptrace");
  write_trace(p, t, kTraceVersionRaw);
  // A name the writer never writes (not printable ASCII) is rejected where it is read, on one line.
  EXPECT_EQ(error_reading(p), p.string() + ": malformed PASS chunk at byte 188: the name is not printable ASCII");
}

// Version 2 (compact records): the same records, each invocation's in the same order, in issue order
// (workgroup, seq, invocation), in fewer bytes; lanes far apart, repeated seqs, seq gaps, offsets that
// jump both ways and an info word that changes are all in the sample below.
TEST(TraceFile, CompactRecordsKeepEveryInvocationsRecordsInIssueOrder) {
  Trace t = sample();
  t.records[0].push_back({5, 1, HP_TRACE_INFO(0u, HP_TRACE_LOAD, 4u), 4000});  // invocation 5, seq 1 again
  t.records[0].push_back({120, 9, HP_TRACE_INFO(0u, HP_TRACE_STORE, 2u), 0});  // a seq gap, lane 56 of wg 1
  t.records[0].push_back({64, 9, HP_TRACE_INFO(0u, HP_TRACE_LOAD, 1u), 0xFFF});
  t.records[0].push_back({0, 0xFFFFFFFF, HP_TRACE_INFO(7u, HP_TRACE_LOAD, 8u), 8});
  const auto raw = tmp("compact_raw.hptrace"), compact = tmp("compact.hptrace");
  write_trace(raw, t, kTraceVersionRaw);
  // Both codings (2 is written by default; files of coding 1 are still read).
  for (const uint32_t coding : {kCodingSizedGroups, kCodingDeltaVarint}) {
    SCOPED_TRACE("coding " + std::to_string(coding));
    write_trace(compact, t, kTraceVersion, coding);
    EXPECT_EQ(TraceReader(compact).version(), 2u);
    EXPECT_LT(fs::file_size(compact) * 3, fs::file_size(raw));
    const Trace r = read_trace(compact);
    for (size_t p = 0; p < t.passes.size(); ++p) {
      ASSERT_EQ(r.records[p].size(), t.records[p].size());
      const uint64_t per_group = t.passes[p].dispatch.invocations_per_workgroup();
      for (size_t i = 1; i < r.records[p].size(); ++i) {
        const TraceRecord &a = r.records[p][i - 1], &b = r.records[p][i];
        const auto key = [&](const TraceRecord& x) {
          return std::tuple(x.invocation / per_group, x.seq, x.invocation);
        };
        EXPECT_LE(key(a), key(b)) << i;
      }
      // Per invocation, the same records in the same order.
      auto by_invocation = [](const std::vector<TraceRecord>& recs) {
        std::map<uint32_t, std::vector<std::tuple<uint32_t, uint32_t, uint32_t>>> m;
        for (const TraceRecord& x : recs) m[x.invocation].emplace_back(x.seq, x.info, x.offset);
        return m;
      };
      EXPECT_EQ(by_invocation(r.records[p]), by_invocation(t.records[p]));
    }
    // Invocation 5's two seq-1 records keep their order (the store first, as written).
    const auto it = std::find_if(r.records[0].begin(), r.records[0].end(),
                                 [](const TraceRecord& x) { return x.invocation == 5 && x.seq == 1; });
    ASSERT_NE(it, r.records[0].end());
    EXPECT_EQ(it->offset, 40u);
    EXPECT_EQ((it + 1)->offset, 4000u);
  }
}

// The coding does not depend on the order the records come in: records appended by workgroup in runs
// (as two GPU cores append them) and the same records shuffled give the same bytes, with a sparse seq among
// them (a comparison sort instead of direct placement), and decode to the same records.
TEST(TraceFile, CompactCodingDoesNotDependOnTheRecordsOrder) {
  std::mt19937 rng(5);
  // 40 workgroups of 64 lanes; two at a time, each in 3 runs taking turns (as two GPU cores append).
  std::vector<TraceRecord> clustered;
  for (uint32_t pair = 0; pair < 20; ++pair) {
    for (uint32_t part = 0; part < 3; ++part) {
      for (uint32_t g = 2 * pair; g < 2 * pair + 2; ++g) {
        for (uint32_t lane = part * 22; lane < std::min(64u, part * 22 + 22); ++lane) {
          const uint32_t n = 1 + rng() % 30;
          for (uint32_t seq = 0; seq < n; ++seq)
            clustered.push_back({(100 + g) * 64 + lane, seq == n - 1 && lane == 5 ? 1000 + seq : seq,
                                 HP_TRACE_INFO(uint32_t(rng() % 3), HP_TRACE_LOAD, 4u), uint32_t(rng() % 4096) * 4});
        }
      }
    }
  }
  std::vector<TraceRecord> shuffled = clustered;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  // One invocation's records keep their order in both (the coding keeps it for equal seqs only, and the
  // seqs here are distinct per invocation).
  SliceEncoder a, b;
  std::vector<uint8_t> ca, cb;
  a.encode(clustered, 100, 140, 64, ca);
  b.encode(shuffled, 100, 140, 64, cb);
  EXPECT_EQ(ca, cb);
  std::vector<TraceRecord> back(clustered.size());
  decode_slice(ca, clustered.size(), 100, 140, 64, back.data(), "test", [](const TraceRecord*, uint64_t, uint64_t) {});
  auto key = [](const TraceRecord& r) { return std::tuple(r.invocation, r.seq, r.info, r.offset); };
  std::vector<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>> x, y;
  for (const auto& r : clustered) x.push_back(key(r));
  for (const auto& r : back) y.push_back(key(r));
  std::sort(x.begin(), x.end());
  std::sort(y.begin(), y.end());
  EXPECT_EQ(x, y);
}

// Offsets anywhere in 32 bits code exactly, in both codings and from parts: a difference of 2^31 or more
// from the previous record's offset (its zigzag needs 33 bits) is stored as the offset itself.
TEST(TraceFile, CompactCodingKeepsOffsetsThatDifferBy2To31OrMore) {
  std::mt19937 rng(11);
  const uint32_t edge[] = {0u, 0x80000001u, 0u, 0x80000000u, 0xFFFFFFFFu, 0x7FFFFFFFu, 0xFFFFFFFFu, 1u, 0x80000000u};
  std::vector<TraceRecord> in;
  for (uint32_t g = 0; g < 2; ++g) {
    for (uint32_t lane = 0; lane < 64; ++lane) {
      for (uint32_t seq = 0; seq < 9; ++seq) {
        const uint32_t offset = g == 0 ? edge[(lane + seq) % 9] : uint32_t(rng());
        in.push_back({g * 64 + lane, seq, HP_TRACE_INFO(1u, HP_TRACE_LOAD, 4u), offset});
      }
    }
  }
  auto key = [](const TraceRecord& r) { return std::tuple(r.invocation, r.seq, r.info, r.offset); };
  std::vector<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>> want;
  for (const auto& r : in) want.push_back(key(r));
  std::sort(want.begin(), want.end());
  for (const uint32_t coding : {kCodingDeltaVarint, kCodingSizedGroups}) {
    SliceEncoder e;
    std::vector<uint8_t> whole, from_parts;
    e.encode(in, 0, 2, 64, whole, coding);
    const std::span<const TraceRecord> parts[] = {std::span(in).first(64 * 9), std::span(in).subspan(64 * 9)};
    ASSERT_TRUE(e.encode_parts(parts, 0, 2, 64, from_parts, coding));
    EXPECT_EQ(whole, from_parts);
    std::vector<TraceRecord> back(in.size());
    decode_slice(
        whole, in.size(), 0, 2, 64, back.data(), "test", [](const TraceRecord*, uint64_t, uint64_t) {}, nullptr,
        coding);
    std::vector<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>> got;
    for (const auto& r : back) got.push_back(key(r));
    std::sort(got.begin(), got.end());
    EXPECT_EQ(want, got) << "coding " << coding;
  }
}

// The AVX-512 step coder gives the portable coder's bytes: steps of every size from one lane to 64, lanes far
// apart (a delta of 7 or more takes a varint byte), info words that change or repeat, offsets close, far and
// 2^31 or more apart; workgroups of 64, 48 and 8 lanes, and of 100 (more than 64: always the portable coder).
TEST(TraceFile, CompactCodingIsTheSameWithAndWithoutTheVectorCoder) {
  if (!SliceEncoder::simd_available()) GTEST_SKIP() << "this host has no AVX-512 VBMI2: only the portable coder runs";
  std::mt19937 rng(23);
  for (const uint64_t per_group : {64u, 48u, 8u, 100u}) {
    for (const uint32_t coding : {kCodingDeltaVarint, kCodingSizedGroups}) {
      std::vector<TraceRecord> in;
      const uint32_t groups = 40;
      for (uint32_t g = 0; g < groups; ++g) {
        // Workgroup g's steps: each seq takes a random share of the lanes, from one lane to all of them.
        const uint32_t keep = 1 + rng() % 100;
        for (uint32_t seq = 0; seq < 70; ++seq) {
          const uint32_t share = seq < 64 ? seq + 1 : keep;
          for (uint32_t lane = 0; lane < per_group; ++lane) {
            if (rng() % 100 >= share * 100 / 64 && !(seq == 0 && lane == 0)) continue;
            const uint32_t pick = rng() % 8;
            const uint32_t offset = pick == 0   ? uint32_t(rng())
                                    : pick == 1 ? 0x80000000u + rng() % 4
                                    : pick == 2 ? rng() % 4
                                                : 4096 * (g % 3) + 16 * (rng() % 64);
            in.push_back({uint32_t((100 + g) * per_group + lane), seq,
                          HP_TRACE_INFO(uint32_t(rng() % 3 == 0 ? 2 : 1), HP_TRACE_LOAD, 16u), offset});
          }
        }
      }
      std::shuffle(in.begin(), in.end(), rng);
      SliceEncoder vector_coder, portable;
      portable.use_simd(false);
      std::vector<uint8_t> a, b;
      vector_coder.encode(in, 100, 100 + groups, per_group, a, coding);
      portable.encode(in, 100, 100 + groups, per_group, b, coding);
      EXPECT_EQ(a, b) << per_group << " lanes, coding " << coding;
      std::vector<TraceRecord> back(in.size());
      decode_slice(
          a, in.size(), 100, 100 + groups, per_group, back.data(), "test",
          [](const TraceRecord*, uint64_t, uint64_t) {}, nullptr, coding);
    }
  }
}

// A workgroup whose seqs are dense but where one key repeats (the format allows it, a capture never makes
// it): its records are placed into the slot table until the repeat shows, then it is sorted instead,
// keeping the repeated key's records in the order they came; the other workgroups keep the table.
TEST(TraceFile, ARepeatedKeyFallsBackToSortingItsWorkgroupOnly) {
  std::vector<TraceRecord> in;
  for (uint32_t g = 0; g < 3; ++g) {
    for (uint32_t lane = 0; lane < 64; ++lane) {
      for (uint32_t seq = 0; seq < 4; ++seq) {
        in.push_back({g * 64 + lane, seq, HP_TRACE_INFO(0u, HP_TRACE_LOAD, 4u), (g * 1000 + lane * 10 + seq) * 4});
      }
    }
  }
  in.push_back({64 + 7, 2, HP_TRACE_INFO(1u, HP_TRACE_STORE, 4u), 12345});  // workgroup 1, lane 7, seq 2 again
  SliceEncoder e;
  std::vector<uint8_t> coded;
  e.encode(in, 0, 3, 64, coded);
  std::vector<TraceRecord> back(in.size());
  decode_slice(coded, in.size(), 0, 3, 64, back.data(), "test", [](const TraceRecord*, uint64_t, uint64_t) {});
  // Canonical order: by workgroup, seq, lane; the repeated key's two records in the order they came.
  std::vector<TraceRecord> want = in;
  std::stable_sort(want.begin(), want.end(), [](const TraceRecord& a, const TraceRecord& b) {
    return std::tuple(a.invocation / 64, a.seq, a.invocation) < std::tuple(b.invocation / 64, b.seq, b.invocation);
  });
  ASSERT_EQ(back.size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) {
    EXPECT_TRUE(std::tie(back[i].invocation, back[i].seq, back[i].info, back[i].offset) ==
                std::tie(want[i].invocation, want[i].seq, want[i].info, want[i].offset))
        << "record " << i;
  }
}

// A capture's regions: each lavapipe thread runs whole workgroups in turn, so in its region each workgroup's
// records are one run, in increasing workgroup order, and the regions interleave (rows in spread order).
// Coded where they lie, they give the bytes of the records put together, for both codings; parts that are
// not in run order are refused with nothing written, and the records put together are coded instead.
TEST(TraceFile, RegionsInRunOrderCodeWhereTheyLieAsTheirRecordsPutTogether) {
  std::mt19937 rng(11);
  // Workgroup g's records, lanes interleaved step by step as subgroups make them; some lanes stop early.
  const auto group_records = [&](uint32_t g) {
    std::vector<TraceRecord> v;
    std::vector<uint32_t> steps(64);
    for (auto& n : steps) n = 1 + rng() % 6;
    for (uint32_t seq = 0; seq < 6; ++seq) {
      for (uint32_t lane = 0; lane < 64; ++lane) {
        if (seq < steps[lane]) {
          v.push_back({(100 + g) * 64 + lane, seq, HP_TRACE_INFO(uint32_t(rng() % 3), HP_TRACE_LOAD, 16u),
                       uint32_t(rng() % 512) * 16});
        }
      }
    }
    return v;
  };
  std::vector<TraceRecord> even, odd;
  for (uint32_t g = 0; g < 24; ++g) {
    if (g == 9) continue;  // a workgroup without records
    auto v = group_records(g);
    if (g == 14) {  // one workgroup's records split between the two regions, a key in both (ties keep
                    // the order of the records put together)
      even.insert(even.end(), v.begin(), v.begin() + v.size() / 3);
      odd.insert(odd.end(), v.begin() + v.size() / 3, v.end());
      odd.push_back({v[0].invocation, v[0].seq, v[0].info, v[0].offset + 4096});
      continue;
    }
    (g % 2 ? odd : even).insert((g % 2 ? odd : even).end(), v.begin(), v.end());
  }
  std::vector<TraceRecord> together = even;
  together.insert(together.end(), odd.begin(), odd.end());
  for (uint32_t coding : {kCodingDeltaVarint, kCodingSizedGroups}) {
    SliceEncoder a, b;
    std::vector<uint8_t> want, got = {0xAB};  // appended to, as the file writer's buffer
    a.encode(together, 100, 124, 64, want, coding);
    const std::span<const TraceRecord> parts[] = {even, {}, odd};
    ASSERT_TRUE(b.encode_parts(parts, 100, 124, 64, got, coding));
    ASSERT_EQ(got.size(), want.size() + 1);
    EXPECT_TRUE(std::equal(want.begin(), want.end(), got.begin() + 1)) << "coding " << coding;
    // The encoder's scratch carries nothing from one slice to the next.
    got.clear();
    ASSERT_TRUE(b.encode_parts(parts, 100, 124, 64, got, coding));
    EXPECT_EQ(got, want);
  }
  // Not in run order: a part's workgroups decreasing, or a workgroup's records in two runs of one part.
  SliceEncoder e;
  std::vector<uint8_t> out = {1, 2, 3};
  std::vector<TraceRecord> backwards = odd;
  std::rotate(backwards.begin(), backwards.begin() + backwards.size() / 2, backwards.end());
  const std::span<const TraceRecord> unordered[] = {even, backwards};
  EXPECT_FALSE(e.encode_parts(unordered, 100, 124, 64, out));
  std::vector<TraceRecord> twice = even;
  twice.push_back(even.front());  // workgroup 0 again after the others
  const std::span<const TraceRecord> repeated[] = {twice, odd};
  EXPECT_FALSE(e.encode_parts(repeated, 100, 124, 64, out));
  EXPECT_EQ(out, (std::vector<uint8_t>{1, 2, 3}));
  // What the coding cannot hold is refused as encode() refuses it, naming the record by its place in the
  // records put together.
  std::vector<TraceRecord> bad = odd;
  bad[5].info = 0x10000;
  const std::span<const TraceRecord> with_bad[] = {even, bad};
  try {
    e.encode_parts(with_bad, 100, 124, 64, out);
    FAIL() << "no error";
  } catch (const InputError& x) {
    EXPECT_STREQ(x.what(),
                 ("trace writer: record " + std::to_string(even.size() + 5) + ": reserved info bits set").c_str());
  }
  bad = odd;
  bad.back().invocation = 124 * 64;
  const std::span<const TraceRecord> outside[] = {even, bad};
  EXPECT_THROW(e.encode_parts(outside, 100, 124, 64, out), InputError);
}

TEST(TraceFile, CorruptCompactRecordsGiveOneLineErrorsNamingTheFile) {
  const auto good = tmp("compact_good.hptrace"), bad = tmp("compact_bad.hptrace");
  write_trace(good, sample());
  const auto bytes = bytes_of(good);
  // The first 'RECV' chunk: its 40-byte entry (u32 pass, u32 coding, u64 first, end, count, coded_bytes)
  // follows the 16-byte chunk header, then the coded bytes.
  const std::string tag = "RECV";
  const size_t at = size_t(std::search(bytes.begin(), bytes.end(), tag.begin(), tag.end()) - bytes.begin());
  ASSERT_LT(at, bytes.size());
  const size_t entry = at + 16, coded = entry + 40;
  auto put_u64 = [](std::vector<char>& b, size_t pos, uint64_t v) { std::memcpy(b.data() + pos, &v, 8); };
  uint64_t count = 0;
  std::memcpy(&count, bytes.data() + entry + 24, 8);

  auto c = bytes;
  c[entry + 4] = 9;  // coding
  write_bytes(bad, c);
  EXPECT_NE(error_reading(bad).find(bad.string() + ": RECV chunk at byte " + std::to_string(at) + ": unknown coding 9"),
            std::string::npos)
      << error_reading(bad);

  c = bytes;
  put_u64(c, entry + 24, count + 1);  // one record more than the coding holds (and the END chunk agrees)
  uint64_t total = 0;
  std::memcpy(&total, c.data() + c.size() - 16, 8);
  put_u64(c, c.size() - 16, total + 1);
  write_bytes(bad, c);
  EXPECT_NE(error_reading(bad).find("holds " + std::to_string(count) + " records, the chunk declares " +
                                    std::to_string(count + 1)),
            std::string::npos)
      << error_reading(bad);

  c = bytes;
  put_u64(c, entry + 24, uint64_t(1) << 40);  // far more records than bytes: refused before any allocation
  write_bytes(bad, c);
  EXPECT_NE(error_reading(bad).find("malformed RECV"), std::string::npos) << error_reading(bad);

  // The first record's control byte (after the workgroup varint, the body's u32 size, the step count, seq
  // and record count varints).
  c = bytes;
  c[coded + 8] = char(uint8_t(c[coded + 8]) | 0x80);
  write_bytes(bad, c);
  EXPECT_NE(error_reading(bad).find(bad.string() +
                                    ": pass 'shadows': compact records, byte 9: reserved control bit set"),
            std::string::npos)
      << error_reading(bad);
  EXPECT_EQ(error_reading(bad).find('\n'), std::string::npos);

  // A body size that does not match the body, one byte short of it and past the slice's end.
  uint32_t body = 0;
  std::memcpy(&body, bytes.data() + coded + 1, 4);
  c = bytes;
  const uint32_t shorter = body - 1;
  std::memcpy(c.data() + coded + 1, &shorter, 4);
  write_bytes(bad, c);
  EXPECT_NE(error_reading(bad).find(": pass 'shadows': compact records, byte "), std::string::npos)
      << error_reading(bad);
  EXPECT_NE(error_reading(bad).find("workgroup 0: its body ends 1 bytes from the size it states"), std::string::npos)
      << error_reading(bad);
  c = bytes;
  const uint32_t huge = 0x7FFFFFFF;
  std::memcpy(c.data() + coded + 1, &huge, 4);
  write_bytes(bad, c);
  EXPECT_NE(error_reading(bad).find("workgroup 0: body of 2147483647 bytes past the end of the slice"),
            std::string::npos)
      << error_reading(bad);

  // A coding-1 file: the same control byte comes four bytes earlier (no body size).
  write_trace(good, sample(), kTraceVersion, kCodingDeltaVarint);
  c = bytes_of(good);
  c[coded + 4] = char(uint8_t(c[coded + 4]) | 0x80);
  write_bytes(bad, c);
  EXPECT_NE(error_reading(bad).find(bad.string() +
                                    ": pass 'shadows': compact records, byte 5: reserved control bit set"),
            std::string::npos)
      << error_reading(bad);

  // A writer refuses what the coding cannot hold, and leaves no file.
  const auto refused = tmp("compact_refused.hptrace");
  Trace t = sample();
  {
    TraceWriter w(refused, t.header);
    const uint32_t a = w.begin_pass(t.passes[0]);
    try {
      w.write_records(a, t.records[0], 1, 2);  // workgroup 0's records in the slice of workgroup 1
      ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("record 0: invocation 0 outside its slice's workgroups [1, 2)"),
                std::string::npos)
          << e.what();
    }
  }
  EXPECT_FALSE(fs::exists(refused));
}

}  // namespace
}  // namespace hp::trace
