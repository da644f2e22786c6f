// Speed of the cache simulator, single thread, on a generated BVH-like trace (cachesim/synthetic.hpp:
// 512x512 rays over a 2^18-node tree), or on a captured one: HP_BENCH_TRACE=FILE (a `hybridprof trace`
// output) and HP_BENCH_PASS=NAME (default its first pass). What an "access" is:
//   lane access  one record of the trace: one lane's load/store (27.0 M here);
//   request      one coalesced line request that a wave step sends to an L1 (10.6 M here): what
//                Dinero IV counts as a reference, so the rates to compare with a Dinero-style
//                simulator are requests per second.
// Benchmarks:
//   Hierarchy/*      the coalesced request stream of vega56 replayed through 56 L1s + the L2
//                    (items = requests; lane_accesses = the same work counted in lane accesses),
//                    one request per call (/0) or in batches of 4096 requests of any CUs (/1), as
//                    Simulator::run_pass issues them; /2 the same batches with the portable L2 code
//                    (/1 runs the AVX2 L2 path where the CPU has AVX2).
//   L1Only/*         the same requests' L1 lookups alone: through the 56 L1s (/0), or all through one
//                    16 KiB L1 whose whole state stays in the host's L1 cache (/1): what one lookup
//                    costs without host cache misses.
//   DineroStyle      one 16k:64:4 L1 + one 4m:64:16 L2 on the same line stream, as `--din` does.
//   L2Fixed / L2Mrc  the L2 request stream (9.6 M) through one fixed-size L2, vs the exact all-sizes
//                    stack-distance curve (one by one, and batched as the hierarchy feeds it), vs
//                    SHARDS sampling: the MRC cost ratio.
//   EndToEnd         Simulator::run_pass: grouping, SIMT scheduling, coalescing and caches
//                    (items = lane accesses); /1 adds per-invocation counts, /2 the exact L1 and L2
//                    miss-ratio curves (what `hybridprof cachesim --mrc` and the run matrix compute).
// End-to-end paths of the CLI, from files (wall time: they use several threads; items per second are
// per wall second here):
//   TraceFileRead/F  reading (and, for format version 2, decoding) and validating a trace file slice by
//                    slice (TraceReader::read_slices), nothing else. F: the file in format version 1
//                    (16 bytes a record, /1), version 2 with record coding 1 (/2) or coding 2 (/3, what
//                    `trace` writes: each workgroup's coding stands alone).
//   TraceFileReplay/F  `cachesim TRACE`: the same file replayed (feed_slices: a coding-2 slice is built
//                    straight from its coding); its counters read_ms (the fastest TraceFileRead of that
//                    file, timed beforehand), file_read_ms (the fastest read(2) of its bytes from the page
//                    cache, nothing decoded) and replay_over_read, replay_over_file_read (the replay's
//                    time over each) put the ratios in the same row.
//   TraceFileWrite/F  the capture's writer: the trace's slices (held in memory) coded and written to a
//                    file in form F as a capture hands them over (TraceWriter::write_record_parts, each
//                    slice split where its workgroup order restarts, as the trace buffer's regions lie;
//                    write_records where the parts are not in run order). in_place: the share of
//                    slices coded where they lie.
//   DinFileRead      read(2) of a Dinero text file into a 1 MiB buffer: the memory-speed floor.
//   DinFileReplay    `cachesim --din FILE`: the file streamed through the parser and a 16k:64:4 L1 +
//                    4m:64:16 L2 (/0), or read whole into memory first and then replayed (/1: what the
//                    streamed parser saves). items = Dinero records.
// The files: HP_BENCH_TRACE as above, copied into the three forms (else the generated trace written, in
// 64-workgroup slices as a capture writes them, to temporary files in the three forms) and HP_BENCH_DIN=FILE
// (else the generated trace's L1 request stream, written as Dinero text to a temporary file). Temporary
// files are removed at exit.
// Rates are per CPU second (Google Benchmark's default): on a shared VM they are less disturbed by
// other processes than wall time, not undisturbed. Note the load average printed in the header.
#include <benchmark/benchmark.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <span>
#include <string>

#include "cachesim/din_replay.hpp"
#include "cachesim/hierarchy.hpp"
#include "cachesim/preset.hpp"
#include "cachesim/simulator.hpp"
#include "cachesim/stack_distance.hpp"
#include "cachesim/synthetic.hpp"
#include "trace/din.hpp"

namespace {

using namespace hp::cachesim;

struct Fixture {
  hp::trace::Trace trace;
  Preset preset;
  std::vector<std::pair<uint32_t, Request>> requests;  // coalesced, in issue order
  std::vector<uint64_t> l2_lines;                      // the L2's request stream
  // The same requests and their CUs as two arrays, the way Simulator::run_pass hands them to
  // Hierarchy::issue(span, cus, out).
  std::vector<Request> flat;
  std::vector<uint32_t> flat_cu;
  Fixture() {
    if (const char* path = std::getenv("HP_BENCH_TRACE")) {
      // A captured trace (hybridprof trace --out FILE): its pass HP_BENCH_PASS, default the first.
      trace = hp::trace::read_trace(path);
      const char* want = std::getenv("HP_BENCH_PASS");
      size_t p = 0;
      while (want && p < trace.passes.size() && trace.passes[p].name != want) ++p;
      if (p == trace.passes.size()) {
        std::fprintf(stderr, "HP_BENCH_PASS=%s: no such pass in %s\n", want, path);
        std::exit(2);
      }
      trace.passes = {trace.passes[p]};
      trace.records = {std::move(trace.records[p])};
    } else {
      SyntheticBvhOptions o;
      // HP_BENCH_RAYS (default 512) shrinks the image for instruction-level profiling under callgrind;
      // every figure in docs/cache-model.md is taken at the default.
      const char* rays = std::getenv("HP_BENCH_RAYS");
      o.width = o.height = rays ? uint32_t(std::max(8, std::atoi(rays))) : 512u;
      o.tree_depth = 17;
      o.incoherent_fraction = 0.25;
      trace = make_bvh_like_trace(o);
    }
    preset = find_preset("vega56");
    SimOptions so;
    so.per_invocation = false;
    so.observer = [&](uint32_t cu, const Request& r) { requests.emplace_back(cu, r); };
    Simulator sim(preset, trace.header, so);
    sim.run_pass(trace.passes[0], trace.records[0]);
    for (const auto& [cu, r] : requests) {
      flat.push_back(r);
      flat_cu.push_back(cu);
    }
    // The L2 stream: what misses the L1s (plus stores, atomics), recomputed with plain caches.
    std::vector<Cache> l1(preset.compute_units, Cache(preset.l1));
    for (const auto& [cu, r] : requests)
      if (r.kind != AccessKind::load || l1[cu].load(r.line, r.sectors).missing) l2_lines.push_back(r.line);
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

constexpr size_t kBatch = 4096;  // Simulator's batch

// Whether a vega56 hierarchy's batched path uses AVX2 here.
bool h_avx2() {
  const Preset p = find_preset("vega56");
  return Hierarchy(p.l1, 1, p.l2).avx2();
}

void Hierarchy_L1L2(benchmark::State& state) {
  const Fixture& f = fixture();
  for (auto _ : state) {
    Hierarchy h(f.preset.l1, f.preset.compute_units, f.preset.l2);
    if (state.range(0) == 2) h.use_avx2(false);
    if (state.range(0)) {
      const std::span<const Request> all(f.flat);
      const std::span<const uint32_t> cus(f.flat_cu);
      for (size_t b = 0; b < all.size(); b += kBatch) {
        const size_t n = std::min(kBatch, all.size() - b);
        h.issue(all.subspan(b, n), cus.subspan(b, n), nullptr);
      }
    } else {
      for (const auto& [cu, r] : f.requests) h.issue(cu, r);
    }
    benchmark::DoNotOptimize(h.stats().l2.misses);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * f.requests.size()));
  // The same work counted in the lane accesses the coalescer turned into these requests.
  state.counters["lane_accesses"] =
      benchmark::Counter(double(f.trace.records[0].size()), benchmark::Counter::kIsIterationInvariantRate);
  state.SetLabel(state.range(0) == 0 ? "one by one"
                 : state.range(0) == 1
                     ? (h_avx2() ? "batched, as the simulator issues (AVX2 L2)" : "batched, as the simulator issues")
                     : "batched, portable L2 code");
}
BENCHMARK(Hierarchy_L1L2)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void Hierarchy_L1L2_withL2Mrc(benchmark::State& state) {
  const Fixture& f = fixture();
  for (auto _ : state) {
    Hierarchy h(f.preset.l1, f.preset.compute_units, f.preset.l2);
    h.enable_mrc(false, true);
    for (const auto& [cu, r] : f.requests) h.issue(cu, r);
    benchmark::DoNotOptimize(h.stats().l2.misses);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * f.requests.size()));
}
BENCHMARK(Hierarchy_L1L2_withL2Mrc)->Unit(benchmark::kMillisecond);

void L1Only(benchmark::State& state) {
  const Fixture& f = fixture();
  const bool one = state.range(0) == 1;
  uint64_t loads = 0;
  for (const auto& [cu, r] : f.requests) loads += r.kind == AccessKind::load;
  for (auto _ : state) {
    std::vector<Cache> l1(one ? 1 : f.preset.compute_units, Cache(f.preset.l1));
    uint64_t misses = 0;
    for (const auto& [cu, r] : f.requests)
      if (r.kind == AccessKind::load) misses += l1[one ? 0 : cu].load(r.line, r.sectors).missing != 0;
    benchmark::DoNotOptimize(misses);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * loads));
  state.SetLabel(one ? "all through one L1" : "one L1 per CU");
}
BENCHMARK(L1Only)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void DineroStyle_L1L2(benchmark::State& state) {
  const Fixture& f = fixture();
  CacheConfig l1{16 << 10, 64, 64, 4}, l2{4 << 20, 64, 64, 16};
  for (auto _ : state) {
    Cache c1(l1), c2(l2);
    uint64_t misses = 0;
    for (const auto& [cu, r] : f.requests)
      if (c1.load(r.line, 1).missing) misses += c2.load(r.line, 1).missing != 0;
    benchmark::DoNotOptimize(misses);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * f.requests.size()));
}
BENCHMARK(DineroStyle_L1L2)->Unit(benchmark::kMillisecond);

void L2Fixed(benchmark::State& state) {
  const Fixture& f = fixture();
  for (auto _ : state) {
    Cache l2(f.preset.l2);
    uint64_t misses = 0;
    for (uint64_t line : f.l2_lines) misses += l2.load(line, 1).missing != 0;
    benchmark::DoNotOptimize(misses);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * f.l2_lines.size()));
  state.counters["l2_requests"] = double(f.l2_lines.size());
}
BENCHMARK(L2Fixed)->Unit(benchmark::kMillisecond);

void L2Mrc(benchmark::State& state) {
  const Fixture& f = fixture();
  const double rate = state.range(0) == 0 ? 1.0 : 1.0 / double(state.range(0));
  for (auto _ : state) {
    StackDistance sd(64, rate);
    if (state.range(1))
      sd.access(std::span<const uint64_t>(f.l2_lines));
    else
      for (uint64_t line : f.l2_lines) sd.access(line);
    benchmark::DoNotOptimize(sd.curve().cold);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * f.l2_lines.size()));
  state.SetLabel((state.range(0) == 0 ? "exact" : "SHARDS 1/" + std::to_string(state.range(0))) +
                 (state.range(1) ? ", batch" : ", one by one"));
}
BENCHMARK(L2Mrc)->Args({0, 0})->Args({0, 1})->Args({100, 0})->Unit(benchmark::kMillisecond);

void EndToEnd(benchmark::State& state) {
  const Fixture& f = fixture();
  SimOptions so;
  so.per_invocation = state.range(0) == 1;
  so.l1_mrc = so.l2_mrc = state.range(0) == 2;  // the exact L1 and L2 curves as well
  for (auto _ : state) {
    Simulator sim(f.preset, f.trace.header, so);
    auto r = sim.run_pass(f.trace.passes[0], f.trace.records[0]);
    benchmark::DoNotOptimize(r.stats.l2.misses);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * f.trace.records[0].size()));
  state.counters["lane_accesses"] = double(f.trace.records[0].size());
  state.SetLabel(so.per_invocation ? "with per-invocation counts"
                 : so.l2_mrc       ? "totals + exact L1 and L2 curves"
                                   : "totals only");
}
BENCHMARK(EndToEnd)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// Reads every slice of every pass of a trace file (TraceReader::read_slices: read, decode, validate);
// returns the records read.
uint64_t read_whole_trace(const std::string& path) {
  hp::trace::TraceReader reader(path);
  uint64_t records = 0;
  for (uint32_t p = 0; p < reader.passes().size(); ++p)
    reader.read_slices(p, [&](std::span<const hp::trace::TraceRecord> r, uint64_t, uint64_t) { records += r.size(); });
  return records;
}

// The forms a trace file is benchmarked in (index: the benchmarks' argument): format version and record
// coding.
struct TraceForm {
  uint32_t version, coding;
  const char* label;
};
constexpr TraceForm kForms[4] = {{0, 0, ""},
                                 {1, hp::trace::kCodingSizedGroups, "version 1 (16-byte records)"},
                                 {2, hp::trace::kCodingDeltaVarint, "version 2, coding 1"},
                                 {2, hp::trace::kCodingSizedGroups, "version 2, coding 2"}};

// Copies a trace file into another form, slice by slice.
void convert_trace(const std::string& from, const std::string& to, const TraceForm& form) {
  hp::trace::TraceReader reader(from);
  hp::trace::TraceWriter w(to, reader.header(), form.version, form.coding);
  for (uint32_t p = 0; p < reader.passes().size(); ++p) {
    const uint32_t index = w.begin_pass(reader.passes()[p]);
    reader.read_slices(p, [&](std::span<const hp::trace::TraceRecord> r, uint64_t first, uint64_t end) {
      w.write_records(index, r, first, end);
    });
  }
  w.finish();
}

// The files the end-to-end benchmarks read, made once (see the header comment).
struct Files {
  std::string trace_path[4];         // by form (kForms)
  double read_seconds[4] = {};       // the fastest of three whole reads of each (TraceFileRead's work)
  double file_read_seconds[4] = {};  // the fastest of three read(2)s of each one's bytes
  std::string din_path;
  std::vector<std::string> remove;
  uint64_t din_records = 0;
  Files() {
    const Fixture& f = fixture();
    const std::string tmp =
        std::filesystem::temp_directory_path().string() + "/hp_bench_cachesim_" + std::to_string(::getpid());
    for (uint32_t k = 1; k < 4; ++k) {
      trace_path[k] = tmp + ".form" + std::to_string(k) + ".trace";
      remove.push_back(trace_path[k]);
    }
    if (const char* t = std::getenv("HP_BENCH_TRACE")) {
      for (uint32_t k = 1; k < 4; ++k) convert_trace(t, trace_path[k], kForms[k]);
    } else {
      for (uint32_t k = 1; k < 4; ++k) {
        hp::trace::TraceWriter w(trace_path[k], f.trace.header, kForms[k].version, kForms[k].coding);
        const hp::trace::PassInfo& pass = f.trace.passes[0];
        const uint32_t p = w.begin_pass(pass);
        const uint64_t per_group = pass.dispatch.invocations_per_workgroup(), groups = pass.dispatch.workgroups();
        std::vector<hp::trace::TraceRecord> part;
        for (uint64_t g0 = 0; g0 < groups; g0 += 64) {
          const uint64_t g1 = std::min(groups, g0 + 64);
          part.clear();
          for (const auto& r : f.trace.records[0])
            if (r.invocation >= g0 * per_group && r.invocation < g1 * per_group) part.push_back(r);
          w.write_records(p, part, g0, g1);
        }
        w.finish();
      }
    }
    std::unique_ptr<char[]> buf(new char[1 << 20]);
    for (uint32_t k = 1; k < 4; ++k) {
      read_seconds[k] = file_read_seconds[k] = 1e30;
      for (int rep = 0; rep < 3; ++rep) {
        auto t0 = std::chrono::steady_clock::now();
        benchmark::DoNotOptimize(read_whole_trace(trace_path[k]));
        read_seconds[k] =
            std::min(read_seconds[k], std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        t0 = std::chrono::steady_clock::now();
        const int fd = ::open(trace_path[k].c_str(), O_RDONLY);
        uint64_t bytes = 0;
        for (ssize_t n; (n = ::read(fd, buf.get(), 1 << 20)) > 0;) bytes += uint64_t(n);
        ::close(fd);
        benchmark::DoNotOptimize(bytes);
        file_read_seconds[k] = std::min(file_read_seconds[k],
                                        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      }
    }
    if (const char* d = std::getenv("HP_BENCH_DIN")) {
      din_path = d;
    } else {
      din_path = tmp + ".din";
      remove.push_back(din_path);
      std::ofstream out(din_path);
      for (const auto& [cu, r] : f.requests)
        hp::trace::write_din_line(out, hp::trace::DinAccess{r.kind == AccessKind::store, r.line << 6, 64});
    }
    hp::trace::DinReader reader(din_path);
    std::vector<hp::trace::DinAccess> batch(16384);
    while (size_t n = reader.read(batch)) din_records += n;
  }
  ~Files() {
    for (const std::string& p : remove) std::filesystem::remove(p);
  }
};

Files& files() {
  static Files f;
  return f;
}

// /1, /2, /3: the trace file in each form (kForms).
void TraceFileRead(benchmark::State& state) {
  const Files& fs = files();
  const std::string& path = fs.trace_path[state.range(0)];
  uint64_t records = 0;
  for (auto _ : state) {
    records = read_whole_trace(path);
    benchmark::DoNotOptimize(records);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * records));
  state.counters["bytes"] = double(std::filesystem::file_size(path));
  state.counters["bytes_per_lane_access"] = double(std::filesystem::file_size(path)) / double(records);
  state.SetLabel(kForms[state.range(0)].label);
}
BENCHMARK(TraceFileRead)->Arg(1)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond)->UseRealTime();

// The capture's writer (what `trace` runs on its worker thread for each slice): the trace's slices, held in
// memory as read from the version-1 file and split into the parts a capture's regions make (a region holds
// an increasing run of workgroups, so a new part starts where the workgroup order goes back), coded and
// written to a temporary file in form /1, /2 or /3 (items: lane accesses, per wall second; bytes: the file
// written).
void TraceFileWrite(benchmark::State& state) {
  const Files& fs = files();
  struct Slice {
    uint32_t pass;
    std::vector<hp::trace::TraceRecord> records;
    uint64_t first, end;
    std::vector<size_t> part_begin;  // where each part starts in records
  };
  static const auto held = [&] {
    hp::trace::TraceReader reader(fs.trace_path[1]);
    std::vector<Slice> slices;
    for (uint32_t p = 0; p < reader.passes().size(); ++p) {
      const uint64_t per_group = reader.passes()[p].dispatch.invocations_per_workgroup();
      reader.read_slices(p, [&](std::span<const hp::trace::TraceRecord> r, uint64_t first, uint64_t end) {
        Slice s{p, {r.begin(), r.end()}, first, end, {0}};
        for (size_t i = 1; i < r.size(); ++i) {
          if (r[i].invocation / per_group < r[i - 1].invocation / per_group) s.part_begin.push_back(i);
        }
        slices.push_back(std::move(s));
      });
    }
    return std::tuple(reader.header(), reader.passes(), std::move(slices));
  }();
  const auto& [header, passes, slices] = held;
  const std::string out = fs.trace_path[1] + ".written";
  const TraceForm& form = kForms[state.range(0)];
  uint64_t records = 0, in_place = 0;
  std::vector<std::span<const hp::trace::TraceRecord>> parts;
  for (auto _ : state) {
    hp::trace::TraceWriter w(out, header, form.version, form.coding);
    records = in_place = 0;
    uint32_t pass = 0, begun = 0;  // slices come pass by pass
    for (const Slice& s : slices) {
      while (begun <= s.pass) pass = w.begin_pass(passes[begun++]);
      parts.clear();
      for (size_t k = 0; k < s.part_begin.size(); ++k) {
        const size_t end = k + 1 < s.part_begin.size() ? s.part_begin[k + 1] : s.records.size();
        parts.emplace_back(s.records.data() + s.part_begin[k], end - s.part_begin[k]);
      }
      if (w.write_record_parts(pass, parts, s.first, s.end)) {
        ++in_place;
      } else {
        w.write_records(pass, s.records, s.first, s.end);
      }
      records += s.records.size();
    }
    while (begun < passes.size()) w.begin_pass(passes[begun++]);
    w.finish();
  }
  state.SetItemsProcessed(int64_t(state.iterations() * records));
  state.counters["bytes"] = double(std::filesystem::file_size(out));
  state.counters["in_place"] = slices.empty() ? 0.0 : double(in_place) / double(slices.size());
  std::filesystem::remove(out);
  state.SetLabel(form.label);
}
BENCHMARK(TraceFileWrite)->Arg(1)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond)->UseRealTime();

// `cachesim TRACE` end to end from the file (items: lane accesses, per wall second). read_ms is the
// fastest whole read of the same file (TraceFileRead's work, timed when the files were made), so each
// row shows replay / read, the replay's cost relative to reading its input.
void TraceFileReplay(benchmark::State& state) {
  const Files& fs = files();
  const Fixture& f = fixture();
  const std::string& path = fs.trace_path[state.range(0)];
  uint64_t records = 0;
  double wall_seconds = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    hp::trace::TraceReader reader(path);
    SimOptions so;
    so.per_invocation = false;
    Simulator sim(f.preset, reader.header(), so);
    records = 0;
    for (uint32_t p = 0; p < reader.passes().size(); ++p) {
      sim.begin_pass(reader.passes()[p]);
      feed_slices(sim, reader, p);
      records += sim.end_pass().lane_accesses;
    }
    benchmark::DoNotOptimize(sim.finish());
    wall_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  state.SetItemsProcessed(int64_t(state.iterations() * records));
  state.counters["lane_accesses"] = double(records);
  state.counters["bytes_per_lane_access"] = double(std::filesystem::file_size(path)) / double(records);
  const size_t k = size_t(state.range(0));
  state.counters["read_ms"] = fs.read_seconds[k] * 1e3;
  state.counters["file_read_ms"] = fs.file_read_seconds[k] * 1e3;
  // The mean replay over each read (all wall clock).
  const double replay_seconds = wall_seconds / double(state.iterations());
  state.counters["replay_over_read"] = replay_seconds / fs.read_seconds[k];
  state.counters["replay_over_file_read"] = replay_seconds / fs.file_read_seconds[k];
  state.SetLabel(kForms[k].label);
}
BENCHMARK(TraceFileReplay)->Arg(1)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond)->UseRealTime();

void DinFileRead(benchmark::State& state) {
  const Files& fs = files();
  std::unique_ptr<char[]> buf(new char[1 << 20]);
  uint64_t bytes = 0;
  for (auto _ : state) {
    const int fd = ::open(fs.din_path.c_str(), O_RDONLY);
    bytes = 0;
    for (ssize_t n; (n = ::read(fd, buf.get(), 1 << 20)) > 0;) bytes += uint64_t(n);
    ::close(fd);
    benchmark::DoNotOptimize(bytes);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * fs.din_records));
  state.SetBytesProcessed(int64_t(state.iterations() * bytes));
}
BENCHMARK(DinFileRead)->Unit(benchmark::kMillisecond)->UseRealTime();

void DinFileReplay(benchmark::State& state) {
  const Files& fs = files();
  const CacheConfig l1 = parse_cache_spec("16k:64:4", "--l1"), l2 = parse_cache_spec("4m:64:16", "--l2");
  for (auto _ : state) {
    DinResult r;
    if (state.range(0) == 0) {
      uint64_t refs = 0;
      r = replay_din_file(fs.din_path, l1, l2, false, refs);
    } else {
      r = replay_din(hp::trace::read_din(fs.din_path), l1, l2, false);
    }
    benchmark::DoNotOptimize(r.l2.misses);
  }
  state.SetItemsProcessed(int64_t(state.iterations() * fs.din_records));
  state.SetLabel(state.range(0) == 0 ? "streamed (cachesim --din)" : "whole file in memory, then replayed");
}
BENCHMARK(DinFileReplay)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  // Built before any benchmark runs, so a profiler collecting inside one benchmark
  // (valgrind --tool=callgrind --collect-atstart=no --toggle-collect=...) sees only that benchmark.
  const Fixture& f = fixture();
  benchmark::AddCustomContext("trace", std::getenv("HP_BENCH_TRACE") ? std::getenv("HP_BENCH_TRACE") : "generated");
  benchmark::AddCustomContext("pass", f.trace.passes[0].name);
  benchmark::AddCustomContext("lane_accesses", std::to_string(f.trace.records[0].size()));
  benchmark::AddCustomContext("l1_requests", std::to_string(f.requests.size()));
  benchmark::AddCustomContext("l2_requests", std::to_string(f.l2_lines.size()));
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
