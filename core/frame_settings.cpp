#include "frame_settings.hpp"

#include "error.hpp"

#include <algorithm>

namespace hp {

GeometryLayout parse_geometry_layout(const std::string& name) {
  if (name == "indexed" || name == "ebo") return GeometryLayout::indexed;
  if (name == "soup" || name == "no-ebo") return GeometryLayout::soup;
  throw InputError("--geometry " + name + ": unknown layout (choose indexed or soup)");
}

const char* to_string(GeometryLayout g) { return g == GeometryLayout::indexed ? "indexed" : "soup"; }

bvh::NodeLayout parse_node_layout(const std::string& name) {
  if (name == "binary32") return bvh::NodeLayout::binary32;
  if (name == "wide4") return bvh::NodeLayout::wide4;
  throw InputError("--node-layout " + name + ": unknown BVH node layout (choose binary32 or wide4)");
}

const char* to_string(bvh::NodeLayout l) { return l == bvh::NodeLayout::wide4 ? "wide4" : "binary32"; }

ShadowOffset parse_shadow_offset(const std::string& name) {
  if (name == "normal-bias") return ShadowOffset::normal_bias;
  if (name == "robust") return ShadowOffset::robust;
  throw InputError("--shadow-offset " + name + ": unknown mode (choose normal-bias or robust)");
}

JitterMode parse_jitter_mode(const std::string& name) {
  if (name == "shared") return JitterMode::shared;
  if (name == "per-thread") return JitterMode::per_thread;
  throw InputError("--jitter " + name + ": unknown mode (choose shared or per-thread)");
}

ReflectionPath parse_reflection_path(const std::string& name) {
  if (name == "direct") return ReflectionPath::direct;
  if (name == "compact") return ReflectionPath::compact;
  throw InputError("--reflection-path " + name + ": unknown path (choose direct or compact)");
}

SortKey parse_sort_key(const std::string& name) {
  if (name == "none") return SortKey::none;
  if (name == "octant") return SortKey::octant;
  if (name == "direction") return SortKey::direction;
  if (name == "origin") return SortKey::origin;
  throw InputError("--sort " + name + ": unknown key (choose none, octant, direction, origin)");
}

Writeback parse_writeback(const std::string& name) {
  if (name == "index") return Writeback::index;
  if (name == "reproject") return Writeback::reproject;
  throw InputError("--writeback " + name + ": unknown mode (choose index or reproject)");
}

Traversal parse_traversal(const std::string& name) {
  if (name == "compute") return Traversal::compute;
  if (name == "ray-query") return Traversal::ray_query;
  if (name == "pipeline") return Traversal::pipeline;
  throw InputError("--traversal " + name + ": unknown traversal (choose compute, ray-query or pipeline)");
}

AsOrder parse_as_order(const std::string& name) {
  if (name == "leaf") return AsOrder::leaf;
  if (name == "scene") return AsOrder::scene;
  if (name == "morton") return AsOrder::morton;
  throw InputError("--as-order " + name + ": unknown order (choose leaf, scene or morton)");
}

AsLayout parse_as_layout(const std::string& name) {
  if (name == "flat") return AsLayout::flat;
  if (name == "instances") return AsLayout::instances;
  throw InputError("--as-layout " + name + ": unknown layout (choose flat or instances)");
}

const char* to_string(AsLayout l) { return l == AsLayout::instances ? "instances" : "flat"; }

const char* to_string(Traversal t) {
  switch (t) {
    case Traversal::ray_query: return "ray-query";
    case Traversal::pipeline: return "pipeline";
    default: return "compute";
  }
}

const char* to_string(AsOrder o) {
  switch (o) {
    case AsOrder::scene: return "scene";
    case AsOrder::morton: return "morton";
    default: return "leaf";
  }
}

const char* to_string(ReflectionPath p) { return p == ReflectionPath::compact ? "compact" : "direct"; }
const char* to_string(SortKey k) {
  switch (k) {
    case SortKey::octant: return "octant";
    case SortKey::direction: return "direction";
    case SortKey::origin: return "origin";
    default: return "none";
  }
}
const char* to_string(Writeback w) { return w == Writeback::reproject ? "reproject" : "index"; }

uint32_t sort_key_bits(SortKey k) {
  switch (k) {
    case SortKey::octant: return 3;
    case SortKey::direction: return 20;
    case SortKey::origin: return 30;
    default: return 0;
  }
}

const char* to_string(ShadowOffset o) { return o == ShadowOffset::robust ? "robust" : "normal-bias"; }
const char* to_string(JitterMode j) { return j == JitterMode::shared ? "shared" : "per-thread"; }

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

}  // namespace hp
