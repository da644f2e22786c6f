// The hybrid frame's ray-tracing passes on the Vulkan device (lavapipe by default), and the C++ reference
// traversal on the very same rays with the same number of threads.
//
//   Gpu/<pass>/<scene>: manual time = the pass's GPU timestamp interval; "rays" is a rate (rays/s).
//   Trace/<pass>/<scene>: the same rays through the passes' traversal alone on the device (trace_rays.comp,
//                       one thread per ray, no ray generation or shading), timed by GPU timestamps.
//   Cpu/<pass>/<scene>: the reference traversal casting the rays the GPU cast in that pass (dumped once),
//                       on T threads, T = LP_NUM_THREADS if set, else the core count (lavapipe's default).
// Cpu/* also report the work per ray (nodes and triangles tested, from the reference) and a model of SIMD
// lane use: llvmpipe runs eight horizontally adjacent invocations of an 8x8 workgroup as one 256-bit vector,
// and a vector takes as many node (triangle) steps as its busiest lane, so sum(steps) / (8 * sum(max steps
// per vector)) bounds the fraction of lane-steps doing useful work (idle lanes, e.g. background, count as
// wasted). A model from the reference's counters, not a measurement of the driver.
// Shadows: one any-hit ray per lit-facing pixel. Reflections: closest-hit rays of reflective pixels,
// shaded without a shadow ray at the hit (so both sides cast exactly the same rays); every visible pixel
// reflects (roughness threshold above 1).
//   Capture/<pass>/<scene>: `hybridprof trace` of that pass alone: its instrumented variant, sliced through
//                       the trace buffer into a compact (version 2) trace file; manual time = the real time
//                       per capture, after an untimed first one (pipelines, buffers), each into a new file.
//                       untraced_ms: the median GPU time of the same pass untraced (6 frames);
//                       capture_over_untraced: the mean capture over it (the whole capture: the G-buffer
//                       it rasterizes first, the traced pass, the file's close);
//                       pass_capture_over_untraced: the traced pass's own capture (CapturedPass::seconds,
//                       from its first slice to its last written) over it.
// Gpu/* and Trace/* also run on the wide4 node layout (names ending in /wide4: the same rays, the compute
// traversal over 64-byte 4-wide nodes, bvh/wide.hpp), and through the driver's ray tracing where the device
// has it: names ending in
// /ray-query (ray queries from the same compute shaders) and /pipeline (a ray-tracing pipeline whose
// ray-generation shaders are the same sources), the driver's acceleration structure built from the compute
// BVH's leaf order. The label names the device; "as_build_ms" and "as_mib" the structure's build and size.
// Run: build/tests/bench/hp_bench_frame [--benchmark_filter=...] ; HP_BENCH_WIDTH/HEIGHT override 1280x720.
// With --benchmark_repetitions=N the Gpu, Trace and Cpu rows also print _min and _max (bench_extremes.hpp):
// the best rate of N repetitions is the _max row's "rays".
// HP_BENCH_RAY_COPIES=N (default 1) casts each dumped ray N times in a row in the Trace and Cpu rows: with
// N = 8 the eight lanes of a vector trace the same ray, which measures a vector step without divergence
// (docs/gpu-passes.md, "Where the rest of the gap is"). Their rates count every copy; the Gpu rows (which
// render the pass), the work per ray and the lane-use model stay those of the rays as cast.
#include "bench_extremes.hpp"
#include "bvh/traverse.hpp"
#include "frame.hpp"
#include "passes/ray_batch.hpp"
#include "scene/load.hpp"
#include "timing/stats.hpp"
#include "trace/trace_file.hpp"
#include "vk/context.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <thread>
#include <tuple>
#include <unistd.h>

namespace {

using namespace hp;

uint32_t env_or(const char* name, uint32_t fallback) {
  const char* v = std::getenv(name);
  return v && *v ? uint32_t(std::strtoul(v, nullptr, 10)) : fallback;
}

int reference_threads() {
  const uint32_t lp = env_or("LP_NUM_THREADS", 0);
  return lp > 0 ? int(lp) : int(std::thread::hardware_concurrency());
}

vk::Context& context() {
  static vk::Context ctx{vk::ContextOptions{}};
  return ctx;
}

enum class Pass { shadows, reflections };

struct Setup {
  Scene scene;
  Camera camera;
  std::unique_ptr<Frame> frame;
  std::vector<bvh::Ray> rays;  // the rays the GPU cast in this pass (from a dumped frame)
  size_t rays_cast = 0;        // how many: rays holds each HP_BENCH_RAY_COPIES times
  double nodes_per_ray = 0, tris_per_ray = 0;
  double node_lane_use = 0, tri_lane_use = 0;  // the SIMD lane-use model above
  std::unique_ptr<RayBatchTracer> batch;       // the rays uploaded for Trace/*, on first use
};

// The work per ray and the lane-use model, from the dumped cells (row-major, width a multiple of 8 lanes
// or a ragged last vector) and the reference traversal's counters.
void measure_work(Setup& s, const std::vector<gpu::RayDump>& dump, uint32_t width, Pass pass) {
  const RtGeometry& g = *s.frame->rt_geometry();
  uint64_t rays = 0, nodes = 0, tris = 0, max_nodes = 0, max_tris = 0;
  const size_t lanes = 8;  // llvmpipe's default 256-bit vectors of 32-bit lanes
  for (size_t row = 0; row * width < dump.size(); ++row) {
    for (size_t x0 = 0; x0 < width; x0 += lanes) {
      uint64_t vn = 0, vt = 0;
      for (size_t x = x0; x < std::min<size_t>(x0 + lanes, width); ++x) {
        const auto& d = dump[row * width + x];
        if (d.hit.z == 0) continue;
        const bvh::Ray r = dumped_ray(d);
        bvh::TraversalStats st;
        if (pass == Pass::shadows) {
          bvh::intersect_any(g.bvh, g.leaf, r, &st);
        } else {
          bvh::intersect_closest(g.bvh, g.leaf, r, &st);
        }
        ++rays;
        nodes += st.nodes_visited;
        tris += st.triangles_tested;
        vn = std::max(vn, st.nodes_visited);
        vt = std::max(vt, st.triangles_tested);
      }
      max_nodes += vn;
      max_tris += vt;
    }
  }
  if (rays == 0) return;
  s.nodes_per_ray = double(nodes) / double(rays);
  s.tris_per_ray = double(tris) / double(rays);
  s.node_lane_use = max_nodes ? double(nodes) / double(lanes * max_nodes) : 0.0;
  s.tri_lane_use = max_tris ? double(tris) / double(lanes * max_tris) : 0.0;
}

FrameSettings settings_for(Pass pass, bool dump, Traversal traversal,
                           bvh::NodeLayout layout = bvh::NodeLayout::binary32) {
  FrameSettings s;
  s.bvh.node_layout = layout;
  s.width = env_or("HP_BENCH_WIDTH", 1280);
  s.height = env_or("HP_BENCH_HEIGHT", 720);
  s.rt.shadows = pass == Pass::shadows;
  s.rt.reflections = pass == Pass::reflections;
  s.rt.reflection_shadows = false;
  // Every visible pixel reflects, so that scenes with rough materials (the shared glTF scenes) have
  // reflection rays too.
  s.rt.roughness_threshold = 1.01f;
  s.rt.counters = false;
  s.rt.dump_rays = dump;
  s.rt.offset = ShadowOffset::robust;
  s.rt.traversal = traversal;
  return s;
}

// One setup per (scene, pass), built on first use and kept: building a frame compiles pipelines.
Setup& setup(const std::string& spec, Pass pass, Traversal traversal,
             bvh::NodeLayout layout = bvh::NodeLayout::binary32) {
  // The context first: statics are destroyed in reverse order, so the frames go before their device.
  vk::Context& ctx = context();
  static std::map<std::tuple<std::string, int, int, int>, std::unique_ptr<Setup>> cache;
  auto& slot = cache[{spec, int(pass), int(traversal), int(layout)}];
  if (!slot) {
    slot = std::make_unique<Setup>();
    Setup& s = *slot;
    s.scene = load_scene(spec);
    const FrameSettings fs = settings_for(pass, false, traversal, layout);
    s.camera = s.scene.has_camera ? s.scene.camera : auto_frame(s.scene, float(fs.width) / float(fs.height));
    s.frame = std::make_unique<Frame>(ctx, s.scene, s.camera, fs);
    // The rays: one frame with dumps on (the dump writes cost GPU time, so timed frames run without them).
    // Every traversal and node layout casts the same rays (the same hits make the same reflection rays).
    Frame dumper(context(), s.scene, s.camera, settings_for(pass, true, Traversal::compute));
    dumper.render();
    const auto dump = pass == Pass::shadows ? dumper.rt_passes()->read_shadow_dump(context())
                                            : dumper.rt_passes()->read_reflection_dump(context());
    const uint32_t copies = std::max(1u, env_or("HP_BENCH_RAY_COPIES", 1));
    for (const auto& d : dump) {
      if (d.hit.z == 0) continue;
      s.rays.insert(s.rays.end(), copies, dumped_ray(d));
      ++s.rays_cast;
    }
    // The dump is per cell of the pass's grid: the full frame (reflections at scale 1 here).
    measure_work(s, dump, fs.width, pass);
  }
  return *slot;
}

// Warm-up before a timed row: at least two runs (the first frames on lavapipe are slower) and at least a
// quarter of a second of them. A GPU left idle while the host builds a setup drops its clocks (the H200 to
// 345 MHz from 1980), and a sub-millisecond pass timed right after two runs read up to 3x slower there.
template <typename Run>
void warm_up(Run&& run) {
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 2 || std::chrono::steady_clock::now() - start < std::chrono::milliseconds(250); ++i) run();
}

// The driver's acceleration structure of a driver-traversal setup, as counters.
void as_counters(benchmark::State& state, const Setup& s) {
  if (const AccelStructure* as = s.frame->accel_structure()) {
    state.counters["as_build_ms"] = as->stats().build_ms;
    state.counters["as_mib"] = double(as->stats().blas_bytes + as->stats().tlas_bytes) / 1048576.0;
  }
}

void gpu_pass(benchmark::State& state, const std::string& spec, Pass pass, Traversal traversal,
              bvh::NodeLayout layout) {
  Setup& s = setup(spec, pass, traversal, layout);
  const char* name = pass == Pass::shadows ? "shadows" : "reflections";
  warm_up([&] { s.frame->render(); });
  for (auto _ : state) {
    const FrameTiming t = s.frame->render();
    for (const auto& p : t.passes) {
      if (p.name == name) state.SetIterationTime(double(p.duration_ns()) * 1e-9);
    }
  }
  state.counters["rays"] = benchmark::Counter(double(s.rays_cast), benchmark::Counter::kIsIterationInvariantRate);
  as_counters(state, s);
  state.SetLabel(context().info().name);
}

void trace_pass(benchmark::State& state, const std::string& spec, Pass pass, Traversal traversal,
                bvh::NodeLayout layout) {
  Setup& s = setup(spec, pass, traversal, layout);
  if (!s.batch) {
    s.batch = std::make_unique<RayBatchTracer>(context(), *s.frame->rt_scene(), s.rays, s.frame->accel_structure(),
                                               traversal);
  }
  const auto mode = pass == Pass::shadows ? bvh::HitMode::any : bvh::HitMode::closest;
  warm_up([&] { s.batch->trace(context(), mode); });
  for (auto _ : state) state.SetIterationTime(double(s.batch->trace(context(), mode)) * 1e-9);
  state.counters["rays"] = benchmark::Counter(double(s.rays.size()), benchmark::Counter::kIsIterationInvariantRate);
  as_counters(state, s);
  state.SetLabel(context().info().name);
}

void cpu_pass(benchmark::State& state, const std::string& spec, Pass pass) {
  Setup& s = setup(spec, pass, Traversal::compute);
  const RtGeometry& g = *s.frame->rt_geometry();
  const int threads = reference_threads();
  const auto mode = pass == Pass::shadows ? bvh::HitMode::any : bvh::HitMode::closest;
  for (auto _ : state) {
    auto hits = bvh::cast_rays(g.bvh, g.leaf, s.rays, mode, threads);
    benchmark::DoNotOptimize(hits.data());
  }
  state.counters["rays"] = benchmark::Counter(double(s.rays.size()), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["threads"] = threads;
  state.counters["nodes_per_ray"] = s.nodes_per_ray;
  state.counters["tris_per_ray"] = s.tris_per_ray;
  state.counters["node_lane_use"] = s.node_lane_use;
  state.counters["tri_lane_use"] = s.tri_lane_use;
}

void capture_pass(benchmark::State& state, const std::string& spec, Pass pass) {
  Setup& s = setup(spec, pass, Traversal::compute);
  const char* name = pass == Pass::shadows ? "shadows" : "reflections";
  warm_up([&] { s.frame->render(); });
  std::vector<double> untraced;
  for (int i = 0; i < 6; ++i) {
    for (const auto& p : s.frame->render().passes) {
      if (p.name == name) untraced.push_back(double(p.duration_ns()) * 1e-9);
    }
  }
  if (untraced.empty()) {
    state.SkipWithError("the pass did not run");
    return;
  }
  const double untraced_s = quantile(untraced, 0.5);
  CaptureOptions o;
  o.shadows = pass == Pass::shadows;
  o.reflections = pass == Pass::reflections;
  o.final_image = false;
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("hp_bench_capture_" + std::to_string(::getpid()) + ".hptrace");
  uint64_t records = 0, bytes = 0;
  double wall = 0, pass_wall = 0, pass_seconds = 0;
  const auto capture = [&] {
    trace::TraceWriter writer(file, s.frame->trace_header(o.tiled_images));
    records = 0;
    pass_seconds = 0;
    for (const CapturedPass& cp : s.frame->render_captured(o, writer)) {
      records += cp.records;
      pass_seconds += cp.seconds;
    }
    writer.finish();
  };
  // Warm-up, as the untraced frames above: the instrumented pipelines are built and the trace buffer is
  // allocated by the first capture.
  capture();
  std::filesystem::remove(file);
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    capture();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    state.SetIterationTime(seconds);
    wall += seconds;
    pass_wall += pass_seconds;
    bytes = std::filesystem::file_size(file);
    // Untimed: the next capture's rename would otherwise replace this file and free its pages inside
    // the timed part (about 0.09 s for a 1080p reflection trace).
    std::filesystem::remove(file);
  }
  state.counters["lane_accesses"] = double(records);
  state.counters["bytes_per_lane_access"] = records ? double(bytes) / double(records) : 0.0;
  state.counters["untraced_ms"] = untraced_s * 1e3;
  state.counters["capture_over_untraced"] = wall / double(state.iterations()) / untraced_s;
  // The traced pass's own capture (CapturedPass::seconds): without the G-buffer the capture runs first
  // (untraced, as in the frame whose pass is the denominator) and the file's close.
  state.counters["pass_capture_over_untraced"] = pass_wall / double(state.iterations()) / untraced_s;
  state.SetLabel(context().info().name);
}

std::vector<std::string> scenes() {
  std::vector<std::string> out = {"builtin:pica"};
  const std::filesystem::path root = std::filesystem::path(HP_SHARED_DIR) / "scenes";
  for (const char* f :
       {"DamagedHelmet/DamagedHelmet.gltf", "WaterBottle/WaterBottle.gltf", "Balloon/scene.gltf", "Pine/scene.gltf"}) {
    if (std::filesystem::exists(root / f)) out.push_back((root / f).string());
  }
  return out;
}

std::string short_name(const std::string& spec) {
  if (spec.rfind("builtin:", 0) == 0) return spec.substr(8);
  return std::filesystem::path(spec).parent_path().filename().string();
}

const bool registered = [] {
  for (const std::string& spec : scenes()) {
    for (Pass pass : {Pass::shadows, Pass::reflections}) {
      const std::string p = pass == Pass::shadows ? "shadows" : "reflections";
      for (Traversal t : {Traversal::compute, Traversal::ray_query, Traversal::pipeline}) {
        if (t == Traversal::ray_query && !context().ray_query_enabled()) continue;
        if (t == Traversal::pipeline && !context().ray_tracing_pipeline_enabled()) continue;
        for (bvh::NodeLayout layout : {bvh::NodeLayout::binary32, bvh::NodeLayout::wide4}) {
          if (layout != bvh::NodeLayout::binary32 && t != Traversal::compute) continue;  // the driver's own nodes
          const std::string suffix = t != Traversal::compute               ? std::string("/") + to_string(t)
                                     : layout != bvh::NodeLayout::binary32 ? std::string("/") + to_string(layout)
                                                                           : std::string();
          hp::bench::with_extremes(benchmark::RegisterBenchmark(("Gpu/" + p + "/" + short_name(spec) + suffix).c_str(),
                                                                gpu_pass, spec, pass, t, layout))
              ->UseManualTime()
              ->Unit(benchmark::kMillisecond)
              ->Iterations(6);
          hp::bench::with_extremes(
              benchmark::RegisterBenchmark(("Trace/" + p + "/" + short_name(spec) + suffix).c_str(), trace_pass, spec,
                                           pass, t, layout))
              ->UseManualTime()
              ->Unit(benchmark::kMillisecond)
              ->Iterations(6);
        }
      }
      hp::bench::with_extremes(
          benchmark::RegisterBenchmark(("Cpu/" + p + "/" + short_name(spec)).c_str(), cpu_pass, spec, pass))
          ->UseRealTime()
          ->Unit(benchmark::kMillisecond)
          ->Iterations(6);
      benchmark::RegisterBenchmark(("Capture/" + p + "/" + short_name(spec)).c_str(), capture_pass, spec, pass)
          ->UseManualTime()
          ->Unit(benchmark::kMillisecond)
          ->Iterations(3);
    }
  }
  return true;
}();

}  // namespace

BENCHMARK_MAIN();
