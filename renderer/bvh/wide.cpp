// Compiled with -ffp-contract=off (CMakeLists.txt): the box decoding, the slab test and the triangle test
// must round as the shader's `precise` code does (shaders/common/traversal.glsl, hp_trace_wide).
#include "bvh/wide.hpp"

#include "bvh/traverse_detail.hpp"
#include "error.hpp"

#include <emmintrin.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

namespace hp::bvh {
namespace {

using detail::prepare;
using detail::PreparedRay;

/// The step of an axis with biased exponent e (1..254): 2^(e - 127), a normal float.
float axis_step(uint32_t e) { return std::bit_cast<float>(e << 23); }

/// A quantized bound decoded: origin + q * step, one rounding (q * step is exact: q has 8 bits).
float decode(float origin, uint32_t q, float step) { return origin + static_cast<float>(q) * step; }

/// 2^k for k in [-1022, 1023], built from its bits: std::ldexp and std::frexp, library calls, were 9 % of the
/// conversion's instructions (sphere-1m).
double pow2(int k) { return std::bit_cast<double>(static_cast<uint64_t>(k + 1023) << 52); }
/// std::frexp's exponent of a positive normal double: v = m * 2^x with m in [0.5, 1).
int frexp_exponent(double v) { return static_cast<int>((std::bit_cast<uint64_t>(v) >> 52) & 0x7ffu) - 1022; }

/// The smallest exponent whose 255 steps from `lo` decode to at least `hi` (so every box inside the frame
/// gets bounds in 0..255). extent / 255 of two finite floats is a normal double or 0.
uint32_t frame_exponent(float lo, float hi) {
  const double extent = static_cast<double>(hi) - static_cast<double>(lo);
  int e = 1;
  // extent / 255 <= 2^x: a step of 2^(x - 1) may do too.
  if (extent > 0.0) e = std::clamp(frexp_exponent(extent / 255.0) - 1 + 127, 1, 254);
  while (e < 254 && !(255.0 * pow2(e - 127) >= extent && decode(lo, 255, axis_step(e)) >= hi)) ++e;
  return static_cast<uint32_t>(e);
}

/// Conservative 8-bit bounds of [blo, bhi] in the frame (origin, step): the largest q whose decoded value is
/// <= blo and the smallest whose decoded value is >= bhi. Rounding is monotonic, so decoded values compare
/// with the float bounds exactly as they are computed on the GPU.
void quantize(float origin, float step, float blo, float bhi, uint32_t& qlo, uint32_t& qhi) {
  const double s = static_cast<double>(step);
  const double glo = std::floor((static_cast<double>(blo) - origin) / s);
  const double ghi = std::ceil((static_cast<double>(bhi) - origin) / s);
  qlo = static_cast<uint32_t>(std::clamp(glo, 0.0, 255.0));
  while (qlo > 0 && decode(origin, qlo, step) > blo) --qlo;
  while (qlo < 255 && decode(origin, qlo + 1, step) <= blo) ++qlo;
  qhi = static_cast<uint32_t>(std::clamp(ghi, 0.0, 255.0));
  while (qhi < 255 && decode(origin, qhi, step) < bhi) ++qhi;
  while (qhi > 0 && decode(origin, qhi - 1, step) >= bhi) --qhi;
  if (decode(origin, qlo, step) > blo || decode(origin, qhi, step) < bhi) {
    throw std::logic_error("make_wide: a child box does not fit its frame");
  }
}

class Converter {
 public:
  explicit Converter(const Bvh& bvh, WideBvh& out) : bvh_(bvh), out_(out) {}

  void run() {
    out_.nodes.reserve(bvh_.nodes.size() / 3 + 1);
    if (bvh_.prim_ids.empty()) {
      out_.nodes.push_back(gpu::WideNode{});  // four empty slots: every ray misses at once
      return;
    }
    const gpu::BvhNode& root = bvh_.nodes[0];
    if (node_is_leaf(root)) {
      // One slot: the root leaf, framed by its own box.
      out_.nodes.push_back(gpu::WideNode{});
      const int slots[4] = {0, -1, -1, -1};
      fill(0, 0, slots, 0);
      return;
    }
    split_.resize(bvh_.nodes.size());
    plan(0);
    emit(0, 0);
  }

 private:
  /// Emits the wide node of binary interior node p; `stack_before` = entries its ancestors may have pushed.
  uint32_t emit(uint32_t p, int stack_before) {
    const gpu::BvhNode& n = bvh_.nodes[p];
    int slots[4] = {-1, -1, -1, -1};
    int occupied = 0;
    const int split = split_[p][3];
    cut(p + 1, split, slots, occupied);
    cut(static_cast<uint32_t>(n.offset), 4 - split, slots, occupied);
    const uint32_t index = static_cast<uint32_t>(out_.nodes.size());
    out_.nodes.push_back(gpu::WideNode{});
    const int stack_here = stack_before + occupied - 1;
    fill(index, p, slots, stack_here);
    for (int k = 0; k < 4; ++k) {
      if (slots[k] < 0 || node_is_leaf(bvh_.nodes[slots[k]])) continue;
      const uint32_t child = emit(static_cast<uint32_t>(slots[k]), stack_here);
      out_.nodes[index].w[3][k] = child;
    }
    return index;
  }

  /// The cheapest way to stand for each binary subtree with at most k slots (k = 1..3), and an interior
  /// node's cost as a wide node: the wide tree's SAH cost is the sum of its nodes' box areas (the leaves'
  /// cost is the same for every collapse), so the cheapest collapse is found bottom up (Ylitie, Karras and
  /// Laine 2017, "Efficient incoherent ray traversal on GPUs through compressed wide BVHs", section 4, for
  /// four slots). plan(b) returns b's costs, cost[k] = the least sum of wide-node areas below and including
  /// the slots with at most k slots, cost[0] as a wide node of its own; it keeps only the splits, split_[b][k]
  /// = 0 where b itself is the one slot, else how many of the k + 1 slots go to its first child, and
  /// split_[b][3] the wide node's own split of four slots. Depth first, so the costs live on the recursion's
  /// stack (as deep as the tree: build_bvh caps it at 64) and the splits take 4 bytes a node; a cost table
  /// for every node (3.3 MB on pica) was fresh memory whose page faults cost more than the arithmetic.
  struct Costs {
    double cost[4] = {0, 0, 0, 0};
  };
  Costs plan(uint32_t b) {
    const gpu::BvhNode& n = bvh_.nodes[b];
    Costs c;
    if (node_is_leaf(n)) return c;  // a leaf is one slot and no wide node: cost 0
    const Costs l = plan(b + 1);
    const Costs r = plan(static_cast<uint32_t>(n.offset));
    std::array<uint8_t, 4>& split = split_[b];
    // As a wide node: its box plus the cheapest four-slot split between the children.
    double own = std::numeric_limits<double>::infinity();
    for (int a = 1; a <= 3; ++a) {
      const double v = l.cost[a] + r.cost[4 - a];
      if (v < own) own = v, split[3] = static_cast<uint8_t>(a);
    }
    c.cost[0] = box_area(n) + own;
    // As at most k slots: itself (one slot, a wide node below), or opened into its children.
    c.cost[1] = c.cost[0];
    for (int k = 2; k <= 3; ++k) {
      c.cost[k] = c.cost[0];
      split[k - 1] = 0;
      for (int a = 1; a < k; ++a) {
        const double v = l.cost[a] + r.cost[k - a];
        if (v < c.cost[k]) c.cost[k] = v, split[k - 1] = static_cast<uint8_t>(a);
      }
    }
    return c;
  }

  /// Appends the slots standing for binary node b with at most k of them, in left-to-right order.
  void cut(uint32_t b, int k, int (&slots)[4], int& occupied) const {
    const gpu::BvhNode& n = bvh_.nodes[b];
    const int a = k >= 2 && !node_is_leaf(n) ? split_[b][k - 1] : 0;
    if (a == 0) {
      slots[occupied++] = static_cast<int>(b);
      return;
    }
    cut(b + 1, a, slots, occupied);
    cut(static_cast<uint32_t>(n.offset), k - a, slots, occupied);
  }

  /// Half the area of a binary node's box (the SAH's measure), in double.
  static double box_area(const gpu::BvhNode& c) {
    const glm::dvec3 e = glm::dvec3(c.bmax) - glm::dvec3(c.bmin);
    return e.x * e.y + e.y * e.z + e.z * e.x;
  }

  /// The binary nodes between a wide node's binary node and its slots (at most three: four slots are the
  /// leaves of a binary tree of three interior nodes), each with its split axis and its two sides, a side
  /// being a slot (0-3) or another fork (4 + its index).
  struct Fork {
    uint32_t axis;
    int side[2];
  };
  /// Records the forks under binary node b down to the slots; returns b's code (slot, or 4 + fork). The walk
  /// is depth first, first child first, as cut() laid the slots out, so the next slot is the one to meet
  /// (a slot is recognised by position, which also holds where one binary node fills two slots).
  int forks(uint32_t b, const int (&slots)[4], Fork (&f)[3], int& count, int& next) const {
    if (slots[next] == static_cast<int>(b)) return next++;
    const gpu::BvhNode& n = bvh_.nodes[b];
    const int i = count++;
    f[i].axis = node_axis(n);
    f[i].side[0] = forks(b + 1, slots, f, count, next);
    f[i].side[1] = forks(static_cast<uint32_t>(n.offset), slots, f, count, next);
    return 4 + i;
  }
  /// Appends to `order` (2 bits per position) the slots under `code` in the binary traversal's order for a
  /// ray of octant `octant` (bit a set: negative on axis a): at each fork the second side first where the ray
  /// is negative on its split axis.
  static void order_slots(int code, uint32_t octant, const Fork (&f)[3], uint32_t& order, int& pos) {
    if (code < 4) {
      order |= static_cast<uint32_t>(code) << (2 * pos++);
      return;
    }
    const Fork& x = f[code - 4];
    const int first = static_cast<int>((octant >> x.axis) & 1u);
    order_slots(x.side[first], octant, f, order, pos);
    order_slots(x.side[1 - first], octant, f, order, pos);
  }

  /// Writes wide node `index` for binary node p: frame = p's box, the slots' quantized boxes, leaf words (interior
  /// words are set by emit once the child exists).
  void fill(uint32_t index, uint32_t p, const int (&slots)[4], int stack_here) {
    const gpu::BvhNode& frame = bvh_.nodes[p];
    if (stack_here > HP_BVH_STACK_SIZE) {
      throw InputError("node layout wide4: the tree needs " + std::to_string(stack_here) +
                       " traversal stack entries, over HP_BVH_STACK_SIZE (" + std::to_string(HP_BVH_STACK_SIZE) +
                       "); the binary32 layout traces this tree");
    }
    out_.stack_need = std::max(out_.stack_need, stack_here);
    gpu::WideNode w{};
    uint32_t e[3];
    for (int a = 0; a < 3; ++a) e[a] = frame_exponent(frame.bmin[a], frame.bmax[a]);
    w.w[0] = glm::uvec4(std::bit_cast<uint32_t>(frame.bmin.x), std::bit_cast<uint32_t>(frame.bmin.y),
                        std::bit_cast<uint32_t>(frame.bmin.z), e[0] | e[1] << 8 | e[2] << 16);
    // The visiting order per ray octant, a byte each (octants 0-3 in w[2].z, 4-7 in w[2].w): the occupied
    // slots in the binary order, then the empty ones.
    // The root leaf alone is its own slot 0, so its code is that slot.
    Fork f[3];
    int fork_count = 0, next_slot = 0;
    const int top = forks(p, slots, f, fork_count, next_slot);
    for (uint32_t octant = 0; octant < 8; ++octant) {
      uint32_t order = 0;
      int pos = 0;
      order_slots(top, octant, f, order, pos);
      for (int k = 0; k < 4; ++k) {
        if (slots[k] < 0) order |= static_cast<uint32_t>(k) << (2 * pos++);
      }
      w.w[2][2 + octant / 4] |= order << (8 * (octant % 4));
    }
    for (int k = 0; k < 4; ++k) {
      if (slots[k] < 0) continue;
      const gpu::BvhNode& c = bvh_.nodes[slots[k]];
      for (int a = 0; a < 3; ++a) {
        uint32_t qlo, qhi;
        quantize(frame.bmin[a], axis_step(e[a]), c.bmin[a], c.bmax[a], qlo, qhi);
        // lo.x, hi.x, lo.y, hi.y in w[1]; lo.z, hi.z in w[2].
        const int word = 2 * a;
        w.w[1 + word / 4][word % 4] |= qlo << (8 * k);
        w.w[1 + (word + 1) / 4][(word + 1) % 4] |= qhi << (8 * k);
      }
      if (node_is_leaf(c)) {
        const uint32_t count = node_count(c), first = static_cast<uint32_t>(c.offset);
        if (count > HP_WIDE_COUNT_MASK) {
          throw InputError("node layout wide4: a leaf holds " + std::to_string(count) +
                           " primitives, over the layout's 15 (use a BVH leaf size of at most 15)");
        }
        if (first > HP_WIDE_FIRST_MASK) {
          throw InputError("node layout wide4: primitive slot " + std::to_string(first) + " needs more than 27 bits");
        }
        w.w[3][k] = HP_WIDE_LEAF | count << HP_WIDE_COUNT_SHIFT | first;
      }
    }
    out_.nodes[index] = w;
  }

  const Bvh& bvh_;
  WideBvh& out_;
  std::vector<std::array<uint8_t, 4>> split_;  // plan()
};

inline bool neg(const PreparedRay& r, uint32_t axis) { return r.near_at[axis] >= 4; }

/// Four 8-bit bounds (byte i = slot i) as floats.
inline __m128 bytes4(uint32_t w) {
  const __m128i zero = _mm_setzero_si128();
  const __m128i v = _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(static_cast<int>(w)), zero), zero);
  return _mm_cvtepi32_ps(v);
}

/// wide_child_box and detail::slab on the four slots at once: the scalar operations in the same order per
/// lane (_mm_max_ps(a, b) is "a > b ? a : b", _mm_min_ps(a, b) "a < b ? a : b", the slab test's
/// NaN-discarding selects). Returns the mask of slots whose box the ray's [tmin, t_hi] meets.
inline int slab4(const PreparedRay& r, const gpu::WideNode& n, float t_hi) {
  const uint32_t meta = n.w[0].w;
  __m128 tn = _mm_set1_ps(r.tmin);
  __m128 tf = _mm_set1_ps(detail::kInf);
  for (int a = 0; a < 3; ++a) {
    const __m128 origin = _mm_set1_ps(std::bit_cast<float>(n.w[0][a]));
    const __m128 step = _mm_set1_ps(axis_step((meta >> (8 * a)) & 255u));
    const int word = 2 * a;
    const __m128 lo = _mm_add_ps(origin, _mm_mul_ps(bytes4(n.w[1 + word / 4][word % 4]), step));
    const __m128 hi = _mm_add_ps(origin, _mm_mul_ps(bytes4(n.w[1 + (word + 1) / 4][(word + 1) % 4]), step));
    const __m128 org = _mm_set1_ps(r.org[a]);
    const __m128 inv = _mm_set1_ps(r.inv[a]);
    const bool negative = r.near_at[a] >= 4;
    const __m128 t0 = _mm_mul_ps(_mm_sub_ps(negative ? hi : lo, org), inv);
    const __m128 t1 = _mm_mul_ps(_mm_sub_ps(negative ? lo : hi, org), inv);
    tn = _mm_max_ps(t0, tn);
    tf = _mm_min_ps(t1, tf);
  }
  tf = _mm_min_ps(_mm_set1_ps(t_hi), tf);
  const __m128 nonneg = _mm_cmpge_ps(tf, _mm_setzero_ps());
  tf = _mm_or_ps(_mm_and_ps(nonneg, _mm_mul_ps(tf, _mm_set1_ps(detail::kFarUp))),
                 _mm_andnot_ps(nonneg, _mm_mul_ps(tf, _mm_set1_ps(detail::kFarDown))));
  return _mm_movemask_ps(_mm_cmple_ps(tn, tf));
}

template <bool kAny>
Hit traverse(const WideBvh& bvh, const LeafOrderTriangles& lt, const Ray& ray, TraversalStats* stats) {
  Hit best;
  PreparedRay r;
  if (bvh.nodes.empty() || !prepare(ray, r)) return best;
  const gpu::WideNode* nodes = bvh.nodes.data();

  float best_t = r.tmax;
  uint32_t best_scene = UINT32_MAX;
  uint64_t visited = 0, tested = 0;
  uint32_t stack[HP_BVH_STACK_SIZE];
  int sp = 0;
  uint32_t entry = 0;  // the root, an interior node
  const uint32_t octant = (neg(r, 0) ? 1u : 0u) | (neg(r, 1) ? 2u : 0u) | (neg(r, 2) ? 4u : 0u);
  for (;;) {
    if ((entry & HP_WIDE_LEAF) != 0) {
      const uint32_t first = entry & HP_WIDE_FIRST_MASK;
      const uint32_t last = first + ((entry >> HP_WIDE_COUNT_SHIFT) & HP_WIDE_COUNT_MASK);
      // Any hit: occluded, nothing else matters.
      if (detail::test_leaf<kAny>(r, lt, first, last, best, best_t, best_scene, tested)) sp = 0;
    } else {
      const gpu::WideNode& n = nodes[entry];
      ++visited;
      const int mask = slab4(r, n, best_t);
      bool hit[4];
      for (int k = 0; k < 4; ++k) hit[k] = n.w[3][k] != 0 && ((mask >> k) & 1) != 0;
      // The binary order: the node's visiting order for the ray's octant (make_wide).
      const uint32_t ow = n.w[2][2 + octant / 4] >> (8 * (octant % 4));
      const int order[4] = {static_cast<int>(ow & 3u), static_cast<int>((ow >> 2) & 3u),
                            static_cast<int>((ow >> 4) & 3u), static_cast<int>((ow >> 6) & 3u)};
      // The first hit child in that order is next; the other hit children are pushed, the last first.
      bool have = false;
      uint32_t next = 0;
      for (int k = 3; k >= 0; --k) {
        if (!hit[order[k]]) continue;
        if (have) {
          if (sp == HP_BVH_STACK_SIZE) throw std::logic_error("wide bvh traversal: stack overflow");
          stack[sp++] = next;
        }
        next = n.w[3][order[k]];
        have = true;
      }
      if (have) {
        entry = next;
        continue;
      }
    }
    if (sp == 0) break;
    entry = stack[--sp];
  }
  if (stats) {
    stats->nodes_visited += visited;
    stats->triangles_tested += tested;
  }
  return best;
}

}  // namespace

WideBvh make_wide(const Bvh& bvh) {
  WideBvh out;
  Converter(bvh, out).run();
  return out;
}

void wide_child_box(const gpu::WideNode& n, int slot, glm::vec3& bmin, glm::vec3& bmax) {
  const uint32_t meta = n.w[0].w;
  const uint32_t sh = 8u * static_cast<uint32_t>(slot);
  for (int a = 0; a < 3; ++a) {
    const float origin = std::bit_cast<float>(n.w[0][a]);
    const float step = axis_step((meta >> (8 * a)) & 255u);
    const int word = 2 * a;
    const uint32_t qlo = (n.w[1 + word / 4][word % 4] >> sh) & 255u;
    const uint32_t qhi = (n.w[1 + (word + 1) / 4][(word + 1) % 4] >> sh) & 255u;
    bmin[a] = decode(origin, qlo, step);
    bmax[a] = decode(origin, qhi, step);
  }
}

Hit intersect_closest(const WideBvh& bvh, const LeafOrderTriangles& tris, const Ray& ray, TraversalStats* stats) {
  return traverse<false>(bvh, tris, ray, stats);
}

Hit intersect_any(const WideBvh& bvh, const LeafOrderTriangles& tris, const Ray& ray, TraversalStats* stats) {
  return traverse<true>(bvh, tris, ray, stats);
}

std::vector<Hit> cast_rays(const WideBvh& bvh, const LeafOrderTriangles& tris, std::span<const Ray> rays, HitMode mode,
                           int threads, TraversalStats* stats) {
  return detail::cast_mode(rays, mode, threads, stats, [&](auto any, const Ray& ray, TraversalStats* local) {
    return traverse<decltype(any)::value>(bvh, tris, ray, local);
  });
}

}  // namespace hp::bvh
