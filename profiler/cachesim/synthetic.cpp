#include "cachesim/synthetic.hpp"

#include <cmath>

namespace hp::cachesim {

namespace {

uint64_t hash64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
double unit(uint64_t h) { return double(h >> 11) * (1.0 / 9007199254740992.0); }

constexpr uint32_t kEpilogueSeq = 1u << 20;

}  // namespace

trace::Trace make_bvh_like_trace(const SyntheticBvhOptions& o) {
  using trace::BufferInfo;
  using trace::BufferKind;
  trace::Trace t;
  t.header.image_width = o.width;
  t.header.image_height = o.height;
  const uint64_t nodes = (uint64_t(2) << o.tree_depth) - 1;
  const uint64_t leaves = uint64_t(1) << o.tree_depth;
  // Bases 64 KiB-aligned and apart, like separate allocations.
  auto align = [](uint64_t v) { return (v + 0xFFFF) & ~uint64_t(0xFFFF); };
  uint64_t base = 0x100000000ull;
  auto add = [&](uint32_t id, const char* name, uint64_t size, BufferKind kind) -> BufferInfo& {
    BufferInfo b;
    b.id = id;
    b.name = name;
    b.base_address = base;
    b.size_bytes = size;
    b.kind = kind;
    base = align(base + size + 1);
    t.header.buffers.push_back(b);
    return t.header.buffers.back();
  };
  add(0, "nodes", nodes * 32, BufferKind::buffer);
  add(1, "triangles", leaves * 2 * 48, BufferKind::buffer);
  BufferInfo& gb = add(2, "gbuffer", uint64_t(o.width) * o.height * 8, BufferKind::image_tiled);
  gb.texel_bytes = 8, gb.width = o.width, gb.height = o.height, gb.tile_width = 8, gb.tile_height = 8;
  // The tiled layout may pad the last tile row/column: reserve the padded size in the address space.
  base = align(gb.base_address + uint64_t((o.width + 7) / 8 * 8) * ((o.height + 7) / 8 * 8) * 8 + 1);
  BufferInfo& out = add(3, "output", uint64_t(o.width) * o.height * 4, BufferKind::image_linear);
  out.texel_bytes = 4, out.width = o.width, out.height = o.height, out.row_pitch_bytes = o.width * 4;

  trace::PassInfo pass;
  pass.name = "bvh_like";
  pass.dispatch.workgroup_size[0] = 8;
  pass.dispatch.workgroup_size[1] = 8;
  pass.dispatch.workgroup_count[0] = (o.width + 7) / 8;
  pass.dispatch.workgroup_count[1] = (o.height + 7) / 8;
  t.passes.push_back(pass);
  std::vector<trace::TraceRecord> recs;

  struct Item {
    uint64_t node;
    uint32_t depth;
    uint64_t leaf_first;  // index of the subtree's leftmost leaf (triangles are stored by leaf)
    double lo[2], hi[2];
  };
  std::vector<Item> stack;
  const uint32_t groups_x = pass.dispatch.workgroup_count[0];
  for (uint32_t y = 0; y < o.height; ++y)
    for (uint32_t x = 0; x < o.width; ++x) {
      const uint32_t inv = ((y / 8) * groups_x + x / 8) * 64 + (y % 8) * 8 + x % 8;
      uint32_t seq = 0;
      auto rec = [&](uint32_t buffer, uint32_t kind, uint32_t size, uint64_t offset) {
        recs.push_back({inv, seq++, HP_TRACE_INFO(buffer, kind, size), uint32_t(offset)});
      };
      const uint64_t pixel = uint64_t(y) * o.width + x;
      rec(2, HP_TRACE_LOAD, 8, pixel * 8);
      const uint64_t h = hash64(pixel ^ (o.seed << 32));
      double p[2] = {(x + 0.5) / o.width, (y + 0.5) / o.height};
      if (unit(h) < o.incoherent_fraction) {
        p[0] = unit(hash64(h + 1));
        p[1] = unit(hash64(h + 2));
      }
      stack.clear();
      stack.push_back(Item{0, 0, 0, {0, 0}, {1, 1}});
      while (!stack.empty()) {
        Item it = stack.back();
        stack.pop_back();
        rec(0, HP_TRACE_LOAD, 16, it.node * 32);
        rec(0, HP_TRACE_LOAD, 16, it.node * 32 + 16);
        if (it.depth == o.tree_depth) {
          const uint64_t leaf_id = it.leaf_first;
          for (uint32_t tri = 0; tri < 2; ++tri)
            for (uint32_t v = 0; v < 3; ++v) rec(1, HP_TRACE_LOAD, 16, (leaf_id * 2 + tri) * 48 + v * 16);
          continue;
        }
        const int axis = int(it.depth % 2);
        const double mid = 0.5 * (it.lo[axis] + it.hi[axis]);
        const uint64_t left = it.node + 1;
        const uint64_t right = it.node + 1 + ((uint64_t(2) << (o.tree_depth - it.depth - 1)) - 1);
        Item l = it, r = it;
        l.node = left, r.node = right, l.depth = r.depth = it.depth + 1;
        l.hi[axis] = mid, r.lo[axis] = mid;
        r.leaf_first = it.leaf_first + (uint64_t(1) << (o.tree_depth - it.depth - 1));
        const bool near_left = p[axis] < mid;
        const bool far = std::fabs(p[axis] - mid) < o.far_margin * (it.hi[axis] - it.lo[axis]);
        // Push far first so the near child is visited next (front-to-back order).
        if (far) stack.push_back(near_left ? r : l);
        stack.push_back(near_left ? l : r);
      }
      // The epilogue after the traversal loop runs reconverged on a GPU: give it a seq shared by all
      // lanes, as a capture does at reconvergence points, so the stores coalesce.
      seq = kEpilogueSeq;
      rec(3, HP_TRACE_STORE, 4, pixel * 4);
    }
  t.records.push_back(std::move(recs));
  return t;
}

}  // namespace hp::cachesim
