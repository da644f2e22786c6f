// BVH benchmarks: build speed (single thread and all threads) and SAH quality against the exact full sweep
// on the ~1M-triangle built-in meshes and the shared glTF scenes; single-thread traversal throughput for
// coherent primary rays and random rays, closest and any hit: trace/... the binary reference traversal,
// trace8/... the 8-wide one (bvh8.hpp) on the same tree.
//
// Counters: Mtri/s (build), sah (cost relative to the root's area), sah_vs_sweep_% (binned cost over the
// full sweep's, minus 1), sah_largest_axis_vs_sweep_% (the same for the study's largest-axis-only rule);
// Mrays/s, nodes/ray, tris/ray, hit_% (traversal); differ_from_binary (trace8 closest: rays whose hit is not
// bit for bit the binary traversal's, counted once outside the timing; must be 0).
//
// build_scaling/<scene>/threads:2vs1 alternates one-thread and two-thread builds and reports the median of the
// pairs' ratio with its 95% interval (speedup, speedup_lo, speedup_hi), the measure of the two-thread target.
//
// With --benchmark_repetitions=N the build rows also print _min and _max (bench_extremes.hpp): the best build of
// N is the _min row's time and the _max row's Mtri/s.
//
// Scenes come from hp_scene (builtin:sphere-1m, builtin:terrain-1m, HP_SHARED_DIR/scenes/*) when it is built;
// without it, a procedural 1M-triangle sphere and terrain stand in and the shared scenes are skipped.
//
// With Embree 3 (optional: libembree-dev, found by CMake; HP_BENCH_HAVE_EMBREE), the same triangles and
// rays also go through Embree on one thread: embree/build_medium|build_high/<scene>/threads:1 (robust scene,
// rtcCommitScene) and embree/trace/<scene>/... (rtcIntersect1 / rtcOccluded1). After the runs a table
// prints ours, Embree's and ours / Embree per scene and row (medians over repetitions). disagree_per_M:
// closest hits whose triangle differs from ours, per million rays (counted once, outside the timing).
#include "../unit/bvh/bvh_test_scenes.hpp"
#include "bench_extremes.hpp"
#include "bvh/bvh.hpp"
#include "bvh/bvh8.hpp"
#include "bvh/traverse.hpp"

#include <benchmark/benchmark.h>

#include "timing/stats.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#if HP_BENCH_HAVE_SCENE
#include "scene/load.hpp"
#include "scene/scene.hpp"
#endif

#if HP_BENCH_HAVE_EMBREE
#include <embree3/rtcore.h>
#endif

#include <algorithm>
#include <cmath>
#include <limits>

namespace {

using namespace hp::bvh;

struct View {
  glm::vec3 eye, target, up;
  float vfov_deg;
};

/// One benchmark scene, with everything derived from it computed once.
struct BenchScene {
  std::string name;
  std::vector<Triangle> tris;
  View view;
  Bvh bvh;  // default build, for traversal
  LeafOrderTriangles lt;
  Bvh8 wide;  // the same tree, 8-wide
  double wide_differs_primary = 0.0, wide_differs_random = 0.0;
  double sah_sweep = 0.0, sah_binned = 0.0, sah_largest_axis = 0.0;
  std::vector<Ray> primary, random;
#if HP_BENCH_HAVE_EMBREE
  RTCScene embree = nullptr;                             // medium quality, robust: what embree/trace/* traces
  double disagree_primary = 0.0, disagree_random = 0.0;  // per million rays, closest hit
#endif
};

glm::vec3 bounds_lo(const std::vector<Triangle>& tris) {
  glm::vec3 lo(std::numeric_limits<float>::infinity());
  for (const auto& t : tris) lo = glm::min(lo, glm::min(t.v0, glm::min(t.v1, t.v2)));
  return lo;
}
glm::vec3 bounds_hi(const std::vector<Triangle>& tris) {
  glm::vec3 hi(-std::numeric_limits<float>::infinity());
  for (const auto& t : tris) hi = glm::max(hi, glm::max(t.v0, glm::max(t.v1, t.v2)));
  return hi;
}

/// Coherent primary rays: one per pixel of a 512 x 512 pinhole image.
std::vector<Ray> primary_rays(const View& v) { return pinhole_rays(v.eye, v.target, v.up, v.vfov_deg, 512 * 512); }

/// Incoherent rays: origins uniform in the scene's box, directions uniform on the sphere.
std::vector<Ray> random_rays(const std::vector<Triangle>& tris) {
  const glm::vec3 lo = bounds_lo(tris), hi = bounds_hi(tris);
  std::mt19937 rng(1234);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Ray> rays(1 << 18);
  for (auto& r : rays) {
    r.origin = lo + glm::vec3(u(rng), u(rng), u(rng)) * (hi - lo);
    r.dir = hp::bvh::testing::random_dir(rng);
  }
  return rays;
}

#if HP_BENCH_HAVE_EMBREE
/// One Embree device on one thread for every Embree row.
RTCDevice embree_device() {
  static RTCDevice device = [] {
    RTCDevice d = rtcNewDevice("threads=1,set_affinity=0");
    if (!d) {
      std::fprintf(stderr, "bench_bvh: rtcNewDevice failed (error %d)\n", static_cast<int>(rtcGetDeviceError(nullptr)));
      std::exit(1);
    }
    return d;
  }();
  return device;
}

/// The scene's triangles as one Embree triangle mesh (scene order, so Embree's primID is our scene index).
RTCScene embree_scene(const std::vector<Triangle>& tris, RTCBuildQuality quality) {
  RTCDevice device = embree_device();
  RTCScene scene = rtcNewScene(device);
  rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(scene, quality);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(geom, quality);
  auto* v = static_cast<float*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * tris.size()));
  auto* idx = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), tris.size()));
  std::memcpy(v, tris.data(), tris.size() * sizeof(Triangle));
  for (std::size_t i = 0; i < 3 * tris.size(); ++i) idx[i] = static_cast<unsigned>(i);
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene);
  return scene;
}

RTCRayHit embree_ray(const Ray& r) {
  RTCRayHit rh;
  rh.ray.org_x = r.origin.x;
  rh.ray.org_y = r.origin.y;
  rh.ray.org_z = r.origin.z;
  rh.ray.tnear = r.tmin;
  rh.ray.dir_x = r.dir.x;
  rh.ray.dir_y = r.dir.y;
  rh.ray.dir_z = r.dir.z;
  rh.ray.time = 0.0f;
  rh.ray.tfar = r.tmax;
  rh.ray.mask = 0xffffffffu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

/// Closest hits whose triangle differs from the reference traversal's, per million rays.
double embree_disagreement(const BenchScene& s, const std::vector<Ray>& rays) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  std::size_t differ = 0;
  for (const Ray& r : rays) {
    RTCRayHit rh = embree_ray(r);
    rtcIntersect1(s.embree, &ctx, &rh);
    const int32_t theirs = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? -1 : static_cast<int32_t>(rh.hit.primID);
    differ += theirs != intersect_closest(s.bvh, s.lt, r).prim;
  }
  return 1e6 * static_cast<double>(differ) / static_cast<double>(rays.size());
}
#endif

/// Rays whose 8-wide closest hit is not bit for bit the binary traversal's.
double wide_differences(const BenchScene& s, const std::vector<Ray>& rays) {
  std::size_t differ = 0;
  for (const Ray& r : rays) {
    const Hit a = intersect_closest(s.bvh, s.lt, r), b = intersect_closest(s.wide, r);
    differ += std::memcmp(&a, &b, sizeof(Hit)) != 0;
  }
  return static_cast<double>(differ);
}

std::unique_ptr<BenchScene> prepare(std::string name, std::vector<Triangle> tris, View view) {
  auto s = std::make_unique<BenchScene>();
  s->name = std::move(name);
  s->tris = std::move(tris);
  s->view = view;
  BuildOptions sweep;
  sweep.full_sweep = true;
  s->sah_sweep = bvh_stats(build_bvh(s->tris, sweep)).sah_cost;
  BuildOptions largest;
  largest.all_axes = false;
  s->sah_largest_axis = bvh_stats(build_bvh(s->tris, largest)).sah_cost;
  s->bvh = build_bvh(s->tris, BuildOptions{});
  s->sah_binned = bvh_stats(s->bvh).sah_cost;
  s->lt = leaf_order(s->bvh, s->tris);
  s->wide = make_bvh8(s->bvh, s->lt);
  s->primary = primary_rays(view);
  s->random = random_rays(s->tris);
  s->wide_differs_primary = wide_differences(*s, s->primary);
  s->wide_differs_random = wide_differences(*s, s->random);
#if HP_BENCH_HAVE_EMBREE
  s->embree = embree_scene(s->tris, RTC_BUILD_QUALITY_MEDIUM);
  s->disagree_primary = embree_disagreement(*s, s->primary);
  s->disagree_random = embree_disagreement(*s, s->random);
#endif
  return s;
}

#if HP_BENCH_HAVE_SCENE
std::unique_ptr<BenchScene> from_spec(const std::string& name, const std::string& spec) {
  const hp::Scene scene = hp::load_scene(spec);
  const hp::WorldGeometry world = hp::world_geometry(scene);
  const hp::Camera cam = scene.has_camera ? scene.camera : hp::auto_frame(scene, 1.0f);
  return prepare(name, make_triangles(world.positions, world.indices),
                 View{cam.position, cam.target, cam.up, cam.vfov_deg});
}
#endif

std::vector<std::unique_ptr<BenchScene>> load_scenes() {
  std::vector<std::unique_ptr<BenchScene>> scenes;
#if HP_BENCH_HAVE_SCENE
  scenes.push_back(from_spec("sphere-1m", "builtin:sphere-1m"));
  scenes.push_back(from_spec("terrain-1m", "builtin:terrain-1m"));
  const std::filesystem::path shared = std::filesystem::path(HP_SHARED_DIR) / "scenes";
  if (std::filesystem::is_directory(shared)) {
    std::map<std::string, std::string> found;  // sorted, so the order is stable
    for (const auto& dir : std::filesystem::directory_iterator(shared)) {
      if (!dir.is_directory()) continue;
      for (const auto& f : std::filesystem::directory_iterator(dir.path())) {
        const auto ext = f.path().extension();
        if (ext == ".gltf" || ext == ".glb") found[dir.path().filename().string()] = f.path().string();
      }
    }
    for (const auto& [name, path] : found) scenes.push_back(from_spec(name, path));
  } else {
    std::fprintf(stderr, "bench_bvh: %s not found, shared scenes skipped\n", shared.string().c_str());
  }
#else
  const auto frame_bounds = [](const std::vector<Triangle>& tris) {
    const glm::vec3 lo = bounds_lo(tris), hi = bounds_hi(tris);
    const glm::vec3 c = 0.5f * (lo + hi);
    const float r = 0.5f * glm::length(hi - lo);
    return View{c + r * glm::normalize(glm::vec3(0.6f, 0.5f, 1.0f)) * 2.2f, c, glm::vec3(0, 1, 0), 45.0f};
  };
  std::fprintf(stderr, "bench_bvh: built without hp_scene: procedural meshes only, shared scenes skipped\n");
  {
    auto tris = hp::bvh::testing::uv_sphere(708, 708).triangles();
    View v = frame_bounds(tris);
    scenes.push_back(prepare("sphere-1m", std::move(tris), v));
  }
  {
    auto tris = hp::bvh::testing::terrain(708).triangles();
    View v = frame_bounds(tris);
    scenes.push_back(prepare("terrain-1m", std::move(tris), v));
  }
#endif
  return scenes;
}

void build_bench(benchmark::State& state, const BenchScene* s, int threads, bool full_sweep) {
  BuildOptions o;
  o.threads = threads;
  o.full_sweep = full_sweep;
  double sah = 0.0;
  for (auto _ : state) {
    Bvh b = build_bvh(s->tris, o);
    benchmark::DoNotOptimize(b.nodes.data());
    state.PauseTiming();
    sah = bvh_stats(b).sah_cost;
    state.ResumeTiming();
  }
  const double iters = static_cast<double>(state.iterations());
  state.counters["Mtri/s"] =
      benchmark::Counter(static_cast<double>(s->tris.size()) * iters / 1e6, benchmark::Counter::kIsRate);
  state.counters["triangles"] = static_cast<double>(s->tris.size());
  state.counters["sah"] = sah;
  state.counters["sah_vs_sweep_%"] = 100.0 * (sah / s->sah_sweep - 1.0);
  if (!full_sweep) state.counters["sah_largest_axis_vs_sweep_%"] = 100.0 * (s->sah_largest_axis / s->sah_sweep - 1.0);
}

/// The name of a scene's scaling row: what it is registered as and what print_scaling() lists it as.
std::string scaling_row(const BenchScene& s, int threads) {
  return "build_scaling/" + s.name + "/threads:" + std::to_string(threads) + "vs1";
}

/// Every pair of scaling_bench, per row, over all repetitions: one-thread and N-thread wall times (ms).
struct ScalingPairs {
  std::vector<double> one, many;
};
std::map<std::string, ScalingPairs>& scaling_pairs() {
  static std::map<std::string, ScalingPairs> pairs;
  return pairs;
}

/// Each pair's one-thread / N-thread ratio.
std::vector<double> pair_ratios(const std::vector<double>& one, const std::vector<double>& many) {
  std::vector<double> ratio(one.size());
  for (std::size_t i = 0; i < ratio.size(); ++i) ratio[i] = one[i] / many[i];
  return ratio;
}

/// Two-thread scaling by alternation: each iteration builds the scene once on one thread and once on `threads`
/// (the order alternating, wall time each), so both builds of a pair see the same minutes of a noisy host.
/// speedup is the median of the pairs' one-thread / N-thread ratios, speedup_lo and speedup_hi its 95%
/// order-statistic interval; ms_1thread and ms_Nthreads the medians. print_scaling() pools the repetitions.
void scaling_bench(benchmark::State& state, const BenchScene* s, int threads) {
  BuildOptions one, many;
  one.threads = 1;
  many.threads = threads;
  const auto wall_ms = [&](const BuildOptions& o) {
    const auto start = std::chrono::steady_clock::now();
    Bvh b = build_bvh(s->tris, o);
    benchmark::DoNotOptimize(b.nodes.data());
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  };
  std::vector<double> t1, tn;
  for (auto _ : state) {
    const bool many_first = t1.size() % 2 == 1;
    const double first = wall_ms(many_first ? many : one);
    const double second = wall_ms(many_first ? one : many);
    t1.push_back(many_first ? second : first);
    tn.push_back(many_first ? first : second);
  }
  ScalingPairs& pooled = scaling_pairs()[scaling_row(*s, threads)];
  pooled.one.insert(pooled.one.end(), t1.begin(), t1.end());
  pooled.many.insert(pooled.many.end(), tn.begin(), tn.end());
  const hp::Summary r = hp::summarize(pair_ratios(t1, tn));
  state.counters["speedup"] = r.median;
  state.counters["speedup_lo"] = r.median_ci.low;
  state.counters["speedup_hi"] = r.median_ci.high;
  state.counters["ms_1thread"] = hp::quantile(t1, 0.5);
  state.counters["ms_" + std::to_string(threads) + "threads"] = hp::quantile(tn, 0.5);
}

/// After the runs: each scaling row's pairs pooled over its repetitions.
void print_scaling() {
  if (scaling_pairs().empty()) return;
  std::printf(
      "\nbuild scaling, pairs pooled over repetitions (wall time; median and 95%% interval of one / two "
      "threads)\n");
  std::printf("%-44s %6s %11s %11s %8s %16s\n", "row", "pairs", "1 thread ms", "2 threads ms", "speedup",
              "95% interval");
  for (const auto& [row, p] : scaling_pairs()) {
    const hp::Summary r = hp::summarize(pair_ratios(p.one, p.many));
    std::printf("%-44s %6zu %11.1f %11.1f %8.3f %7.3f - %6.3f\n", row.c_str(), r.count, hp::quantile(p.one, 0.5),
                hp::quantile(p.many, 0.5), r.median, r.median_ci.low, r.median_ci.high);
  }
}

void trace_bench(benchmark::State& state, const BenchScene* s, bool primary, bool any, bool wide) {
  const std::vector<Ray>& rays = primary ? s->primary : s->random;
  TraversalStats ts;
  std::size_t hits = 0;
  for (auto _ : state) {
    ts = TraversalStats{};
    hits = 0;
    if (wide) {
      for (const Ray& r : rays)
        hits += (any ? intersect_any(s->wide, r, &ts) : intersect_closest(s->wide, r, &ts)).hit();
    } else {
      for (const Ray& r : rays) {
        hits += (any ? intersect_any(s->bvh, s->lt, r, &ts) : intersect_closest(s->bvh, s->lt, r, &ts)).hit();
      }
    }
    benchmark::DoNotOptimize(hits);
  }
  const double n = static_cast<double>(rays.size());
  state.counters["Mrays/s"] =
      benchmark::Counter(n * static_cast<double>(state.iterations()) / 1e6, benchmark::Counter::kIsRate);
  state.counters["nodes/ray"] = static_cast<double>(ts.nodes_visited) / n;
  state.counters["tris/ray"] = static_cast<double>(ts.triangles_tested) / n;
  state.counters["hit_%"] = 100.0 * static_cast<double>(hits) / n;
  if (wide && !any) state.counters["differ_from_binary"] = primary ? s->wide_differs_primary : s->wide_differs_random;
}

#if HP_BENCH_HAVE_EMBREE
void embree_build_bench(benchmark::State& state, const BenchScene* s, RTCBuildQuality quality) {
  for (auto _ : state) {
    RTCScene scene = embree_scene(s->tris, quality);
    state.PauseTiming();
    rtcReleaseScene(scene);
    state.ResumeTiming();
  }
  const double iters = static_cast<double>(state.iterations());
  state.counters["Mtri/s"] =
      benchmark::Counter(static_cast<double>(s->tris.size()) * iters / 1e6, benchmark::Counter::kIsRate);
  state.counters["triangles"] = static_cast<double>(s->tris.size());
}

void embree_trace_bench(benchmark::State& state, const BenchScene* s, bool primary, bool any) {
  const std::vector<Ray>& rays = primary ? s->primary : s->random;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  std::size_t hits = 0;
  for (auto _ : state) {
    hits = 0;
    for (const Ray& r : rays) {
      RTCRayHit rh = embree_ray(r);
      if (any) {
        rtcOccluded1(s->embree, &ctx, &rh.ray);
        hits += rh.ray.tfar < 0.0f;  // Embree marks an occluded ray with tfar = -inf
      } else {
        rtcIntersect1(s->embree, &ctx, &rh);
        hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      }
    }
    benchmark::DoNotOptimize(hits);
  }
  const double n = static_cast<double>(rays.size());
  state.counters["Mrays/s"] =
      benchmark::Counter(n * static_cast<double>(state.iterations()) / 1e6, benchmark::Counter::kIsRate);
  state.counters["hit_%"] = 100.0 * static_cast<double>(hits) / n;
  if (!any) state.counters["disagree_per_M"] = primary ? s->disagree_primary : s->disagree_random;
}

/// Which row of the ratio table a registered benchmark belongs to, and as whose figure.
struct PairKey {
  std::string row;  // "build/sphere-1m/threads:1", "trace/sphere-1m/primary/closest"
  std::string who;  // ours: "binned", "binary", "8-wide"; Embree's: "embree", "embree medium", "embree high"
  std::string counter;
};
std::map<std::string, PairKey>& pair_keys() {
  static std::map<std::string, PairKey> keys;
  return keys;
}

/// The console output plus, at the end, ours vs Embree per row: medians of the runs' rate counters.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& run : runs) {
      if (run.run_type != Run::RT_Iteration || run.error_occurred) continue;
      const auto key = pair_keys().find(run.run_name.function_name);
      if (key == pair_keys().end()) continue;
      const auto c = run.counters.find(key->second.counter);
      if (c != run.counters.end()) values_[key->second.row][key->second.who].push_back(c->second.value);
    }
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    if (values_.empty()) return;
    std::printf("\nours vs Embree %d.%d.%d (one thread each; medians of the runs above)\n", RTC_VERSION_MAJOR,
                RTC_VERSION_MINOR, RTC_VERSION_PATCH);
    std::printf("%-40s %-8s %-14s %10s %10s %7s\n", "row", "ours", "embree", "ours", "embree", "ratio");
    for (auto& [row, by] : values_) {
      for (auto& [ours, ov] : by) {
        if (ours.rfind("embree", 0) == 0) continue;
        const double o = hp::quantile(ov, 0.5);
        for (auto& [theirs, tv] : by) {
          if (theirs.rfind("embree", 0) != 0) continue;
          const double e = hp::quantile(tv, 0.5);
          std::printf("%-40s %-8s %-14s %10.3f %10.3f %7.2f\n", row.c_str(), ours.c_str(), theirs.c_str(), o, e,
                      e > 0.0 ? o / e : 0.0);
        }
      }
    }
  }

 private:
  std::map<std::string, std::map<std::string, std::vector<double>>> values_;
};
#endif

#if HP_BENCH_HAVE_SCENE
// Generating a built-in 1M-triangle scene (it was a timed unit test once; speed belongs here).
void generate_bench(benchmark::State& state, const char* spec) {
  for (auto _ : state) benchmark::DoNotOptimize(hp::load_scene(spec).meshes.data());
}
#endif

}  // namespace

int main(int argc, char** argv) {
  // The ratio and scaling tables ride on the console output; another --benchmark_format keeps stdout its own.
  bool console = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--benchmark_format=", 0) == 0 && a != "--benchmark_format=console") console = false;
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  const auto scenes = load_scenes();
  const int all = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (const auto& sp : scenes) {
    const BenchScene* s = sp.get();
    // Single-thread builds report CPU time (robust to other load on the machine); threaded ones wall time.
    hp::bench::with_extremes(
        benchmark::RegisterBenchmark(("build/" + s->name + "/threads:1").c_str(), build_bench, s, 1, false))
        ->Unit(benchmark::kMillisecond);
    hp::bench::with_extremes(
        benchmark::RegisterBenchmark(("build/" + s->name + "/threads:" + std::to_string(all)).c_str(), build_bench, s,
                                     all, false))
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    // The two-thread target is a ratio to the one-thread rate: measured pairwise (the rows above run minutes
    // apart when repetitions are not interleaved).
    benchmark::RegisterBenchmark(scaling_row(*s, 2).c_str(), scaling_bench, s, 2)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(12);
    benchmark::RegisterBenchmark(("build_full_sweep/" + s->name + "/threads:" + std::to_string(all)).c_str(),
                                 build_bench, s, all, true)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(1);
    for (const bool primary : {true, false}) {
      for (const bool any : {false, true}) {
        const std::string name =
            std::string("trace/") + s->name + (primary ? "/primary" : "/random") + (any ? "/any" : "/closest");
        const std::string wide = "trace8/" + name.substr(6);
        benchmark::RegisterBenchmark(name.c_str(), trace_bench, s, primary, any, false)->Unit(benchmark::kMillisecond);
        benchmark::RegisterBenchmark(wide.c_str(), trace_bench, s, primary, any, true)->Unit(benchmark::kMillisecond);
#if HP_BENCH_HAVE_EMBREE
        const std::string theirs = "embree/" + name;
        benchmark::RegisterBenchmark(theirs.c_str(), embree_trace_bench, s, primary, any)
            ->Unit(benchmark::kMillisecond);
        pair_keys()[name] = PairKey{name, "binary", "Mrays/s"};
        pair_keys()[wide] = PairKey{name, "8-wide", "Mrays/s"};
        pair_keys()[theirs] = PairKey{name, "embree", "Mrays/s"};
#endif
      }
    }
#if HP_BENCH_HAVE_EMBREE
    const std::string ours_build = "build/" + s->name + "/threads:1";
    pair_keys()[ours_build] = PairKey{ours_build, "binned", "Mtri/s"};
    for (const auto& [quality, label] :
         {std::pair{RTC_BUILD_QUALITY_MEDIUM, "medium"}, std::pair{RTC_BUILD_QUALITY_HIGH, "high"}}) {
      const std::string name = std::string("embree/build_") + label + "/" + s->name + "/threads:1";
      benchmark::RegisterBenchmark(name.c_str(), embree_build_bench, s, quality)->Unit(benchmark::kMillisecond);
      pair_keys()[name] = PairKey{ours_build, std::string("embree ") + label, "Mtri/s"};
    }
#endif
  }
#if HP_BENCH_HAVE_SCENE
  for (const char* spec : {"builtin:sphere-1m", "builtin:terrain-1m"}) {
    benchmark::RegisterBenchmark((std::string("generate/") + (spec + 8)).c_str(), generate_bench, spec)
        ->Unit(benchmark::kMillisecond);
  }
#endif
#if HP_BENCH_HAVE_EMBREE
  if (console) {
    RatioReporter reporter;
    benchmark::RunSpecifiedBenchmarks(&reporter);
  } else {
    benchmark::RunSpecifiedBenchmarks();
  }
  for (const auto& sp : scenes) rtcReleaseScene(sp->embree);
  rtcReleaseDevice(embree_device());
#else
  benchmark::RunSpecifiedBenchmarks();
#endif
  if (console) print_scaling();
  benchmark::Shutdown();
  return 0;
}
