// Small helpers shared by the subcommands: parsing "x,y,z" vectors, camera and light options.
#pragma once

#include "frame.hpp"
#include "scene/scene.hpp"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdint>
#include <fstream>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hp::cli {

/// Progress of a long command on stderr: one line updated in place with an ETA on a terminal, else a plain
/// line at most every few seconds and at the end (a CI log); nothing when quiet.
class Progress {
 public:
  Progress(std::string what, bool quiet);
  /// Call as work completes; done == total ends the line. `detail` follows the count ("3.1 M records").
  void update(uint64_t done, uint64_t total, const std::string& detail = "");

 private:
  std::string what_;
  bool quiet_, tty_;
  std::chrono::steady_clock::time_point start_, last_;
};

/// A byte count for people: "812 B", "3.4 MB", "1.25 GB" (decimal units, as disk tools print them).
std::string format_bytes(uint64_t bytes);

/// A closed range for a floating-point option that also rejects NaN (which CLI::Range lets through: every
/// comparison with NaN is false).
CLI::Validator finite_range(double lo, double hi);

/// Parses "x,y,z" into a vector; throws hp::InputError naming the option.
glm::vec3 parse_vec3(const std::string& option, const std::string& text);

/// Camera and light overrides from the command line, applied on top of the scene's own.
struct ViewOptions {
  std::string camera_pos, camera_target, light_dir;
  float fov_deg = 0.0f;  // 0 = keep
  void add_to(CLI::App* cmd);
  /// The camera to render with: the scene's (or auto-framed) with the overrides applied.
  Camera camera_for(const Scene& scene, float aspect) const;
  /// Applies the light override to the scene.
  void apply_light(Scene& scene) const;
};

/// The Vulkan device choice: `--device` (index or name substring) and `--validate` (the Khronos layer, any
/// message fails the run). Returns the two options, for `needs` constraints.
std::pair<CLI::Option*, CLI::Option*> add_device_options(CLI::App* cmd, std::string& device, bool& validate);

/// `--traversal`, `--as-order`, `--as-compaction` (render, trace, bvh --gpu), and their validation into `rt`
/// (InputError naming the option).
struct TraversalOptions {
  std::string traversal = "compute", as_order = "leaf", as_layout = "flat";
  bool as_compaction = false;
};
void add_traversal_options(CLI::App* cmd, TraversalOptions& o);
void apply_traversal_options(RayTracingOptions& rt, const TraversalOptions& o);

/// One line on the driver's acceleration structure: triangles, order, build time and how it was timed, sizes.
std::string describe_accel(const AsBuildStats& s, AsOrder order, AsLayout layout);

/// The options that describe a frame (scene, resolution, passes and their modes, BVH build, device), shared by
/// `render` and `trace`.
struct FrameOptions {
  std::string scene = "builtin:pica";
  uint32_t width = 1280, height = 720;
  bool reversed_z = false;
  std::string geometry = "indexed";
  std::string jitter = "per-thread";
  std::string shadow_offset = "normal-bias";
  float bias = 0.1f;
  float reflection_scale = 1.0f;
  float roughness_threshold = 0.35f;
  bool no_shadows = false, no_reflections = false, no_reflection_shadows = false;
  std::string granularity = "triangle";
  int buckets = 12;
  int leaf_size = 4;
  std::string node_layout = "binary32";
  uint32_t seed = 1;
  std::string reflection_path = "direct", sort = "none", writeback = "index";
  TraversalOptions traversal;
  std::string device;
  bool validate = false;
  bool host_timing = false;
  ViewOptions view;

  void add_to(CLI::App* cmd);
  /// Validated settings; throws hp::InputError naming the option.
  FrameSettings settings() const;
};

}  // namespace hp::cli
