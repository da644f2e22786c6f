// The memory-trace capture of a frame (Frame::render_captured): the frame's pass list run once, the passes
// the options select as their instrumented variants, dispatched slice by slice into a trace::TraceSink; and
// the trace file's buffer table (Frame::trace_header).
#include "frame.hpp"

#include "error.hpp"
#include "gpu/trace_buffers.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <span>
#include <thread>
#include <utility>
#include <vector>

namespace hp {

unsigned capture_writer_threads(unsigned cores, unsigned device_threads) {
  const unsigned free_cores = cores > device_threads ? cores - device_threads : 0;
  return std::clamp(free_cores, 1u, kTraceBufferParts - 1);
}

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

// The trace buffer: kTraceBufferParts buffers, each a header and records (one bound at a time: a slice
// fills one part while the host writes out others), each at most maxStorageBufferRange. Each of a part's
// `regions` must hold a record per lane of a workgroup. Returns a part's bytes.
uint64_t checked_part_bytes(const CaptureOptions& o, const vk::Context& ctx, uint32_t regions) {
  const uint64_t limit = ctx.properties().limits.maxStorageBufferRange;
  const uint64_t bytes = o.buffer_bytes ? o.buffer_bytes / kTraceBufferParts : std::min<uint64_t>(64ull << 20, limit);
  if (bytes > limit) {
    throw InputError("trace: a trace buffer of " + std::to_string(o.buffer_bytes >> 20) + " MiB makes parts of " +
                     std::to_string(bytes >> 20) + " MiB (it has " + std::to_string(kTraceBufferParts) +
                     "), over this device's maxStorageBufferRange of " + std::to_string(limit >> 20) + " MiB");
  }
  if (bytes < sizeof(gpu::TraceBufferHeader) + uint64_t(regions) * 64 * sizeof(gpu::TraceRecord)) {
    throw InputError("trace: a trace buffer of " + std::to_string(o.buffer_bytes) + " bytes (" +
                     std::to_string(kTraceBufferParts) + " parts) cannot hold one record per lane" +
                     (regions > 1 ? " in each of a part's " + std::to_string(regions) + " regions" : std::string()));
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

// The slice writers' threads: CaptureOptions::writer_threads, else capture_writer_threads.
unsigned checked_writer_threads(const CaptureOptions& o, const vk::Context& ctx) {
  if (o.writer_threads > kTraceBufferParts - 1) {
    throw InputError("trace: " + std::to_string(o.writer_threads) + " writer threads is over the limit of " +
                     std::to_string(kTraceBufferParts - 1));
  }
  if (o.writer_threads) return o.writer_threads;
  return capture_writer_threads(std::thread::hardware_concurrency(), device_cpu_threads(ctx));
}

// Writes captured slices on worker threads, straight from their parts of the trace buffer, while the device
// runs the next slice into a free part. A sink that can stage a slice (TraceSink::stage_record_parts: the
// trace file's coding) works on several slices at once, one per worker, and each part is free again once
// its slice is staged; the staged slices, or the whole writes of a sink that cannot stage, reach the sink in
// slice order, one at a time, each slice's progress call right after its write. Beside the `workers`, one
// helper takes slices only while the capture thread waits (for a free part, or in drain()): the device is
// then idle, so on a CPU device the helper codes on a core its threads left, where a second writer running
// beside them holds up their dispatches (docs/memory-traces.md). An error stops the writing: acquire() and
// drain() rethrow the first; the destructor joins the workers, so a capture that throws leaves no thread
// behind.
class SliceWriter {
 public:
  SliceWriter(trace::TraceSink& sink, const std::array<gpu::TraceRecord*, kTraceBufferParts>& records,
              uint32_t region_capacity, unsigned workers)
      : sink_(sink), records_(records), region_capacity_(region_capacity) {
    for (uint32_t p = 0; p < kTraceBufferParts; ++p) free_.push_back(p);
    for (unsigned w = 0; w < workers; ++w) workers_.emplace_back([this] { work(false); });
    workers_.emplace_back([this] { work(true); });
  }
  SliceWriter(const SliceWriter&) = delete;
  SliceWriter& operator=(const SliceWriter&) = delete;
  // After drain() there is nothing left to write; otherwise (a capture that throws) the slices not yet
  // written are dropped.
  ~SliceWriter() {
    {
      const std::lock_guard lock(m_);
      stop_ = true;
      queue_.clear();
    }
    cv_.notify_all();
    for (std::thread& t : workers_) t.join();
  }
  // A free part of the buffer for the next slice, once one is (rethrows a write's error).
  uint32_t acquire() {
    std::unique_lock lock(m_);
    if (!error_ && free_.empty()) {
      ++device_waiting_;
      cv_.notify_all();
      cv_.wait(lock, [&] { return error_ || !free_.empty(); });
      --device_waiting_;
    }
    if (error_) std::rethrow_exception(error_);
    const uint32_t p = free_.front();
    free_.pop_front();
    return p;
  }
  // Queues the slice in part `part`: workgroups [first, end) of sink pass `pass`, `counts[r]` records in
  // each region r; `progress` (may be empty) runs right after its write.
  void submit(uint32_t part, uint32_t pass, std::span<const uint32_t> counts, uint64_t first, uint64_t end,
              std::function<void()> progress) {
    Job j{part, pass, {}, uint32_t(counts.size()), first, end, 0, std::move(progress)};
    std::copy(counts.begin(), counts.end(), j.counts.begin());
    {
      const std::lock_guard lock(m_);
      j.order = submitted_++;
      queue_.push_back(std::move(j));
    }
    cv_.notify_all();
  }
  // Waits until every queued slice is written (rethrows a write's error).
  void drain() {
    std::unique_lock lock(m_);
    ++device_waiting_;
    cv_.notify_all();
    cv_.wait(lock, [&] { return error_ || committed_ == submitted_; });
    --device_waiting_;
    if (error_) std::rethrow_exception(error_);
  }

 private:
  struct Job {
    uint32_t part, pass;
    std::array<uint32_t, HP_TRACE_MAX_REGIONS> counts;
    uint32_t regions;
    uint64_t first, end;
    uint64_t order;  // the slice's place in the sink's order
    std::function<void()> progress;
  };

  void work(bool helper) {
    for (;;) {
      Job j;
      {
        std::unique_lock lock(m_);
        cv_.wait(lock, [&] { return stop_ || (!queue_.empty() && (!helper || device_waiting_ > 0)); });
        if (queue_.empty()) return;
        j = std::move(queue_.front());
        queue_.pop_front();
      }
      gpu::TraceRecord* const base = records_[j.part];
      bool ok = !failed();
      trace::TraceSink::Commit commit;
      std::array<std::span<const gpu::TraceRecord>, HP_TRACE_MAX_REGIONS> parts;
      for (uint32_t r = 0; r < j.regions; ++r) parts[r] = {base + r * uint64_t(region_capacity_), j.counts[r]};
      const std::span<const std::span<const gpu::TraceRecord>> regions(parts.data(), j.regions);
      if (ok) ok = run([&] { commit = sink_.stage_record_parts(j.pass, regions, j.first, j.end); });
      if (commit) release(j.part);  // staged: the records are no longer needed
      ok = wait_turn(j.order) && ok;
      if (ok && !failed()) {
        run([&] {
          if (commit) {
            commit();
          } else if (!sink_.write_record_parts(j.pass, regions, j.first, j.end)) {
            // Moved together in place, then written as one span.
            uint64_t total = j.counts[0];
            for (uint32_t r = 1; r < j.regions; ++r) {
              std::memmove(base + total, base + r * uint64_t(region_capacity_), j.counts[r] * sizeof(gpu::TraceRecord));
              total += j.counts[r];
            }
            sink_.write_records(j.pass, std::span<const gpu::TraceRecord>(base, total), j.first, j.end);
          }
          if (j.progress) j.progress();
        });
      }
      {
        const std::lock_guard lock(m_);
        ++committed_;
        if (!commit) free_.push_back(j.part);
      }
      cv_.notify_all();
    }
  }
  // Runs f, keeping the first error; false if it threw.
  template <typename F>
  bool run(F&& f) {
    try {
      f();
      return true;
    } catch (...) {
      const std::lock_guard lock(m_);
      if (!error_) error_ = std::current_exception();
      return false;
    }
  }
  bool failed() {
    const std::lock_guard lock(m_);
    return error_ != nullptr;
  }
  void release(uint32_t part) {
    {
      const std::lock_guard lock(m_);
      free_.push_back(part);
    }
    cv_.notify_all();
  }
  // Waits until the slices before `order` are written; false if the writer is being torn down instead.
  bool wait_turn(uint64_t order) {
    std::unique_lock lock(m_);
    cv_.wait(lock, [&] { return committed_ == order || stop_; });
    return committed_ == order;
  }

  trace::TraceSink& sink_;
  const std::array<gpu::TraceRecord*, kTraceBufferParts> records_;  // each part's, after its header
  const uint32_t region_capacity_;
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<uint32_t> free_;  // parts the device may fill
  std::deque<Job> queue_;
  uint64_t submitted_ = 0, committed_ = 0;
  unsigned device_waiting_ = 0;  // the capture thread waits for a free part or for the writes to end
  bool stop_ = false;
  std::exception_ptr error_;
  std::vector<std::thread> workers_;
};

// The mapped trace buffer parts and what one capture writes into them.
struct Slicer {
  vk::Context& ctx;
  trace::TraceSink& sink;
  std::array<gpu::TraceBufferHeader*, kTraceBufferParts> heads;
  std::function<void(uint32_t part)> bind;  // points the traced passes' descriptors at a part
  uint32_t regions;
  uint32_t region_capacity;  // records per region
  uint32_t sampling;
  unsigned writers;  // threads that write the slices
  uint32_t sharing;  // the workgroups of a work-sharing dispatch (CaptureOptions::share_work), or 0
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
    const auto start = std::chrono::steady_clock::now();
    CapturedPass cp;
    cp.pass = step.name;
    cp.workgroups = uint64_t(wg.x) * wg.y;
    const uint32_t block_log2 = uint32_t(std::countr_zero(options.sample_block));
    for (uint64_t w = 0; w < cp.workgroups; ++w) {
      cp.sampled_workgroups += ((w >> block_log2) % options.sample_every) == 0;
    }
    std::array<gpu::TraceRecord*, kTraceBufferParts> recs;
    for (uint32_t p = 0; p < kTraceBufferParts; ++p) recs[p] = reinterpret_cast<gpu::TraceRecord*>(heads[p] + 1);
    const uint32_t units = step.one_d ? wg.x : wg.y;
    const uint64_t groups_per_unit = step.one_d ? 1 : wg.x;
    // The next slice's size, aimed at a 32nd of a part: rows differ tenfold (sky rows make few records), so
    // the density assumed is the largest seen in the pass so far, and a slice grows at most twofold. Small
    // slices keep the device and the writer busy together: at 1080p on lavapipe with one writer a slice is
    // then a row or two of pica (a dense row makes about 1 M records), and the captures took 3-12% less time
    // than with slices aimed at a quarter of a part, and less than with a 64th (docs/memory-traces.md). Where the
    // pass is not expected to fit, the first slice is a probe (CaptureOptions::first_slice_units): trying
    // the whole pass first ran the whole instrumented pass once for nothing (a slice that overflows still
    // counts every record it made, so its re-run is sized from that count). Measured on pica's 1920x1080
    // passes (64 MiB buffer): about 30% less capture time. The regions share a slice's records about
    // evenly (each takes every 2^L-th row of it, L the spread levels); a slice re-run after a region
    // overflowed is sized from that region's count times the regions.
    const uint64_t capacity = uint64_t(regions) * region_capacity;
    double peak_density = 0;  // records per unit, the most seen in a slice of this pass
    const auto sized = [&](uint32_t n, uint64_t count) {
      const double aim = double(capacity) / 32;
      peak_density = std::max(peak_density, double(count) / n);
      const double m = peak_density <= 0 ? 2.0 * n : std::min(aim / peak_density, 2.0 * n);
      return uint32_t(std::clamp<double>(std::floor(m), 1, units));
    };
    // Slices are written while the next ones run; a slice's progress call (which may stop the capture, e.g.
    // for disk space: the next acquire() rethrows) follows its write.
    SliceWriter writer(sink, recs, region_capacity, writers);
    // The first slice: the whole pass where it is expected to fit (at 1920x1080 pica's passes make 23-38
    // records per invocation; a shared slice must fit one region), else the probe.
    const uint64_t room = step.shares_work && sharing ? region_capacity : capacity;
    const uint64_t traced_invocations = cp.sampled_workgroups * uint64_t(step.group_size.x) * step.group_size.y;
    const uint32_t first_units = options.first_slice_units ? options.first_slice_units
                                 : traced_invocations * kExpectedRecordsPerInvocation <= room ? units
                                                                                              : 1;
    uint32_t n_max = std::clamp<uint32_t>(first_units, 1, units);
    uint32_t part = writer.acquire();  // the part of the buffer the next slice goes to
    // In the work-sharing mode a device thread may take any share of a slice's tiles, so a slice is kept only
    // where all its records would fit one region (the slicing, and so the file, then do not depend on how the
    // threads shared it); one that cannot be made smaller (one row or group) is re-run without sharing.
    bool unshared = false;
    for (uint32_t unit = 0; unit < units;) {
      const uint32_t n = std::min(n_max, units - unit);
      if (step.save) step.save();
      gpu::TraceBufferHeader* const head = heads[part];
      head->regions = regions;
      head->region_capacity = region_capacity;
      head->pass_id = pass_index;
      for (uint32_t r = 0; r < regions; ++r) head->region[r].count = 0;
      const uint32_t share = step.shares_work && !unshared ? sharing : 0;
      head->units = share ? uint32_t(uint64_t(n) * groups_per_unit * step.group_size.x * step.group_size.y) : 0;
      head->work.count = 0;
      bind(part);
      ctx.submit_and_wait([&](VkCommandBuffer cmd) { step.record_slice(cmd, unit, n, sampling, share); });
      std::array<uint32_t, HP_TRACE_MAX_REGIONS> counts{};
      uint64_t count = 0, fullest = 0;
      for (uint32_t r = 0; r < regions; ++r) {
        counts[r] = head->region[r].count;
        count += counts[r];
        fullest = std::max<uint64_t>(fullest, counts[r]);
      }
      if (share ? count > region_capacity : fullest > region_capacity) {
        if (n == 1 && share) {
          if (step.restore) step.restore();
          unshared = true;
          ++cp.reruns;
          continue;
        }
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
        n_max = std::min(sized(n, (share ? count : fullest) * regions), n - 1);  // re-run this slice smaller
        ++cp.reruns;
        continue;
      }
      unshared = false;
      cp.records += count;
      ++cp.slices;
      cp.shared_slices += share != 0;
      std::function<void()> progress;
      if (options.on_slice) {
        progress = [&on_slice = options.on_slice, name = step.name, records = cp.records, done = unit + n, units] {
          on_slice(name, records, done, units);
        };
      }
      writer.submit(part, pass_index, std::span<const uint32_t>(counts.data(), regions), unit * groups_per_unit,
                    (unit + n) * groups_per_unit, std::move(progress));
      unit += n;
      n_max = sized(n, count);
      if (unit < units) part = writer.acquire();
    }
    writer.drain();
    if (step.finish) step.finish();
    cp.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
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
  const unsigned writers = checked_writer_threads(o, ctx_);
  const uint64_t part_bytes = checked_part_bytes(o, ctx_, regions);
  const uint64_t capacity = (part_bytes - sizeof(gpu::TraceBufferHeader)) / sizeof(gpu::TraceRecord);  // a slice's
  if (trace_buffers_.size() != kTraceBufferParts || trace_buffers_[0]->size() != part_bytes) {
    trace_buffers_.clear();
    for (uint32_t p = 0; p < kTraceBufferParts; ++p) {
      trace_buffers_.push_back(
          std::make_unique<vk::Buffer>(ctx_, part_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true));
    }
  }
  std::array<gpu::TraceBufferHeader*, kTraceBufferParts> heads;
  for (uint32_t p = 0; p < kTraceBufferParts; ++p) {
    heads[p] = static_cast<gpu::TraceBufferHeader*>(trace_buffers_[p]->mapped());
  }
  // Between slices (the device idle): the passes' descriptors to the part the next slice fills.
  const auto bind = [&](uint32_t part) {
    const vk::Buffer& b = *trace_buffers_[part];
    rt_->attach_trace_buffer(b);
    for (const FramePass& pass : passes_) {
      if (selected(pass.traced, o) && pass.traced.attach) pass.traced.attach(ctx_, b);
    }
  };
  bind(0);
  // Work sharing where the device is the host's CPU with more than one thread, each with a region of its own.
  const uint32_t device_threads = device_cpu_threads(ctx_);
  const uint32_t sharing = o.share_work && device_threads > 1 && regions >= device_threads ? device_threads : 0;
  const Slicer slicer{ctx_, sink, heads, bind, regions, uint32_t(capacity / regions), sampling, writers, sharing, o};

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
