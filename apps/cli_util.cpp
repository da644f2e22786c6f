#include "apps/cli_util.hpp"

#include "error.hpp"
#include "output_path.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <unistd.h>

namespace hp::cli {

Progress::Progress(std::string what, bool quiet)
    : what_(std::move(what)),
      quiet_(quiet),
      tty_(::isatty(::fileno(stderr)) != 0),
      start_(std::chrono::steady_clock::now()),
      last_(start_) {}

void Progress::update(uint64_t done, uint64_t total, const std::string& detail) {
  if (quiet_ || total == 0) return;
  const auto now = std::chrono::steady_clock::now();
  const double el = std::chrono::duration<double>(now - start_).count();
  const bool last = done >= total;
  if (!tty_ && !last && std::chrono::duration<double>(now - last_).count() < 5.0) return;
  last_ = now;
  char eta[32] = "?";
  if (done > 0) std::snprintf(eta, sizeof(eta), "%.0fs", el / double(done) * double(total - done));
  std::fprintf(stderr, "%s%s: %llu/%llu%s%s, %.1f s, ETA %s%s", tty_ ? "\r" : "", what_.c_str(),
               (unsigned long long)done, (unsigned long long)total, detail.empty() ? "" : ", ", detail.c_str(), el, eta,
               tty_ && !last ? "   " : "\n");
  std::fflush(stderr);
}

std::string format_bytes(uint64_t bytes) {
  char buf[32];
  if (bytes < 1000) {
    std::snprintf(buf, sizeof buf, "%llu B", (unsigned long long)bytes);
  } else if (bytes < 1000ull * 1000 * 1000) {
    std::snprintf(buf, sizeof buf, "%.1f %s", double(bytes) / (bytes < 1000ull * 1000 ? 1e3 : 1e6),
                  bytes < 1000ull * 1000 ? "kB" : "MB");
  } else {
    std::snprintf(buf, sizeof buf, "%.2f GB", double(bytes) / 1e9);
  }
  return buf;
}

CLI::Validator finite_range(double lo, double hi) {
  CLI::Validator finite(
      [](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0') return "not a number: " + text;
        if (!std::isfinite(v)) return "not a finite number: " + text;
        return {};
      },
      "", "finite");
  return finite & CLI::Range(lo, hi);
}

glm::vec3 parse_vec3(const std::string& option, const std::string& text) {
  std::vector<float> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      float f = std::stof(item, &used);
      if (used != item.size() || !std::isfinite(f)) throw std::invalid_argument(item);
      v.push_back(f);
    } catch (const std::exception&) {
      throw InputError(option + " '" + text + "': '" + item + "' is not a finite number");
    }
  }
  if (v.size() != 3) throw InputError(option + " '" + text + "': expected three numbers x,y,z");
  return {v[0], v[1], v[2]};
}

void ViewOptions::add_to(CLI::App* cmd) {
  cmd->add_option("--camera-pos", camera_pos, "camera position x,y,z (default: the scene's, or auto-framed)");
  cmd->add_option("--camera-target", camera_target, "point the camera looks at, x,y,z");
  cmd->add_option("--fov", fov_deg, "vertical field of view in degrees")->check(finite_range(1.0, 179.0));
  cmd->add_option("--light-dir", light_dir, "direction toward the directional light, x,y,z");
}

Camera ViewOptions::camera_for(const Scene& scene, float aspect) const {
  Camera cam = scene.has_camera ? scene.camera : auto_frame(scene, aspect);
  if (!camera_pos.empty()) cam.position = parse_vec3("--camera-pos", camera_pos);
  if (!camera_target.empty()) cam.target = parse_vec3("--camera-target", camera_target);
  if (fov_deg > 0.0f) cam.vfov_deg = fov_deg;
  if (glm::length(cam.target - cam.position) == 0.0f) {
    throw InputError("--camera-pos and --camera-target are the same point");
  }
  return cam;
}

void ViewOptions::apply_light(Scene& scene) const {
  if (light_dir.empty()) return;
  glm::vec3 d = parse_vec3("--light-dir", light_dir);
  if (glm::length(d) == 0.0f) throw InputError("--light-dir '" + light_dir + "': zero vector");
  scene.light.direction = glm::normalize(d);
}

std::pair<CLI::Option*, CLI::Option*> add_device_options(CLI::App* cmd, std::string& device, bool& validate) {
  CLI::Option* d = cmd->add_option("--device", device,
                                   "Vulkan device: index or name substring (default: discrete GPU, else lavapipe)");
  CLI::Option* v =
      cmd->add_flag("--validate", validate, "enable the Khronos validation layer; any message fails the run");
  return {d, v};
}

void add_traversal_options(CLI::App* cmd, TraversalOptions& o) {
  cmd->add_option("--traversal", o.traversal,
                  "who walks the rays: compute (hybridprof's BVH in compute shaders), ray-query (the driver's "
                  "acceleration structure from the same compute shaders) or pipeline (a ray-tracing pipeline)")
      ->capture_default_str();
  cmd->add_option("--as-order", o.as_order,
                  "ray-query/pipeline: triangle order handed to the driver's build: leaf (the compute BVH's), "
                  "scene or morton")
      ->capture_default_str();
  cmd->add_option("--as-layout", o.as_layout,
                  "ray-query/pipeline: flat (one bottom level of the world-space triangles) or instances (a bottom "
                  "level per mesh under a top level of the scene's instances)")
      ->capture_default_str();
  cmd->add_flag("--as-compaction", o.as_compaction,
                "ray-query/pipeline: compact the bottom-level acceleration structures after their build");
}

void apply_traversal_options(RayTracingOptions& rt, const TraversalOptions& o) {
  rt.traversal = parse_traversal(o.traversal);
  rt.as_order = parse_as_order(o.as_order);
  rt.as_layout = parse_as_layout(o.as_layout);
  rt.as_compaction = o.as_compaction;
  if (rt.traversal == Traversal::compute &&
      (rt.as_order != AsOrder::leaf || rt.as_layout != AsLayout::flat || o.as_compaction)) {
    throw InputError("--as-order/--as-layout/--as-compaction apply to --traversal ray-query or pipeline only");
  }
  if (rt.as_layout == AsLayout::instances && rt.as_order != AsOrder::leaf) {
    throw InputError("--as-order " + o.as_order + ": applies to --as-layout flat (instances keep each mesh's order)");
  }
}

std::string describe_accel(const AsBuildStats& s, AsOrder order, AsLayout layout) {
  char line[400];
  const std::string shape = layout == AsLayout::instances
                                ? std::to_string(s.blas_count) + " bottom levels (one per mesh), " +
                                      std::to_string(s.instances) + " instances, " + std::to_string(s.triangles) +
                                      " mesh triangles"
                                : std::to_string(s.triangles) + " triangles in " + to_string(order) + " order";
  std::snprintf(line, sizeof line,
                "acceleration structure: %s, built in %.2f ms (%s), BLAS %.2f MiB%s, TLAS %.1f KiB, build scratch "
                "%.1f KiB",
                shape.c_str(), s.build_ms, s.build_timed_on_device ? "GPU timestamps" : "host wall time",
                double(s.blas_bytes) / 1048576.0, s.compacted ? " (compacted)" : "", double(s.tlas_bytes) / 1024.0,
                double(s.scratch_bytes) / 1048576.0);
  return line;
}

void FrameOptions::add_to(CLI::App* cmd) {
  cmd->add_option("--scene", scene, "builtin:pica|cornell|sphere-1m|terrain-1m, or a .gltf/.glb path")
      ->capture_default_str();
  cmd->add_option("--width", width, "image width in pixels")->capture_default_str();
  cmd->add_option("--height", height, "image height in pixels")->capture_default_str();
  cmd->add_flag("--reversed-z", reversed_z, "reversed-Z depth buffer (near = 1, far = 0)");
  cmd->add_option("--geometry", geometry, "triangle fetch: indexed (EBO) or soup (de-indexed, no EBO)")
      ->capture_default_str();
  cmd->add_option("--jitter", jitter, "reflection jitter: shared (one offset per frame) or per-thread")
      ->capture_default_str();
  cmd->add_option("--shadow-offset", shadow_offset, "ray origin offset: normal-bias or robust")->capture_default_str();
  cmd->add_option("--bias", bias, "normal-bias distance in world units (the study's 0.1)")->capture_default_str();
  cmd->add_option("--reflection-scale", reflection_scale, "reflection resolution per axis: 1, 0.5 or 0.25")
      ->capture_default_str();
  cmd->add_option("--roughness-threshold", roughness_threshold, "pixels with roughness below it reflect")
      ->check(finite_range(0.0, 1.01))
      ->capture_default_str();
  cmd->add_flag("--no-shadows", no_shadows, "skip the shadow pass");
  cmd->add_flag("--no-reflections", no_reflections, "skip the reflection and accumulation passes");
  cmd->add_flag("--no-reflection-shadows", no_reflection_shadows, "shade reflection hits without a shadow ray");
  cmd->add_option("--granularity", granularity, "BVH leaves: triangle, or object (the study's Unity BVH)")
      ->capture_default_str();
  cmd->add_option("--buckets", buckets, "SAH buckets of the BVH build")
      ->check(CLI::Range(2, 1024))
      ->capture_default_str();
  cmd->add_option("--leaf-size", leaf_size, "largest BVH leaf")->check(CLI::Range(1, 1 << 20))->capture_default_str();
  cmd->add_option("--node-layout", node_layout,
                  "BVH nodes the compute traversal reads: binary32 (the study's) or wide4 (4-wide, quantized boxes)")
      ->capture_default_str();
  cmd->add_option("--seed", seed, "seed of the reflection jitter")->capture_default_str();
  cmd->add_option("--reflection-path", reflection_path,
                  "direct (a thread per reflective pixel) or compact (append, sort, consume: the study's 4.2)")
      ->capture_default_str();
  cmd->add_option("--sort", sort, "compact path: sort key none, octant, direction or origin")->capture_default_str();
  cmd->add_option("--writeback", writeback, "compact path: index (exact) or reproject (the study's)")
      ->capture_default_str();
  add_traversal_options(cmd, traversal);
  add_device_options(cmd, device, validate);
  cmd->add_flag("--host-timing", host_timing,
                "time each pass on the host (one submission per pass, labelled cpu-wall), as on a queue "
                "without timestamps");
  view.add_to(cmd);
}

FrameSettings FrameOptions::settings() const {
  validate_extent(width, height, kMaxImageSide);
  FrameSettings s;
  s.width = width;
  s.height = height;
  s.reversed_z = reversed_z;
  s.host_timing = host_timing;
  s.geometry = parse_geometry_layout(geometry);
  s.rt.shadows = !no_shadows;
  s.rt.reflections = !no_reflections;
  s.rt.offset = parse_shadow_offset(shadow_offset);
  s.rt.bias = bias;
  s.rt.jitter = parse_jitter_mode(jitter);
  if (reflection_scale == 1.0f) {
    s.rt.reflection_divisor = 1;
  } else if (reflection_scale == 0.5f) {
    s.rt.reflection_divisor = 2;
  } else if (reflection_scale == 0.25f) {
    s.rt.reflection_divisor = 4;
  } else {
    throw InputError("--reflection-scale " + std::to_string(reflection_scale) + ": must be 1, 0.5 or 0.25");
  }
  s.rt.roughness_threshold = roughness_threshold;
  s.rt.reflection_shadows = !no_reflection_shadows;
  s.rt.seed = seed;
  if (granularity == "triangle") {
    s.bvh.granularity = bvh::Granularity::triangle;
  } else if (granularity == "object") {
    s.bvh.granularity = bvh::Granularity::object;
  } else {
    throw InputError("--granularity " + granularity + ": choose triangle or object");
  }
  s.bvh.buckets = buckets;
  s.bvh.max_leaf_size = leaf_size;
  s.bvh.node_layout = parse_node_layout(node_layout);
  s.rt.reflection_path = parse_reflection_path(reflection_path);
  s.rt.sort = parse_sort_key(sort);
  s.rt.writeback = parse_writeback(writeback);
  if (s.rt.reflection_path == ReflectionPath::direct &&
      (s.rt.sort != SortKey::none || s.rt.writeback != Writeback::index)) {
    throw InputError("--sort/--writeback apply to --reflection-path compact only");
  }
  apply_traversal_options(s.rt, traversal);
  if (s.bvh.node_layout == bvh::NodeLayout::wide4) {
    if (s.rt.traversal != Traversal::compute)
      throw InputError("--node-layout wide4 applies to --traversal compute only");
    if (s.bvh.max_leaf_size > 15) {
      throw InputError("--node-layout wide4 holds leaves of at most 15 primitives: --leaf-size " +
                       std::to_string(s.bvh.max_leaf_size));
    }
  }
  return s;
}

}  // namespace hp::cli
