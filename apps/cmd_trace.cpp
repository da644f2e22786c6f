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
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace hp::cli {

namespace fs = std::filesystem;

namespace {

// Whether the rest of a pass whose first `done` of `total` rows took `pass_bytes` fits in `available` bytes,
// projected linearly from those rows, with a reserve so that a capture never fills the disk to its last byte.
struct TraceSpaceCheck {
  uint64_t projected_pass_bytes = 0, needed_bytes = 0, available_bytes = 0;
  bool fits = true;
};

TraceSpaceCheck check_trace_space(uint64_t pass_bytes, uint64_t done, uint64_t total, uint64_t available) {
  constexpr uint64_t kReserveBytes = 4ull << 20;
  TraceSpaceCheck c;
  c.available_bytes = available;
  c.projected_pass_bytes = done == 0 ? pass_bytes : uint64_t(double(pass_bytes) * double(total) / double(done) + 0.5);
  c.needed_bytes = c.projected_pass_bytes > pass_bytes ? c.projected_pass_bytes - pass_bytes : 0;
  c.fits = done >= total || c.needed_bytes + kReserveBytes <= available;
  return c;
}

struct TraceArgs {
  FrameOptions frame;
  std::string out;
  std::string passes = "shadows,reflections";
  uint32_t sample_every = 1;
  uint32_t sample_block = 1;
  uint32_t buffer_mib = 0;
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
  co.buffer_bytes = uint64_t(a.buffer_mib) << 20;  // 0: the default
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
    trace::TraceWriter writer(a.out, header, a.format_version);
    // Progress per pass: its workgroup rows done, and the records and bytes written so far. A trace's size is known only as
    // it is captured, so after every slice the pass's size is projected from its rows done, said on the
    // pass's first slice, and checked against the free space of --out's folder: a capture that cannot fit
    // stops there, with the projection, instead of filling the disk (the writer then removes its file).
    std::optional<Progress> progress;
    std::string current;
    uint64_t pass_start_bytes = 0;
    const fs::path folder = fs::absolute(fs::path(a.out)).parent_path();
    co.on_slice = [&](const std::string& pass, uint64_t records, uint64_t done, uint64_t total) {
      const uint64_t written = writer.bytes_written();
      const bool first = pass != current;
      if (first) {
        current = pass;
        progress.emplace("hybridprof trace: " + pass + " rows", a.quiet);
      }
      const uint64_t pass_bytes = written - pass_start_bytes;
      const TraceSpaceCheck c = check_trace_space(pass_bytes, done, total, fs::space(folder).available);
      if (first && !a.quiet && done < total) {
        std::fprintf(stderr, "hybridprof trace: %s: about %s projected from %llu of %llu rows, %s free in %s\n",
                     pass.c_str(), format_bytes(c.projected_pass_bytes).c_str(), (unsigned long long)done,
                     (unsigned long long)total, format_bytes(c.available_bytes).c_str(), folder.c_str());
      }
      if (!c.fits) {
        throw InputError("--out " + a.out + ": the " + pass + " pass projects to about " +
                         format_bytes(c.projected_pass_bytes) + " (from " + std::to_string(done) + " of " +
                         std::to_string(total) + " rows) and needs " + format_bytes(c.needed_bytes) + " more, but " +
                         folder.string() + " has " + format_bytes(c.available_bytes) +
                         " free; sample workgroups (--sample-every), trace a smaller frame or write elsewhere");
      }
      if (done == total) pass_start_bytes = written;
      char count[32];
      std::snprintf(count, sizeof(count), "%.1f M records (", double(records) / 1e6);
      progress->update(done, total, count + format_bytes(pass_bytes) + ")");
    };
    captured = frame.render_captured(co, writer);
    writer.finish();
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!a.image_out.empty()) write_image(a.image_out, frame.read_color());
  for (const CapturedPass& c : captured) {
    std::printf(
        "%s: %llu records from %llu of %llu workgroups (%s), %u slice(s), %u re-run(s) after overflow, %.2f s\n",
        c.pass.c_str(), (unsigned long long)c.records, (unsigned long long)c.sampled_workgroups,
        (unsigned long long)c.workgroups,
        a.sample_every == 1 ? "all" : ("1 in " + std::to_string(a.sample_every) + " sampled").c_str(), c.slices,
        c.reruns, c.seconds);
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
  cmd->add_option("--out", a->out, "trace file to write (binary; the format is in docs/formats.md)");
  cmd->add_flag("--quiet", a->quiet, "no progress lines on stderr");
  cmd->add_option("--passes", a->passes, "passes to trace: shadows, reflections (comma-separated)")
      ->capture_default_str();
  cmd->add_option("--sample-every", a->sample_every, "record every k-th workgroup burst (in dispatch order)")
      ->check(CLI::Range(1u, 0xFFFFFu))
      ->capture_default_str();
  cmd->add_option("--sample-block", a->sample_block,
                  "workgroups per sampled burst (power of two <= 2048): every k-th burst is recorded")
      ->capture_default_str();
  cmd->add_option("--trace-buffer-mib", a->buffer_mib,
                  "GPU trace buffer in four parts: the device fills one while the others are written out (0: "
                  "four parts of 64 MiB, or of the device's maxStorageBufferRange if smaller)")
      ->check(CLI::Range(0u, 4096u))
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
