#include "frame.hpp"

#include "error.hpp"

#include <glm/gtc/packing.hpp>

#include <chrono>
#include <cstring>

namespace hp {

void validate_extent(uint32_t width, uint32_t height, uint32_t device_max_side) {
  const uint32_t limit = std::min(kMaxImageSide, device_max_side);
  if (width == 0 || height == 0) {
    throw InputError("resolution " + std::to_string(width) + "x" + std::to_string(height) +
                     ": width and height must be at least 1");
  }
  if (width > limit || height > limit) {
    throw InputError("resolution " + std::to_string(width) + "x" + std::to_string(height) + ": exceeds the limit of " +
                     std::to_string(limit) + " pixels per side (maxImageDimension2D of this device)");
  }
}

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

constexpr uint32_t kCompositeShadows = 1u;
constexpr uint32_t kCompositeReflections = 2u;
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
      timestamps_(ctx, kMaxPasses) {
  const bool traced = settings.rt.shadows || settings.rt.reflections;
  if (traced) {
    rt_geometry_ = build_rt_geometry(scene, settings.bvh);
    rt_scene_ = std::make_unique<RtScene>(ctx, scene, *rt_geometry_, settings.geometry, settings.rt.reflections);
    rt_passes_ = std::make_unique<RayTracingPasses>(ctx, *rt_scene_, gbuffer_, uniforms_, sampler_.handle(),
                                                    settings.rt);
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
  u.view_proj = view_.view_proj;
  u.inv_view_proj = view_.inv_view_proj;
  u.camera_pos = glm::vec4(camera_.position, 1.0f);
  u.light_dir = glm::vec4(glm::normalize(light_.direction), light_.intensity);
  u.light_color = glm::vec4(light_.color, 1.0f);
  u.sky_color = glm::vec4(scene_.sky_color, 1.0f);
  uint32_t flags = 0;
  if (settings_.rt.shadows) flags |= kCompositeShadows;
  if (settings_.rt.reflections) flags |= kCompositeReflections;
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

void Frame::record_passes(VkCommandBuffer cmd, bool ts) {
  auto pass = [&](const char* name, auto&& body) {
    if (ts) timestamps_.begin(cmd, name);
    body();
    if (ts) timestamps_.end(cmd);
  };
  pass("gbuffer", [&] { gbuffer_pass_.record(cmd, gpu_scene_, gbuffer_); });
  if (rt_passes_) {
    rt_passes_->record_prepare(cmd);
    if (settings_.rt.shadows) pass("shadows", [&] { rt_passes_->record_shadows(cmd); });
    if (settings_.rt.reflections) {
      pass("reflections", [&] { rt_passes_->record_reflections(cmd); });
      pass("accumulate", [&] { rt_passes_->record_accumulate(cmd); });
    }
  }
  pass("composite", [&] { composite_pass_->record(cmd, color_); });
}

FrameTiming Frame::render(bool with_timestamps) {
  upload_uniforms();
  if (rt_passes_) rt_passes_->begin_frame(sample_index_);
  FrameTiming timing;
  const auto t0 = std::chrono::steady_clock::now();
  if (!with_timestamps) {
    timing.source = "none";
    ctx_.submit_and_wait([&](VkCommandBuffer cmd) { record_passes(cmd, false); });
  } else if (timestamps_.supported()) {
    timing.source = "gpu-timestamps";
    ctx_.submit_and_wait([&](VkCommandBuffer cmd) {
      timestamps_.reset(cmd);
      record_passes(cmd, true);
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
    timed("gbuffer", [&](VkCommandBuffer cmd) { gbuffer_pass_.record(cmd, gpu_scene_, gbuffer_); });
    if (rt_passes_) {
      ctx_.submit_and_wait([&](VkCommandBuffer cmd) { rt_passes_->record_prepare(cmd); });
      if (settings_.rt.shadows) timed("shadows", [&](VkCommandBuffer cmd) { rt_passes_->record_shadows(cmd); });
      if (settings_.rt.reflections) {
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
