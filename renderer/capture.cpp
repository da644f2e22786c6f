// The memory-trace capture of a frame (Frame::render_captured): the frame's pass list run once, the passes
// the options select as their instrumented variants, dispatched slice by slice into a trace::TraceSink; and
// the trace file's buffer table (Frame::trace_header).
#include "frame.hpp"

#include "error.hpp"
#include "gpu/trace_buffers.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <exception>
#include <functional>
#include <span>
#include <thread>
#include <utility>
#include <vector>

namespace hp {

namespace {

bool selected(const TracedVariant& t, const CaptureOptions& o) {
  switch (t.selected_by) {
    case TracedVariant::Switch::shadows: return o.shadows;
    case TracedVariant::Switch::reflections: return o.reflections;
    default: return false;
  }
}

// The workgroup sampling word of the traced variants: k | log2(burst) << 20.
uint32_t checked_sampling(const CaptureOptions& o) {
  if (o.sample_every == 0 || o.sample_every > 0xFFFFFu) {
    throw InputError("trace: --sample-every must be in 1.." + std::to_string(0xFFFFFu));
  }
  if (o.sample_block == 0 || o.sample_block > 2048 || (o.sample_block & (o.sample_block - 1)) != 0) {
    throw InputError("trace: --sample-block " + std::to_string(o.sample_block) + " must be a power of two in 1..2048");
  }
  return o.sample_every | (uint32_t(std::countr_zero(o.sample_block)) << 20);
}

/// Records per traced invocation assumed when choosing a pass's first slice (CaptureOptions::first_slice_units).
constexpr uint64_t kExpectedRecordsPerInvocation = 32;

// The trace buffer: its header and two halves of records; a slice fills one half while the host writes out
// the other. Each of a half's `regions` must hold a record per lane of a workgroup.
uint64_t checked_buffer_bytes(const CaptureOptions& o, const vk::Context& ctx, uint32_t regions) {
  const uint64_t limit = ctx.properties().limits.maxStorageBufferRange;
  const uint64_t bytes = o.buffer_bytes ? o.buffer_bytes : std::min<uint64_t>(128ull << 20, limit);
  if (bytes > limit) {
    throw InputError("trace: a trace buffer of " + std::to_string(bytes >> 20) + " MiB exceeds this device's " +
                     "maxStorageBufferRange of " + std::to_string(limit >> 20) + " MiB");
  }
  if (bytes < sizeof(gpu::TraceBufferHeader) + 2 * uint64_t(regions) * 64 * sizeof(gpu::TraceRecord)) {
    throw InputError("trace: a trace buffer of " + std::to_string(bytes) + " bytes cannot hold one record per lane" +
                     (regions > 1 ? " in each of its " + std::to_string(regions) + " regions" : std::string()));
  }
  return bytes;
}

// The trace buffer's regions (gpu/trace_record.h): one per block of the passes' dispatch order, i.e. one per
// lavapipe thread (2^spread levels), one on a GPU; CaptureOptions::record_regions overrides.
uint32_t checked_regions(const CaptureOptions& o, const RtScene* scene) {
  if (o.record_regions > HP_TRACE_MAX_REGIONS) {
    throw InputError("trace: " + std::to_string(o.record_regions) + " record regions is over the limit of " +
                     std::to_string(HP_TRACE_MAX_REGIONS));
  }
  if (o.record_regions) return o.record_regions;
  static_assert(std::has_single_bit(HP_TRACE_MAX_REGIONS));
  constexpr uint32_t most_levels = std::countr_zero(HP_TRACE_MAX_REGIONS);
  return 1u << std::min<uint32_t>(scene ? scene->spread_levels() : 0, most_levels);
}

// Writes a captured slice on a worker thread, straight from its half of the trace buffer, while the device
// runs the next slice into the other half. The sink is only ever called by one thread at a time, in slice
// order. wait() joins the write in flight and rethrows its error; the destructor joins it too, so a capture
// that throws leaves no thread behind.
class SliceWriter {
 public:
  explicit SliceWriter(trace::TraceSink& sink) : sink_(sink) {}
  SliceWriter(const SliceWriter&) = delete;
  SliceWriter& operator=(const SliceWriter&) = delete;
  ~SliceWriter() {
    if (thread_.joinable()) thread_.join();
  }
  void wait() {
    if (thread_.joinable()) thread_.join();
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }
  // Starts writing the records of workgroups [first, end) of sink pass `pass` (after wait()): those of
  // each region, `counts[r]` from `records + r * region_capacity`, handed to the sink as they lie, or moved
  // together in place (on the worker) and written as one span where it cannot take them so. The half must stay untouched by the device until wait() returns.
  void start(uint32_t pass, gpu::TraceRecord* records, std::span<const uint32_t> counts, uint32_t region_capacity,
             uint64_t first, uint64_t end) {
    std::array<uint32_t, HP_TRACE_MAX_REGIONS> n{};
    std::copy(counts.begin(), counts.end(), n.begin());
    thread_ = std::thread([this, pass, records, n, regions = counts.size(), region_capacity, first, end] {
      try {
        // As they lie where the sink can take them so (the coding reads each record once then), else
        // put together.
        std::array<std::span<const gpu::TraceRecord>, HP_TRACE_MAX_REGIONS> parts;
        for (size_t r = 0; r < regions; ++r) parts[r] = {records + r * uint64_t(region_capacity), n[r]};
        if (sink_.write_record_parts(pass, std::span(parts.data(), regions), first, end)) return;
        uint64_t total = n[0];
        for (size_t r = 1; r < regions; ++r) {
          const gpu::TraceRecord* from = records + r * uint64_t(region_capacity);
          std::memmove(records + total, from, n[r] * sizeof(gpu::TraceRecord));
          total += n[r];
        }
        sink_.write_records(pass, std::span<const gpu::TraceRecord>(records, total), first, end);
      } catch (...) {
        error_ = std::current_exception();
      }
    });
  }

 private:
  trace::TraceSink& sink_;
  std::thread thread_;
  std::exception_ptr error_;
};

// The mapped trace buffer and what one capture writes into it.
struct Slicer {
  vk::Context& ctx;
  trace::TraceSink& sink;
  gpu::TraceBufferHeader* head;
  uint32_t regions;
  uint32_t region_capacity;  // records per region
  uint32_t sampling;
  const CaptureOptions& options;

  // Captures one dispatch in slices: of workgroup rows for a 2D pass, of groups for a 1D one (the consume
  // pass, the sort kernels). A small first slice probes the pass's density; a slice that overflows is re-run
  // smaller, sized from its count.
  CapturedPass capture(const TracedStep& step) const {
    const glm::uvec2 wg = step.workgroups();
    trace::PassInfo info;
    info.name = step.name;
    info.dispatch.workgroup_size[0] = step.group_size.x;
    info.dispatch.workgroup_size[1] = step.group_size.y;
    info.dispatch.workgroup_count[0] = wg.x;
    info.dispatch.workgroup_count[1] = wg.y;
    const uint32_t pass_index = sink.begin_pass(info);
    CapturedPass cp;
    cp.pass = step.name;
    cp.workgroups = uint64_t(wg.x) * wg.y;
    const uint32_t block_log2 = uint32_t(std::countr_zero(options.sample_block));
    for (uint64_t w = 0; w < cp.workgroups; ++w) {
      cp.sampled_workgroups += ((w >> block_log2) % options.sample_every) == 0;
    }
    auto* const recs = reinterpret_cast<gpu::TraceRecord*>(head + 1);
    uint32_t half = 0;  // the half of the buffer the next slice goes to
    const uint32_t units = step.one_d ? wg.x : wg.y;
    const uint64_t groups_per_unit = step.one_d ? 1 : wg.x;
    // The next slice's size, aimed at half the buffer: rows differ tenfold (sky rows make few records), so the
    // density assumed is the largest seen in the pass so far, and a slice grows at most twofold. Where the
    // pass is not expected to fit, the first slice is a probe (CaptureOptions::first_slice_units): trying
    // the whole pass first ran the whole instrumented pass once for nothing (a slice that overflows still
    // counts every record it made, so its re-run is sized from that count). Measured on pica's 1920x1080
    // passes (64 MiB buffer): about 30% less capture time. The regions share a slice's records about
    // evenly (each takes every 2^L-th row of it, L the spread levels); a slice re-run after a region
    // overflowed is sized from that region's count times the regions.
    const uint64_t capacity = uint64_t(regions) * region_capacity;
    double peak_density = 0;  // records per unit, the most seen in a slice of this pass
    const auto sized = [&](uint32_t n, uint64_t count) {
      const double aim = double(capacity) / 2;
      peak_density = std::max(peak_density, double(count) / n);
      const double m = peak_density <= 0 ? 2.0 * n : std::min(aim / peak_density, 2.0 * n);
      return uint32_t(std::clamp<double>(std::floor(m), 1, units));
    };
    // A slice is written while the next one runs; its progress call (which may stop the capture, e.g. for
    // disk space) follows its write, before the next write starts.
    SliceWriter writer(sink);
    std::function<void()> written_progress;
    const auto finish_write = [&] {
      writer.wait();
      if (written_progress) std::exchange(written_progress, nullptr)();
    };
    // The first slice: the whole pass where it is expected to fit (at 1920x1080 pica's passes make 23-38
    // records per invocation), else the probe.
    const uint64_t traced_invocations = cp.sampled_workgroups * uint64_t(step.group_size.x) * step.group_size.y;
    const uint32_t first_units = options.first_slice_units ? options.first_slice_units
                                 : traced_invocations * kExpectedRecordsPerInvocation <= capacity ? units
                                                                                                  : 1;
    uint32_t n_max = std::clamp<uint32_t>(first_units, 1, units);
    for (uint32_t unit = 0; unit < units;) {
      const uint32_t n = std::min(n_max, units - unit);
      if (step.save) step.save();
      head->regions = regions;
      head->region_capacity = region_capacity;
      head->pass_id = pass_index;
      head->record_base = half * capacity;
      for (uint32_t r = 0; r < regions; ++r) head->region[r].count = 0;
      ctx.submit_and_wait([&](VkCommandBuffer cmd) { step.record_slice(cmd, unit, n, sampling); });
      std::array<uint32_t, HP_TRACE_MAX_REGIONS> counts{};
      uint64_t count = 0, fullest = 0;
      for (uint32_t r = 0; r < regions; ++r) {
        counts[r] = head->region[r].count;
        count += counts[r];
        fullest = std::max<uint64_t>(fullest, counts[r]);
      }
      if (fullest > region_capacity) {
        if (n == 1) {
          throw InputError(std::string("trace: one workgroup ") + (step.one_d ? "" : "row ") + "of the " + step.name +
                           " pass makes " + std::to_string(count) + " records, over the trace buffer's capacity of " +
                           std::to_string(capacity) + " a slice" +
                           (regions > 1 ? ", " + std::to_string(region_capacity) + " in each of its " +
                                              std::to_string(regions) + " regions"
                                        : std::string()) +
                           " (raise the trace buffer size, or sample workgroups)");
        }
        if (step.restore) step.restore();
        n_max = std::min(sized(n, fullest * regions), n - 1);  // re-run this slice smaller
        ++cp.reruns;
        continue;
      }
      finish_write();
      writer.start(pass_index, recs + head->record_base, std::span<const uint32_t>(counts.data(), regions),
                   region_capacity, unit * groups_per_unit, (unit + n) * groups_per_unit);
      half ^= 1;
      cp.records += count;
      ++cp.slices;
      unit += n;
      n_max = sized(n, count);
      if (options.on_slice) {
        written_progress = [&on_slice = options.on_slice, name = step.name, records = cp.records, unit, units] {
          on_slice(name, records, unit, units);
        };
      }
    }
    finish_write();
    if (step.finish) step.finish();
    return cp;
  }
};

}  // namespace

std::vector<std::string> Frame::captured_pass_names(const CaptureOptions& o) const {
  std::vector<std::string> names;
  for (const FramePass& pass : passes_) {
    if (!selected(pass.traced, o)) continue;
    for (const TracedStep& step : pass.traced.steps) names.push_back(step.name);
  }
  return names;
}

std::vector<CapturedPass> Frame::render_captured(const CaptureOptions& o, trace::TraceSink& sink) {
  if (!rt_) throw InputError("trace: no ray-tracing pass is enabled, nothing to trace");
  if (!ctx_.info().subgroup_ballot_compute) {
    throw InputError("trace: " + ctx_.info().name +
                     " has no subgroup ballot in compute shaders, which the instrumented passes use to reserve "
                     "their record slots");
  }
  const uint32_t sampling = checked_sampling(o);
  const uint32_t regions = checked_regions(o, rt_scene_.get());
  const uint64_t bytes = checked_buffer_bytes(o, ctx_, regions);
  const uint64_t capacity = (bytes - sizeof(gpu::TraceBufferHeader)) / sizeof(gpu::TraceRecord) / 2;  // a slice's
  if (!trace_buffer_ || trace_buffer_->size() != bytes) {
    trace_buffer_ = std::make_unique<vk::Buffer>(ctx_, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  }
  rt_->attach_trace_buffer(*trace_buffer_);
  for (const FramePass& pass : passes_) {
    if (selected(pass.traced, o) && pass.traced.attach) pass.traced.attach(ctx_, *trace_buffer_);
  }
  const Slicer slicer{ctx_,
                      sink,
                      static_cast<gpu::TraceBufferHeader*>(trace_buffer_->mapped()),
                      regions,
                      uint32_t(capacity / regions),
                      sampling,
                      o};

  upload_uniforms();
  rt_->begin_frame(sample_index_);
  std::vector<CapturedPass> out;
  for (const FramePass& pass : passes_) {
    if (selected(pass.traced, o)) {
      const TracedVariant& t = pass.traced;
      if (t.before) ctx_.submit_and_wait(t.before);
      for (const TracedStep& step : t.steps) out.push_back(slicer.capture(step));
      if (t.after) ctx_.submit_and_wait(t.after);
    } else if (pass.capture_always || o.final_image) {
      ctx_.submit_and_wait([&](VkCommandBuffer cmd) { pass.record(cmd, true); });
    }
  }
  ++frame_index_;
  ++sample_index_;
  return out;
}

namespace {

// The trace file's buffer table: consecutive 4 KiB-aligned synthetic base addresses, in the order added.
struct BufferTable {
  trace::TraceHeader& h;
  bool tiled;
  uint64_t next = 0x10000;  // synthetic device addresses: consecutive, 4 KiB aligned, never 0

  void place(trace::BufferInfo b, uint64_t footprint_bytes) {
    b.base_address = next;
    next += (footprint_bytes + 4095) / 4096 * 4096;
    h.buffers.push_back(std::move(b));
  }
  void add(uint32_t id, const char* name, uint64_t size) {
    trace::BufferInfo b;
    b.id = id;
    b.name = name;
    b.size_bytes = std::max<uint64_t>(size, 4);
    place(std::move(b), std::max<uint64_t>(size, 4));
  }
  void add_image(uint32_t id, const char* name, uint32_t w, uint32_t hh, uint32_t texel) {
    trace::BufferInfo b;
    b.id = id;
    b.name = name;
    b.texel_bytes = texel;
    b.width = w;
    b.height = hh;
    b.size_bytes = uint64_t(w) * hh * texel;
    uint64_t footprint = b.size_bytes;
    if (tiled) {  // whole 8x8 tiles are stored, ragged edges included
      b.kind = trace::BufferKind::image_tiled;
      b.tile_width = b.tile_height = 8;
      footprint = uint64_t((w + 7) / 8) * ((hh + 7) / 8) * 64 * texel;
    } else {
      b.kind = trace::BufferKind::image_linear;
      b.row_pitch_bytes = w * texel;
    }
    place(std::move(b), footprint);
  }
};

}  // namespace

trace::TraceHeader Frame::trace_header(bool tiled) const {
  trace::TraceHeader h;
  h.image_width = settings_.width;
  h.image_height = settings_.height;
  BufferTable t{h, tiled};
  if (rt_scene_) {
    const RtScene& r = *rt_scene_;
    t.add(HP_TBUF_NODES, "bvh_nodes", r.nodes().size());
    t.add(HP_TBUF_POSITIONS, "positions", r.positions_bytes());
    t.add(HP_TBUF_INDICES, "indices", r.indices_bytes());
    t.add(HP_TBUF_SOUP, "soup", r.soup_bytes());
    t.add(HP_TBUF_OBJECT_FIRST, "object_first", r.object_first().size());
    t.add(HP_TBUF_SLOT_SCENE, "slot_scene", r.slot_scene().size());
    t.add(HP_TBUF_NORMALS, "normals", r.normals_bytes());
    t.add(HP_TBUF_SOUP_NORMALS, "soup_normals", r.soup_normals_bytes());
    t.add(HP_TBUF_SLOT_MATERIAL, "slot_material", r.slot_material().size());
    t.add(HP_TBUF_MATERIALS, "materials", r.materials().size());
  }
  if (compaction_) {
    const uint64_t cells = uint64_t(rt_->grid_width()) * rt_->grid_height();
    t.add(HP_TBUF_COMPACT_RAYS, "compact_rays", cells * sizeof(gpu::CompactRay));
    t.add(HP_TBUF_SORT_KEYS, "sort_keys", cells * 4);
    t.add(HP_TBUF_SORT_VALUES, "sort_values", cells * 4);
    t.add(HP_TBUF_RAY_COUNT, "ray_count", 16);
    if (const RadixSort* sorter = compaction_->sorter()) {
      t.add(HP_TBUF_SORT_SCRATCH_KEYS, "sort_scratch_keys", sorter->scratch_bytes());
      t.add(HP_TBUF_SORT_SCRATCH_VALUES, "sort_scratch_values", sorter->scratch_bytes());
      t.add(HP_TBUF_SORT_HISTOGRAMS, "sort_histograms", sorter->histogram_bytes());
    }
  }
  t.add_image(HP_TBUF_GBUF_DEPTH, "gbuffer_depth", settings_.width, settings_.height, 4);
  t.add_image(HP_TBUF_GBUF_NORMAL, "gbuffer_normal_roughness", settings_.width, settings_.height, 8);
  t.add_image(HP_TBUF_SHADOW_MASK, "shadow_mask", settings_.width, settings_.height, 4);
  if (rt_) t.add_image(HP_TBUF_REFLECTION, "reflection", rt_->grid_width(), rt_->grid_height(), 16);
  return h;
}

}  // namespace hp
