#include "scenario_keys.hpp"

#include "cachesim/preset.hpp"
#include "error.hpp"
#include "scenario.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace hp {

namespace {

using json = nlohmann::json;

json vec_json(const std::optional<glm::vec3>& v) {
  if (!v) return nullptr;
  return json::array({(*v).x, (*v).y, (*v).z});
}
std::optional<glm::vec3> vec_of(const json& v) {
  if (v.is_null()) return std::nullopt;
  return glm::vec3(v[0].get<float>(), v[1].get<float>(), v[2].get<float>());
}
template <class T>
json optional_json(const std::optional<T>& v) {
  return v ? json(*v) : json(nullptr);
}

// Shorthands for the table's rows.
ScenarioKey boolean(std::string path, bool def, std::string description) {
  ScenarioKey k;
  k.path = std::move(path);
  k.type = KeyType::boolean;
  k.default_value = def;
  k.description = std::move(description);
  return k;
}
ScenarioKey number(std::string path, double lo, double hi, json def, std::string description) {
  ScenarioKey k;
  k.path = std::move(path);
  k.type = KeyType::number;
  k.lo = lo;
  k.hi = hi;
  k.default_value = std::move(def);
  k.description = std::move(description);
  return k;
}
ScenarioKey integer(std::string path, std::int64_t lo, std::int64_t hi, std::int64_t def, std::string description) {
  ScenarioKey k;
  k.path = std::move(path);
  k.type = KeyType::integer;
  k.int_lo = lo;
  k.int_hi = hi;
  k.default_value = def;
  k.description = std::move(description);
  return k;
}
ScenarioKey choice(std::string path, std::vector<std::string> choices, std::string def, std::string description) {
  ScenarioKey k;
  k.path = std::move(path);
  k.type = KeyType::choice;
  k.choices = std::move(choices);
  k.default_value = std::move(def);
  k.description = std::move(description);
  return k;
}
ScenarioKey typed(std::string path, KeyType type, json def, std::string description) {
  ScenarioKey k;
  k.path = std::move(path);
  k.type = type;
  k.default_value = std::move(def);
  k.description = std::move(description);
  return k;
}

template <class F>
ScenarioKey with(ScenarioKey k, F&& edit) {
  edit(k);
  return k;
}

std::vector<ScenarioKey> make_keys() {
  using S = Scenario;
  using C = const KeyContext&;
  const auto is_compact = [](const S& s) { return s.frame.rt.reflection_path != ReflectionPath::direct; };
  const auto has_transform = [](const S& s) { return s.world_scale != 1.0 || s.world_translate != glm::dvec3(0.0); };
  const auto has_error = [](const S& s) { return s.error; };
  // The compute traversal's cells keep the ids they had before the driver traversals existed.
  const auto is_driver = [](const S& s) { return s.frame.rt.traversal != Traversal::compute; };
  std::vector<ScenarioKey> k;

  k.push_back(with(typed("name", KeyType::string, "", "a label for reports (not part of the id)"), [](ScenarioKey& e) {
    e.default_text = "the matrix's name";
    e.apply = [](S& s, const json& v, C) { s.name = v.get<std::string>(); };
  }));
  k.push_back(with(typed("scene", KeyType::string, "builtin:pica", "built-in scene name or glTF path"), [](auto& e) {
    e.range_text = "not empty";
    e.apply = [](S& s, const json& v, C c) {
      s.scene = v.get<std::string>();
      if (s.scene.empty()) c.fail("scene", "empty scene");
    };
    e.canonical = [](const S& s) { return json(s.scene); };
  }));

  // camera, light: unset keys keep the scene's (or the auto-framed camera's) values.
  k.push_back(with(typed("camera.position", KeyType::vec3, nullptr, "eye position"), [](auto& e) {
    e.default_text = "the scene's, or auto-framed";
    e.apply = [](S& s, const json& v, C) { s.camera_position = vec_of(v); };
    e.canonical = [](const S& s) { return vec_json(s.camera_position); };
  }));
  k.push_back(with(typed("camera.target", KeyType::vec3, nullptr, "point looked at"), [](auto& e) {
    e.default_text = "the scene's, or auto-framed";
    e.range_text = "not camera.position";
    e.apply = [](S& s, const json& v, C) { s.camera_target = vec_of(v); };
    e.canonical = [](const S& s) { return vec_json(s.camera_target); };
  }));
  k.push_back(with(number("camera.fov", 1.0, 179.0, nullptr, "vertical field of view, degrees"), [](auto& e) {
    e.default_text = "the scene's, or 45";
    e.apply = [](S& s, const json& v, C c) {
      if (!v.is_null()) s.camera_fov_deg = float(v.get<double>());
      // Checked once the whole camera object is read, as before the table: a bad fov is named first.
      if (s.camera_position && s.camera_target && *s.camera_position == *s.camera_target) {
        c.fail("camera.target", "equals camera.position");
      }
    };
    e.canonical = [](const S& s) { return optional_json(s.camera_fov_deg); };
  }));
  k.push_back(with(typed("light.direction", KeyType::vec3, nullptr, "toward the light (normalized)"), [](auto& e) {
    e.default_text = "the scene's";
    e.range_text = "not zero";
    e.apply = [](S& s, const json& v, C c) {
      s.light_direction = vec_of(v);
      if (s.light_direction && glm::length(*s.light_direction) == 0.0f) c.fail("light.direction", "zero vector");
    };
    e.canonical = [](const S& s) { return vec_json(s.light_direction); };
  }));
  k.push_back(with(number("light.intensity", 0.0, 1e6, nullptr, "light intensity"), [](auto& e) {
    e.default_text = "the scene's";
    e.apply = [](S& s, const json& v, C) {
      if (!v.is_null()) s.light_intensity = float(v.get<double>());
    };
    e.canonical = [](const S& s) { return optional_json(s.light_intensity); };
  }));

  k.push_back(
      with(typed("resolution", KeyType::resolution, json::array({1280, 720}), "image size in pixels"), [](auto& e) {
        e.range_text = "1.." + std::to_string(kMaxImageSide) + " per side";
        e.apply = [](S& s, const json& v, C) {
          s.frame.width = v[0].get<std::uint32_t>();
          s.frame.height = v[1].get<std::uint32_t>();
        };
        e.canonical = [](const S& s) { return json::array({s.frame.width, s.frame.height}); };
      }));
  k.push_back(with(boolean("reversed_z", false, "reversed-Z depth"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frame.reversed_z = v.get<bool>(); };
    e.canonical = [](const S& s) { return json(s.frame.reversed_z); };
  }));
  k.push_back(with(boolean("passes.shadows", true, "the shadow pass runs"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frame.rt.shadows = v.get<bool>(); };
    e.canonical = [](const S& s) { return json(s.frame.rt.shadows); };
  }));
  k.push_back(with(boolean("passes.reflections", true, "the reflection pass runs"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frame.rt.reflections = v.get<bool>(); };
    e.canonical = [](const S& s) { return json(s.frame.rt.reflections); };
  }));
  k.push_back(with(choice("geometry", {"indexed", "soup"}, "indexed",
                          "ray-tracing geometry: indexed (shared vertices) or a triangle soup"),
                   [](auto& e) {
                     e.apply = [](S& s, const json& v, C) {
                       s.frame.geometry = parse_geometry_layout(v.get<std::string>());
                     };
                     e.canonical = [](const S& s) { return json(to_string(s.frame.geometry)); };
                   }));
  k.push_back(
      with(choice("jitter", {"shared", "per-thread"}, "per-thread", "reflection jitter: one per frame or per pixel"),
           [](auto& e) {
             e.apply = [](S& s, const json& v, C) { s.frame.rt.jitter = parse_jitter_mode(v.get<std::string>()); };
             e.canonical = [](const S& s) { return json(to_string(s.frame.rt.jitter)); };
           }));
  k.push_back(with(choice("shadow_offset", {"normal-bias", "robust"}, "normal-bias",
                          "shadow-ray origin offset: `bias` along the normal, or by the point's error bound"),
                   [](auto& e) {
                     e.apply = [](S& s, const json& v, C) {
                       s.frame.rt.offset = parse_shadow_offset(v.get<std::string>());
                     };
                     e.canonical = [](const S& s) { return json(to_string(s.frame.rt.offset)); };
                   }));
  k.push_back(with(number("bias", 0.0, 1e6, 0.1, "normal-bias offset, world units"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frame.rt.bias = float(v.get<double>()); };
    e.canonical = [](const S& s) { return json(s.frame.rt.bias); };
  }));
  k.push_back(
      with(number("reflection_scale", 0.25, 1.0, 1.0, "reflection grid resolution relative to the image"), [](auto& e) {
        e.range_text = "1, 0.5 or 0.25";
        e.apply = [](S& s, const json& v, C c) {
          const double scale = v.get<double>();
          if (scale != 1.0 && scale != 0.5 && scale != 0.25) c.fail("reflection_scale", "must be 1, 0.5 or 0.25");
          s.frame.rt.reflection_divisor = std::uint32_t(std::lround(1.0 / scale));
        };
        e.canonical = [](const S& s) { return json(1.0 / s.frame.rt.reflection_divisor); };
      }));
  k.push_back(
      with(number("roughness_threshold", 0.0, 1.01, 0.35, "pixels rougher than this reflect nothing"), [](auto& e) {
        e.apply = [](S& s, const json& v, C) { s.frame.rt.roughness_threshold = float(v.get<double>()); };
        e.canonical = [](const S& s) { return json(s.frame.rt.roughness_threshold); };
      }));
  k.push_back(with(boolean("reflection_shadows", true, "shadow rays at reflection hits"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frame.rt.reflection_shadows = v.get<bool>(); };
    e.canonical = [](const S& s) { return json(s.frame.rt.reflection_shadows); };
  }));
  k.push_back(with(choice("reflection_path", {"direct", "compact"}, "direct",
                          "reflections traced per pixel, or compacted into a ray list first"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C) {
                       s.frame.rt.reflection_path = parse_reflection_path(v.get<std::string>());
                     };
                     e.canonical = [](const S& s) { return json(to_string(s.frame.rt.reflection_path)); };
                     e.canonical_when = is_compact;
                   }));
  k.push_back(with(choice("sort", {"none", "octant", "direction", "origin"}, "none",
                          "sort key of the compacted rays (compact path only)"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C) { s.frame.rt.sort = parse_sort_key(v.get<std::string>()); };
                     e.canonical = [](const S& s) { return json(to_string(s.frame.rt.sort)); };
                     e.canonical_when = is_compact;
                   }));
  k.push_back(with(choice("writeback", {"index", "reproject"}, "index",
                          "how compacted results reach their pixels (compact path only)"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C c) {
                       s.frame.rt.writeback = parse_writeback(v.get<std::string>());
                       const RayTracingOptions& rt = s.frame.rt;
                       const bool compact_keys = rt.sort != SortKey::none || rt.writeback != Writeback::index;
                       if (rt.reflection_path == ReflectionPath::direct && compact_keys) {
                         c.fail("sort", "sort and writeback apply to \"reflection_path\": \"compact\" only");
                       }
                     };
                     e.canonical = [](const S& s) { return json(to_string(s.frame.rt.writeback)); };
                     e.canonical_when = is_compact;
                   }));

  k.push_back(with(choice("traversal", {"compute", "ray-query", "pipeline"}, "compute",
                          "who walks the rays: the compute shaders' BVH, or the driver's acceleration structure "
                          "through ray queries or a ray-tracing pipeline"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C) {
                       s.frame.rt.traversal = parse_traversal(v.get<std::string>());
                     };
                     e.canonical = [](const S& s) { return json(to_string(s.frame.rt.traversal)); };
                     e.canonical_when = is_driver;
                   }));
  k.push_back(with(choice("as_order", {"leaf", "scene", "morton"}, "leaf",
                          "triangle order handed to the driver's acceleration-structure build (ray-query and "
                          "pipeline only)"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C) {
                       s.frame.rt.as_order = parse_as_order(v.get<std::string>());
                     };
                     e.canonical = [](const S& s) { return json(to_string(s.frame.rt.as_order)); };
                     e.canonical_when = is_driver;
                   }));
  k.push_back(with(choice("as_layout", {"flat", "instances"}, "flat",
                          "the driver's structure: one bottom level of the world-space triangles, or one per mesh "
                          "under a top level of the scene's instances (ray-query and pipeline only)"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C) {
                       s.frame.rt.as_layout = parse_as_layout(v.get<std::string>());
                     };
                     e.canonical = [](const S& s) { return json(to_string(s.frame.rt.as_layout)); };
                     e.canonical_when = is_driver;
                   }));
  k.push_back(with(boolean("as_compaction", false,
                           "compact the driver's bottom-level acceleration structure (ray-query and pipeline only)"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C c) {
                       s.frame.rt.as_compaction = v.get<bool>();
                       const RayTracingOptions& rt = s.frame.rt;
                       if (rt.traversal == Traversal::compute &&
                           (rt.as_order != AsOrder::leaf || rt.as_layout != AsLayout::flat || rt.as_compaction)) {
                         c.fail("as_order",
                                "as_order, as_layout and as_compaction apply to \"traversal\": "
                                "\"ray-query\" or \"pipeline\" only");
                       }
                       if (rt.as_layout == AsLayout::instances && rt.as_order != AsOrder::leaf) {
                         c.fail("as_order", "applies to \"as_layout\": \"flat\" (instances keep each mesh's order)");
                       }
                     };
                     e.canonical = [](const S& s) { return json(s.frame.rt.as_compaction); };
                     e.canonical_when = is_driver;
                   }));

  k.push_back(with(integer("bvh.buckets", 2, 1024, 12, "SAH buckets per binned axis"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frame.bvh.buckets = int(v.get<std::int64_t>()); };
    e.canonical = [](const S& s) { return json(s.frame.bvh.buckets); };
  }));
  k.push_back(
      with(boolean("bvh.full_sweep", false, "exact SAH over every split position instead of buckets"), [](auto& e) {
        e.apply = [](S& s, const json& v, C) { s.frame.bvh.full_sweep = v.get<bool>(); };
        e.canonical = [](const S& s) { return json(s.frame.bvh.full_sweep); };
      }));
  k.push_back(with(integer("bvh.leaf_size", 1, 1 << 20, 4, "largest leaf, in primitives"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frame.bvh.max_leaf_size = int(v.get<std::int64_t>()); };
    e.canonical = [](const S& s) { return json(s.frame.bvh.max_leaf_size); };
  }));
  k.push_back(
      with(choice("bvh.granularity", {"triangle", "object"}, "triangle", "BVH leaves hold triangles or objects"),
           [](auto& e) {
             e.apply = [](S& s, const json& v, C) {
               s.frame.bvh.granularity = v == "object" ? bvh::Granularity::object : bvh::Granularity::triangle;
             };
             e.canonical = [](const S& s) {
               return json(s.frame.bvh.granularity == bvh::Granularity::object ? "object" : "triangle");
             };
           }));
  k.push_back(with(choice("bvh.node_layout", {"binary32", "wide4"}, "binary32",
                          "nodes the compute traversal reads: the study's 32-byte binary nodes, or 64-byte 4-wide "
                          "nodes with quantized child boxes (leaves of at most 15)"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C c) {
                       s.frame.bvh.node_layout = parse_node_layout(v.get<std::string>());
                       if (s.frame.bvh.node_layout != bvh::NodeLayout::wide4) return;
                       if (s.frame.rt.traversal != Traversal::compute) {
                         c.fail("bvh.node_layout", "wide4 applies to \"traversal\": \"compute\" only");
                       }
                       if (s.frame.bvh.max_leaf_size > 15) {
                         c.fail("bvh.node_layout", "wide4 holds leaves of at most 15 primitives (bvh.leaf_size is " +
                                                       std::to_string(s.frame.bvh.max_leaf_size) + ")");
                       }
                     };
                     e.canonical = [](const S& s) { return json(to_string(s.frame.bvh.node_layout)); };
                     e.canonical_when = [](const S& s) { return s.frame.bvh.node_layout != bvh::NodeLayout::binary32; };
                   }));
  k.push_back(
      with(number("bvh.traversal_cost", 1e-6, 1e6, 0.5, "SAH cost of a traversal step (a test costs 1)"), [](auto& e) {
        e.apply = [](S& s, const json& v, C) { s.frame.bvh.traversal_cost = float(v.get<double>()); };
        e.canonical = [](const S& s) { return json(s.frame.bvh.traversal_cost); };
      }));

  k.push_back(with(integer("frames", 1, 100000, 10, "measured frames"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frames = std::uint32_t(v.get<std::int64_t>()); };
    e.canonical = [](const S& s) { return json(s.frames); };
  }));
  k.push_back(with(integer("warmup", 0, 100000, 3, "discarded frames before them"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.warmup = std::uint32_t(v.get<std::int64_t>()); };
    e.canonical = [](const S& s) { return json(s.warmup); };
  }));
  k.push_back(with(boolean("counters", true, "count rays, nodes visited and triangles tested per pass"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frame.rt.counters = v.get<bool>(); };
    e.canonical = [](const S& s) { return json(s.frame.rt.counters); };
  }));
  k.push_back(with(boolean("query_overhead", false,
                           "also time as many frames without timestamp queries, interleaved: the queries' overhead "
                           "(doubles the frames)"),
                   [](auto& e) {
                     e.apply = [](S& s, const json& v, C) { s.query_overhead = v.get<bool>(); };
                     e.canonical = [](const S&) { return json(true); };
                     e.canonical_when = [](const S& s) { return s.query_overhead; };
                   }));
  k.push_back(with(boolean("overlap", true,
                           "also time, beside each measured (serialized) frame, the frame as an application records "
                           "it: what overlapping the passes saves; false halves the GPU frames"),
                   [](auto& e) {
                     e.apply = [](S& s, const json& v, C) { s.overlap = v.get<bool>(); };
                     e.canonical = [](const S&) { return json(false); };
                     e.canonical_when = [](const S& s) { return !s.overlap; };
                   }));
  k.push_back(with(integer("seed", 0, 0xFFFFFFFFll, 1, "reflection jitter seed"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.frame.rt.seed = std::uint32_t(v.get<std::int64_t>()); };
    e.canonical = [](const S& s) { return json(s.frame.rt.seed); };
  }));
  k.push_back(with(typed("cache_preset", KeyType::string, "vega56", "cache model of the cache simulator"), [](auto& e) {
    e.range_text = "`vega56`, `ga102`, `h100` or a preset JSON file";
    e.apply = [](S& s, const json& v, C c) {
      s.cache_preset = v.get<std::string>();
      if (!c.present) return;
      try {
        (void)cachesim::find_preset(s.cache_preset);  // an unknown name or a broken preset file fails here, not mid-run
      } catch (const InputError& err) {
        c.fail("cache_preset", err.what());
      }
    };
    e.canonical = [](const S& s) { return json(s.cache_preset); };
  }));

  k.push_back(with(typed("trace.passes", KeyType::pass_list, json::array(),
                         "passes to capture in one more, instrumented frame and replay through the cache simulator "
                         "(only the G-buffer and these run in it; the cell's images come from the timed frames)"),
                   [](auto& e) {
                     e.range_text = "`\"shadows\"`, `\"reflections\"`";
                     e.default_text = "none";
                     e.apply = [](S& s, const json& v, C) { s.trace_passes = v.get<std::vector<std::string>>(); };
                     e.canonical = [](const S& s) { return json(s.trace_passes); };
                   }));
  k.push_back(
      with(integer("trace.sample_every", 1, 0xFFFFF, 1, "record only every k-th burst of workgroups"), [](auto& e) {
        e.apply = [](S& s, const json& v, C) { s.trace_sample_every = std::uint32_t(v.get<std::int64_t>()); };
        e.canonical = [](const S& s) { return json(s.trace_sample_every); };
      }));
  k.push_back(with(integer("trace.sample_block", 1, 2048, 1, "consecutive workgroups per sampled burst"), [](auto& e) {
    e.range_text = "a power of two, 1..2048";
    e.apply = [](S& s, const json& v, C c) {
      s.trace_sample_block = std::uint32_t(v.get<std::int64_t>());
      const std::uint32_t b = s.trace_sample_block;
      if ((b & (b - 1)) != 0) c.fail("trace.sample_block", "must be a power of two");
    };
    e.canonical = [](const S& s) { return json(s.trace_sample_block); };
    e.canonical_when = [](const S& s) { return s.trace_sample_block != 1; };
  }));
  k.push_back(
      with(boolean("trace.scale_model", true, "replay a sampled trace on 1/k of the CUs and the L2"), [](auto& e) {
        e.apply = [](S& s, const json& v, C) { s.trace_scale_model = v.get<bool>(); };
        e.canonical = [](const S& s) { return json(s.trace_scale_model); };
        e.canonical_when = [](const S& s) { return s.trace_sample_every > 1; };  // irrelevant to a full trace
      }));
  k.push_back(with(boolean("trace.keep", false, "keep the trace file beside the results (not part of the id)"),
                   [](auto& e) { e.apply = [](S& s, const json& v, C) { s.trace_keep = v.get<bool>(); }; }));
  k.push_back(with(choice("trace.image_layout", {"tiled", "linear"}, "tiled", "image address layout of the trace"),
                   [](auto& e) {
                     e.apply = [](S& s, const json& v, C) { s.trace_tiled_images = v == "tiled"; };
                     e.canonical = [](const S& s) { return json(s.trace_tiled_images ? "tiled" : "linear"); };
                   }));

  k.push_back(with(choice("inject.pass", {"shadows"}, "shadows", "the pass that does extra work"), [](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.inject_pass = v.get<std::string>(); };
    e.canonical = [](const S& s) { return json(s.inject_pass); };
  }));
  k.push_back(with(number("inject.fraction", 0.0, 1.0, 0.0,
                          "the shadow pass re-traces this first fraction of the rows (same image, more work): a known "
                          "slowdown for validating the gate; 0 = off"),
                   [](auto& e) {
                     e.apply = [](S& s, const json& v, C c) {
                       s.inject_fraction = float(v.get<double>());
                       if (s.inject_fraction > 0.0f && !s.frame.rt.shadows)
                         c.fail("inject", "injects work into shadows, which are off");
                       s.frame.rt.inject_shadow_fraction = s.inject_fraction;
                     };
                     e.canonical = [](const S& s) { return json(s.inject_fraction); };
                   }));

  k.push_back(with(number("transform.scale", 1e-6, 1e6, 1.0,
                          "the whole world (geometry, camera, clip planes) scaled about the origin"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C) { s.world_scale = v.get<double>(); };
                     e.canonical = [](const S& s) { return json(s.world_scale); };
                     e.canonical_when = has_transform;
                   }));
  k.push_back(with(typed("transform.translate", KeyType::vec3, json::array({0, 0, 0}),
                         "then moved: the same image far from the origin"),
                   [&](auto& e) {
                     e.range_text = "at most 1e7 from the origin";
                     e.apply = [](S& s, const json& v, C c) {
                       s.world_translate = glm::dvec3(*vec_of(v));
                       if (c.present && glm::length(s.world_translate) > 1e7) {
                         c.fail("transform.translate", "farther than 1e7 from the origin");
                       }
                     };
                     e.canonical = [](const S& s) {
                       return json::array({s.world_translate.x, s.world_translate.y, s.world_translate.z});
                     };
                     e.canonical_when = has_transform;
                   }));

  // "error": present (even empty), the error against the CPU reference is measured.
  k.push_back(with(integer("error.frames", 1, 4096, 16,
                           "after the timed frames, accumulate this many frames and compare them with the CPU "
                           "reference"),
                   [&](auto& e) {
                     e.apply = [](S& s, const json& v, C) { s.error_frames = std::uint32_t(v.get<std::int64_t>()); };
                     e.canonical = [](const S& s) { return json(s.error_frames); };
                     e.canonical_when = has_error;
                   }));
  k.push_back(
      with(integer("error.reference_samples", 1, 1 << 16, 256, "samples per pixel of the CPU reference"), [&](auto& e) {
        e.apply = [](S& s, const json& v, C) { s.reference_samples = std::uint32_t(v.get<std::int64_t>()); };
        e.canonical = [](const S& s) { return json(s.reference_samples); };
        e.canonical_when = has_error;
      }));
  k.push_back(
      with(number("error.threshold", 0.0, 1e6, 0.1, "per-pixel error counted as over the threshold"), [&](auto& e) {
        e.apply = [](S& s, const json& v, C) { s.error_threshold = v.get<double>(); };
        e.canonical = [](const S& s) { return json(s.error_threshold); };
        e.canonical_when = has_error;
      }));
  k.push_back(with(boolean("error.flip", true, "also compute LDR-FLIP and write its error map"), [&](auto& e) {
    e.apply = [](S& s, const json& v, C) { s.error_flip = v.get<bool>(); };
    e.canonical = [](const S& s) { return json(s.error_flip); };
    e.canonical_when = has_error;
  }));
  return k;
}

std::string number_text(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}

std::string type_text(KeyType t) {
  switch (t) {
    case KeyType::boolean: return "bool";
    case KeyType::number: return "number";
    case KeyType::integer: return "integer";
    case KeyType::string: return "string";
    case KeyType::choice: return "string";
    case KeyType::vec3: return "[x, y, z]";
    case KeyType::resolution: return "[width, height]";
    case KeyType::pass_list: return "list of strings";
  }
  return "?";
}

std::string range_text(const ScenarioKey& k) {
  if (!k.range_text.empty()) return k.range_text;
  switch (k.type) {
    case KeyType::number: return "[" + number_text(k.lo) + ", " + number_text(k.hi) + "]";
    case KeyType::integer: return std::to_string(k.int_lo) + ".." + std::to_string(k.int_hi);
    case KeyType::choice: {
      std::string s;
      for (const std::string& c : k.choices) s += (s.empty() ? "`\"" : ", `\"") + c + "\"`";
      return s;
    }
    default: return "";
  }
}

}  // namespace

void KeyContext::fail(const std::string& key_path, const std::string& why) const {
  throw InputError(file + ": " + (path.empty() ? key_path : path + "." + key_path) + ": " + why);
}

const std::vector<ScenarioKey>& scenario_keys() {
  static const std::vector<ScenarioKey> keys = make_keys();
  return keys;
}

std::string scenario_keys_markdown() {
  std::string md = "| key | type | range / choices | default | description |\n|---|---|---|---|---|\n";
  for (const ScenarioKey& k : scenario_keys()) {
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on a chain of a + b.
    std::string def = k.default_text;
    if (def.empty()) {
      def.push_back('`');
      def += k.default_value.dump();
      def.push_back('`');
    }
    std::string key(1, '`');
    key += k.path;
    key += '`';
    for (const std::string& cell : {key, type_text(k.type), range_text(k), def, k.description}) {
      md += "| ";
      md += cell;
      md += ' ';
    }
    md += "|\n";
  }
  return md;
}

}  // namespace hp
