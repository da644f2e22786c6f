// Compiled with -ffp-contract=off like traverse.cpp: the lanes must round exactly as the scalar reference.
#include "bvh/bvh8.hpp"

#include "bvh/build_common.hpp"
#include "bvh/traverse_detail.hpp"

#include <emmintrin.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace hp::bvh {
namespace {

using detail::kInf;
using detail::PreparedRay;

/// Every wide level pushes at most kWidth - 1 children, and a wide tree is never deeper than its binary tree,
/// which build_bvh bounds by HP_BVH_STACK_SIZE (make_bvh8 checks it).
constexpr int kW = Bvh8::kWidth;
constexpr int kStackSize = (kW - 1) * HP_BVH_STACK_SIZE + 1;

class Converter {
 public:
  Converter(const Bvh& bvh, const LeafOrderTriangles& lt, Bvh8& out) : bvh_(bvh), lt_(lt), out_(out) {
    // Children follow their parent in the depth-first layout, so one backward pass sums the subtrees.
    const std::size_t n = bvh.nodes.size();
    tri_count_.resize(n);
    for (std::size_t k = n; k-- > 0;) {
      const gpu::BvhNode& node = bvh.nodes[k];
      if (node_is_leaf(node)) {
        const auto [first, last] = leaf_range(node);
        tri_count_[k] = last - first;
      } else {
        tri_count_[k] = tri_count_[k + 1] + tri_count_[static_cast<std::size_t>(node.offset)];
      }
    }
  }

  void run() {
    // Upper bounds for build_bvh's trees, reserved so that the arrays do not move as they grow (a wide node
    // per opened interior node, of which a binary tree has (nodes - 1) / 2; a packet holds at least one
    // triangle); only the pages written are ever touched.
    out_.nodes.reserve(bvh_.nodes.size() / 2 + 1);
    out_.packets.reserve(std::max<std::size_t>(lt_.triangles.size(), 1));
    detail::advise_huge_pages(out_.nodes.data(), out_.nodes.capacity() * sizeof(Bvh8::Node));
    detail::advise_huge_pages(out_.packets.data(), out_.packets.capacity() * sizeof(Bvh8::Packet));
    const gpu::BvhNode& root = bvh_.nodes[0];
    if (bvh_.prim_ids.empty()) {
      out_.nodes.push_back(empty_node());
    } else if (open(0)) {
      emit(0, 1);
    } else {
      out_.nodes.push_back(empty_node());
      set_box(out_.nodes[0], 0, root);
      out_.nodes[0].child[0] = Bvh8::kLeaf | make_leaf(0);
    }
  }

 private:
  std::pair<uint32_t, uint32_t> leaf_range(const gpu::BvhNode& node) const {
    uint32_t first = static_cast<uint32_t>(node.offset);
    uint32_t last = first + node_count(node);
    if (!lt_.object_first.empty()) {
      first = lt_.object_first[first];
      last = lt_.object_first[last];
    }
    return {first, last};
  }

  /// An interior binary node worth a wide node of its own; smaller subtrees become one leaf packet.
  bool open(uint32_t k) const { return !node_is_leaf(bvh_.nodes[k]) && tri_count_[k] > 4; }

  static Bvh8::Node empty_node() {
    Bvh8::Node n{};
    for (int i = 0; i < kW; ++i) {
      for (int a = 0; a < 3; ++a) {
        n.box[2 * a][i] = kInf;
        n.box[2 * a + 1][i] = -kInf;
      }
    }
    return n;
  }

  static void set_box(Bvh8::Node& w, int i, const gpu::BvhNode& b) {
    for (int a = 0; a < 3; ++a) {
      w.box[2 * a][i] = b.bmin[a];
      w.box[2 * a + 1][i] = b.bmax[a];
    }
  }

  /// The triangle slots under binary node k, in leaf order.
  void gather(uint32_t k, std::vector<uint32_t>& slots) const {
    const gpu::BvhNode& node = bvh_.nodes[k];
    if (node_is_leaf(node)) {
      const auto [first, last] = leaf_range(node);
      for (uint32_t s = first; s < last; ++s) slots.push_back(s);
      return;
    }
    gather(k + 1, slots);
    gather(static_cast<uint32_t>(node.offset), slots);
  }

  /// Packets for the triangles under binary node k; returns the first.
  uint32_t make_leaf(uint32_t k) {
    slots_.clear();
    gather(k, slots_);
    const uint32_t first = static_cast<uint32_t>(out_.packets.size());
    if (first >= Bvh8::kLeaf) throw std::length_error("make_bvh8: too many packets for 31-bit references");
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (std::size_t base = 0; base < slots_.size(); base += 4) {
      Bvh8::Packet p;
      for (int lane = 0; lane < 4; ++lane) {
        const bool used = base + lane < slots_.size();
        const Triangle* t = used ? &lt_.triangles[slots_[base + lane]] : nullptr;
        for (int v = 0; v < 3; ++v) {
          for (int a = 0; a < 3; ++a) {
            const glm::vec3* vert = t ? (v == 0 ? &t->v0 : v == 1 ? &t->v1 : &t->v2) : nullptr;
            p.v[v][a][lane] = vert ? (*vert)[a] : nan;
          }
        }
        p.scene[lane] = used ? lt_.scene_index[slots_[base + lane]] : Bvh8::kNoTriangle;
      }
      if (base + 4 < slots_.size()) p.scene[0] |= Bvh8::kMore;
      out_.packets.push_back(p);
    }
    return first;
  }

  /// A wide node for interior binary node k: its children, opened largest box first until there are kWidth.
  uint32_t emit(uint32_t k, int depth) {
    if (depth > HP_BVH_STACK_SIZE) {
      throw std::logic_error("make_bvh8: tree deeper than HP_BVH_STACK_SIZE (not built by build_bvh)");
    }
    uint32_t c[kW] = {k + 1, static_cast<uint32_t>(bvh_.nodes[k].offset)};
    int count = 2;
    while (count < kW) {
      int pick = -1;
      float pick_area = -1.0f;
      for (int i = 0; i < count; ++i) {
        if (!open(c[i])) continue;
        const float a = detail::half_area(bvh_.nodes[c[i]].bmin, bvh_.nodes[c[i]].bmax);
        if (a > pick_area) {
          pick_area = a;
          pick = i;
        }
      }
      if (pick < 0) break;
      const uint32_t p = c[pick];
      c[pick] = p + 1;
      c[count++] = static_cast<uint32_t>(bvh_.nodes[p].offset);
    }
    const uint32_t index = static_cast<uint32_t>(out_.nodes.size());
    out_.nodes.push_back(empty_node());
    for (int i = 0; i < count; ++i) {
      const uint32_t child = open(c[i]) ? emit(c[i], depth + 1) : Bvh8::kLeaf | make_leaf(c[i]);
      Bvh8::Node& w = out_.nodes[index];  // emit() may have moved the array
      set_box(w, i, bvh_.nodes[c[i]]);
      w.child[i] = child;
    }
    return index;
  }

  const Bvh& bvh_;
  const LeafOrderTriangles& lt_;
  Bvh8& out_;
  std::vector<uint32_t> tri_count_;
  std::vector<uint32_t> slots_;
};

/// The per-ray constants of PreparedRay, splatted across four lanes.
struct Ray4 {
  __m128 org[3], inv[3];
  int near_row[3], far_row[3];  // rows of Node::box holding the near and far planes per axis
  __m128 tmin;
  __m128 okx, oky, okz;  // origin on the watertight test's kx, ky, kz axes
  __m128 sx, sy, sz;
  __m128 inf, far_up, far_down;  // constants, kept in registers across the loop rather than reloaded
};

Ray4 splat(const PreparedRay& r) {
  Ray4 q;
  for (int a = 0; a < 3; ++a) {
    q.org[a] = _mm_set1_ps(r.org[a]);
    q.inv[a] = _mm_set1_ps(r.inv[a]);
    const bool neg = r.near_at[a] >= 4;
    q.near_row[a] = 2 * a + (neg ? 1 : 0);
    q.far_row[a] = 2 * a + (neg ? 0 : 1);
  }
  q.tmin = _mm_set1_ps(r.tmin);
  q.okx = _mm_set1_ps(r.org[r.kx]);
  q.oky = _mm_set1_ps(r.org[r.ky]);
  q.okz = _mm_set1_ps(r.org[r.kz]);
  q.sx = _mm_set1_ps(r.sx);
  q.sy = _mm_set1_ps(r.sy);
  q.sz = _mm_set1_ps(r.sz);
  q.inf = _mm_set1_ps(kInf);
  q.far_up = _mm_set1_ps(detail::kFarUp);
  q.far_down = _mm_set1_ps(detail::kFarDown);
  return q;
}

/// detail::slab on a node's eight boxes, four at a time: the same operations in the same order per lane.
/// _mm_max_ps(a, b) is "a > b ? a : b" and _mm_min_ps(a, b) "a < b ? a : b", the reference's NaN-discarding
/// selects exactly. Writes each box's near t to tnear; returns the mask of boxes hit.
inline int slab8(const Ray4& q, const Bvh8::Node& n, __m128 t_hi, float* tnear) {
  int mask = 0;
  for (int h = 0; h < kW; h += 4) {
    __m128 tn = q.tmin;
    __m128 tf = q.inf;
    for (int a = 0; a < 3; ++a) {
      const __m128 t0 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[q.near_row[a]] + h), q.org[a]), q.inv[a]);
      const __m128 t1 = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.box[q.far_row[a]] + h), q.org[a]), q.inv[a]);
      tn = _mm_max_ps(t0, tn);
      tf = _mm_min_ps(t1, tf);
    }
    tf = _mm_min_ps(t_hi, tf);
    const __m128 nonneg = _mm_cmpge_ps(tf, _mm_setzero_ps());
    tf = _mm_or_ps(_mm_and_ps(nonneg, _mm_mul_ps(tf, q.far_up)), _mm_andnot_ps(nonneg, _mm_mul_ps(tf, q.far_down)));
    _mm_store_ps(tnear + h, tn);
    mask |= _mm_movemask_ps(_mm_cmple_ps(tn, tf)) << h;
  }
  return mask;
}

/// detail::watertight on the four lanes of a packet. Returns the mask of lanes whose t lies in [tmin, t_hi];
/// T, det, U (unused), V, W per lane in the arrays for the caller's pick.
struct Lanes {
  alignas(16) float t[4], det[4], v[4], w[4];
};
inline int watertight4(const Ray4& q, const PreparedRay& r, const Bvh8::Packet& p, __m128 t_hi, Lanes& out) {
  const int kx = r.kx, ky = r.ky, kz = r.kz;
  const __m128 ax = _mm_sub_ps(_mm_load_ps(p.v[0][kx]), q.okx), ay = _mm_sub_ps(_mm_load_ps(p.v[0][ky]), q.oky),
               az = _mm_sub_ps(_mm_load_ps(p.v[0][kz]), q.okz);
  const __m128 bx = _mm_sub_ps(_mm_load_ps(p.v[1][kx]), q.okx), by = _mm_sub_ps(_mm_load_ps(p.v[1][ky]), q.oky),
               bz = _mm_sub_ps(_mm_load_ps(p.v[1][kz]), q.okz);
  const __m128 cx = _mm_sub_ps(_mm_load_ps(p.v[2][kx]), q.okx), cy = _mm_sub_ps(_mm_load_ps(p.v[2][ky]), q.oky),
               cz = _mm_sub_ps(_mm_load_ps(p.v[2][kz]), q.okz);
  const __m128 Ax = _mm_sub_ps(ax, _mm_mul_ps(q.sx, az)), Ay = _mm_sub_ps(ay, _mm_mul_ps(q.sy, az));
  const __m128 Bx = _mm_sub_ps(bx, _mm_mul_ps(q.sx, bz)), By = _mm_sub_ps(by, _mm_mul_ps(q.sy, bz));
  const __m128 Cx = _mm_sub_ps(cx, _mm_mul_ps(q.sx, cz)), Cy = _mm_sub_ps(cy, _mm_mul_ps(q.sy, cz));
  __m128 U = _mm_sub_ps(_mm_mul_ps(Cx, By), _mm_mul_ps(Cy, Bx));
  __m128 V = _mm_sub_ps(_mm_mul_ps(Ax, Cy), _mm_mul_ps(Ay, Cx));
  __m128 W = _mm_sub_ps(_mm_mul_ps(Bx, Ay), _mm_mul_ps(By, Ax));
  const __m128 zero = _mm_setzero_ps();
  const int on_edge =
      _mm_movemask_ps(_mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(U, zero), _mm_cmpeq_ps(V, zero)), _mm_cmpeq_ps(W, zero)));
  if (on_edge) {
    // The reference's exact fallback, lane by lane (rare: a ray within rounding of an edge).
    alignas(16) float u[4], v[4], w[4], ax4[4], ay4[4], bx4[4], by4[4], cx4[4], cy4[4];
    _mm_store_ps(u, U);
    _mm_store_ps(v, V);
    _mm_store_ps(w, W);
    _mm_store_ps(ax4, Ax);
    _mm_store_ps(ay4, Ay);
    _mm_store_ps(bx4, Bx);
    _mm_store_ps(by4, By);
    _mm_store_ps(cx4, Cx);
    _mm_store_ps(cy4, Cy);
    for (int l = 0; l < 4; ++l) {
      if (!(on_edge >> l & 1)) continue;
      u[l] = static_cast<float>(static_cast<double>(cx4[l]) * by4[l] - static_cast<double>(cy4[l]) * bx4[l]);
      v[l] = static_cast<float>(static_cast<double>(ax4[l]) * cy4[l] - static_cast<double>(ay4[l]) * cx4[l]);
      w[l] = static_cast<float>(static_cast<double>(bx4[l]) * ay4[l] - static_cast<double>(by4[l]) * ax4[l]);
    }
    U = _mm_load_ps(u);
    V = _mm_load_ps(v);
    W = _mm_load_ps(w);
  }
  const __m128 neg = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(U, zero), _mm_cmplt_ps(V, zero)), _mm_cmplt_ps(W, zero));
  const __m128 pos = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(U, zero), _mm_cmpgt_ps(V, zero)), _mm_cmpgt_ps(W, zero));
  const __m128 det = _mm_add_ps(_mm_add_ps(U, V), W);
  // A NaN det passes cmpneq, as det == 0 fails in the reference; its NaN t then fails the range test.
  const __m128 inside = _mm_andnot_ps(_mm_and_ps(neg, pos), _mm_cmpneq_ps(det, zero));
  if (!_mm_movemask_ps(inside)) return 0;
  const __m128 T = _mm_add_ps(_mm_add_ps(_mm_mul_ps(U, _mm_mul_ps(q.sz, az)), _mm_mul_ps(V, _mm_mul_ps(q.sz, bz))),
                              _mm_mul_ps(W, _mm_mul_ps(q.sz, cz)));
  const __m128 t = _mm_div_ps(T, det);
  const __m128 in_range = _mm_and_ps(_mm_cmpge_ps(t, q.tmin), _mm_cmple_ps(t, t_hi));
  const int mask = _mm_movemask_ps(_mm_and_ps(inside, in_range));
  if (mask) {
    _mm_store_ps(out.t, t);
    _mm_store_ps(out.det, det);
    _mm_store_ps(out.v, V);
    _mm_store_ps(out.w, W);
  }
  return mask;
}

/// Starts fetching a pushed child: it is usually visited soon, and on trees larger than the caches the
/// wait for its node or packet is what a ray spends most of its time on.
inline void prefetch(const Bvh8& b, uint32_t ref) {
  const char* p = ref & Bvh8::kLeaf ? reinterpret_cast<const char*>(&b.packets[ref & ~Bvh8::kLeaf])
                                    : reinterpret_cast<const char*>(&b.nodes[ref]);
  _mm_prefetch(p, _MM_HINT_T0);
  _mm_prefetch(p + 64, _MM_HINT_T0);
}

template <bool kAny>
Hit trace(const Bvh8& b, const Ray& ray, TraversalStats* stats) {
  Hit best;
  PreparedRay r;
  if (b.nodes.empty() || !detail::prepare(ray, r)) return best;
  const Ray4 q = splat(r);
  const Bvh8::Node* nodes = b.nodes.data();
  const Bvh8::Packet* packets = b.packets.data();

  float best_t = r.tmax;
  float best_far = detail::widen_far(best_t);  // a box whose near t exceeds this cannot hold a closer hit
  uint32_t best_scene = UINT32_MAX;
  const __m128 tmax4 = _mm_set1_ps(r.tmax);
  __m128 best4 = tmax4;
  uint64_t visited = 0, tested = 0;
  struct Entry {
    uint32_t ref;
    float tnear;
  };
  Entry stack[kStackSize];
  int sp = 0;
  uint32_t ref = 0;
  for (;;) {
    if (!(ref & Bvh8::kLeaf)) {
      const Bvh8::Node& n = nodes[ref];
      ++visited;
      alignas(16) float tn[kW];
      int mask = slab8(q, n, kAny ? tmax4 : best4, tn);
      if (mask) {
        const int first = __builtin_ctz(mask);
        mask &= mask - 1;
        if (!mask) {
          ref = n.child[first];
          continue;
        }
        // Two or more boxes hit: visit the nearest, push the others farthest first.
        const int second = __builtin_ctz(mask);
        mask &= mask - 1;
        if (!mask) {
          // Two, the common case: selects rather than branches, whose outcome a random ray cannot predict.
          const bool swap = tn[second] < tn[first];
          const uint32_t c0 = n.child[first], c1 = n.child[second];
          const float t0 = tn[first], t1 = tn[second];
          ref = swap ? c1 : c0;
          const uint32_t far_ref = swap ? c0 : c1;
          stack[sp++] = Entry{far_ref, swap ? t0 : t1};
          prefetch(b, far_ref);
          continue;
        }
        mask |= 1 << second;
        uint32_t cr[kW];
        float ct[kW];
        cr[0] = n.child[first];
        ct[0] = tn[first];
        int k = 1;
        do {
          const int l = __builtin_ctz(mask);
          mask &= mask - 1;
          uint32_t c = n.child[l];
          float t = tn[l];
          int j = k++;
          for (; j > 0 && ct[j - 1] > t; --j) {
            cr[j] = cr[j - 1];
            ct[j] = ct[j - 1];
          }
          cr[j] = c;
          ct[j] = t;
        } while (mask);
        for (int i = k - 1; i > 0; --i) {
          stack[sp++] = Entry{cr[i], ct[i]};
          prefetch(b, cr[i]);
        }
        ref = cr[0];
        continue;
      }
    } else {
      for (uint32_t pi = ref & ~Bvh8::kLeaf;; ++pi) {
        const Bvh8::Packet& p = packets[pi];
        tested += 4;
        Lanes lanes;
        int hits = watertight4(q, r, p, kAny ? tmax4 : best4, lanes);
        if constexpr (kAny) {
          if (hits) {
            const int l = __builtin_ctz(hits);
            best = Hit{static_cast<int32_t>(p.scene[l] & ~Bvh8::kMore), lanes.t[l], lanes.v[l] / lanes.det[l],
                       lanes.w[l] / lanes.det[l]};
            sp = 0;
            break;
          }
        } else {
          while (hits) {
            const int l = __builtin_ctz(hits);
            hits &= hits - 1;
            const float t = lanes.t[l];
            const uint32_t s = p.scene[l] & ~Bvh8::kMore;
            if (t < best_t || (t == best_t && s < best_scene)) {
              best_t = t;
              best_scene = s;
              best = Hit{static_cast<int32_t>(s), t, lanes.v[l] / lanes.det[l], lanes.w[l] / lanes.det[l]};
            }
          }
          best4 = _mm_set1_ps(best_t);
          best_far = detail::widen_far(best_t);
        }
        if (!(p.scene[0] & Bvh8::kMore)) break;
      }
    }
    // Pop the next entry that the reference's test, with the closest t found so far, would still accept.
    if constexpr (kAny) {
      if (sp == 0) break;
      ref = stack[--sp].ref;
    } else {
      while (sp > 0 && !(stack[sp - 1].tnear <= best_far)) --sp;
      if (sp == 0) break;
      ref = stack[--sp].ref;
    }
  }
  if (stats) {
    stats->nodes_visited += visited;
    stats->triangles_tested += tested;
  }
  return best;
}

}  // namespace

Bvh8 make_bvh8(const Bvh& bvh, const LeafOrderTriangles& tris) {
  Bvh8 out;
  if (bvh.nodes.empty()) return out;
  Converter(bvh, tris, out).run();
  return out;
}

Hit intersect_closest(const Bvh8& bvh, const Ray& ray, TraversalStats* stats) { return trace<false>(bvh, ray, stats); }

Hit intersect_any(const Bvh8& bvh, const Ray& ray, TraversalStats* stats) { return trace<true>(bvh, ray, stats); }

}  // namespace hp::bvh
