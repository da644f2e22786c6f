// One hybrid frame on the GPU: owns the scene's GPU copies, the render targets and the passes, records a
// frame's command buffer with a timestamp pair around every pass, submits it and reads the timings back.
//   gbuffer (raster) -> shadows (compute) -> reflections (compute) -> accumulate -> composite
// The frame is a list of passes (frame_pass.hpp) built once from the settings (frame_passes.cpp): rendering,
// host timing, timestamps, the captured pass names and the capture (capture.cpp) all iterate it. A pass the
// settings do not ask for is neither compiled nor recorded, and no BVH is built when no ray is traced.
#pragma once

#include "accel_structure.hpp"
#include "bvh/bvh.hpp"
#include "frame_pass.hpp"
#include "frame_settings.hpp"
#include "gpu_scene.hpp"
#include "image/image.hpp"
#include "passes/accumulate_pass.hpp"
#include "passes/compaction_path.hpp"
#include "passes/composite.hpp"
#include "passes/gbuffer.hpp"
#include "passes/reflection_pass.hpp"
#include "passes/rt_resources.hpp"
#include "passes/shadow_pass.hpp"
#include "rt_scene.hpp"
#include "trace_format.hpp"
#include "view.hpp"
#include "vk/pipeline_stats.hpp"
#include "vk/timestamps.hpp"

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace hp {


/// The views `--aov` can write.
enum class Aov { color, depth, normal, albedo, roughness, metallic, shadow, reflection };
Aov parse_aov(const std::string& name);  // throws InputError listing the choices

/// The queries a frame records. Timed frames carry timestamps only: on lavapipe the pipeline statistics
/// queries around the compute passes added about 0.3% of a 640x360 frame to the timestamps' 0.4%, so the
/// invocation counts, which do not change from frame to frame, are taken in a frame of their own.
enum class FrameQueries {
  none,  ///< no query (cpu_wall_ns only): the other side of the query-overhead pairs
  /// A timestamp at each pass boundary, and before each boundary an execution dependency (ALL_COMMANDS ->
  /// ALL_COMMANDS) so that no pass starts before the previous one is done: each interval holds one pass
  /// (PassIsolation::Serialized). Without it a device that overlaps independent passes (Mesa 25 lavapipe,
  /// every GPU) lets a boundary fall inside the next pass's work.
  timestamps,
  /// The frame as the application records it: the passes with only their own dependencies, a timestamp
  /// before the first and after the last (FrameTiming::span, no pass times).
  frame_span,
  pipeline_statistics,  ///< compute invocations per compute pass, no timestamps (needs counters on)
};

/// What one frame cost. `source` says how the pass times were taken: "gpu-timestamps", or "cpu-wall"
/// (one submission per pass, timed on the host) where the queue has no timestamps.
struct FrameTiming {
  struct Pass {
    std::string name;
    uint64_t begin_ns = 0, end_ns = 0;
    uint64_t duration_ns() const { return end_ns - begin_ns; }
  };
  std::vector<Pass> passes;
  /// FrameQueries::frame_span: the frame's begin and end on the timing source's clock.
  std::optional<Pass> span;
  uint64_t cpu_wall_ns = 0;  ///< record + submit + wait, on the host
  std::string source;
  /// Compute-shader invocations per compute pass (pipeline statistics queries), when counters are on and
  /// the device supports the queries.
  std::vector<std::pair<std::string, uint64_t>> compute_invocations;
};

/// What a memory-trace capture records (Frame::render_captured).
/// Parts of the capture's trace buffer: the device fills one with a slice while the host writes the slices
/// in the others (coding them on up to three threads at once where the sink allows it and the device leaves
/// the cores free).
inline constexpr uint32_t kTraceBufferParts = 4;

/// The threads that write a capture's slices, given the host's cores and the device's CPU threads
/// (device_cpu_threads: 0 on a GPU): one per part the device is not filling, and no more than the cores the
/// device leaves free, but at least one. On lavapipe the device computes on the same cores, and a writer
/// that preempts one of its threads holds up the whole dispatch (docs/memory-traces.md).
unsigned capture_writer_threads(unsigned cores, unsigned device_threads);

struct CaptureOptions {
  bool shadows = true;        ///< trace the shadow pass (when it is enabled)
  bool reflections = true;    ///< trace the reflection pass (when it is enabled)
  uint32_t sample_every = 1;  ///< record every k-th burst of workgroups (dispatch order); 1 = all
  /// Workgroups per burst, a power of two up to 2048: consecutive workgroups are traced together, so the
  /// sampled trace keeps the sharing between neighbouring workgroups that the caches see (1 = single
  /// workgroups, the plain every-k-th sampling).
  uint32_t sample_block = 1;
  /// Trace buffer size: kTraceBufferParts parts, each a header and records and at most
  /// maxStorageBufferRange; a slice fills one part while the host writes out others. 0 = four parts of
  /// min(64 MiB, maxStorageBufferRange).
  uint64_t buffer_bytes = 0;
  /// Workgroup units (rows, or groups of a 1D pass) of a pass's first slice. 0 = automatic: the whole pass
  /// where 32 records per traced invocation would fit the buffer, else one unit, a probe whose count sizes
  /// the next slices (a first slice that overflows runs once for nothing but its count).
  uint32_t first_slice_units = 0;
  /// Regions of the trace buffer, each with its own record counter (gpu/trace_record.h), up to
  /// HP_TRACE_MAX_REGIONS. 0 = one per block of the passes' dispatch order (RtScene::spread_levels): one per
  /// lavapipe thread, so that no two threads add to one counter; one on a GPU. The records are the same.
  uint32_t record_regions = 0;
  /// Threads that write the slices, 1 .. kTraceBufferParts - 1. 0 = capture_writer_threads of the host's
  /// cores and the device's CPU threads.
  uint32_t writer_threads = 0;
  /// Work sharing on a CPU device of more than one thread: a pass that can (TracedStep::shares_work) runs
  /// each slice as one workgroup per device thread, and these take the slice's tiles whole from a counter,
  /// so that a thread the writers hold up leaves its share to the others instead of holding up the slice
  /// (gpu::TraceBufferHeader::units). The records are the same. Needs a region per device thread.
  bool share_work = true;
  bool tiled_images = true;  ///< G-buffer and outputs laid out in 8x8-texel tiles (else linear rows)
  /// Also run the enabled passes that are not traced, then accumulate and composite, so that the frame's
  /// image is whole (`trace --image`). Off: only the G-buffer and the traced passes run.
  bool final_image = true;
  /// Called after each slice is written, with the pass (step) name, the records so far in it, and its
  /// workgroup units (rows, or groups of a 1D pass) done and in all: progress for a command. Calls come in
  /// slice order, one at a time, from the capture's writer threads; one that throws stops the capture.
  std::function<void(const std::string& pass, uint64_t records, uint64_t done, uint64_t total)> on_slice;
};

struct CapturedPass {
  std::string pass;
  uint64_t records = 0;
  uint32_t slices = 0;         ///< dispatches that produced records
  uint32_t reruns = 0;         ///< slices that overflowed the buffer and were re-run smaller
  uint32_t shared_slices = 0;  ///< slices whose tiles the device threads shared (CaptureOptions::share_work)
  uint64_t workgroups = 0, sampled_workgroups = 0;
  /// Wall time of the pass's capture, from its first slice to its last slice written: the cost of tracing
  /// the pass, without the untraced passes the capture also runs (the G-buffer) or the file's close.
  double seconds = 0;
};

class Frame {
 public:
  Frame(vk::Context& ctx, const Scene& scene, const Camera& camera, const FrameSettings& settings);

  /// Records, submits and waits for one frame; accumulation advances by one sample. Passes are timed with
  /// FrameQueries::timestamps; with `none` no query is recorded (passes empty, cpu_wall_ns only): frames
  /// with and without queries measure the queries' own overhead; with `pipeline_statistics` the frame
  /// fills compute_invocations (when counters are on and the device has the queries) and no pass times.
  FrameTiming render(FrameQueries queries = FrameQueries::timestamps);
  /// The frame as the application records it, timed as a whole (FrameQueries::frame_span), repeating the
  /// sample the next render() draws (`previous` false) or the one the last render() drew (true): the same
  /// work as that frame. The sample index and the accumulated reflections are left as they were (the
  /// running mean is copied aside and back in submissions of their own), so frames timed this way beside
  /// the measured ones change neither their rays nor the final image.
  FrameTiming render_overlapped(bool previous);
  /// Renders one frame like render(), with the chosen ray-tracing passes run as their instrumented variants
  /// in slices that each fit the trace buffer; each slice's records go to `sink` (a trace file, the cache
  /// simulator, both) before the next slice runs (bounded memory). A slice that overflows is re-run with fewer workgroup rows; a single row that
  /// does not fit is an InputError naming the limit. The image equals the untraced one.
  std::vector<CapturedPass> render_captured(const CaptureOptions& options, trace::TraceSink& sink);
  /// The passes render_captured(options) traces, in its order (the traced steps of passes()): "shadows";
  /// "reflections", or on the compaction path "compact", the sort's steps (RadixSort::Step::name) and
  /// "consume". Known before the capture, so a command can check a pass name before any work.
  std::vector<std::string> captured_pass_names(const CaptureOptions& options) const;
  /// The trace file header for this frame: image size and the buffer table (ids of trace_buffers.h,
  /// consecutive 4 KiB-aligned synthetic base addresses, image layouts).
  trace::TraceHeader trace_header(bool tiled_images) const;

  /// Restarts temporal accumulation (call after changing the camera or the light).
  void reset_accumulation() { sample_index_ = 0; }
  void set_camera(const Camera& camera);
  void set_light(const DirectionalLight& light);

  const View& view() const { return view_; }
  const FrameSettings& settings() const { return settings_; }
  /// The BVH and leaf-order geometry (when rays are traced), for CPU reference checks.
  const RtGeometry* rt_geometry() const { return rt_geometry_ ? &*rt_geometry_ : nullptr; }
  /// What the ray-tracing passes share: output images, counters, dumps (nullptr without ray-traced passes).
  const RtResources* rt_passes() const { return rt_.get(); }
  /// The frame's passes in order, as every way of running it sees them.
  const std::vector<FramePass>& passes() const { return passes_; }
  /// The uploaded ray-tracing scene (nullptr without ray-traced passes).
  const RtScene* rt_scene() const { return rt_scene_.get(); }
  /// The driver's acceleration structure (nullptr unless RayTracingOptions::traversal is ray-query or pipeline).
  const AccelStructure* accel_structure() const { return accel_.get(); }
  uint32_t samples_accumulated() const { return sample_index_; }
  /// The queries of the first frame this Frame rendered (none before any): profilers keep every query out
  /// of it (see profile_frames).
  std::optional<FrameQueries> first_frame_queries() const { return first_queries_; }
  bool timestamps_supported() const { return timestamps_.supported(); }
  /// Whether render(FrameQueries::pipeline_statistics) counts invocations: counters on, queries supported.
  /// Invocation counts come with the ray counters, which only a frame with a ray-tracing pass has. Not taken
  /// with Traversal::pipeline: Mesa 25.0.7 lavapipe crashes (in its worker thread) executing a command
  /// buffer with a pipeline-statistics query and vkCmdTraceRaysKHR, and its ray-tracing stages are not
  /// compute invocations anyway.
  bool pipeline_statistics_available() const {
    return settings_.rt.counters && (settings_.rt.shadows || settings_.rt.reflections) && invocations_.supported() &&
           settings_.rt.traversal != Traversal::pipeline;
  }

  Image4f read_color() const;
  /// G-buffer and ray-tracing views: depth in r (raw depth-buffer value), normal rgb (world, unit), albedo
  /// rgb (linear), roughness / metalness in r, shadow mask in r (1 lit, 0 shadowed), reflection rgb (the
  /// accumulated reflection grid, alpha 1 where reflective). Background pixels have alpha 0 for G-buffer
  /// views.
  Image4f read_aov(Aov aov) const;
  std::vector<float> read_depth() const;
  RayCounters read_counters() const;

 private:
  void upload_uniforms();
  void record_passes(VkCommandBuffer cmd, FrameQueries queries);
  void render_host_timed(FrameTiming& timing, std::chrono::steady_clock::time_point t0);
  std::vector<FramePass> build_passes();  // frame_passes.cpp
  void add_compaction_passes(std::vector<FramePass>& out);
  const char* traversal_reads() const;  // what a tracing pass reads to trace, for FramePass::reads
  std::optional<FrameQueries> first_queries_;

  vk::Context& ctx_;
  const Scene& scene_;
  Camera camera_;
  DirectionalLight light_;
  FrameSettings settings_;
  View view_;
  GpuScene gpu_scene_;
  vk::Buffer uniforms_;
  GBuffer gbuffer_;
  vk::Image color_;
  vk::Sampler sampler_;
  std::optional<RtGeometry> rt_geometry_;
  std::unique_ptr<RtScene> rt_scene_;
  std::unique_ptr<AccelStructure> accel_;  // driver traversals only
  std::unique_ptr<RtResources> rt_;
  // The ray-tracing passes the settings ask for (each null otherwise); they record against rt_.
  std::unique_ptr<ShadowPass> shadows_;
  std::unique_ptr<ReflectionPass> reflections_;
  std::unique_ptr<CompactionPath> compaction_;
  std::unique_ptr<AccumulatePass> accumulate_;
  vk::Image dummy_shadow_, dummy_reflection_;  // bound by the composite when no ray is traced
  GBufferPass gbuffer_pass_;
  std::unique_ptr<CompositePass> composite_pass_;
  vk::TimestampQueries timestamps_;
  vk::ComputeInvocationQueries invocations_;
  std::vector<FramePass> passes_;                           // built last: its entries point at the passes above
  std::vector<std::unique_ptr<vk::Buffer>> trace_buffers_;  // the capture's trace buffer parts
  uint32_t compact_saved_ = 0;  // the capture's compacted count before a slice (restored on overflow)
  uint32_t frame_index_ = 0;
  uint32_t sample_index_ = 0;
};

}  // namespace hp
