// `hybridprof render`: renders one scene and writes the final image or a G-buffer view.
#include "apps/cli_util.hpp"
#include "apps/commands.hpp"
#include "error.hpp"
#include "frame.hpp"
#include "frame_profiler.hpp"
#include "output_path.hpp"
#include "reference/reference.hpp"
#include "rt_scene.hpp"
#include "scene/load.hpp"
#include "timing/result_json.hpp"
#include "timing/timeline.hpp"
#include "vk/context.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>

namespace hp::cli {

namespace {

struct RenderArgs {
  std::string out = "frame.png";
  std::string aov = "color";
  uint32_t frames = 1;
  uint32_t warmup = 0;
  std::string timings_path, timeline_path;
  bool counters = false;
  bool overlap = false;
  uint32_t cpu_reference = 0;  ///< > 0: render the CPU reference with this many reflection samples instead
  bool quiet = false;
  FrameOptions frame;
};

// Every output path is checked before any work: a bad --timings path fails at once, not after the frames
// with the image already written.
void check_outputs(const RenderArgs& a) {
  check_image_output(a.out, "--out");
  if (!a.timings_path.empty()) check_output_path(a.timings_path, "--timings");
  if (!a.timeline_path.empty()) check_output_path(a.timeline_path, "--timeline");
}

// The converged CPU reference of the same frame (renderer/reference): no Vulkan device is needed.
void run_reference(const RenderArgs& a) {
  const Aov aov = parse_aov(a.aov);
  if (aov != Aov::color && aov != Aov::shadow) throw InputError("--cpu-reference: --aov must be color or shadow");
  const FrameSettings settings = a.frame.settings();
  Scene scene = load_scene(a.frame.scene);
  a.frame.view.apply_light(scene);
  const Camera camera = a.frame.view.camera_for(scene, float(settings.width) / float(settings.height));
  ReferenceSettings rs;
  rs.width = settings.width;
  rs.height = settings.height;
  rs.shadows = settings.rt.shadows;
  rs.reflections = settings.rt.reflections;
  rs.reflection_shadows = settings.rt.reflection_shadows;
  rs.roughness_threshold = settings.rt.roughness_threshold;
  rs.samples = a.cpu_reference;
  const ReferenceImage ref = render_reference(scene, camera, rs);
  if (aov == Aov::shadow) {
    Image4f mask(ref.shading.width, ref.shading.height);
    for (size_t i = 0; i < mask.rgba.size() / 4; ++i) {
      const float v = std::max(0.0f, ref.shading.rgba[4 * i]);
      mask.rgba[4 * i] = mask.rgba[4 * i + 1] = mask.rgba[4 * i + 2] = v;
      mask.rgba[4 * i + 3] = 1.0f;
    }
    write_image(a.out, mask);
  } else {
    write_image(a.out, ref.color);
  }
  std::printf("%s: CPU reference %ux%u, %u reflection samples per reflective pixel, %llu rays in %.2f s -> %s\n",
              scene.name.c_str(), rs.width, rs.height, rs.samples, (unsigned long long)ref.rays, ref.render_s,
              a.out.c_str());
}

void print_overlap(const OverlapSummary& o, TimingSource source) {
  auto ci = [](const MedianCi& c, double scale, const char* unit) {
    char b[96];
    if (c.valid)
      std::snprintf(b, sizeof b, " [%.3f%s, %.3f%s]", c.low * scale, unit, c.high * scale, unit);
    else
      std::snprintf(b, sizeof b, " (too few pairs for a 95%% CI)");
    return std::string(b);
  };
  std::printf("  frame as recorded (passes free to overlap, %s): %.3f ms%s; serialized passes sum %.3f ms\n",
              source == TimingSource::CpuWall ? "one submission, host clock" : "timestamps at its ends only",
              o.overlapped_frame_ns.median * 1e-6, ci(o.overlapped_frame_ns.median_ci, 1e-6, "").c_str(),
              o.serialized_sum_ns.median * 1e-6);
  if (o.saving_ns && o.saving_fraction) {
    std::printf("  overlap saves %.3f ms%s, %.2f%%%s of the serialized sum (paired over %u frames)\n",
                *o.saving_ns * 1e-6, ci(o.saving_ns_ci, 1e-6, "").c_str(), *o.saving_fraction * 100.0,
                ci(o.saving_fraction_ci, 100.0, "%").c_str(), o.frames);
  }
}

void run_render(const RenderArgs& a) {
  check_outputs(a);
  if (a.cpu_reference > 0) return run_reference(a);
  const Aov aov = parse_aov(a.aov);
  FrameSettings settings = a.frame.settings();
  settings.rt.counters = a.counters;
  Scene scene = load_scene(a.frame.scene);
  a.frame.view.apply_light(scene);
  const Camera camera = a.frame.view.camera_for(scene, float(settings.width) / float(settings.height));
  vk::Context ctx({a.frame.device, a.frame.validate, true});
  Frame frame(ctx, scene, camera, settings);
  if (!frame.timestamps_supported())
    std::fprintf(stderr, "hybridprof: %s\n", host_timing_note(settings.host_timing).c_str());
  const auto t0 = std::chrono::steady_clock::now();
  ProfileOptions po;
  po.warmup = a.warmup;
  po.frames = a.frames;
  // The overhead of the queries is measured only when a timing result is asked for (it doubles the frames).
  po.measure_query_overhead = !a.timings_path.empty();
  // So is the frame as the application records it (serialized passes would otherwise hide any overlap).
  po.measure_overlap = a.overlap || !a.timings_path.empty() || !a.timeline_path.empty();
  Progress progress("hybridprof render: frames", a.quiet);
  po.on_frame = [&](uint32_t done, uint32_t total) { progress.update(done, total); };
  const FrameTimings timings = profile_frames(frame, po);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  write_image(a.out, frame.read_aov(aov));
  const TimingSummary summary = timings.summarize();
  if (!a.timings_path.empty()) {
    write_timing_result(a.timings_path, capture_environment(describe_device(ctx)), timings);
  }
  if (!a.timeline_path.empty()) write_timeline(a.timeline_path, timings);
  if (ctx.validation_enabled() && ctx.validation_message_count() > 0) {
    throw std::runtime_error(std::to_string(ctx.validation_message_count()) +
                             " validation message(s); last: " + ctx.last_validation_message());
  }
  std::printf("%s: %zu triangles, %ux%u on %s (driver %s %s), %u frame(s) in %.1f ms (CPU wall) -> %s\n",
              scene.name.c_str(), triangle_count(scene), settings.width, settings.height, ctx.info().name.c_str(),
              ctx.info().driver_name.c_str(), ctx.info().driver_version.c_str(), a.frames, ms, a.out.c_str());
  std::printf(
      "%u warm-up + %u measured frames (%s), passes %s, %u samples accumulated; per pass: median [95%% CI] ms\n",
      a.warmup, a.frames, std::string(to_string(summary.source)).c_str(),
      std::string(to_string(summary.pass_isolation)).c_str(), frame.samples_accumulated());
  for (const auto& p : summary.passes) {
    std::printf("  %-12s %8.3f [%8.3f, %8.3f]%s\n", p.pass.c_str(), p.duration_ns.median * 1e-6,
                p.duration_ns.median_ci.low * 1e-6, p.duration_ns.median_ci.high * 1e-6,
                p.duration_ns.median_ci.valid ? "" : " (too few frames for a 95% CI: full range)");
  }
  if (const AccelStructure* as = frame.accel_structure()) {
    std::printf("  %s\n", describe_accel(as->stats(), as->order(), as->layout()).c_str());
  }
  if (summary.overlap) print_overlap(*summary.overlap, summary.source);
  if (summary.query_overhead) {
    const QueryOverhead& q = *summary.query_overhead;
    // The paired estimate, with its CI, first: the ratio of the two sides' medians has no interval and
    // mostly follows the machine's drift (docs/timing.md, "Query overhead").
    std::printf("  timestamp query overhead:");
    if (q.paired_fraction) {
      std::printf(" %.3f%% [%.3f%%, %.3f%%]%s of the CPU wall time per frame, paired over %u frame pairs;",
                  100.0 * *q.paired_fraction, 100.0 * q.paired_fraction_ci.low, 100.0 * q.paired_fraction_ci.high,
                  q.paired_fraction_ci.valid ? " (95% CI)" : " (range: too few pairs for a 95% CI)", q.frames);
    }
    std::printf(" ratio of medians %.3f%% (no interval; drift-prone)\n", 100.0 * q.overhead_fraction());
  }
  const Counters total = timings.total_counters();
  for (const char* pass : {"shadows", "reflections"}) {
    if (!a.counters) break;
    std::printf("  %-12s rays %llu, nodes visited %llu, triangles tested %llu (over %u frames)\n", pass,
                (unsigned long long)total.get(pass, counter::rays_cast),
                (unsigned long long)total.get(pass, counter::nodes_visited),
                (unsigned long long)total.get(pass, counter::triangles_tested), a.frames);
    if (settings.rt.traversal != Traversal::compute) {
      std::printf("  %-12s (the driver's traversal: its nodes and triangles are not visible, not counted)\n", "");
    }
  }
  if (!timings.frame_invocations().empty()) {
    std::printf("  compute invocations per frame (pipeline statistics, counted in an untimed frame):");
    const char* sep = " ";
    for (const auto& [pass, names] : timings.frame_invocations().passes()) {
      std::printf("%s%s %llu", sep, pass.c_str(), (unsigned long long)names.at(counter::compute_invocations));
      sep = ", ";
    }
    std::printf("\n");
  }
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand("render", "render a scene and write the image (or a G-buffer view)");
  args->frame.add_to(cmd);
  cmd->add_option("--out", args->out, "output image: .png (display-referred sRGB) or .exr (linear float)")
      ->capture_default_str();
  cmd->add_option("--aov", args->aov,
                  "what to write: color, depth, normal, albedo, roughness, metallic, shadow, reflection")
      ->capture_default_str();
  cmd->add_option("--frames", args->frames,
                  "measured frames (accumulated; the last one is written; with --timings, as many frames without "
                  "queries are interleaved and accumulate too; frames timed for --overlap repeat a measured frame's "
                  "sample and leave the accumulation unchanged)")
      ->check(CLI::Range(1u, 100000u))
      ->capture_default_str();
  cmd->add_flag("--quiet", args->quiet, "no progress lines on stderr");
  cmd->add_option("--warmup", args->warmup, "frames rendered and discarded before the measured ones")
      ->check(CLI::Range(0u, 100000u))
      ->capture_default_str();
  auto* timings = cmd->add_option("--timings", args->timings_path,
                                  "write the timing result (JSON: environment, statistics, raw samples)");
  auto* timeline = cmd->add_option("--timeline", args->timeline_path,
                                   "write a Chrome Trace Event timeline (opens in ui.perfetto.dev)");
  auto* counters =
      cmd->add_flag("--counters", args->counters, "count rays, BVH nodes visited and triangles tested (deterministic)");
  auto* overlap = cmd->add_flag("--overlap", args->overlap,
                                "also time, beside each measured frame, the same frame without the dependencies that "
                                "serialize the timed passes (on with --timings or --timeline)");
  // The reference renders on the CPU: it has no GPU timings or counters to write.
  cmd->add_option("--cpu-reference", args->cpu_reference,
                  "render the converged CPU reference instead, with N reflection samples per pixel (no GPU needed)")
      ->check(CLI::Range(1u, 65536u))
      ->excludes(timings)
      ->excludes(timeline)
      ->excludes(counters)
      ->excludes(overlap);
  cmd->callback([args] { run_render(*args); });
}

void add_devices_command(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("devices", "list the Vulkan devices and the facts hybridprof records");
  auto json_out = std::make_shared<bool>(false);
  cmd->add_flag("--json", *json_out, "one JSON array of the devices on stdout, for scripts");
  cmd->callback([json_out] {
    const auto devices = vk::list_devices();
    if (devices.empty())
      throw DeviceError("no Vulkan device found; install lavapipe (apt-get install mesa-vulkan-drivers)");
    if (*json_out) {
      nlohmann::json list = nlohmann::json::array();
      for (size_t i = 0; i < devices.size(); ++i) {
        const auto& d = devices[i];
        std::vector<std::string> traversals = {"compute"};
        if (d.ray_query) traversals.push_back("ray-query");
        if (d.ray_tracing_pipeline) traversals.push_back("pipeline");
        list.push_back({{"index", i},
                        {"name", d.name},
                        {"type", d.type},
                        {"driver_name", d.driver_name},
                        {"driver_version", d.driver_version},
                        {"driver_info", d.driver_info},
                        {"api_version", d.api_version},
                        {"subgroup_size", d.subgroup_size},
                        {"timestamp_period_ns", d.timestamp_period_ns},
                        {"timestamp_valid_bits", d.timestamp_valid_bits},
                        {"max_storage_buffer_range", d.max_storage_buffer_range},
                        {"traversals", traversals},
                        {"traversal_division", exact_traversal_division(d.driver_name) ? "double" : "float"},
                        {"traversal_texel_reads", storage_texel_reads(d.driver_name) ? "storage" : "uniform"}});
      }
      std::printf("%s\n", list.dump(1).c_str());
      return;
    }
    for (size_t i = 0; i < devices.size(); ++i) {
      const auto& d = devices[i];
      std::printf(
          "%zu: %s [%s] driver %s %s (%s), Vulkan %s, subgroup %u, timestamp period %.3f ns (%u valid bits), "
          "max storage buffer %llu MiB, traversals: compute%s%s, traversal division: %s, traversal texel reads: %s\n",
          i, d.name.c_str(), d.type.c_str(), d.driver_name.c_str(), d.driver_version.c_str(), d.driver_info.c_str(),
          d.api_version.c_str(), d.subgroup_size, d.timestamp_period_ns, d.timestamp_valid_bits,
          static_cast<unsigned long long>(d.max_storage_buffer_range >> 20), d.ray_query ? ", ray-query" : "",
          d.ray_tracing_pipeline ? ", pipeline" : "",
          exact_traversal_division(d.driver_name) ? "double (rounded once to float)" : "float",
          storage_texel_reads(d.driver_name) ? "storage texel buffers (imageLoad)"
                                             : "uniform texel buffers (texelFetch)");
    }
  });
}

}  // namespace hp::cli
