#include "frame.hpp"

#include "gpu/radix_config.h"

#include <bit>

#include "gpu/trace_buffers.h"
#include "error.hpp"

#include <glm/gtc/packing.hpp>

#include <chrono>
#include <functional>
#include <string_view>
#include <cstring>

namespace hp {

Aov parse_aov(const std::string& name) {
  static const std::pair<const char*, Aov> kNames[] = {
      {"color", Aov::color},         {"depth", Aov::depth},         {"normal", Aov::normal},
      {"albedo", Aov::albedo},       {"roughness", Aov::roughness}, {"metallic", Aov::metallic},
      {"shadow", Aov::shadow},       {"reflection", Aov::reflection}};
  for (const auto& [n, a] : kNames) {
    if (name == n) return a;
  }
  throw InputError("--aov " + name +
                   ": unknown view (choose color, depth, normal, albedo, roughness, metallic, shadow, reflection)");
}

namespace {

constexpr uint32_t kMaxPasses = 8;

vk::Image make_dummy(vk::Context& ctx, VkFormat format) {
  vk::Image img(ctx, 1, 1, format, VK_IMAGE_USAGE_STORAGE_BIT);
  ctx.submit_and_wait([&](VkCommandBuffer cmd) {
    vk::transition(cmd, img, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_2_NONE, 0,
                   VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_READ_BIT);
  });
  return img;
}

const FrameSettings& checked(const FrameSettings& s, const vk::Context& ctx) {
  validate_extent(s.width, s.height, ctx.properties().limits.maxImageDimension2D);
  return s;
}

}  // namespace

Frame::Frame(vk::Context& ctx, const Scene& scene, const Camera& camera, const FrameSettings& settings)
    : ctx_(ctx),
      scene_(scene),
      camera_(camera),
      light_(scene.light),
      settings_(checked(settings, ctx)),
      view_(make_view(camera, float(settings.width) / float(settings.height), settings.reversed_z)),
      gpu_scene_(ctx, scene),
      uniforms_(ctx, sizeof(gpu::FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true),
      gbuffer_(ctx, settings.width, settings.height),
      color_(ctx, settings.width, settings.height, CompositePass::kOutputFormat,
             VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT),
      sampler_(ctx),
      gbuffer_pass_(ctx, uniforms_, settings.reversed_z),
      timestamps_(ctx, settings.host_timing ? 0 : kMaxPasses),
      invocations_(ctx, kMaxPasses) {
  const bool traced = settings.rt.shadows || settings.rt.reflections;
  if (traced) {
    rt_geometry_ = build_rt_geometry(scene, settings.bvh);
    rt_scene_ = std::make_unique<RtScene>(ctx, scene, *rt_geometry_, settings.geometry, settings.rt.reflections, true,
                                          settings.rt.reflections || settings.rt.dump_rays);
    Aabb bounds;
    if (!rt_geometry_->bvh.nodes.empty()) {
      bounds.min = rt_geometry_->bvh.nodes[0].bmin;
      bounds.max = rt_geometry_->bvh.nodes[0].bmax;
    }
    rt_passes_ = std::make_unique<RayTracingPasses>(ctx, *rt_scene_, gbuffer_, uniforms_, sampler_.handle(),
                                                    settings.rt, bounds);
  } else {
    dummy_shadow_ = make_dummy(ctx, VK_FORMAT_R32_SFLOAT);
    dummy_reflection_ = make_dummy(ctx, VK_FORMAT_R32G32B32A32_SFLOAT);
  }
  composite_pass_ = std::make_unique<CompositePass>(ctx, uniforms_, gbuffer_, color_, sampler_.handle(),
                                                    traced ? rt_passes_->shadow_mask() : dummy_shadow_,
                                                    traced ? rt_passes_->reflection_accum() : dummy_reflection_);
  upload_uniforms();
}

void Frame::upload_uniforms() {
  gpu::FrameUniforms u{};
  u.view_proj = view_.view_proj_rel;  // camera-relative (view.hpp): hp_world_position adds camera_pos
  u.inv_view_proj = view_.inv_view_proj_rel;
  u.camera_pos = glm::vec4(camera_.position, 1.0f);
  u.light_dir = glm::vec4(glm::normalize(light_.direction), light_.intensity);
  u.light_color = glm::vec4(light_.color, 1.0f);
  u.sky_color = glm::vec4(scene_.sky_color, 1.0f);
  uint32_t flags = 0;
  if (settings_.rt.shadows) flags |= HP_COMPOSITE_SHADOWS;
  if (settings_.rt.reflections) flags |= HP_COMPOSITE_REFLECTIONS;
  u.extent = glm::uvec4(settings_.width, settings_.height, frame_index_, flags);
  u.params = glm::vec4(settings_.reversed_z ? 1.0f : 0.0f, camera_.znear, camera_.zfar,
                       float(settings_.rt.reflection_divisor));
  std::memcpy(uniforms_.mapped(), &u, sizeof(u));
}

void Frame::set_camera(const Camera& camera) {
  camera_ = camera;
  view_ = make_view(camera, float(settings_.width) / float(settings_.height), settings_.reversed_z);
  reset_accumulation();
}

void Frame::set_light(const DirectionalLight& light) {
  light_ = light;
  reset_accumulation();
}

void Frame::record_passes(VkCommandBuffer cmd, FrameQueries queries) {
  const bool ts = queries == FrameQueries::timestamps;
  const bool count = queries == FrameQueries::pipeline_statistics && pipeline_statistics_available();
  if (count) invocations_.reset(cmd);
  // Serialized timing (PassIsolation::Serialized): an execution dependency after every timestamp, so no
  // pass starts before the timestamp and everything before it are done. A timestamp at ALL_COMMANDS waits
  // for earlier work but holds back no later work, so without it a device may run the next pass before
  // the boundary is written (every GPU; Mesa 25 lavapipe records a timestamp in its rasterizer's command
  // stream, where it is only executed at the next flush, after the next pass: 76 ms "shadows" and 3.6 ms
  // "reflections" against 30 and 72 ms each alone at 480x270; a dependency before the timestamp does not
  // help). The dependency after the timestamp makes the device execute it before going on. Its cost counts
  // toward the next pass, and is part of the measured query overhead.
  auto serialize = [&] {
    vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, 0, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, 0);
  };
  auto pass = [&](const char* name, auto&& body) {
    const bool compute = std::string_view(name) != "gbuffer";
    if (ts && timestamps_.begin(cmd, name)) serialize();
    if (count && compute) invocations_.begin(cmd, name);
    body();
    if (count && compute) invocations_.end(cmd);
    if (ts) {
      timestamps_.end(cmd);
      serialize();
    }
  };
  pass("gbuffer", [&] { gbuffer_pass_.record(cmd, gpu_scene_, gbuffer_, camera_.position); });
  if (rt_passes_) {
    rt_passes_->record_prepare(cmd);
    // The reflection passes end with a compute barrier that also covers the shadow mask's writes, and do
    // not read it: no barrier between the two, so a device may overlap them (the frame as an application
    // records it; timed frames serialize at the boundary anyway).
    if (settings_.rt.shadows) pass("shadows", [&] { rt_passes_->record_shadows(cmd, !settings_.rt.reflections); });
    if (settings_.rt.reflections) {
      if (settings_.rt.reflection_path == ReflectionPath::compact) {
        pass("compact", [&] { rt_passes_->record_compact(cmd); });
        if (settings_.rt.sort != SortKey::none) pass("sort", [&] { rt_passes_->record_sort(cmd); });
        pass("consume", [&] { rt_passes_->record_consume(cmd); });
      } else {
        pass("reflections", [&] { rt_passes_->record_reflections(cmd); });
      }
      pass("accumulate", [&] { rt_passes_->record_accumulate(cmd); });
    }
  }
  pass("composite", [&] { composite_pass_->record(cmd, color_); });
}

FrameTiming Frame::render(FrameQueries queries) {
  if (!first_queries_) first_queries_ = queries;
  upload_uniforms();
  if (rt_passes_) rt_passes_->begin_frame(sample_index_);
  FrameTiming timing;
  const auto t0 = std::chrono::steady_clock::now();
  if (queries == FrameQueries::frame_span && timestamps_.supported()) {
    timing.source = "gpu-timestamps";
    ctx_.submit_and_wait([&](VkCommandBuffer cmd) {
      timestamps_.reset(cmd);
      timestamps_.begin(cmd, "frame");
      // Executes the first timestamp before the frame's work (see record_passes); nothing between passes.
      vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, 0, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, 0);
      record_passes(cmd, FrameQueries::none);
      timestamps_.end(cmd);
    });
    const auto iv = timestamps_.read(ctx_).at(0);
    timing.span = FrameTiming::Pass{iv.pass, iv.begin_ns, iv.end_ns};
  } else if (queries == FrameQueries::frame_span) {
    // No timestamps on this queue: the whole frame in one submission, timed on the host.
    timing.source = "cpu-wall";
    ctx_.submit_and_wait([&](VkCommandBuffer cmd) { record_passes(cmd, FrameQueries::none); });
    const auto e = std::chrono::steady_clock::now();
    timing.span = FrameTiming::Pass{"frame", 0, uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(e - t0).count())};
  } else if (queries != FrameQueries::timestamps) {
    timing.source = "none";
    ctx_.submit_and_wait([&](VkCommandBuffer cmd) { record_passes(cmd, queries); });
    if (queries == FrameQueries::pipeline_statistics && pipeline_statistics_available())
      timing.compute_invocations = invocations_.read();
  } else if (timestamps_.supported()) {
    timing.source = "gpu-timestamps";
    ctx_.submit_and_wait([&](VkCommandBuffer cmd) {
      timestamps_.reset(cmd);
      record_passes(cmd, queries);
    });
    for (const auto& iv : timestamps_.read(ctx_)) timing.passes.push_back({iv.pass, iv.begin_ns, iv.end_ns});
  } else {
    // No timestamps on this queue: one submission per pass, timed on the host (includes submit latency).
    timing.source = "cpu-wall";
    auto timed = [&](const char* name, auto&& body) {
      const auto b = std::chrono::steady_clock::now();
      ctx_.submit_and_wait(body);
      const auto e = std::chrono::steady_clock::now();
      timing.passes.push_back({name, uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(b - t0).count()),
                               uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(e - t0).count())});
    };
    timed("gbuffer", [&](VkCommandBuffer cmd) { gbuffer_pass_.record(cmd, gpu_scene_, gbuffer_, camera_.position); });
    if (rt_passes_) {
      ctx_.submit_and_wait([&](VkCommandBuffer cmd) { rt_passes_->record_prepare(cmd); });
      if (settings_.rt.shadows) timed("shadows", [&](VkCommandBuffer cmd) { rt_passes_->record_shadows(cmd); });
      if (settings_.rt.reflections && settings_.rt.reflection_path == ReflectionPath::compact) {
        timed("compact", [&](VkCommandBuffer cmd) { rt_passes_->record_compact(cmd); });
        if (settings_.rt.sort != SortKey::none) timed("sort", [&](VkCommandBuffer cmd) { rt_passes_->record_sort(cmd); });
        timed("consume", [&](VkCommandBuffer cmd) { rt_passes_->record_consume(cmd); });
        timed("accumulate", [&](VkCommandBuffer cmd) { rt_passes_->record_accumulate(cmd); });
      } else if (settings_.rt.reflections) {
        timed("reflections", [&](VkCommandBuffer cmd) { rt_passes_->record_reflections(cmd); });
        timed("accumulate", [&](VkCommandBuffer cmd) { rt_passes_->record_accumulate(cmd); });
      }
    }
    timed("composite", [&](VkCommandBuffer cmd) { composite_pass_->record(cmd, color_); });
  }
  timing.cpu_wall_ns =
      uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count());
  ++frame_index_;
  ++sample_index_;
  return timing;
}

FrameTiming Frame::render_overlapped(bool previous) {
  const uint32_t sample = sample_index_, index = frame_index_;
  if (previous && sample_index_ > 0) --sample_index_;
  if (previous && frame_index_ > 0) --frame_index_;
  const bool accumulates = rt_passes_ && settings_.rt.reflections;
  if (accumulates) rt_passes_->save_accumulation(ctx_);
  FrameTiming t = render(FrameQueries::frame_span);
  if (accumulates) rt_passes_->restore_accumulation(ctx_);
  sample_index_ = sample;
  frame_index_ = index;
  return t;
}

trace::TraceHeader Frame::trace_header(bool tiled) const {
  trace::TraceHeader h;
  h.image_width = settings_.width;
  h.image_height = settings_.height;
  uint64_t next = 0x10000;  // synthetic device addresses: consecutive, 4 KiB aligned, never 0
  auto place = [&](trace::BufferInfo b, uint64_t footprint_bytes) {
    b.base_address = next;
    next += (footprint_bytes + 4095) / 4096 * 4096;
    h.buffers.push_back(std::move(b));
  };
  auto add = [&](uint32_t id, const char* name, uint64_t size) {
    trace::BufferInfo b;
    b.id = id;
    b.name = name;
    b.size_bytes = std::max<uint64_t>(size, 4);
    place(std::move(b), std::max<uint64_t>(size, 4));
  };
  auto add_image = [&](uint32_t id, const char* name, uint32_t w, uint32_t hh, uint32_t texel) {
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
  };
  if (rt_scene_) {
    const RtScene& r = *rt_scene_;
    add(HP_TBUF_NODES, "bvh_nodes", r.nodes().size());
    add(HP_TBUF_POSITIONS, "positions", r.positions().size());
    add(HP_TBUF_INDICES, "indices", r.indices().size());
    add(HP_TBUF_SOUP, "soup", r.soup().size());
    add(HP_TBUF_OBJECT_FIRST, "object_first", r.object_first().size());
    add(HP_TBUF_SLOT_SCENE, "slot_scene", r.slot_scene().size());
    add(HP_TBUF_NORMALS, "normals", r.normals().size());
    add(HP_TBUF_SOUP_NORMALS, "soup_normals", r.soup_normals().size());
    add(HP_TBUF_SLOT_MATERIAL, "slot_material", r.slot_material().size());
    add(HP_TBUF_MATERIALS, "materials", r.materials().size());
  }
  if (rt_passes_ && settings_.rt.reflections && settings_.rt.reflection_path == ReflectionPath::compact) {
    const uint64_t cells = uint64_t(rt_passes_->grid_width()) * rt_passes_->grid_height();
    add(HP_TBUF_COMPACT_RAYS, "compact_rays", cells * sizeof(gpu::CompactRay));
    add(HP_TBUF_SORT_KEYS, "sort_keys", cells * 4);
    add(HP_TBUF_SORT_VALUES, "sort_values", cells * 4);
    add(HP_TBUF_RAY_COUNT, "ray_count", 16);
    if (const RadixSort* sorter = rt_passes_->sorter()) {
      add(HP_TBUF_SORT_SCRATCH_KEYS, "sort_scratch_keys", sorter->scratch_bytes());
      add(HP_TBUF_SORT_SCRATCH_VALUES, "sort_scratch_values", sorter->scratch_bytes());
      add(HP_TBUF_SORT_HISTOGRAMS, "sort_histograms", sorter->histogram_bytes());
    }
  }
  add_image(HP_TBUF_GBUF_DEPTH, "gbuffer_depth", settings_.width, settings_.height, 4);
  add_image(HP_TBUF_GBUF_NORMAL, "gbuffer_normal_roughness", settings_.width, settings_.height, 8);
  add_image(HP_TBUF_SHADOW_MASK, "shadow_mask", settings_.width, settings_.height, 4);
  if (rt_passes_) {
    add_image(HP_TBUF_REFLECTION, "reflection", rt_passes_->grid_width(), rt_passes_->grid_height(), 16);
  }
  return h;
}

std::vector<std::string> Frame::captured_pass_names(const CaptureOptions& o) const {
  std::vector<std::string> names;
  if (!rt_passes_) return names;
  if (settings_.rt.shadows && o.shadows) names.push_back("shadows");
  if (settings_.rt.reflections && o.reflections) {
    if (settings_.rt.reflection_path == ReflectionPath::compact) {
      names.push_back("compact");
      for (const RadixSort::Step& step : rt_passes_->sort_steps()) names.push_back(step.name);
      names.push_back("consume");
    } else {
      names.push_back("reflections");
    }
  }
  return names;
}

std::vector<CapturedPass> Frame::render_captured(const CaptureOptions& o, trace::TraceSink& writer) {
  if (!rt_passes_) throw InputError("trace: no ray-tracing pass is enabled, nothing to trace");
  if (o.sample_every == 0 || o.sample_every > 0xFFFFFu) {
    throw InputError("trace: --sample-every must be in 1.." + std::to_string(0xFFFFFu));
  }
  if (o.sample_block == 0 || o.sample_block > 2048 || (o.sample_block & (o.sample_block - 1)) != 0) {
    throw InputError("trace: --sample-block " + std::to_string(o.sample_block) + " must be a power of two in 1..2048");
  }
  const uint32_t block_log2 = uint32_t(std::countr_zero(o.sample_block));
  const uint32_t sampling = o.sample_every | (block_log2 << 20);
  const uint64_t limit = ctx_.properties().limits.maxStorageBufferRange;
  const uint64_t bytes = o.buffer_bytes ? o.buffer_bytes : std::min<uint64_t>(64ull << 20, limit);
  if (bytes > limit) {
    throw InputError("trace: a trace buffer of " + std::to_string(bytes >> 20) + " MiB exceeds this device's " +
                     "maxStorageBufferRange of " + std::to_string(limit >> 20) + " MiB");
  }
  if (bytes < sizeof(gpu::TraceBufferHeader) + 64 * sizeof(gpu::TraceRecord)) {
    throw InputError("trace: a trace buffer of " + std::to_string(bytes) + " bytes cannot hold one record per lane");
  }
  if (!trace_buffer_ || trace_buffer_->size() != bytes) {
    trace_buffer_ = std::make_unique<vk::Buffer>(ctx_, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, true);
  }
  rt_passes_->attach_trace_buffer(ctx_, *trace_buffer_, o.shadows, o.reflections);
  const uint32_t capacity = uint32_t((bytes - sizeof(gpu::TraceBufferHeader)) / sizeof(gpu::TraceRecord));
  auto* head = static_cast<gpu::TraceBufferHeader*>(trace_buffer_->mapped());
  const auto* recs = reinterpret_cast<const gpu::TraceRecord*>(head + 1);

  upload_uniforms();
  rt_passes_->begin_frame(sample_index_);
  std::vector<CapturedPass> out;
  ctx_.submit_and_wait([&](VkCommandBuffer cmd) {
    gbuffer_pass_.record(cmd, gpu_scene_, gbuffer_, camera_.position);
    rt_passes_->record_prepare(cmd);
  });
  using Traced = RayTracingPasses::Traced;
  // Captures one dispatch in slices: of workgroup rows for a 2D pass, of groups for a 1D one (the consume
  // pass, the sort kernels). `run_slice(first, n)` records and runs units [first, first + n) with the
  // instrumented pipeline. `save` runs before each slice and `restore` after an overflow, for passes whose
  // writes are not idempotent (the compaction's atomic append).
  auto capture_slices = [&](const std::string& name, glm::uvec2 wg, uint32_t group_w, uint32_t group_h, bool one_d,
                            const std::function<void(uint32_t, uint32_t)>& run_slice,
                            const std::function<void()>& save, const std::function<void()>& restore) {
    trace::PassInfo info;
    info.name = name;
    info.dispatch.workgroup_size[0] = group_w;
    info.dispatch.workgroup_size[1] = group_h;
    info.dispatch.workgroup_count[0] = wg.x;
    info.dispatch.workgroup_count[1] = wg.y;
    const uint32_t pass_index = writer.begin_pass(info);
    CapturedPass cp;
    cp.pass = name;
    cp.workgroups = uint64_t(wg.x) * wg.y;
    for (uint64_t w = 0; w < cp.workgroups; ++w) cp.sampled_workgroups += ((w >> block_log2) % o.sample_every) == 0;
    const uint32_t units = one_d ? wg.x : wg.y;
    const uint64_t groups_per_unit = one_d ? 1 : wg.x;
    uint32_t step = units;  // first try: the whole pass in one slice
    for (uint32_t unit = 0; unit < units;) {
      const uint32_t n = std::min(step, units - unit);
      if (save) save();
      head->count = 0;
      head->capacity = capacity;
      head->pass_id = pass_index;
      run_slice(unit, n);
      const uint32_t count = head->count;
      if (count > capacity) {
        if (n == 1) {
          throw InputError(std::string("trace: one workgroup ") + (one_d ? "" : "row ") + "of the " + name +
                           " pass makes " + std::to_string(count) + " records, over the trace buffer's capacity of " +
                           std::to_string(capacity) + " (raise the trace buffer size, or sample workgroups)");
        }
        if (restore) restore();
        step = std::max(1u, n / 2);  // re-run this slice smaller
        ++cp.reruns;
        continue;
      }
      writer.write_records(pass_index, std::span<const gpu::TraceRecord>(recs, count), unit * groups_per_unit,
                           (unit + n) * groups_per_unit);
      cp.records += count;
      ++cp.slices;
      unit += n;
    }
    out.push_back(cp);
  };
  // A ray-tracing pass: 8x8 groups, except the consume pass's one row of 64-wide groups.
  auto capture = [&](const char* name, Traced pass, glm::uvec2 wg, uint32_t group_w, uint32_t group_h,
                     const std::function<void()>& save, const std::function<void()>& restore) {
    capture_slices(
        name, wg, group_w, group_h, pass == Traced::consume,
        [&](uint32_t unit, uint32_t n) {
          rt_passes_->set_slice(unit, sampling);
          ctx_.submit_and_wait([&](VkCommandBuffer cmd) { rt_passes_->record_traced_slice(cmd, pass, unit, n); });
        },
        save, restore);
    rt_passes_->set_slice(0, 0);
  };
  if (settings_.rt.shadows) {
    if (o.shadows) {
      capture("shadows", Traced::shadows, rt_passes_->workgroups(Traced::shadows), 8, 8, nullptr, nullptr);
    } else if (o.final_image) {
      ctx_.submit_and_wait([&](VkCommandBuffer cmd) { rt_passes_->record_shadows(cmd); });
    }
  }
  if (settings_.rt.reflections && settings_.rt.reflection_path == ReflectionPath::compact) {
    if (o.reflections) {
      // The append is not idempotent: a slice re-run after an overflow restarts from the saved count.
      uint32_t saved = 0;
      ctx_.submit_and_wait([&](VkCommandBuffer cmd) { rt_passes_->record_reset_count(cmd, 0); });
      capture("compact", Traced::compact, rt_passes_->workgroups(Traced::compact), 8, 8,
              [&] { saved = rt_passes_->read_compacted_count(ctx_); },
              [&] { ctx_.submit_and_wait([&](VkCommandBuffer cmd) { rt_passes_->record_reset_count(cmd, saved); }); });
      ctx_.submit_and_wait([&](VkCommandBuffer cmd) { rt_passes_->record_args(cmd); });
      // The sort's dispatches, each a traced pass of its own (1D, 256-thread groups). They are idempotent
      // but for the scan, which is one workgroup: it runs whole or fails with the capacity named.
      for (const RadixSort::Step& step : rt_passes_->sort_steps()) {
        capture_slices(
            step.name, {step.groups, 1u}, RADIX_THREADS, 1, true,
            [&](uint32_t first, uint32_t n) {
              ctx_.submit_and_wait(
                  [&](VkCommandBuffer cmd) { rt_passes_->record_traced_sort_step(cmd, step, first, n, sampling); });
            },
            nullptr, nullptr);
      }
      const uint32_t rays = rt_passes_->read_compacted_count(ctx_);
      capture("consume", Traced::consume, rt_passes_->workgroups(Traced::consume, rays), 64, 1, nullptr, nullptr);
    } else if (o.final_image) {
      ctx_.submit_and_wait([&](VkCommandBuffer cmd) {
        rt_passes_->record_compact(cmd);
        rt_passes_->record_sort(cmd);
        rt_passes_->record_consume(cmd);
      });
    }
  } else if (settings_.rt.reflections) {
    if (o.reflections) {
      capture("reflections", Traced::reflections, rt_passes_->workgroups(Traced::reflections), 8, 8, nullptr,
              nullptr);
    } else if (o.final_image) {
      ctx_.submit_and_wait([&](VkCommandBuffer cmd) { rt_passes_->record_reflections(cmd); });
    }
  }
  if (o.final_image) {
    ctx_.submit_and_wait([&](VkCommandBuffer cmd) {
      if (settings_.rt.reflections) rt_passes_->record_accumulate(cmd);
      composite_pass_->record(cmd, color_);
    });
  }
  ++frame_index_;
  ++sample_index_;
  return out;
}

RayCounters Frame::read_counters() const {
  if (!rt_passes_) return {};
  return rt_passes_->read_counters(ctx_);
}

Image4f Frame::read_color() const {
  auto bytes = vk::read_image(ctx_, color_, VK_IMAGE_LAYOUT_GENERAL);
  Image4f img(settings_.width, settings_.height);
  std::memcpy(img.rgba.data(), bytes.data(), img.rgba.size() * sizeof(float));
  return img;
}

std::vector<float> Frame::read_depth() const {
  auto bytes = vk::read_image(ctx_, gbuffer_.depth, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  std::vector<float> depth(size_t(settings_.width) * settings_.height);
  std::memcpy(depth.data(), bytes.data(), depth.size() * sizeof(float));
  return depth;
}

Image4f Frame::read_aov(Aov aov) const {
  if (aov == Aov::color) return read_color();
  if (aov == Aov::shadow || aov == Aov::reflection) {
    const bool want_shadow = aov == Aov::shadow;
    if (!rt_passes_ || (want_shadow ? !settings_.rt.shadows : !settings_.rt.reflections)) {
      throw InputError(std::string("--aov ") + (want_shadow ? "shadow" : "reflection") + ": that pass is disabled");
    }
    const vk::Image& src = want_shadow ? rt_passes_->shadow_mask() : rt_passes_->reflection_accum();
    auto bytes = vk::read_image(ctx_, src, VK_IMAGE_LAYOUT_GENERAL);
    Image4f img(src.width(), src.height());
    if (want_shadow) {
      const auto* f = reinterpret_cast<const float*>(bytes.data());
      for (size_t i = 0; i < size_t(src.width()) * src.height(); ++i) {
        img.rgba[i * 4 + 0] = img.rgba[i * 4 + 1] = img.rgba[i * 4 + 2] = f[i];
        img.rgba[i * 4 + 3] = 1.0f;
      }
    } else {
      std::memcpy(img.rgba.data(), bytes.data(), img.rgba.size() * sizeof(float));
    }
    return img;
  }
  const size_t n = size_t(settings_.width) * settings_.height;
  const std::vector<float> depth = read_depth();
  Image4f img(settings_.width, settings_.height);
  const float background = view_.far_depth();
  std::vector<std::byte> texels;
  if (aov == Aov::normal || aov == Aov::roughness) {
    texels = vk::read_image(ctx_, gbuffer_.normal_roughness, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  } else if (aov == Aov::albedo || aov == Aov::metallic) {
    texels = vk::read_image(ctx_, gbuffer_.albedo_metal, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  }
  for (size_t i = 0; i < n; ++i) {
    float* px = &img.rgba[i * 4];
    const bool bg = depth[i] == background;
    px[3] = bg ? 0.0f : 1.0f;
    switch (aov) {
      case Aov::depth:
        px[0] = px[1] = px[2] = depth[i];
        break;
      case Aov::normal:
      case Aov::roughness: {
        uint64_t h;
        std::memcpy(&h, &texels[i * 8], 8);
        const glm::vec4 v = glm::unpackHalf4x16(h);
        if (aov == Aov::normal) {
          px[0] = v.x, px[1] = v.y, px[2] = v.z;
        } else {
          px[0] = px[1] = px[2] = v.w;
        }
        break;
      }
      case Aov::albedo:
      case Aov::metallic: {
        const auto* b = reinterpret_cast<const uint8_t*>(&texels[i * 4]);
        if (aov == Aov::albedo) {
          for (int c = 0; c < 3; ++c) px[c] = srgb_to_linear(b[c] / 255.0f);
        } else {
          px[0] = px[1] = px[2] = b[3] / 255.0f;
        }
        break;
      }
      default:
        break;
    }
  }
  return img;
}

}  // namespace hp
