// Memory-trace capture on a real device: the traced frame's image equals the untraced one, slices that
// overflow a small buffer are re-run so that no record is lost, sampling records the sampled workgroups
// only, and the file replays through the cache simulator.
#include "vulkan_env.hpp"

#include "cache_analysis.hpp"
#include "error.hpp"
#include "frame.hpp"
#include "gpu/trace_buffers.h"
#include "rt_scene.hpp"
#include "scene/load.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <tuple>

namespace hp {
namespace {

namespace fs = std::filesystem;

FrameSettings small(uint32_t w, uint32_t h) {
  FrameSettings s;
  s.width = w;
  s.height = h;
  s.rt.shadows = true;
  s.rt.reflections = true;
  s.rt.jitter = JitterMode::shared;
  return s;
}

// A trace buffer (CaptureOptions::buffer_bytes) whose slices hold `records` records each.
uint64_t slice_buffer(uint64_t records) {
  return kTraceBufferParts * (sizeof(gpu::TraceBufferHeader) + records * sizeof(gpu::TraceRecord));
}

struct Captured {
  std::vector<CapturedPass> passes;
  Image4f image;
  fs::path file;
};

Captured capture(vk::Context& ctx, const Scene& scene, const FrameSettings& s, const CaptureOptions& o,
                 const std::string& name) {
  Captured c;
  c.file = fs::temp_directory_path() / ("hp_capture_" + std::to_string(::getpid()) + "_" + name + ".hptrace");
  Frame frame(ctx, scene, scene.camera, s);
  {
    trace::TraceWriter writer(c.file, frame.trace_header(o.tiled_images));
    c.passes = frame.render_captured(o, writer);
    writer.finish();
  }
  c.image = frame.read_color();
  return c;
}

// A pass's records as (invocation, seq, info, offset), sorted: what two captures of it must share, whatever
// their slicing.
std::vector<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>> sorted_keys(const std::vector<gpu::TraceRecord>& rs) {
  std::vector<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>> k;
  k.reserve(rs.size());
  for (const auto& r : rs) k.emplace_back(r.invocation, r.seq, r.info, r.offset);
  std::sort(k.begin(), k.end());
  return k;
}

TEST(Capture, TracedImageEqualsUntracedAndRecordsAreComplete) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  const FrameSettings s = small(96, 112);
  Frame plain(*ctx, scene, scene.camera, s);
  plain.render();
  const Image4f untraced = plain.read_color();

  CaptureOptions o;
  const Captured big = capture(*ctx, scene, s, o, "big");
  ASSERT_EQ(big.passes.size(), 2u);
  EXPECT_EQ(std::memcmp(big.image.rgba.data(), untraced.rgba.data(), untraced.rgba.size() * 4), 0)
      << "the traced frame must render the same image";
  for (const auto& p : big.passes) {
    EXPECT_GT(p.records, p.workgroups * 64) << p.pass << ": at least one access per invocation";
    EXPECT_EQ(p.reruns, 0u);
  }

  // A buffer that holds three quarters of the smaller pass (each pass has 14 workgroup rows): slices shrink
  // until they fit, and the records are the same.
  const uint64_t least = std::min(big.passes[0].records, big.passes[1].records);
  o.buffer_bytes = slice_buffer(least * 3 / 4);
  o.first_slice_units = UINT32_MAX;  // the whole pass first: it overflows, so the re-run path runs
  const Captured tiny = capture(*ctx, scene, s, o, "tiny");
  ASSERT_EQ(tiny.passes.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_GT(tiny.passes[i].slices, 1u) << tiny.passes[i].pass;
    EXPECT_GT(tiny.passes[i].reruns, 0u) << tiny.passes[i].pass << ": the first whole-pass slice must overflow";
    EXPECT_EQ(tiny.passes[i].records, big.passes[i].records) << tiny.passes[i].pass << ": records lost or doubled";
  }
  trace::TraceReader a(big.file), b(tiny.file);
  for (uint32_t p = 0; p < 2; ++p) {
    const auto ka = sorted_keys(a.read_pass(p)), kb = sorted_keys(b.read_pass(p));
    EXPECT_TRUE(ka == kb) << "pass " << p << ": sliced capture differs from the whole-pass capture";
    // Every invocation numbers its accesses 0, 1, 2, ... without gaps.
    std::map<uint32_t, uint32_t> next;
    for (const auto& k : ka) {
      EXPECT_EQ(std::get<1>(k), next[std::get<0>(k)]++) << "sequence gap at invocation " << std::get<0>(k);
      if (::testing::Test::HasFailure()) break;
    }
  }
  fs::remove(big.file);
  fs::remove(tiny.file);
}

TEST(Capture, WritersTakeOnlyTheCoresTheDeviceLeavesFree) {
  // lavapipe computes on the host's cores: on two cores with its two threads, one writer.
  EXPECT_EQ(capture_writer_threads(2, 2), 1u);
  EXPECT_EQ(capture_writer_threads(16, 16), 1u);
  EXPECT_EQ(capture_writer_threads(16, 14), 2u);
  EXPECT_EQ(capture_writer_threads(4, 8), 1u);
  // A GPU (no device threads on the host): one writer per part the device is not filling, at most.
  EXPECT_EQ(capture_writer_threads(2, 0), 2u);
  EXPECT_EQ(capture_writer_threads(16, 0), kTraceBufferParts - 1);
  // Unknown core count: still one writer.
  EXPECT_EQ(capture_writer_threads(0, 0), 1u);
}

// A slice that overflows the buffer still counts every record it made, so the rerun is sized from that
// count: one overflow of the whole pass, not a halving series that runs the pass's work about twice more.
// By default a probe comes first instead, and nothing overflows but where the density jumps.
TEST(Capture, AnOverflowSizesTheRerunFromItsCount) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  const FrameSettings s = small(96, 448);  // 56 workgroup rows a pass
  CaptureOptions o;
  const Captured big = capture(*ctx, scene, s, o, "whole");
  ASSERT_EQ(big.passes.size(), 2u);
  const uint64_t least = std::min(big.passes[0].records, big.passes[1].records);
  o.buffer_bytes = slice_buffer(least / 6);
  o.first_slice_units = UINT32_MAX;
  const Captured small_buffer = capture(*ctx, scene, s, o, "sixth");
  for (size_t i = 0; i < 2; ++i) {
    const CapturedPass& p = small_buffer.passes[i];
    EXPECT_EQ(p.records, big.passes[i].records) << p.pass;
    EXPECT_GE(p.slices, 6u) << p.pass << ": a sixth of the pass a slice at most";
    // Halving would take 56 -> 28 -> 14 -> 7 rows: three reruns at least.
    EXPECT_LE(p.reruns, 2u) << p.pass << ": the whole pass overflowed, then at most one more slice";
  }
  // By default a one-row probe comes first and sizes the rest: the same records, and no whole-pass run
  // for nothing (at most one slice re-run where the density jumps past twice the largest seen).
  o.first_slice_units = 0;
  const Captured probed = capture(*ctx, scene, s, o, "probed");
  for (size_t i = 0; i < 2; ++i) {
    const CapturedPass& p = probed.passes[i];
    EXPECT_EQ(p.records, big.passes[i].records) << p.pass;
    EXPECT_GE(p.slices, 6u) << p.pass;
    EXPECT_LE(p.reruns, 1u) << p.pass;
  }
  trace::TraceReader a(small_buffer.file), b(probed.file);
  for (uint32_t p = 0; p < 2; ++p) {
    EXPECT_TRUE(sorted_keys(a.read_pass(p)) == sorted_keys(b.read_pass(p)))
        << "pass " << p << ": the probed capture's records differ";
  }
  fs::remove(big.file);
  fs::remove(small_buffer.file);
  fs::remove(probed.file);
}

// The trace buffer's regions (one record counter each, so that lavapipe's threads do not add to one
// counter): one region or sixteen, the records are the same. Sixteen regions in a buffer just larger than
// the pass: the pass fits the buffer, but its denser blocks overflow their regions, so slices are re-run.
TEST(Capture, EveryRegionCountGivesTheSameRecords) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  const FrameSettings s = small(96, 112);
  CaptureOptions o;
  o.record_regions = 1;
  const Captured one = capture(*ctx, scene, s, o, "one_region");
  ASSERT_EQ(one.passes.size(), 2u);
  const uint64_t most = std::max(one.passes[0].records, one.passes[1].records);
  o.record_regions = HP_TRACE_MAX_REGIONS;
  o.buffer_bytes = slice_buffer(most * 11 / 10);
  o.first_slice_units = UINT32_MAX;  // the whole pass first: it fits the buffer, not its regions
  const Captured many = capture(*ctx, scene, s, o, "sixteen_regions");
  ASSERT_EQ(many.passes.size(), 2u);
  trace::TraceReader a(one.file), b(many.file);
  for (uint32_t p = 0; p < 2; ++p) {
    EXPECT_EQ(many.passes[p].records, one.passes[p].records) << many.passes[p].pass << ": records lost or doubled";
    EXPECT_GT(many.passes[p].reruns, 0u) << many.passes[p].pass << ": no region overflowed";
    EXPECT_TRUE(sorted_keys(a.read_pass(p)) == sorted_keys(b.read_pass(p))) << "pass " << p;
  }
  fs::remove(one.file);
  fs::remove(many.file);

  o.record_regions = HP_TRACE_MAX_REGIONS + 1;
  Frame frame(*ctx, scene, scene.camera, s);
  struct Discard final : trace::TraceSink {
    uint32_t begin_pass(const trace::PassInfo&) override { return 0; }
    void write_records(uint32_t, std::span<const trace::TraceRecord>, uint64_t, uint64_t) override {}
  } discard;
  const auto refusal = [&] {
    try {
      frame.render_captured(o, discard);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string regions_refused = refusal();
  EXPECT_NE(regions_refused.find("17 record regions is over the limit of 16"), std::string::npos) << regions_refused;
  o.record_regions = 0;
  o.writer_threads = kTraceBufferParts;
  const std::string writers_refused = refusal();
  EXPECT_NE(writers_refused.find("4 writer threads is over the limit of 3"), std::string::npos) << writers_refused;
}

// The file writer codes a slice's trace buffer regions where they lie when each holds its workgroups in
// run order (one lavapipe thread runs a workgroup from start to end), reading every record once, and codes
// several slices at once on worker threads (staged, then written in order); the file is the one it writes
// from the regions moved together, one slice at a time. A slice whose regions are not in run order (the
// spread order over an odd number of rows can put a later row's workgroups first in a region) is moved
// together and written as one span instead.
TEST(Capture, RegionsCodedWhereTheyLieOrSideBySideGiveTheFileOfTheRegionsPutTogether) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  const FrameSettings s = small(96, 112);
  enum class Way { staged, in_place, put_together };
  struct Forward final : trace::TraceSink {
    trace::TraceWriter& writer;
    Way way;
    std::atomic<int> done_that_way{0};
    std::atomic<int> put_together{0};  // slices written as one span
    Forward(trace::TraceWriter& w, Way h) : writer(w), way(h) {}
    uint32_t begin_pass(const trace::PassInfo& pass) override { return writer.begin_pass(pass); }
    void write_records(uint32_t pass, std::span<const trace::TraceRecord> r, uint64_t first, uint64_t end) override {
      writer.write_records(pass, r, first, end);
      done_that_way += way == Way::put_together;
      ++put_together;
    }
    bool write_record_parts(uint32_t pass, std::span<const std::span<const trace::TraceRecord>> parts, uint64_t first,
                            uint64_t end) override {
      const bool done = way == Way::in_place && writer.write_record_parts(pass, parts, first, end);
      done_that_way += done;
      return done;
    }
    Commit stage_record_parts(uint32_t pass, std::span<const std::span<const trace::TraceRecord>> parts, uint64_t first,
                              uint64_t end) override {
      if (way != Way::staged) return nullptr;
      Commit c = writer.stage_record_parts(pass, parts, first, end);
      done_that_way += c != nullptr;
      return c;
    }
  };
  CaptureOptions o;
  o.record_regions = 4;
  o.buffer_bytes = slice_buffer(160000);  // several slices a pass
  std::vector<std::vector<char>> files;
  for (const Way way : {Way::staged, Way::in_place, Way::put_together}) {
    const fs::path file = fs::temp_directory_path() / ("hp_capture_" + std::to_string(::getpid()) + "_ways.hptrace");
    Frame frame(*ctx, scene, scene.camera, s);
    {
      trace::TraceWriter writer(file, frame.trace_header(o.tiled_images));
      Forward sink(writer, way);
      const std::vector<CapturedPass> passes = frame.render_captured(o, sink);
      ASSERT_EQ(passes.size(), 2u);
      EXPECT_GT(passes[0].slices, 1u);
      writer.finish();
      const uint32_t slices = passes[0].slices + passes[1].slices;
      if (way == Way::in_place) {
        // On a CPU device a region is filled by one thread in its run order, so most slices' regions are in
        // run order; the others were moved together. A GPU runs the workgroups of the four regions side by
        // side in no set order (on an H200 every slice was moved together): the file must still be the same.
        if (ctx->properties().deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU) {
          EXPECT_GT(uint32_t(sink.done_that_way), slices / 2);
        }
        EXPECT_EQ(uint32_t(sink.done_that_way + sink.put_together), slices);
      } else {
        EXPECT_EQ(uint32_t(sink.done_that_way), slices) << "way " << int(way);
      }
    }
    std::ifstream in(file, std::ios::binary);
    files.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    fs::remove(file);
  }
  EXPECT_GT(files[0].size(), 1000u);
  EXPECT_TRUE(files[0] == files[2]) << "staged";
  EXPECT_TRUE(files[1] == files[2]) << "coded where they lie";
}

// On a CPU device of more than one thread the shadow and reflection slices are shared out tile by tile
// (CaptureOptions::share_work); the file is the one the fixed split makes, byte for byte, with a roomy
// buffer and with one so small that a slice's records must fit one region and single rows are re-run
// without sharing.
TEST(Capture, SharedTilesGiveTheFileOfTheFixedSplit) {
  HP_REQUIRE_VULKAN(ctx);
  if (device_cpu_threads(*ctx) < 2) GTEST_SKIP() << "the device is not a CPU device of two threads or more: no sharing";
  const Scene scene = load_scene("builtin:pica");
  const FrameSettings s = small(96, 112);
  for (const uint64_t buffer : {uint64_t(0), slice_buffer(120000)}) {
    std::vector<std::vector<char>> files;
    std::vector<uint32_t> reruns;
    for (const bool share : {true, false}) {
      CaptureOptions o;
      o.share_work = share;
      o.buffer_bytes = buffer;
      const fs::path file = fs::temp_directory_path() / ("hp_capture_" + std::to_string(::getpid()) + "_share.hptrace");
      Frame frame(*ctx, scene, scene.camera, s);
      {
        trace::TraceWriter writer(file, frame.trace_header(o.tiled_images));
        const std::vector<CapturedPass> passes = frame.render_captured(o, writer);
        ASSERT_EQ(passes.size(), 2u);
        reruns.push_back(passes[0].reruns + passes[1].reruns);
        for (const CapturedPass& p : passes) {
          if (share) {
            EXPECT_GT(p.shared_slices, 0u) << p.pass;
          } else {
            EXPECT_EQ(p.shared_slices, 0u) << p.pass;
          }
        }
        writer.finish();
      }
      std::ifstream in(file, std::ios::binary);
      files.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
      fs::remove(file);
    }
    EXPECT_GT(files[0].size(), 1000u);
    EXPECT_TRUE(files[0] == files[1]) << "buffer " << buffer;
    if (buffer) {
      EXPECT_GT(reruns[0], 0u) << "the small buffer makes slices re-run";
    }
  }
}

// Audit find (2026-11-30): a capture ran every enabled pass and the composite even when only one pass was
// traced and nobody read the image (every cell of `hybridprof run` with a trace). final_image = false runs
// the traced passes alone, with the same records.
TEST(Capture, WithoutTheFinalImageOnlyTheTracedPassesRun) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = small(64, 48);
  s.rt.counters = true;  // what ran shows in the frame's ray counters
  CaptureOptions o;
  o.reflections = false;  // shadows only, though reflections are enabled
  auto run = [&](bool final_image, const char* name) {
    o.final_image = final_image;
    const fs::path file = fs::temp_directory_path() / ("hp_capture_" + std::to_string(::getpid()) + name);
    Frame frame(*ctx, scene, scene.camera, s);
    std::vector<CapturedPass> passes;
    double capture_seconds = 0;
    {
      trace::TraceWriter writer(file, frame.trace_header(o.tiled_images));
      const auto t0 = std::chrono::steady_clock::now();
      passes = frame.render_captured(o, writer);
      capture_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      writer.finish();
    }
    fs::remove(file);
    // The pass's own capture time is part of the whole capture's.
    for (const CapturedPass& p : passes) {
      EXPECT_GT(p.seconds, 0.0) << p.pass;
      EXPECT_LE(p.seconds, capture_seconds) << p.pass;
    }
    return std::make_pair(passes, frame.read_counters());
  };
  const auto [whole, whole_counts] = run(true, "whole");
  const auto [lean, lean_counts] = run(false, "lean");
  ASSERT_EQ(lean.size(), 1u);
  EXPECT_EQ(lean[0].pass, "shadows");
  EXPECT_EQ(lean[0].records, whole[0].records);
  EXPECT_EQ(lean_counts.shadow_rays, whole_counts.shadow_rays);
  EXPECT_GT(whole_counts.reflection_rays, 0u) << "the whole frame runs the untraced reflection pass";
  EXPECT_EQ(lean_counts.reflection_rays, 0u) << "the lean capture must not run it";
}

TEST(Capture, SamplingRecordsOnlySampledWorkgroupsAndReplays) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = small(128, 64);
  s.rt.reflections = false;
  CaptureOptions o;
  o.sample_every = 4;
  const Captured c = capture(*ctx, scene, s, o, "sampled");
  ASSERT_EQ(c.passes.size(), 1u);
  EXPECT_EQ(c.passes[0].workgroups, 16u * 8u);
  EXPECT_EQ(c.passes[0].sampled_workgroups, 32u);
  trace::TraceReader r(c.file);
  std::set<uint32_t> groups;
  std::set<uint32_t> buffers;
  for (const auto& rec : r.read_pass(0)) {
    groups.insert(rec.invocation / 64);
    buffers.insert(gpu::trace_buffer(rec.info));
  }
  EXPECT_EQ(groups.size(), 32u);
  for (uint32_t g : groups) EXPECT_EQ(g % 4, 0u);
  for (uint32_t b : {HP_TBUF_NODES, HP_TBUF_GBUF_DEPTH, HP_TBUF_GBUF_NORMAL, HP_TBUF_SHADOW_MASK}) {
    EXPECT_TRUE(buffers.count(b)) << "buffer " << b << " never accessed";
  }
  EXPECT_TRUE(buffers.count(HP_TBUF_INDICES) && buffers.count(HP_TBUF_POSITIONS)) << "indexed triangle fetches";
  EXPECT_FALSE(buffers.count(HP_TBUF_SOUP)) << "the indexed layout must not read the soup";

  CacheAnalysisOptions ao;
  ao.curves = true;
  const nlohmann::json cache = analyse_trace(c.file.string(), ao);
  ASSERT_EQ(cache["passes"].size(), 1u);
  const auto& p = cache["passes"][0];
  const uint64_t l1 = p["l1"]["requests"], hits = p["l1"]["hits"], misses = p["l1"]["misses"];
  EXPECT_GT(l1, 0u);
  EXPECT_EQ(hits + misses, l1);
  EXPECT_EQ(p["l2"]["requests"].get<uint64_t>(), misses + p["stores"].get<uint64_t>() + p["atomics"].get<uint64_t>())
      << "the L2 sees the L1's load misses and every store";
  EXPECT_TRUE(p["buffers"].contains("bvh_nodes"));
  fs::remove(c.file);
}

TEST(Capture, StreamedIntoTheSimulatorEqualsReplayingTheFile) {
  // The run matrix hands each slice straight to the cache simulator; `hybridprof cachesim` replays the
  // file slice by slice. Slices forced small (several per pass): both give the same tables and curves.
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  const FrameSettings s = small(96, 112);
  CaptureOptions o;
  o.buffer_bytes = slice_buffer(120000);
  const fs::path file = fs::temp_directory_path() / ("hp_capture_" + std::to_string(::getpid()) + "_tee.hptrace");
  Frame frame(*ctx, scene, scene.camera, s);
  CacheAnalysisOptions ao;
  ao.curves = true;
  nlohmann::json streamed;
  std::vector<CapturedPass> passes;
  {
    const trace::TraceHeader header = frame.trace_header(o.tiled_images);
    trace::TraceWriter writer(file, header);
    CacheAnalysis analysis(header, ao);
    trace::TeeSink both(writer, analysis);
    passes = frame.render_captured(o, both);
    writer.finish();
    streamed = analysis.finish();
  }
  ASSERT_EQ(passes.size(), 2u);
  for (const CapturedPass& p : passes) EXPECT_GT(p.slices, 2u) << p.pass << ": the test needs several slices";
  nlohmann::json replayed = analyse_trace(file.string(), ao);
  streamed.erase("simulation_s");
  replayed.erase("simulation_s");
  EXPECT_EQ(streamed, replayed);
  ASSERT_EQ(streamed["passes"].size(), 2u);
  EXPECT_GT(streamed["passes"][0]["l1"]["requests"].get<uint64_t>(), 0u);
  fs::remove(file);
}

TEST(Capture, SoupLayoutReadsTheSoupOnly) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  FrameSettings s = small(64, 48);
  s.geometry = GeometryLayout::soup;
  s.rt.roughness_threshold = 1.01f;  // every Cornell wall reflects
  const Captured c = capture(*ctx, scene, s, CaptureOptions{}, "soup");
  trace::TraceReader r(c.file);
  std::set<uint32_t> buffers;
  for (uint32_t p = 0; p < r.passes().size(); ++p) {
    for (const auto& rec : r.read_pass(p)) buffers.insert(gpu::trace_buffer(rec.info));
  }
  EXPECT_TRUE(buffers.count(HP_TBUF_SOUP));
  EXPECT_FALSE(buffers.count(HP_TBUF_INDICES));
  EXPECT_FALSE(buffers.count(HP_TBUF_POSITIONS));
  EXPECT_TRUE(buffers.count(HP_TBUF_SOUP_NORMALS)) << "reflection hits shade with the soup's normals";
  EXPECT_TRUE(buffers.count(HP_TBUF_REFLECTION));
  fs::remove(c.file);
}

// With the wide4 node layout the frame renders the binary layout's image, and the trace holds the wide
// nodes' real accesses: four 16-byte loads per visited 64-byte node, inside the uploaded node array (the
// buffer the header declares), fewer node visits than the binary nodes' two 16-byte loads each.
TEST(Capture, Wide4NodesAreTracedAtTheirOwnAddresses) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = small(96, 64);
  const Captured binary = capture(*ctx, scene, s, CaptureOptions{}, "binary_nodes");
  s.bvh.node_layout = bvh::NodeLayout::wide4;
  const Captured wide = capture(*ctx, scene, s, CaptureOptions{}, "wide_nodes");
  EXPECT_EQ(std::memcmp(wide.image.rgba.data(), binary.image.rgba.data(), binary.image.rgba.size() * 4), 0)
      << "the wide nodes must render the same image";
  Frame frame(*ctx, scene, scene.camera, s);
  const size_t wide_nodes = frame.rt_geometry()->wide.nodes.size();
  ASSERT_GT(wide_nodes, 1u);
  const auto node_loads = [](const fs::path& file, uint64_t& declared) {
    trace::TraceReader r(file);
    const auto* b = r.header().find_buffer(HP_TBUF_NODES);
    declared = b ? b->size_bytes : 0;
    std::map<uint32_t, uint32_t> per_size;
    std::vector<uint32_t> offsets;
    for (uint32_t p = 0; p < r.passes().size(); ++p) {
      for (const auto& rec : r.read_pass(p)) {
        if (gpu::trace_buffer(rec.info) != HP_TBUF_NODES) continue;
        per_size[gpu::trace_size(rec.info)]++;
        offsets.push_back(rec.offset);
      }
    }
    return std::make_pair(per_size, offsets);
  };
  uint64_t declared_binary = 0, declared_wide = 0;
  const auto [binary_sizes, binary_offsets] = node_loads(binary.file, declared_binary);
  const auto [wide_sizes, wide_offsets] = node_loads(wide.file, declared_wide);
  EXPECT_EQ(declared_wide, wide_nodes * sizeof(gpu::WideNode));
  EXPECT_EQ(declared_binary, frame.rt_geometry()->bvh.nodes.size() * sizeof(gpu::BvhNode));
  ASSERT_EQ(wide_sizes.size(), 1u);
  EXPECT_EQ(wide_sizes.begin()->first, 16u);
  std::array<uint64_t, 4> quarter{};
  for (uint32_t off : wide_offsets) {
    ASSERT_LT(off, declared_wide);
    quarter[(off % 64) / 16]++;
  }
  EXPECT_EQ(quarter[0], quarter[1]);
  EXPECT_EQ(quarter[0], quarter[2]);
  EXPECT_EQ(quarter[0], quarter[3]);
  // Visits: a binary node is two loads, a wide node four; the wide tree visits far fewer nodes.
  EXPECT_LT(quarter[0] * 2, binary_offsets.size() / 2);
  fs::remove(binary.file);
  fs::remove(wide.file);
}

// Slices are written on a worker thread while the device runs the next one: the sink still sees one call
// at a time in slice order, each slice's progress call follows its write, and an error thrown by the sink
// comes out of render_captured.
struct SliceLog final : trace::TraceSink {
  std::vector<std::pair<uint64_t, uint64_t>> slices;
  uint64_t records = 0;
  size_t fail_at = 0;  // 1-based slice that throws; 0: none
  std::atomic<int> inside{0};
  bool overlapped_calls = false;
  uint32_t begin_pass(const trace::PassInfo&) override { return 0; }
  void write_records(uint32_t, std::span<const gpu::TraceRecord> r, uint64_t first, uint64_t end) override {
    overlapped_calls |= inside.fetch_add(1) != 0;
    slices.emplace_back(first, end);
    records += r.size();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));  // a slow sink: the next slice runs meanwhile
    inside.fetch_sub(1);
    if (fail_at && slices.size() == fail_at) throw InputError("sink: disk full");
  }
};

// pica's shadow pass alone at 96x112, in slices of a row or two (14 rows).
struct ShadowSlices {
  Scene scene = load_scene("builtin:pica");
  FrameSettings settings = [] {
    FrameSettings s = small(96, 112);
    s.rt.reflections = false;
    return s;
  }();
  Frame frame;
  CaptureOptions o;
  explicit ShadowSlices(vk::Context& ctx) : frame(ctx, scene, scene.camera, settings) {
    o.final_image = false;
    o.buffer_bytes = slice_buffer(60000);
  }
};

TEST(Capture, SlicesAreWrittenInOrderBesideTheNextSliceAndTheirErrorsSurface) {
  HP_REQUIRE_VULKAN(ctx);
  ShadowSlices sliced(*ctx);
  Frame& frame = sliced.frame;
  CaptureOptions& o = sliced.o;
  SliceLog log;
  std::vector<std::pair<uint64_t, uint64_t>> progress;  // (records, rows done) at each progress call
  o.on_slice = [&](const std::string&, uint64_t records, uint64_t done, uint64_t) {
    EXPECT_EQ(records, log.records) << "a slice's progress call follows its write";
    progress.emplace_back(records, done);
  };
  const std::vector<CapturedPass> passes = frame.render_captured(o, log);
  ASSERT_EQ(passes.size(), 1u);
  ASSERT_GE(log.slices.size(), 3u);
  EXPECT_FALSE(log.overlapped_calls);
  for (size_t i = 1; i < log.slices.size(); ++i) EXPECT_EQ(log.slices[i].first, log.slices[i - 1].second);
  EXPECT_EQ(log.records, passes[0].records);
  ASSERT_EQ(progress.size(), log.slices.size());
  EXPECT_EQ(progress.back().second, 14u);

  SliceLog failing;
  failing.fail_at = 2;
  o.on_slice = nullptr;
  try {
    frame.render_captured(o, failing);
    FAIL() << "expected the sink's error";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "sink: disk full");
  }
  EXPECT_EQ(failing.slices.size(), 2u) << "no slice is written after the one that failed";
}

// A sink that stages slices (the trace file's coding) works on several at once, on up to three workers:
// the stagings overlap, the commits still come one at a time in slice order, each slice's progress call
// right after its commit, and an error in a staging or a commit comes out of render_captured with no later
// slice committed.
struct StagedLog final : trace::TraceSink {
  std::mutex m;
  std::vector<std::pair<uint64_t, uint64_t>> staged, committed;
  uint64_t records = 0;
  std::atomic<int> staging{0}, committing{0};
  int most_staging = 0;
  bool overlapped_commits = false;
  size_t fail_stage_at = 0, fail_commit_at = 0;  // 1-based staged / committed slice that throws; 0: none
  uint32_t begin_pass(const trace::PassInfo&) override { return 0; }
  void write_records(uint32_t, std::span<const gpu::TraceRecord>, uint64_t, uint64_t) override {
    ADD_FAILURE() << "a staging sink is not written in one step";
  }
  Commit stage_record_parts(uint32_t, std::span<const std::span<const gpu::TraceRecord>> parts, uint64_t first,
                            uint64_t end) override {
    const int now = staging.fetch_add(1) + 1;
    uint64_t n = 0;
    for (const auto& p : parts) n += p.size();
    size_t index;
    {
      const std::lock_guard lock(m);
      most_staging = std::max(most_staging, now);
      staged.emplace_back(first, end);
      index = staged.size();
    }
    // Slow coding, slower for every other slice: the next ones stage meanwhile and finish first.
    std::this_thread::sleep_for(std::chrono::milliseconds(index % 2 ? 25 : 2));
    staging.fetch_sub(1);
    if (fail_stage_at && index == fail_stage_at) throw InputError("sink: coding failed");
    return [this, first, end, n] {
      overlapped_commits |= committing.fetch_add(1) != 0;
      committed.emplace_back(first, end);
      records += n;
      committing.fetch_sub(1);
      if (fail_commit_at && committed.size() == fail_commit_at) throw InputError("sink: disk full");
    };
  }
};

TEST(Capture, StagedSlicesAreCodedSideBySideAndCommittedInOrder) {
  HP_REQUIRE_VULKAN(ctx);
  ShadowSlices sliced(*ctx);
  Frame& frame = sliced.frame;
  CaptureOptions& o = sliced.o;
  StagedLog log;
  std::vector<uint64_t> progress;  // records at each progress call
  o.on_slice = [&](const std::string&, uint64_t records, uint64_t, uint64_t) {
    EXPECT_EQ(records, log.records) << "a slice's progress call follows its commit";
    progress.push_back(records);
  };
  o.writer_threads = kTraceBufferParts - 1;  // on lavapipe with two cores it would be one
  const std::vector<CapturedPass> passes = frame.render_captured(o, log);
  ASSERT_EQ(passes.size(), 1u);
  ASSERT_GE(log.committed.size(), 4u);
  EXPECT_FALSE(log.overlapped_commits);
  for (size_t i = 1; i < log.committed.size(); ++i) EXPECT_EQ(log.committed[i].first, log.committed[i - 1].second);
  EXPECT_EQ(log.committed.back().second, passes[0].workgroups);
  EXPECT_EQ(log.records, passes[0].records);
  EXPECT_EQ(progress.size(), log.committed.size());
  // The sink's coding sleeps, so its slices overlap on any number of cores.
  EXPECT_GE(log.most_staging, 2) << "no two slices were coded at once";

  for (const bool in_commit : {false, true}) {
    StagedLog failing;
    (in_commit ? failing.fail_commit_at : failing.fail_stage_at) = 2;
    o.on_slice = nullptr;
    try {
      frame.render_captured(o, failing);
      FAIL() << "expected the sink's error";
    } catch (const InputError& e) {
      EXPECT_STREQ(e.what(), in_commit ? "sink: disk full" : "sink: coding failed");
    }
    // The failed slice is the second; the first may or may not have been committed before the error.
    if (in_commit) {
      EXPECT_EQ(failing.committed.size(), 2u) << "a slice was committed after the one that failed";
    } else {
      EXPECT_LE(failing.committed.size(), 1u) << "a slice was committed after the one that failed";
    }
  }
}

TEST(Capture, OneRowThatCannotFitIsAClearError) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = small(256, 16);
  s.rt.reflections = false;
  Frame frame(*ctx, scene, scene.camera, s);
  CaptureOptions o;
  o.record_regions = 1;
  o.buffer_bytes = slice_buffer(64 * 2);  // two records per lane of one workgroup: far too small
  const fs::path f = fs::temp_directory_path() / ("hp_capture_err_" + std::to_string(::getpid()) + ".hptrace");
  try {
    trace::TraceWriter writer(f, frame.trace_header(true));
    frame.render_captured(o, writer);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("capacity"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(f)) << "an unfinished trace must leave no file";
}

}  // namespace
}  // namespace hp

namespace hp {
namespace {

// The compaction path traced: the compaction and consume sub-passes get their own records (the study's
// second table), an overflowed compaction slice restarts from its saved ray count (its append is not
// idempotent), and the image equals the untraced one.
TEST(Capture, CompactionSubPassesAreTracedWithoutLosingRays) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = small(96, 112);
  s.rt.shadows = false;
  s.rt.reflection_path = ReflectionPath::compact;
  s.rt.sort = SortKey::octant;
  Frame plain(*ctx, scene, scene.camera, s);
  plain.render();
  const Image4f untraced = plain.read_color();
  const uint32_t rays = plain.rt_passes()->read_compacted_count(*ctx);
  ASSERT_GT(rays, 500u);

  const Captured big = capture(*ctx, scene, s, CaptureOptions{}, "compact_big");
  // The octant key is 3 bits: one digit pass of the radix sort, then the copy back from the scratch
  // buffers; each of its dispatches is a traced pass of its own.
  std::vector<std::string> names;
  for (const auto& p : big.passes) names.push_back(p.pass);
  ASSERT_EQ(names, (std::vector<std::string>{"compact", "sort_histogram_0", "sort_scan_0", "sort_scatter_0",
                                             "sort_copy", "consume"}));
  EXPECT_EQ(plain.captured_pass_names(CaptureOptions{}), names) << "what a command checks names against";
  const auto& consume = big.passes.back();
  EXPECT_EQ(consume.workgroups, (rays + 63) / 64) << "one consume thread per compacted ray";
  EXPECT_EQ(std::memcmp(big.image.rgba.data(), untraced.rgba.data(), untraced.rgba.size() * 4), 0);

  CaptureOptions o;
  const uint64_t least = std::min(big.passes[0].records, consume.records);
  o.buffer_bytes = slice_buffer(least * 3 / 4);
  o.first_slice_units = UINT32_MAX;  // the whole pass first: it overflows, so the re-run path runs
  const Captured tiny = capture(*ctx, scene, s, o, "compact_tiny");
  ASSERT_EQ(tiny.passes.size(), big.passes.size());
  EXPECT_GT(tiny.passes[0].reruns, 0u) << "the compaction's first slice must overflow";
  for (size_t i = 0; i < big.passes.size(); ++i) EXPECT_EQ(tiny.passes[i].records, big.passes[i].records) << names[i];
  EXPECT_EQ(tiny.passes.back().workgroups, consume.workgroups) << "a re-run slice appended its rays twice";
  EXPECT_EQ(std::memcmp(tiny.image.rgba.data(), untraced.rgba.data(), untraced.rgba.size() * 4), 0);
  trace::TraceReader r(big.file);
  std::set<uint32_t> buffers;
  for (const auto& rec : r.read_pass(0)) buffers.insert(gpu::trace_buffer(rec.info));
  for (uint32_t b : {HP_TBUF_COMPACT_RAYS, HP_TBUF_SORT_KEYS, HP_TBUF_SORT_VALUES, HP_TBUF_RAY_COUNT}) {
    EXPECT_TRUE(buffers.count(b)) << "compaction never touched buffer " << b;
  }
  // The sort's passes: every live key read by the histogram, the scatter moving every pair into the
  // scratch buffers, the copy moving them back (records per kernel follow from the ray count).
  auto accesses = [&](uint32_t pass) {
    std::map<std::pair<uint32_t, uint32_t>, uint64_t> n;  // (buffer, kind) -> records
    for (const auto& rec : r.read_pass(pass)) ++n[{gpu::trace_buffer(rec.info), gpu::trace_kind(rec.info)}];
    return n;
  };
  const auto hist = accesses(1), scatter = accesses(3), copy = accesses(4);
  EXPECT_EQ((hist.at({HP_TBUF_SORT_KEYS, HP_TRACE_LOAD})), rays);
  EXPECT_GT((hist.at({HP_TBUF_SORT_HISTOGRAMS, HP_TRACE_STORE})), 0u);
  EXPECT_EQ((scatter.at({HP_TBUF_SORT_KEYS, HP_TRACE_LOAD})), 2u * rays) << "counted, then moved";
  EXPECT_EQ((scatter.at({HP_TBUF_SORT_SCRATCH_KEYS, HP_TRACE_STORE})), rays);
  EXPECT_EQ((scatter.at({HP_TBUF_SORT_SCRATCH_VALUES, HP_TRACE_STORE})), rays);
  EXPECT_EQ((copy.at({HP_TBUF_SORT_SCRATCH_KEYS, HP_TRACE_LOAD})), rays);
  EXPECT_EQ((copy.at({HP_TBUF_SORT_VALUES, HP_TRACE_STORE})), rays);
  EXPECT_TRUE(accesses(2).count({HP_TBUF_SORT_HISTOGRAMS, HP_TRACE_STORE})) << "the scan rewrites the histograms";
  fs::remove(big.file);
  fs::remove(tiny.file);
}

}  // namespace
}  // namespace hp
