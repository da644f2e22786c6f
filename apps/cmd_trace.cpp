// `hybridprof trace`: renders a frame with the chosen ray-tracing passes instrumented and writes every
// memory access they make to a trace file (streamed slice by slice), optionally exporting one compute
// unit's coalesced request stream in Dinero IV format.
#include "apps/cli_util.hpp"
#include "apps/commands.hpp"
#include "atomic_file.hpp"
#include "cachesim/preset.hpp"
#include "cachesim/simulator.hpp"
#include "error.hpp"
#include "frame.hpp"
#include "output_path.hpp"
#include "scene/load.hpp"
#include "vk/context.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace hp::cli {

namespace {

struct TraceArgs {
  FrameOptions frame;
  std::string out;
  std::string passes = "shadows,reflections";
  uint32_t sample_every = 1;
  uint32_t sample_block = 1;
  uint32_t buffer_mib = 64;
  uint32_t format_version = trace::kTraceVersion;
  uint32_t frames_before = 0;
  std::string image_layout = "tiled";
  std::string image_out;
  std::string din_out, din_pass, preset = "vega56";
  uint32_t din_cu = 0;
  bool quiet = false;
};

void run_trace(const TraceArgs& a) {
  if (a.out.empty()) throw InputError("trace: --out is required (the trace file)");
  FrameSettings settings = a.frame.settings();
  CaptureOptions co;
  co.shadows = co.reflections = false;
  std::stringstream ss(a.passes);
  std::string p;
  while (std::getline(ss, p, ',')) {
    if (p == "shadows")
      co.shadows = true;
    else if (p == "reflections")
      co.reflections = true;
    else
      throw InputError("--passes: unknown pass '" + p + "' (choose shadows, reflections)");
  }
  if (co.shadows && !settings.rt.shadows) {
    throw InputError("--passes " + a.passes + ": names the shadow pass, which --no-shadows turns off");
  }
  if (co.reflections && !settings.rt.reflections) {
    throw InputError("--passes " + a.passes + ": names the reflection pass, which --no-reflections turns off");
  }
  if (settings.rt.traversal == Traversal::pipeline) {
    throw InputError(
        "--traversal pipeline: the ray-generation shaders have no instrumented variant; trace with "
        "--traversal compute or ray-query");
  }
  // Only what is traced is computed: a pass that is neither traced nor needed is not run.
  settings.rt.shadows = co.shadows || (settings.rt.shadows && !a.image_out.empty());
  settings.rt.reflections = co.reflections || (settings.rt.reflections && !a.image_out.empty());
  if (a.image_layout != "tiled" && a.image_layout != "linear") {
    throw InputError("--image-layout " + a.image_layout + ": choose tiled or linear");
  }
  co.tiled_images = a.image_layout == "tiled";
  co.final_image = !a.image_out.empty();  // the untraced passes and the composite only for --image
  co.sample_every = a.sample_every;
  co.sample_block = a.sample_block;
  co.buffer_bytes = uint64_t(a.buffer_mib) << 20;
  // The outputs, the preset and the export's CU are checked before any work, so a typo costs nothing and
  // leaves no trace file behind (the export's pass once the frame knows its passes, still before the capture).
  check_output_path(a.out, "--out");
  if (!a.image_out.empty()) check_image_output(a.image_out, "--image");
  const cachesim::Preset preset = a.din_out.empty() ? cachesim::Preset{} : cachesim::find_preset(a.preset);
  if (!a.din_out.empty()) {
    check_output_path(a.din_out, "--export-din");
    if (a.din_cu >= preset.compute_units) {
      throw InputError("--din-cu " + std::to_string(a.din_cu) + ": preset " + preset.name + " has " +
                       std::to_string(preset.compute_units) + " compute units");
    }
  }

  Scene scene = load_scene(a.frame.scene);
  a.frame.view.apply_light(scene);
  const Camera camera = a.frame.view.camera_for(scene, float(settings.width) / float(settings.height));
  vk::Context ctx({a.frame.device, a.frame.validate, true});
  Frame frame(ctx, scene, camera, settings);
  const std::vector<std::string> traced = frame.captured_pass_names(co);
  if (!a.din_out.empty() && !a.din_pass.empty() &&
      std::find(traced.begin(), traced.end(), a.din_pass) == traced.end()) {
    std::string names;
    for (const std::string& n : traced) names += (names.empty() ? "" : ", ") + n;
    throw InputError("--din-pass " + a.din_pass + ": not a traced pass (traced: " + names + ")");
  }
  for (uint32_t i = 0; i < a.frames_before; ++i) frame.render(FrameQueries::none);  // untimed: nobody reads them
  const trace::TraceHeader header = frame.trace_header(co.tiled_images);
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<CapturedPass> captured;
  {
    // Progress per pass: its workgroup rows done, and the records (16 bytes each as captured) so far.
    std::optional<Progress> progress;
    std::string current;
    co.on_slice = [&](const std::string& pass, uint64_t records, uint64_t done, uint64_t total) {
      if (pass != current) {
        current = pass;
        progress.emplace("hybridprof trace: " + pass + " rows", a.quiet);
      }
      char detail[64];
      std::snprintf(detail, sizeof(detail), "%.1f M records (%.0f MB)", double(records) / 1e6,
                    double(records) * sizeof(gpu::TraceRecord) / 1e6);
      progress->update(done, total, detail);
    };
    trace::TraceWriter writer(a.out, header, a.format_version);
    captured = frame.render_captured(co, writer);
    writer.finish();
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!a.image_out.empty()) write_image(a.image_out, frame.read_color());
  for (const CapturedPass& c : captured) {
    std::printf("%s: %llu records from %llu of %llu workgroups (%s), %u slice(s), %u re-run(s) after overflow\n",
                c.pass.c_str(), (unsigned long long)c.records, (unsigned long long)c.sampled_workgroups,
                (unsigned long long)c.workgroups,
                a.sample_every == 1 ? "all" : ("1 in " + std::to_string(a.sample_every) + " sampled").c_str(), c.slices,
                c.reruns);
  }
  std::printf("trace of %s %ux%u on %s in %.2f s -> %s\n", scene.name.c_str(), settings.width, settings.height,
              ctx.info().name.c_str(), s, a.out.c_str());
  if (settings.rt.traversal != Traversal::compute) {
    std::printf(
        "traced through the driver's acceleration structure (--traversal %s): the records are the shaders' "
        "own accesses (G-buffer, the hits' shading, outputs, compaction buffers), not the traversal's, which "
        "the driver does out of sight\n",
        to_string(settings.rt.traversal));
  }
  if (!a.din_out.empty()) {
    trace::TraceReader reader(a.out);
    // The file's passes are captured_pass_names' (checked above): the named one, or the first.
    const uint32_t pass =
        a.din_pass.empty() ? 0u : uint32_t(std::find(traced.begin(), traced.end(), a.din_pass) - traced.begin());
    if (pass >= reader.passes().size() || reader.passes()[pass].name != traced[pass]) {
      throw std::logic_error("trace: the capture's passes are not captured_pass_names'");
    }
    AtomicFile out(a.din_out);
    const uint64_t lines = cachesim::export_din(
        out.stream(), preset, reader.header(), reader.passes()[pass],
        [&](cachesim::Simulator& sim) { cachesim::feed_slices(sim, reader, pass); }, a.din_cu);
    out.commit();
    std::printf("Dinero export: %llu requests of CU %u (%s, pass %s) -> %s\n", (unsigned long long)lines, a.din_cu,
                preset.name.c_str(), reader.passes()[pass].name.c_str(), a.din_out.c_str());
  }
}

}  // namespace

void add_trace_command(CLI::App& app) {
  auto a = std::make_shared<TraceArgs>();
  CLI::App* cmd = app.add_subcommand("trace", "record every memory access of the ray-tracing passes to a trace file");
  a->frame.add_to(cmd);
  cmd->add_option("--out", a->out, "trace file to write (binary; the format is in profiler/trace/trace_file.hpp)");
  cmd->add_flag("--quiet", a->quiet, "no progress lines on stderr");
  cmd->add_option("--passes", a->passes, "passes to trace: shadows, reflections (comma-separated)")
      ->capture_default_str();
  cmd->add_option("--sample-every", a->sample_every, "record every k-th workgroup burst (in dispatch order)")
      ->check(CLI::Range(1u, 0xFFFFFu))
      ->capture_default_str();
  cmd->add_option("--sample-block", a->sample_block,
                  "workgroups per sampled burst (power of two <= 2048): every k-th burst is recorded")
      ->capture_default_str();
  cmd->add_option("--trace-buffer-mib", a->buffer_mib, "GPU trace buffer per slice (bounded by maxStorageBufferRange)")
      ->check(CLI::Range(1u, 4096u))
      ->capture_default_str();
  cmd->add_option("--trace-format", a->format_version,
                  "trace file format: 2 (compact records, about 3 bytes each) or 1 (16 bytes a record)")
      ->check(CLI::IsMember({1u, 2u}))
      ->capture_default_str();
  cmd->add_option("--frames-before", a->frames_before, "untraced frames rendered first (accumulation state)")
      ->check(CLI::Range(0u, 100000u));
  cmd->add_option("--image-layout", a->image_layout, "how images map to addresses: tiled (8x8 texel tiles) or linear")
      ->capture_default_str();
  cmd->add_option("--image", a->image_out, "also write the traced frame's image (equal to an untraced frame's)");
  auto* din = cmd->add_option("--export-din", a->din_out, "write one CU's coalesced request stream as Dinero IV text");
  // The export's options mean nothing without the export: given alone they are an error, not ignored.
  cmd->add_option("--din-pass", a->din_pass, "pass to export (default: the first traced)")->needs(din);
  cmd->add_option("--din-cu", a->din_cu, "compute unit to export")->capture_default_str()->needs(din);
  cmd->add_option("--preset", a->preset, "GPU preset for the export's wave width, CUs and coalescing")
      ->capture_default_str()
      ->needs(din);
  cmd->callback([a] { run_trace(*a); });
}

}  // namespace hp::cli
