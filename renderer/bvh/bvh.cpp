#include "bvh/bvh.hpp"

#include "bvh/build_common.hpp"
#include "error.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>

namespace hp::bvh {
namespace {

using detail::PrimRef;

constexpr float kInf = std::numeric_limits<float>::infinity();

detail::BuildParams validate(const BuildOptions& o, std::size_t primitives) {
  if (o.buckets < 2 || o.buckets > 1024) {
    throw InputError("bvh build: buckets " + std::to_string(o.buckets) + " is outside 2..1024");
  }
  if (!(o.traversal_cost >= 0.0f) || !std::isfinite(o.traversal_cost)) {
    throw InputError("bvh build: traversal cost must be a finite number >= 0");
  }
  constexpr int kMaxCount = (1 << (32 - HP_BVH_AXIS_BITS)) - 1;
  if (o.max_leaf_size < 1 || o.max_leaf_size > kMaxCount) {
    throw InputError("bvh build: leaf size " + std::to_string(o.max_leaf_size) + " is outside 1.." +
                     std::to_string(kMaxCount));
  }
  if (o.max_depth < 1 || o.max_depth > HP_BVH_STACK_SIZE) {
    throw InputError("bvh build: max depth " + std::to_string(o.max_depth) + " is outside 1.." +
                     std::to_string(HP_BVH_STACK_SIZE) + " (the traversal stack size)");
  }
  if (o.threads < 0) throw InputError("bvh build: threads must be >= 0");
  if (primitives > static_cast<std::size_t>(std::numeric_limits<int32_t>::max())) {
    throw InputError("bvh build: " + std::to_string(primitives) + " primitives exceed the 32-bit node offsets");
  }
  // The depth bound holds for any tree that median splits can produce within max_depth levels.
  if (detail::levels_needed(primitives, static_cast<uint64_t>(o.max_leaf_size)) > o.max_depth) {
    throw InputError("bvh build: " + std::to_string(primitives) + " primitives do not fit in a tree of depth " +
                     std::to_string(o.max_depth) + " with leaves of " + std::to_string(o.max_leaf_size) +
                     ": raise the leaf size or the depth");
  }
  detail::BuildParams p;
  p.buckets = o.buckets;
  p.all_axes = o.all_axes;
  p.traversal_cost = o.traversal_cost;
  p.max_leaf = static_cast<uint32_t>(o.max_leaf_size);
  p.max_depth = o.max_depth;
  p.threads = o.threads > 0 ? o.threads : std::max(1u, std::thread::hardware_concurrency());
  return p;
}

/// Primitive references for the valid primitives, in scene order, built in parallel chunks, and their bounds.
struct Refs {
  std::unique_ptr<PrimRef[]> data;  // uninitialised beyond size: 32 MB per million need no zero fill
  std::size_t size = 0;
  detail::RefBounds bounds;
};
Refs make_refs(std::span<const Triangle> tris, std::span<const uint32_t> object_first, int threads) {
  const bool objects = !object_first.empty();
  const std::size_t n = objects ? object_first.size() - 1 : tris.size();
  Refs refs{std::unique_ptr<PrimRef[]>(new PrimRef[std::max<std::size_t>(n, 1)]), 0, {}};
  detail::advise_huge_pages(refs.data.get(), n * sizeof(PrimRef));
  // Each chunk compacts its valid primitives to the front of its own slice; the slices are then joined.
  std::vector<std::size_t> chunk_begin(std::max(threads, 1)), chunk_count(std::max(threads, 1));
  std::vector<detail::RefBounds> chunk_bounds(chunk_begin.size());
  detail::Forker::parallel_chunks(n, threads, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::size_t k = b;
    detail::RefBounds bounds;
    for (std::size_t i = b; i < e; ++i) {
      if (!objects) {
        k += detail::make_triangle_ref(tris[i], static_cast<uint32_t>(i), refs.data[k], &bounds) ? 1 : 0;
        continue;
      }
      PrimRef r{glm::vec3(kInf), static_cast<uint32_t>(i), glm::vec3(-kInf), 0};
      bool any = false;
      for (uint32_t t = object_first[i]; t < object_first[i + 1]; ++t) {
        PrimRef tr;
        if (!detail::make_triangle_ref(tris[t], t, tr)) continue;  // the object's reference is folded below
        r.lo = glm::min(r.lo, tr.lo);
        r.hi = glm::max(r.hi, tr.hi);
        any = true;
      }
      if (any) {
        refs.data[k++] = r;
        bounds.add(r);
      }
    }
    chunk_begin[c] = b;
    chunk_count[c] = k - b;
    chunk_bounds[c] = bounds;
  });
  for (std::size_t c = 0; c < chunk_begin.size(); ++c) {
    refs.bounds.add(chunk_bounds[c]);
    if (chunk_count[c] == 0) continue;
    if (chunk_begin[c] != refs.size) {
      std::memmove(&refs.data[refs.size], &refs.data[chunk_begin[c]], chunk_count[c] * sizeof(PrimRef));
    }
    refs.size += chunk_count[c];
  }
  return refs;
}

/// Rewrites the builders' pair layout (children at offset, offset + 1) depth-first, the first child right
/// after its parent, and measures the depth.
struct Flattener {
  const gpu::BvhNode* in;
  std::vector<gpu::BvhNode>& out;
  int max_depth = 0;

  void emit(uint32_t i, int depth) {
    const uint32_t at = static_cast<uint32_t>(out.size());
    out.push_back(in[i]);
    if (node_is_leaf(in[i])) {
      max_depth = std::max(max_depth, depth);
      return;
    }
    const uint32_t child = static_cast<uint32_t>(in[i].offset);
    emit(child, depth + 1);
    out[at].offset = static_cast<int>(out.size());
    emit(child + 1, depth + 1);
  }
};

}  // namespace

Bvh build_bvh(std::span<const Triangle> triangles, const BuildOptions& options,
              std::span<const uint32_t> object_first) {
  const bool objects = options.granularity == Granularity::object;
  if (objects) {
    if (object_first.empty() || object_first.front() != 0 || object_first.back() != triangles.size()) {
      throw InputError("bvh build: object ranges must start at 0 and end at the triangle count (" +
                       std::to_string(triangles.size()) + ")");
    }
    for (std::size_t i = 1; i < object_first.size(); ++i) {
      if (object_first[i] < object_first[i - 1]) {
        throw InputError("bvh build: object ranges decrease at object " + std::to_string(i - 1));
      }
    }
  } else if (!object_first.empty()) {
    throw InputError("bvh build: object ranges given for the triangle granularity");
  }
  if (triangles.size() > static_cast<std::size_t>(std::numeric_limits<int32_t>::max())) {
    throw InputError("bvh build: " + std::to_string(triangles.size()) + " triangles exceed 32-bit indices");
  }
  const std::size_t nprims = objects ? object_first.size() - 1 : triangles.size();
  const detail::BuildParams params = validate(options, nprims);

  Bvh bvh;
  bvh.granularity = options.granularity;
  bvh.traversal_cost = options.traversal_cost;
  if (objects) bvh.object_first.assign(object_first.begin(), object_first.end());

  using Clock = std::chrono::steady_clock;
  const Clock::time_point refs_start = Clock::now();
  Refs refs = make_refs(triangles, objects ? object_first : std::span<const uint32_t>{}, params.threads);
  bvh.phases.references_ms = detail::ms_between(refs_start, Clock::now());
  if (refs.size == 0) {
    // An inverted box fails every slab test, so a traversal that tests the root's box ends at once.
    bvh.nodes.push_back(gpu::BvhNode{glm::vec3(kInf), 0, glm::vec3(-kInf), 0});
    return bvh;
  }

  const std::span<PrimRef> prims(refs.data.get(), refs.size);
  const Clock::time_point tree_start = Clock::now();
  detail::PairTree tree = options.full_sweep
                              ? detail::build_full_sweep(prims, params)
                              : detail::build_binned(prims, params, detail::BinnedIsa::automatic, &refs.bounds);
  if (tree.nodes) {
    bvh.nodes.reserve(tree.node_count);
    Flattener f{tree.nodes.get(), bvh.nodes};
    f.emit(0, 0);
    bvh.max_depth = f.max_depth;
  } else {
    bvh.nodes = std::move(tree.flat);
    bvh.max_depth = tree.flat_max_depth;
  }
  bvh.prim_ids = std::move(tree.order);
  bvh.depth_limited_splits = tree.depth_limited_splits;
  tree.phases.references_ms = bvh.phases.references_ms;
  tree.phases.tree_ms = detail::ms_between(tree_start, Clock::now());
  bvh.phases = tree.phases;
  if (bvh.max_depth > options.max_depth) {
    // The builders bound the depth by construction; this is a guard against a bug, not an input error.
    throw std::logic_error("bvh build: depth " + std::to_string(bvh.max_depth) + " exceeds the bound " +
                           std::to_string(options.max_depth));
  }
  return bvh;
}

BvhStats bvh_stats(const Bvh& bvh) {
  BvhStats s;
  if (bvh.prim_ids.empty()) return s;
  const auto tri_count = [&](uint32_t first, uint32_t count) -> std::size_t {
    if (bvh.granularity == Granularity::triangle) return count;
    std::size_t total = 0;
    for (uint32_t k = first; k < first + count; ++k) {
      const uint32_t obj = bvh.prim_ids[k];
      total += bvh.object_first[obj + 1] - bvh.object_first[obj];
    }
    return total;
  };
  const double root_area = detail::half_area(bvh.nodes[0].bmin, bvh.nodes[0].bmax);
  const double inv_root = root_area > 0.0 ? 1.0 / root_area : 0.0;
  // Depth-first walk with an explicit stack of (node, depth).
  std::vector<std::pair<uint32_t, int>> stack{{0u, 0}};
  while (!stack.empty()) {
    const auto [i, depth] = stack.back();
    stack.pop_back();
    const gpu::BvhNode& n = bvh.nodes[i];
    ++s.nodes;
    const double rel_area = detail::half_area(n.bmin, n.bmax) * inv_root;
    if (node_is_leaf(n)) {
      const uint32_t count = node_count(n);
      ++s.leaves;
      s.primitives += count;
      const std::size_t tris = tri_count(static_cast<uint32_t>(n.offset), count);
      s.triangles += tris;
      if (s.leaf_size_histogram.size() <= count) s.leaf_size_histogram.resize(count + 1);
      ++s.leaf_size_histogram[count];
      s.max_depth = std::max(s.max_depth, depth);
      s.sah_cost += count * rel_area;
      s.sah_cost_triangles += static_cast<double>(tris) * rel_area;
    } else {
      s.sah_cost += bvh.traversal_cost * rel_area;
      s.sah_cost_triangles += bvh.traversal_cost * rel_area;
      stack.emplace_back(static_cast<uint32_t>(n.offset), depth + 1);
      stack.emplace_back(i + 1, depth + 1);
    }
  }
  return s;
}

LeafOrderTriangles leaf_order(const Bvh& bvh, std::span<const Triangle> triangles) {
  LeafOrderTriangles out;
  if (bvh.granularity == Granularity::triangle) {
    out.triangles.resize(bvh.prim_ids.size());
    out.scene_index = bvh.prim_ids;
    for (std::size_t k = 0; k < bvh.prim_ids.size(); ++k) out.triangles[k] = triangles[bvh.prim_ids[k]];
    return out;
  }
  out.object_first.reserve(bvh.prim_ids.size() + 1);
  out.object_first.push_back(0);
  for (const uint32_t obj : bvh.prim_ids) {
    for (uint32_t t = bvh.object_first[obj]; t < bvh.object_first[obj + 1]; ++t) {
      Triangle tri = triangles[t];
      if (is_degenerate(tri)) {
        // A point: every edge function is exactly 0, in float and in double, so it is never hit.
        const glm::vec3 p = !glm::any(glm::isnan(tri.v0)) && !glm::any(glm::isinf(tri.v0)) ? tri.v0 : glm::vec3(0.0f);
        tri = Triangle{p, p, p};
      }
      out.triangles.push_back(tri);
      out.scene_index.push_back(t);
    }
    out.object_first.push_back(static_cast<uint32_t>(out.triangles.size()));
  }
  return out;
}

}  // namespace hp::bvh
