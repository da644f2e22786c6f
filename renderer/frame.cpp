#include "frame.hpp"

#include "error.hpp"

#include <glm/gtc/packing.hpp>

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
  if (name == "color") return Aov::color;
  if (name == "depth") return Aov::depth;
  if (name == "normal") return Aov::normal;
  if (name == "albedo") return Aov::albedo;
  if (name == "roughness") return Aov::roughness;
  if (name == "metallic") return Aov::metallic;
  throw InputError("--aov " + name + ": unknown view (choose color, depth, normal, albedo, roughness, metallic)");
}

namespace {

gpu::FrameUniforms make_uniforms(const Scene& scene, const Camera& camera, const View& view,
                                 const FrameSettings& s, uint32_t frame_index) {
  gpu::FrameUniforms u{};
  u.view_proj = view.view_proj;
  u.inv_view_proj = view.inv_view_proj;
  u.camera_pos = glm::vec4(camera.position, 1.0f);
  u.light_dir = glm::vec4(glm::normalize(scene.light.direction), scene.light.intensity);
  u.light_color = glm::vec4(scene.light.color, 1.0f);
  u.sky_color = glm::vec4(scene.sky_color, 1.0f);
  u.extent = glm::uvec4(s.width, s.height, frame_index, 0u);
  u.params = glm::vec4(s.reversed_z ? 1.0f : 0.0f, camera.znear, camera.zfar, 0.0f);
  return u;
}

}  // namespace

Frame::Frame(vk::Context& ctx, const Scene& scene, const Camera& camera, const FrameSettings& settings)
    : ctx_(ctx),
      scene_(scene),
      settings_((validate_extent(settings.width, settings.height, ctx.properties().limits.maxImageDimension2D),
                 settings)),
      view_(make_view(camera, float(settings.width) / float(settings.height), settings.reversed_z)),
      gpu_scene_(ctx, scene),
      uniforms_(ctx, sizeof(gpu::FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true),
      gbuffer_(ctx, settings.width, settings.height),
      color_(ctx, settings.width, settings.height, CompositePass::kOutputFormat,
             VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT),
      sampler_(ctx),
      gbuffer_pass_(ctx, uniforms_, settings.reversed_z),
      composite_pass_(ctx, uniforms_, gbuffer_, color_, sampler_.handle()) {
  const gpu::FrameUniforms u = make_uniforms(scene, camera, view_, settings_, 0);
  std::memcpy(uniforms_.mapped(), &u, sizeof(u));
}

void Frame::render() {
  auto* u = static_cast<gpu::FrameUniforms*>(uniforms_.mapped());
  u->extent.z = frame_index_++;
  ctx_.submit_and_wait([&](VkCommandBuffer cmd) {
    gbuffer_pass_.record(cmd, gpu_scene_, gbuffer_);
    composite_pass_.record(cmd, color_);
  });
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
      case Aov::color:
        break;
    }
  }
  return img;
}

}  // namespace hp
