#include "frame.hpp"

#include "error.hpp"

#include <glm/gtc/packing.hpp>

#include <chrono>
#include <cstring>

namespace hp {

Aov parse_aov(const std::string& name) {
  static const std::pair<const char*, Aov> kNames[] = {{"color", Aov::color},         {"depth", Aov::depth},
                                                       {"normal", Aov::normal},       {"albedo", Aov::albedo},
                                                       {"roughness", Aov::roughness}, {"metallic", Aov::metallic},
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
                                          settings.rt.reflections || settings.rt.dump_rays,
                                          settings.rt.traversal == Traversal::compute);
    Aabb bounds;
    if (!rt_geometry_->bvh.nodes.empty()) {
      bounds.min = rt_geometry_->bvh.nodes[0].bmin;
      bounds.max = rt_geometry_->bvh.nodes[0].bmax;
    }
    // The driver traversals: its acceleration structure, built once here (static scene) and timed.
    if (settings.rt.traversal != Traversal::compute) {
      require_traversal(ctx, settings.rt.traversal);
      accel_ = std::make_unique<AccelStructure>(ctx, *rt_geometry_, settings.rt.as_order, settings.rt.as_compaction,
                                                settings.rt.as_layout, &scene);
    }
    rt_ = std::make_unique<RtResources>(ctx, *rt_scene_, gbuffer_, uniforms_, sampler_.handle(), settings.rt, bounds,
                                        accel_.get());
    // Only the pipelines the options ask for are compiled (lavapipe compiles each one with LLVM).
    if (settings.rt.shadows) shadows_ = std::make_unique<ShadowPass>(ctx, *rt_);
    if (rt_->compaction()) compaction_ = std::make_unique<CompactionPath>(ctx, *rt_);
    if (settings.rt.reflections && !rt_->compaction()) reflections_ = std::make_unique<ReflectionPass>(ctx, *rt_);
    if (settings.rt.reflections) accumulate_ = std::make_unique<AccumulatePass>(ctx, *rt_);
  } else {
    dummy_shadow_ = make_dummy(ctx, VK_FORMAT_R32_SFLOAT);
    dummy_reflection_ = make_dummy(ctx, VK_FORMAT_R32G32B32A32_SFLOAT);
  }
  composite_pass_ = std::make_unique<CompositePass>(ctx, uniforms_, gbuffer_, color_, sampler_.handle(),
                                                    traced ? rt_->shadow_mask() : dummy_shadow_,
                                                    traced ? rt_->reflection_accum() : dummy_reflection_);
  passes_ = build_passes();
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
  for (const FramePass& p : passes_) {
    if (p.name.empty()) {  // an untimed step between passes
      p.record(cmd, false);
      continue;
    }
    const bool counted = count && p.compute;
    if (ts && timestamps_.begin(cmd, p.name)) serialize();
    if (counted) invocations_.begin(cmd, p.name);
    p.record(cmd, false);
    if (counted) invocations_.end(cmd);
    if (ts) {
      timestamps_.end(cmd);
      serialize();
    }
  }
}

FrameTiming Frame::render(FrameQueries queries) {
  if (!first_queries_) first_queries_ = queries;
  upload_uniforms();
  if (rt_) rt_->begin_frame(sample_index_);
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
    timing.span =
        FrameTiming::Pass{"frame", 0, uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(e - t0).count())};
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
    render_host_timed(timing, t0);
  }
  timing.cpu_wall_ns =
      uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count());
  ++frame_index_;
  ++sample_index_;
  return timing;
}

// No timestamps on this queue: one submission per pass, timed on the host (includes submit latency).
void Frame::render_host_timed(FrameTiming& timing, std::chrono::steady_clock::time_point t0) {
  timing.source = "cpu-wall";
  auto since_t0 = [&](std::chrono::steady_clock::time_point t) {
    return uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(t - t0).count());
  };
  for (const FramePass& p : passes_) {
    const auto b = std::chrono::steady_clock::now();
    ctx_.submit_and_wait([&](VkCommandBuffer cmd) { p.record(cmd, true); });
    const auto e = std::chrono::steady_clock::now();
    if (!p.name.empty()) timing.passes.push_back({p.name, since_t0(b), since_t0(e)});
  }
}

FrameTiming Frame::render_overlapped(bool previous) {
  const uint32_t sample = sample_index_, index = frame_index_;
  if (previous && sample_index_ > 0) --sample_index_;
  if (previous && frame_index_ > 0) --frame_index_;
  const bool accumulates = rt_ && settings_.rt.reflections;
  if (accumulates) rt_->save_accumulation(ctx_);
  FrameTiming t = render(FrameQueries::frame_span);
  if (accumulates) rt_->restore_accumulation(ctx_);
  sample_index_ = sample;
  frame_index_ = index;
  return t;
}

RayCounters Frame::read_counters() const {
  if (!rt_) return {};
  return rt_->read_counters(ctx_);
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
    if (!rt_ || (want_shadow ? !settings_.rt.shadows : !settings_.rt.reflections)) {
      throw InputError(std::string("--aov ") + (want_shadow ? "shadow" : "reflection") + ": that pass is disabled");
    }
    const vk::Image& src = want_shadow ? rt_->shadow_mask() : rt_->reflection_accum();
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
      case Aov::depth: px[0] = px[1] = px[2] = depth[i]; break;
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
      default: break;
    }
  }
  return img;
}

}  // namespace hp
