// `hybridprof bvh`: builds the BVH of a scene and reports its shape and quality; optionally exports the
// scene's triangles and casts rays from a file with the reference traversal, for cross-checking against
// another ray tracer (formats in renderer/bvh/ray_io.hpp); with --gpu, casts them on the Vulkan device too,
// through the passes' own traversal, times that and checks every ray against the reference.
//   hybridprof bvh --scene S [--buckets N | --full-sweep] [--largest-axis-only] [--granularity triangle|object]
//                  [--leaf-size K] [--node-layout binary32|wide4] [--threads T] [--repeats N]
//                  [--export-triangles FILE]
//                  [--rays FILE --hits FILE [--any-hit]
//                  [--gpu [--geometry indexed|soup] [--traversal compute|ray-query|pipeline [--as-layout L]
//                  [--as-order O] [--as-compaction]] [--device D] [--validate]]]
#include "apps/cli_util.hpp"
#include "apps/commands.hpp"
#include "bvh/bvh.hpp"
#include "bvh/ray_io.hpp"
#include "bvh/traverse.hpp"
#include "error.hpp"
#include "output_path.hpp"
#include "passes/ray_batch.hpp"
#include "rt_geometry.hpp"
#include "rt_scene.hpp"
#include "scene/load.hpp"
#include "scene/scene.hpp"
#include "timing/environment.hpp"
#include "timing/stats.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace hp::cli {
namespace {

struct BvhArgs {
  std::string scene;
  int buckets = 12;
  bool full_sweep = false;
  bool largest_axis_only = false;
  std::string granularity = "triangle";
  int leaf_size = 4;
  std::string node_layout = "binary32";
  int threads = 0;
  int repeats = 1;  ///< builds and CPU casts, each timed; GPU casts after an untimed one: max(3, repeats - 1)
  std::string export_triangles;
  std::string rays;
  uint32_t make_rays = 0;  ///< write this many camera rays into --rays first
  std::string hits;
  bool any_hit = false;
  bool gpu = false;
  std::string geometry = "indexed";
  TraversalOptions traversal;
  std::string device;
  bool validate = false;
};

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// Wall times of a step run --repeats times: the first run of the process, then the later ones.
struct RunTimes {
  double first_ms = 0.0;
  std::vector<double> later_ms;
};

// Runs `step` `repeats` times, timing each run, and returns the last run's result. The clock stops before the
// previous result is dropped (freeing it is not part of the step).
template <class Step>
auto timed_runs(int repeats, RunTimes& times, Step&& step) {
  decltype(step()) last{};
  for (int i = 0; i < repeats; ++i) {
    const auto start = std::chrono::steady_clock::now();
    auto result = step();
    (i == 0 ? times.first_ms : times.later_ms.emplace_back()) = ms_since(start);
    last = std::move(result);
  }
  return last;
}

// Milliseconds to 4 decimals below 1 ms, 2 below 100 ms and 1 above: a small scene's microseconds show.
std::string ms(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", v < 1.0 ? 4 : v < 100.0 ? 2 : 1, v);
  return buf;
}

// "95% interval a-b ms" of a summary's median, or what stands in for it: the range where there are too few
// samples for the interval.
std::string median_interval(const Summary& s) {
  if (s.median_ci.valid) return "95% interval " + ms(s.median_ci.low) + "-" + ms(s.median_ci.high) + " ms";
  return "too few for a 95% interval; range " + ms(s.min) + "-" + ms(s.max) + " ms";
}

// "<step> time: ..." for `items` done per run (triangles built, rays cast). The first run of a process also
// touches its memory for the first time (page faults, and on VMs whose host reclaims freed memory, the host's
// faults too), so it is reported apart from the later runs, whose median and 95% interval (order statistics,
// hp_timing) stand for the step itself.
void print_run_time(const char* step, const RunTimes& t, std::size_t items, const char* unit, int threads) {
  const auto rate = [&](double v) { return v > 0 ? static_cast<double>(items) / v / 1e3 : 0.0; };
  static const std::string cpu = capture_environment().cpu_model;  // read once for the build and the cast lines
  const std::string on = threads == 0   ? std::string("all threads")
                         : threads == 1 ? std::string("1 thread")
                                        : std::to_string(threads) + " threads";
  if (t.later_ms.empty()) {
    std::printf(
        "%s time: %s ms (%.2f M %s/s), one %s, %s, %s; the first %s of a process also touches its memory for the "
        "first time: --repeats 7 or more gives a median with its 95%% interval\n",
        step, ms(t.first_ms).c_str(), rate(t.first_ms), unit, step, on.c_str(), cpu.c_str(), step);
    return;
  }
  const Summary s = summarize(t.later_ms);
  std::printf("%s time: %s ms (%.2f M %s/s), median of the %zu after the first (%s); the first %s ms; %s, %s\n", step,
              ms(s.median).c_str(), rate(s.median), unit, s.count, median_interval(s).c_str(), ms(t.first_ms).c_str(),
              on.c_str(), cpu.c_str());
}

// "build phases: ..." where the builds forked: where their wall time went, as medians over the same runs as the
// build time (the first apart when there are later ones). Nothing for builds that never forked (one thread, a
// small scene, the full sweep).
void print_phases(const std::vector<bvh::BuildPhases>& runs) {
  const std::span<const bvh::BuildPhases> used =
      runs.size() > 1 ? std::span<const bvh::BuildPhases>(runs).subspan(1) : std::span<const bvh::BuildPhases>(runs);
  if (used.empty() || !std::all_of(used.begin(), used.end(), [](const bvh::BuildPhases& p) { return p.forked; })) {
    return;
  }
  const auto median = [&](auto field) {
    std::vector<double> v;
    for (const bvh::BuildPhases& p : used) v.push_back(field(p));
    return summarize(v).median;
  };
  const double first = median([](const bvh::BuildPhases& p) { return p.first_ms; });
  const double second = median([](const bvh::BuildPhases& p) { return p.second_ms; });
  const double wait = median([](const bvh::BuildPhases& p) { return std::abs(p.first_ms - p.second_ms); });
  const std::string of =
      used.size() == 1 ? "the one build" : "medians of the " + std::to_string(used.size()) + " after the first";
  std::printf(
      "build phases: references %s ms; the top of the tree %s ms; below its first fork, side by side, "
      "%zu primitives in %s ms and %zu in %s ms (the one done first waited %s ms); the second's nodes appended in %s "
      "ms; the tree %s ms in all; %s\n",
      ms(median([](const bvh::BuildPhases& p) { return p.references_ms; })).c_str(),
      ms(median([](const bvh::BuildPhases& p) { return p.top_ms; })).c_str(), used.back().first_primitives,
      ms(first).c_str(), used.back().second_primitives, ms(second).c_str(), ms(wait).c_str(),
      ms(median([](const bvh::BuildPhases& p) { return p.append_ms; })).c_str(),
      ms(median([](const bvh::BuildPhases& p) { return p.tree_ms; })).c_str(), of.c_str());
}

// What `bvh` prints of the build: method, node counts, SAH cost, the leaf-size histogram.
void print_build(const BvhArgs& a, const bvh::BuildOptions& o, const bvh::Bvh& tree) {
  const bvh::BvhStats s = bvh::bvh_stats(tree);
  std::string method = a.full_sweep ? std::string("full-sweep SAH (3 axes)")
                                    : "binned SAH, " + std::to_string(a.buckets) + " buckets, " +
                                          (a.largest_axis_only ? "largest centroid axis" : "3 axes");
  std::printf("build: %s, %s granularity, leaf size <= %d\n", method.c_str(), a.granularity.c_str(), a.leaf_size);
  std::printf("nodes: %zu, leaves: %zu, primitives: %zu (%zu triangles), max depth: %d (stack %d)\n", s.nodes, s.leaves,
              s.primitives, s.triangles, s.max_depth, HP_BVH_STACK_SIZE);
  if (tree.depth_limited_splits > 0) {
    std::printf("depth bound: %zu SAH splits replaced by median splits to fit the stack\n", tree.depth_limited_splits);
  }
  if (o.granularity == bvh::Granularity::object) {
    std::printf("SAH cost: %.4f (leaf = objects), %.4f (leaf = triangles), traversal cost %.2f\n", s.sah_cost,
                s.sah_cost_triangles, o.traversal_cost);
  } else {
    std::printf("SAH cost: %.4f (traversal cost %.2f, triangle cost 1, relative to the root's area)\n", s.sah_cost,
                o.traversal_cost);
  }
  std::printf("leaf sizes:");
  for (std::size_t k = 1; k < s.leaf_size_histogram.size(); ++k) {
    if (s.leaf_size_histogram[k] == 0) continue;
    std::printf(" %zu:%zu (%.1f%%)", k, s.leaf_size_histogram[k],
                100.0 * static_cast<double>(s.leaf_size_histogram[k]) / static_cast<double>(s.leaves));
  }
  std::printf("\n");
}

// The rays through the reference traversal of the chosen node layout, --repeats times; the hits go to --hits.
void cast_on_cpu(const BvhArgs& a, const RtGeometry& g, const std::vector<bvh::Ray>& rays) {
  bvh::TraversalStats ts;
  RunTimes times;
  const std::vector<bvh::Hit> hits = timed_runs(a.repeats, times, [&] {
    ts = {};
    return cast_reference(g, rays, a.any_hit ? bvh::HitMode::any : bvh::HitMode::closest, a.threads, &ts);
  });
  bvh::write_hits(a.hits, hits);
  std::size_t hit_count = 0;
  for (const auto& h : hits) hit_count += h.hit();
  const double n = rays.empty() ? 1.0 : static_cast<double>(rays.size());
  std::printf("rays: %zu (%s, %s nodes), %zu hits (%.2f%%), %.2f nodes and %.2f triangles per ray\n", rays.size(),
              a.any_hit ? "any hit" : "closest hit", to_string(g.node_layout), hit_count,
              100.0 * static_cast<double>(hit_count) / n, static_cast<double>(ts.nodes_visited) / n,
              static_cast<double>(ts.triangles_tested) / n);
  print_run_time("cast", times, rays.size(), "rays", a.threads);
  std::printf("hits written to %s\n", a.hits.c_str());
}

// The driver traversal's answers against the reference (compare_driver_with_reference); its hits go to
// --hits. Exit 1 when more than 0.1% of the rays disagree on hit or miss, or on the closest triangle.
void report_driver_agreement(const BvhArgs& a, const DriverAgreement& d, const std::vector<RayBatchTracer::Result>& r) {
  std::vector<bvh::Hit> hits;
  hits.reserve(r.size());
  for (const auto& x : r) hits.push_back(x.hit);
  bvh::write_hits(a.hits, hits);
  for (const std::string& line : d.first_differences) std::printf("  differs: %s\n", line.c_str());
  std::printf(
      "%s vs reference: %zu of %zu rays agree (%zu hit/miss differ, %zu other triangle, %zu t beyond %.0e relative; "
      "%zu ties at the same t; largest relative t difference %.3g); %zu driver hits, %zu reference hits\n",
      a.traversal.traversal.c_str(), d.agree(), d.rays, d.hit_miss_differ, d.triangle_differ, d.t_differ, d.t_tolerance,
      d.ties, d.max_t_relative, d.gpu_hits, d.reference_hits);
  std::printf("%s hits written to %s\n", a.traversal.traversal.c_str(), a.hits.c_str());
  if (d.rays > 0 && double(d.rays - d.agree()) > 1e-3 * double(d.rays)) {
    throw std::runtime_error("bvh --gpu --traversal " + a.traversal.traversal + ": " +
                             std::to_string(d.rays - d.agree()) + " of " + std::to_string(d.rays) +
                             " rays disagree with the reference (limit 0.1%)");
  }
}

// The same rays through the passes' traversal on the device (shaders/trace_rays.comp): one untimed cast
// (pipeline compilation, caches), then max(3, --repeats - 1) timed by GPU timestamps (their median with its 95%
// interval, or their range where they are too few), and the answers checked against the
// reference: bit for bit for the compute traversal, by agreement for the driver's (ray queries or a
// ray-tracing pipeline through its acceleration structure), whose hits then go to --hits.
void trace_on_gpu(const BvhArgs& a, vk::Context& ctx, const Scene& scene, RtGeometry g,
                  const std::vector<bvh::Ray>& rays) {
  RayTracingOptions rt;
  apply_traversal_options(rt, a.traversal);
  const RtScene rts(ctx, scene, g, parse_geometry_layout(a.geometry), false);
  std::unique_ptr<AccelStructure> as;
  if (rt.traversal != Traversal::compute) {
    require_traversal(ctx, rt.traversal);
    as = std::make_unique<AccelStructure>(ctx, g, rt.as_order, rt.as_compaction, rt.as_layout, &scene);
    std::printf("%s\n", describe_accel(as->stats(), rt.as_order, rt.as_layout).c_str());
  }
  RayBatchTracer tracer(ctx, rts, rays, as.get(), rt.traversal);
  const bvh::HitMode mode = a.any_hit ? bvh::HitMode::any : bvh::HitMode::closest;
  tracer.trace(ctx, mode);
  std::vector<double> times;
  for (int i = 0; i < std::max(3, a.repeats - 1); ++i) times.push_back(double(tracer.trace(ctx, mode)) * 1e-6);
  const Summary s = summarize(times);
  if (s.median > 0.0) {
    std::printf(
        "gpu: %s, %s traversal, %s layout, %s nodes: %s ms median of %zu after an untimed first (%s) by timestamps, "
        "%.2f M rays/s\n",
        ctx.info().name.c_str(), a.traversal.traversal.c_str(), a.geometry.c_str(), to_string(g.node_layout),
        ms(s.median).c_str(), s.count, median_interval(s).c_str(), double(rays.size()) / s.median / 1e3);
  } else {
    std::printf("gpu: %s, %s traversal, %s layout: no timestamps on this queue, not timed\n", ctx.info().name.c_str(),
                a.traversal.traversal.c_str(), a.geometry.c_str());
  }
  if (rt.traversal != Traversal::compute) {
    const auto results = tracer.results(ctx);
    report_driver_agreement(a, compare_driver_with_reference(g.bvh, g.leaf, rays, mode, results), results);
    if (ctx.validation_enabled() && ctx.validation_message_count() > 0) {
      throw std::runtime_error("bvh --gpu: " + std::to_string(ctx.validation_message_count()) +
                               " validation message(s); last: " + ctx.last_validation_message());
    }
    return;
  }
  const BatchCheck check = check_against_reference(g, rays, mode, tracer.results(ctx));
  for (const std::string& d : check.first_differences) std::printf("  differs: %s\n", d.c_str());
  std::printf("gpu vs reference: %zu of %zu rays equal (hit, t, u, v bit for bit; nodes and triangles per ray)\n",
              check.rays - check.differ, check.rays);
  if (check.differ > 0) {
    throw std::runtime_error("bvh --gpu: " + std::to_string(check.differ) + " of " + std::to_string(check.rays) +
                             " rays differ from the reference traversal");
  }
  if (ctx.validation_enabled() && ctx.validation_message_count() > 0) {
    throw std::runtime_error("bvh --gpu: " + std::to_string(ctx.validation_message_count()) +
                             " validation message(s); last: " + ctx.last_validation_message());
  }
}

void run_bvh(const BvhArgs& a) {
  if (a.rays.empty() != a.hits.empty()) throw InputError("bvh: --rays and --hits go together");
  if (a.node_layout == "wide4" && a.leaf_size > 15) {
    throw InputError("bvh: --node-layout wide4 holds leaves of at most 15 primitives: --leaf-size " +
                     std::to_string(a.leaf_size));
  }
  if (a.node_layout == "wide4" && a.traversal.traversal != "compute") {
    throw InputError("bvh: --node-layout wide4 applies to --traversal compute only");
  }
  RayTracingOptions checked;
  apply_traversal_options(checked, a.traversal);  // names a bad option first
  // Outputs and the device are checked before any work: a failure leaves no file of this run behind.
  if (!a.export_triangles.empty()) check_output_path(a.export_triangles, "--export-triangles");
  if (!a.hits.empty()) check_output_path(a.hits, "--hits");
  if (a.make_rays > 0) check_output_path(a.rays, "--rays");
  std::optional<vk::Context> ctx;
  if (a.gpu) ctx.emplace(vk::ContextOptions{a.device, a.validate, true});

  const auto load_start = std::chrono::steady_clock::now();
  const Scene scene = load_scene(a.scene);
  const WorldGeometry world = world_geometry(scene);
  const std::vector<bvh::Triangle> tris = bvh::make_triangles(world.positions, world.indices);
  std::printf("scene: %s, %zu triangles, %zu instances (loaded in %.1f ms)\n", a.scene.c_str(), tris.size(),
              scene.instances.size(), ms_since(load_start));

  if (!a.export_triangles.empty()) {
    bvh::write_triangles(a.export_triangles, tris);
    std::printf("exported %zu triangles (scene order) to %s\n", tris.size(), a.export_triangles.c_str());
  }
  if (a.make_rays > 0) {
    const Camera cam = scene.has_camera ? scene.camera : auto_frame(scene, 1.0f);
    bvh::write_rays(a.rays, bvh::pinhole_rays(cam.position, cam.target, cam.up, cam.vfov_deg, a.make_rays));
    std::printf("wrote %u camera rays (a %u-wide grid over a square view of the scene's camera) to %s\n", a.make_rays,
                uint32_t(std::ceil(std::sqrt(double(a.make_rays)))), a.rays.c_str());
  }

  bvh::BuildOptions o;
  o.buckets = a.buckets;
  o.full_sweep = a.full_sweep;
  o.all_axes = !a.largest_axis_only;
  o.max_leaf_size = a.leaf_size;
  o.threads = a.threads;
  o.granularity = a.granularity == "object" ? bvh::Granularity::object : bvh::Granularity::triangle;
  const std::span<const uint32_t> objects = o.granularity == bvh::Granularity::object
                                                ? std::span<const uint32_t>(world.instance_first_triangle)
                                                : std::span<const uint32_t>();

  // Every build makes the same tree (tests/unit/bvh/build_identity_test.cpp); the last one is kept.
  RunTimes times;
  std::vector<bvh::BuildPhases> phases;
  bvh::Bvh tree = timed_runs(a.repeats, times, [&] {
    bvh::Bvh b = bvh::build_bvh(tris, o, objects);
    phases.push_back(b.phases);
    return b;
  });
  print_build(a, o, tree);
  print_run_time("build", times, tris.size(), "triangles", o.threads);
  print_phases(phases);
  RtGeometry g;
  g.node_layout = parse_node_layout(a.node_layout);
  if (g.node_layout == bvh::NodeLayout::wide4) {
    const auto wide_start = std::chrono::steady_clock::now();
    g.wide = bvh::make_wide(tree);
    std::printf("wide4: %zu nodes (%.2f MiB, binary %.2f MiB), stack <= %d entries, converted in %.2f ms\n",
                g.wide.nodes.size(), double(g.wide.nodes.size() * sizeof(gpu::WideNode)) / 1048576.0,
                double(tree.nodes.size() * sizeof(gpu::BvhNode)) / 1048576.0, g.wide.stack_need, ms_since(wide_start));
  }

  if (a.rays.empty()) return;
  const std::vector<bvh::Ray> rays = bvh::read_rays(a.rays);
  g.leaf = bvh::leaf_order(tree, tris);
  g.bvh = std::move(tree);
  // With a driver traversal --hits receives the driver's hits (trace_on_gpu), not the reference's.
  if (a.traversal.traversal == "compute") cast_on_cpu(a, g, rays);
  if (!a.gpu) return;
  g.world = world;
  g.triangles = tris;
  trace_on_gpu(a, *ctx, scene, std::move(g), rays);
}

}  // namespace

void add_bvh_command(CLI::App& app) {
  auto args = std::make_shared<BvhArgs>();
  CLI::App* cmd = app.add_subcommand("bvh", "build a scene's BVH, print its statistics, cast rays from a file");
  cmd->add_option("--scene", args->scene, "scene: builtin:NAME or a .gltf/.glb file")->required();
  auto* buckets = cmd->add_option("--buckets", args->buckets, "SAH buckets per axis (binned build)")
                      ->check(CLI::Range(2, 1024))
                      ->capture_default_str();
  auto* sweep = cmd->add_flag("--full-sweep", args->full_sweep, "exact full-sweep SAH instead of binning");
  buckets->excludes(sweep);
  cmd->add_flag("--largest-axis-only", args->largest_axis_only,
                "bin only the axis of largest centroid extent (the study's rule) instead of all three")
      ->excludes(sweep);
  cmd->add_option("--granularity", args->granularity, "triangle: one primitive per triangle; object: per instance")
      ->check(CLI::IsMember({"triangle", "object"}))
      ->capture_default_str();
  cmd->add_option("--leaf-size", args->leaf_size, "largest leaf, in primitives")
      ->check(CLI::Range(1, (1 << 30) - 1))
      ->capture_default_str();
  cmd->add_option("--node-layout", args->node_layout,
                  "nodes the traversals read: binary32 (the study's 32-byte nodes) or wide4 (64-byte 4-wide nodes, "
                  "quantized boxes, leaves of at most 15)")
      ->check(CLI::IsMember({"binary32", "wide4"}))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "build and cast threads (0 = all cores)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  cmd->add_option("--repeats", args->repeats,
                  "build the BVH, and cast the rays on the CPU, this many times each: the first run is timed apart "
                  "(it touches its memory for the first time), the later ones as a median with its 95% interval; "
                  "with --gpu, max(3, N - 1) casts are timed after an untimed one")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--export-triangles", args->export_triangles,
                  "write world-space triangles in scene order (float32 x 9 each, little-endian, no header)");
  auto* rays =
      cmd->add_option("--rays", args->rays, "cast rays from this file (float32 x 8 each: ox oy oz tmin dx dy dz tmax)");
  auto* hits = cmd->add_option("--hits", args->hits,
                               "write one hit per ray (int32 prim or -1, float32 t u v) in scene triangle order");
  rays->needs(hits);
  hits->needs(rays);
  cmd->add_option("--make-rays", args->make_rays,
                  "write this many primary rays of the scene's camera into the --rays file first, then cast them")
      ->check(CLI::Range(1u, 1u << 26))
      ->needs(rays);
  cmd->add_flag("--any-hit", args->any_hit, "occlusion query: any hit in [tmin, tmax], not the closest")->needs(rays);
  auto* gpu = cmd->add_flag("--gpu", args->gpu,
                            "also cast the rays on the Vulkan device through the passes' traversal, time it and check "
                            "every ray against the reference (exit 1 if one differs)")
                  ->needs(rays);
  cmd->add_option("--geometry", args->geometry, "GPU geometry layout: indexed (EBO) or soup")
      ->check(CLI::IsMember({"indexed", "soup"}))
      ->capture_default_str()
      ->needs(gpu);
  add_traversal_options(cmd, args->traversal);
  for (const char* name : {"--traversal", "--as-order", "--as-layout", "--as-compaction"}) {
    cmd->get_option(name)->needs(gpu);
  }
  const auto [device, validate] = add_device_options(cmd, args->device, args->validate);
  device->needs(gpu);
  validate->needs(gpu);
  cmd->callback([args] { run_bvh(*args); });
}

}  // namespace hp::cli
