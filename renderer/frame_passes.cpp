// The frame's pass list (Frame::build_passes), the one place that says which passes a frame runs, in which
// order, and how each is recorded, traced and documented. A new pass is a class in passes/ and one entry
// here; every way of running the frame (Frame::render, the host-timed fallback, the capture) follows.
#include "frame.hpp"

#include "gpu/radix_config.h"

namespace hp {

namespace {

// A ray-tracing pass's traced dispatch over 8x8 groups, sliced by workgroup rows through RayParams.frame.z.
TracedStep rt_step(RtResources& rt, std::string name, std::function<glm::uvec2()> workgroups,
                   std::function<void(VkCommandBuffer, uint32_t, uint32_t, uint32_t)> record) {
  TracedStep s;
  s.name = std::move(name);
  s.workgroups = std::move(workgroups);
  s.record_slice = [&rt, record = std::move(record)](VkCommandBuffer cmd, uint32_t first, uint32_t n, uint32_t sampling,
                                                     uint32_t sharing) {
    rt.set_slice(first, sampling);  // a host write before the submission
    record(cmd, first, n, sharing);
  };
  s.finish = [&rt] { rt.set_slice(0, 0); };
  return s;
}

}  // namespace

const char* Frame::traversal_reads() const {
  return settings_.rt.traversal == Traversal::compute ? "BVH, geometry"
                                                      : "acceleration structure (primitive -> slot table), geometry";
}

void Frame::add_compaction_passes(std::vector<FramePass>& out) {
  CompactionPath& cp = *compaction_;
  RtResources& rt = *rt_;
  const auto reflections = TracedVariant::Switch::reflections;
  FramePass compact{"compact", true, false, [&cp](VkCommandBuffer cmd, bool) { cp.record_compact(cmd); }};
  compact.traced.selected_by = reflections;
  compact.traced.attach = [&cp](vk::Context& ctx, const vk::Buffer&) { cp.attach_trace_compact(ctx); };
  // The append is not idempotent: the count starts at 0, and a slice re-run after an overflow restarts
  // from the count saved before it.
  compact.traced.before = [&cp](VkCommandBuffer cmd) { cp.record_reset_count(cmd, 0); };
  compact.traced.after = [&cp](VkCommandBuffer cmd) { cp.record_args(cmd); };
  TracedStep cs = rt_step(
      rt, "compact", [&cp] { return cp.compact_workgroups(); },
      [&cp](VkCommandBuffer cmd, uint32_t first, uint32_t n, uint32_t) { cp.record_traced_compact(cmd, first, n); });
  cs.save = [this, &rt] { compact_saved_ = rt.read_compacted_count(ctx_); };
  cs.restore = [this, &cp] {
    ctx_.submit_and_wait([&](VkCommandBuffer cmd) { cp.record_reset_count(cmd, compact_saved_); });
  };
  compact.traced.steps.push_back(std::move(cs));
  compact.dispatch = "8x8 groups over the reflection grid, then 1 group (the consume arguments)";
  compact.reads = "G-buffer, frame, ray params";
  compact.writes = "compact_rays, sort_keys, sort_values, ray_count (+ indirect arguments), reflection (cleared)";
  out.push_back(std::move(compact));

  if (settings_.rt.sort != SortKey::none) {
    FramePass sort{"sort", true, false, [&cp](VkCommandBuffer cmd, bool) { cp.record_sort(cmd); }};
    sort.traced.selected_by = reflections;
    sort.traced.attach = [&cp](vk::Context& ctx, const vk::Buffer& buffer) { cp.attach_trace_sort(ctx, buffer); };
    // Each dispatch a traced pass of its own (1D, 256-thread groups). They are idempotent but for the scan,
    // which is one workgroup: it runs whole or fails with the capacity named.
    for (const RadixSort::Step& step : cp.sort_steps()) {
      TracedStep s;
      s.name = step.name;
      s.group_size = {RADIX_THREADS, 1};
      s.one_d = true;
      s.workgroups = [groups = step.groups] { return glm::uvec2(groups, 1u); };
      s.record_slice = [&cp, step](VkCommandBuffer cmd, uint32_t first, uint32_t n, uint32_t sampling, uint32_t) {
        cp.record_traced_sort_step(cmd, step, first, n, sampling);
      };
      sort.traced.steps.push_back(std::move(s));
    }
    sort.dispatch = "per 4-bit digit: histogram, scan (1 group), scatter; a copy after an odd count";
    sort.reads = sort.writes = "sort_keys, sort_values, ray_count; the sort's scratch and histograms";
    out.push_back(std::move(sort));
  }

  FramePass consume{"consume", settings_.rt.traversal != Traversal::pipeline, false,
                    [&cp](VkCommandBuffer cmd, bool) { cp.record_consume(cmd); }};
  consume.traced.selected_by = reflections;
  consume.traced.attach = [&cp](vk::Context& ctx, const vk::Buffer&) { cp.attach_trace_consume(ctx); };
  TracedStep s = rt_step(
      rt, "consume", [this, &rt] { return CompactionPath::consume_workgroups(rt.read_compacted_count(ctx_)); },
      [&cp](VkCommandBuffer cmd, uint32_t, uint32_t n, uint32_t) { cp.record_traced_consume(cmd, n); });
  s.group_size = {64, 1};  // HP_CONSUME_GROUP (shaders/common/compaction.glsl)
  s.one_d = true;
  consume.traced.steps.push_back(std::move(s));
  consume.dispatch = "indirect: ceil(rays / 64) groups of 64, one row";
  consume.reads = std::string("compact_rays, sort_values, ray_count, ") + traversal_reads() + ", materials";
  consume.writes = "reflection, counters, reflection dump";
  out.push_back(std::move(consume));
}

std::vector<FramePass> Frame::build_passes() {
  std::vector<FramePass> out;
  FramePass gbuffer{"gbuffer", false, true, [this](VkCommandBuffer cmd, bool) {
                      gbuffer_pass_.record(cmd, gpu_scene_, gbuffer_, camera_.position);
                    }};
  gbuffer.dispatch = "raster: one draw per mesh instance";
  gbuffer.reads = "vertex and index buffers, frame";
  gbuffer.writes = "G-buffer (depth, normal + roughness, albedo + metalness), left SHADER_READ_ONLY";
  out.push_back(std::move(gbuffer));
  if (rt_) {
    FramePass prepare{"", true, true, [this](VkCommandBuffer cmd, bool) { rt_->record_prepare(cmd); }};
    prepare.dispatch = "none (layout transitions, a fill)";
    prepare.writes = "shadow_mask, reflection, reflection_accum (to GENERAL), counters (zeroed)";
    out.push_back(std::move(prepare));
  }
  if (shadows_) {
    // The reflection passes end with a compute barrier that also covers the shadow mask's writes, and do
    // not read it: no barrier between the two, so a device may overlap them (the frame as an application
    // records it; timed frames serialize at the boundary anyway).
    const bool next_covers = settings_.rt.reflections;
    ShadowPass& sp = *shadows_;
    const bool compute = settings_.rt.traversal != Traversal::pipeline;  // else ray-tracing stages
    FramePass shadows{"shadows", compute, false,
                      [&sp, next_covers](VkCommandBuffer cmd, bool alone) { sp.record(cmd, alone || !next_covers); }};
    shadows.traced.selected_by = TracedVariant::Switch::shadows;
    shadows.traced.attach = [&sp](vk::Context& ctx, const vk::Buffer&) { sp.attach_trace(ctx); };
    TracedStep shadow_step = rt_step(
        *rt_, "shadows", [&sp] { return sp.workgroups(); },
        [&sp](VkCommandBuffer cmd, uint32_t first, uint32_t n, uint32_t sharing) {
          sp.record_traced_slice(cmd, first, n, sharing);
        });
    shadow_step.shares_work = true;
    shadows.traced.steps.push_back(std::move(shadow_step));
    shadows.dispatch = "8x8 groups over the image (and over the injected rows again)";
    shadows.reads = std::string("G-buffer, frame, ray params, ") + traversal_reads();
    shadows.writes = "shadow_mask, counters, shadow dump";
    out.push_back(std::move(shadows));
  }
  if (compaction_) add_compaction_passes(out);
  if (reflections_) {
    ReflectionPass& rp = *reflections_;
    FramePass refl{"reflections", settings_.rt.traversal != Traversal::pipeline, false,
                   [&rp](VkCommandBuffer cmd, bool) { rp.record(cmd); }};
    refl.traced.selected_by = TracedVariant::Switch::reflections;
    refl.traced.attach = [&rp](vk::Context& ctx, const vk::Buffer&) { rp.attach_trace(ctx); };
    TracedStep refl_step = rt_step(
        *rt_, "reflections", [&rp] { return rp.workgroups(); },
        [&rp](VkCommandBuffer cmd, uint32_t first, uint32_t n, uint32_t sharing) {
          rp.record_traced_slice(cmd, first, n, sharing);
        });
    refl_step.shares_work = true;
    refl.traced.steps.push_back(std::move(refl_step));
    refl.dispatch = "8x8 groups over the reflection grid";
    refl.reads = std::string("G-buffer, frame, ray params, ") + traversal_reads() + ", materials";
    refl.writes = "reflection, counters, reflection dump";
    out.push_back(std::move(refl));
  }
  if (accumulate_) {
    AccumulatePass& ap = *accumulate_;
    FramePass acc{"accumulate", true, false, [&ap](VkCommandBuffer cmd, bool) { ap.record(cmd); }};
    acc.dispatch = "8x8 groups over the reflection grid";
    acc.reads = "reflection, ray params (sample index)";
    acc.writes = "reflection_accum";
    out.push_back(std::move(acc));
  }
  FramePass composite{"composite", true, false,
                      [this](VkCommandBuffer cmd, bool) { composite_pass_->record(cmd, color_); }};
  composite.dispatch = "8x8 groups over the image";
  composite.reads = "G-buffer, frame, shadow_mask, reflection_accum";
  composite.writes = "colour (left GENERAL)";
  out.push_back(std::move(composite));
  return out;
}

}  // namespace hp
