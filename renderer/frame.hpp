// One hybrid frame on the GPU: owns the scene's GPU copies, the render targets and the passes, records a
// frame's command buffer and submits it. Today: G-buffer raster -> composite (direct light).
#pragma once

#include "gpu_scene.hpp"
#include "image/image.hpp"
#include "passes/composite.hpp"
#include "passes/gbuffer.hpp"
#include "view.hpp"

#include <memory>
#include <string>

namespace hp {

struct FrameSettings {
  uint32_t width = 1280;
  uint32_t height = 720;
  bool reversed_z = false;
};

/// Largest image side accepted (Vulkan guarantees 4096 for 2D images; lavapipe and GPUs allow 16384).
constexpr uint32_t kMaxImageSide = 16384;

/// Throws hp::InputError naming the limit when width/height are zero or too large for the device.
void validate_extent(uint32_t width, uint32_t height, uint32_t device_max_side);

/// The G-buffer views `--aov` can write.
enum class Aov { color, depth, normal, albedo, roughness, metallic };
Aov parse_aov(const std::string& name);  // throws InputError listing the choices

class Frame {
 public:
  Frame(vk::Context& ctx, const Scene& scene, const Camera& camera, const FrameSettings& settings);

  /// Records, submits and waits for one frame.
  void render();

  const View& view() const { return view_; }
  const FrameSettings& settings() const { return settings_; }

  /// Host copies of the last frame's outputs (linear floats, RGBA).
  Image4f read_color() const;
  /// G-buffer views: depth in r (raw depth-buffer value), normal in rgb (world, unit), albedo in rgb
  /// (linear), roughness / metalness in r. Alpha is 1; background pixels have alpha 0.
  Image4f read_aov(Aov aov) const;
  /// The raw depth buffer (width * height floats).
  std::vector<float> read_depth() const;

 private:
  vk::Context& ctx_;
  const Scene& scene_;
  FrameSettings settings_;
  View view_;
  GpuScene gpu_scene_;
  vk::Buffer uniforms_;
  GBuffer gbuffer_;
  vk::Image color_;
  vk::Sampler sampler_;
  GBufferPass gbuffer_pass_;
  CompositePass composite_pass_;
  uint32_t frame_index_ = 0;
};

}  // namespace hp
