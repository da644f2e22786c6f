// `hybridprof render`: renders one scene and writes the final image or a G-buffer view.
#include "apps/cli_util.hpp"
#include "apps/commands.hpp"
#include "error.hpp"
#include "frame.hpp"
#include "scene/load.hpp"
#include "vk/context.hpp"

#include <chrono>
#include <cstdio>
#include <memory>

namespace hp::cli {

namespace {

struct RenderArgs {
  std::string scene = "builtin:pica";
  uint32_t width = 1280, height = 720;
  std::string out = "frame.png";
  std::string aov = "color";
  std::string device;
  bool validate = false;
  bool reversed_z = false;
  uint32_t frames = 1;
  ViewOptions view;
};

void run_render(const RenderArgs& a) {
  const Aov aov = parse_aov(a.aov);
  Scene scene = load_scene(a.scene);
  a.view.apply_light(scene);
  if (a.width == 0 || a.height == 0) validate_extent(a.width, a.height, kMaxImageSide);
  const Camera camera = a.view.camera_for(scene, float(a.width) / float(a.height));
  vk::Context ctx({a.device, a.validate, true});
  FrameSettings settings{a.width, a.height, a.reversed_z};
  Frame frame(ctx, scene, camera, settings);
  const auto t0 = std::chrono::steady_clock::now();
  for (uint32_t i = 0; i < a.frames; ++i) frame.render();
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  write_image(a.out, frame.read_aov(aov));
  if (ctx.validation_enabled() && ctx.validation_message_count() > 0) {
    throw std::runtime_error(std::to_string(ctx.validation_message_count()) +
                             " validation message(s); last: " + ctx.last_validation_message());
  }
  std::printf("%s: %zu triangles, %ux%u on %s (%s), %u frame(s) in %.1f ms (CPU wall, incl. submit) -> %s\n",
              scene.name.c_str(), triangle_count(scene), a.width, a.height, ctx.info().name.c_str(),
              ctx.info().driver_info.c_str(), a.frames, ms, a.out.c_str());
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand("render", "render a scene and write the image (or a G-buffer view)");
  cmd->add_option("--scene", args->scene, "builtin:pica|cornell|sphere-1m|terrain-1m, or a .gltf/.glb path")
      ->capture_default_str();
  cmd->add_option("--width", args->width, "image width in pixels")->capture_default_str();
  cmd->add_option("--height", args->height, "image height in pixels")->capture_default_str();
  cmd->add_option("--out", args->out, "output image: .png (display-referred sRGB) or .exr (linear float)")
      ->capture_default_str();
  cmd->add_option("--aov", args->aov, "what to write: color, depth, normal, albedo, roughness, metallic")
      ->capture_default_str();
  cmd->add_option("--frames", args->frames, "frames to render (the last one is written)")
      ->check(CLI::Range(1u, 100000u))
      ->capture_default_str();
  cmd->add_flag("--reversed-z", args->reversed_z, "reversed-Z depth buffer (near = 1, far = 0)");
  cmd->add_option("--device", args->device, "Vulkan device: index or name substring (default: discrete GPU, else lavapipe)");
  cmd->add_flag("--validate", args->validate, "enable the Khronos validation layer; any message fails the run");
  args->view.add_to(cmd);
  cmd->callback([args] { run_render(*args); });
}

void add_devices_command(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("devices", "list the Vulkan devices and the facts hybridprof records");
  cmd->callback([] {
    const auto devices = vk::list_devices();
    if (devices.empty()) throw DeviceError("no Vulkan device found; install lavapipe (apt-get install mesa-vulkan-drivers)");
    for (size_t i = 0; i < devices.size(); ++i) {
      const auto& d = devices[i];
      std::printf("%zu: %s [%s] driver %s (%s), Vulkan %s, subgroup %u, timestamp period %.3f ns (%u valid bits), "
                  "max storage buffer %llu MiB\n",
                  i, d.name.c_str(), d.type.c_str(), d.driver_name.c_str(), d.driver_info.c_str(),
                  d.api_version.c_str(), d.subgroup_size, d.timestamp_period_ns, d.timestamp_valid_bits,
                  static_cast<unsigned long long>(d.max_storage_buffer_range >> 20));
    }
  });
}

}  // namespace hp::cli
