// The binned SAH builder's body, included twice by build_binned.cpp: once for the baseline x86-64 target,
// once compiled for AVX2 (the same operations, VEX-encoded). It is not a header of its own: it has no
// includes (build_binned.cpp includes everything before it, so that library code keeps its own target) and
// no include guard. HP_BINNED_BLENDV (0 or 1) says whether SSE4.1's blend may be used.
constexpr float kInf = std::numeric_limits<float>::infinity();

/// mask ? a : b per lane, for masks of all ones or all zeros: one blend where SSE4.1 is there.
inline __m128 select(__m128 mask, __m128 a, __m128 b) {
#if HP_BINNED_BLENDV
  return _mm_blendv_ps(b, a, mask);
#else
  return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b));
#endif
}

/// Lane 3 of a loaded PrimRef holds the id or padding bits; they are masked to 0 so that no NaN or
/// denormal ever enters the arithmetic.
inline __m128 load3(const glm::vec3& v) {
  const __m128 mask = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));
  return _mm_and_ps(_mm_loadu_ps(&v.x), mask);
}
/// Half area of a box whose lane 3 is 0 in both corners, without leaving the SSE registers (the bin
/// sweeps evaluate it 4 * buckets times per node, which dominates small nodes).
inline float half_area4(__m128 lo, __m128 hi) {
  const __m128 e = _mm_sub_ps(hi, lo);
  const __m128 p = _mm_mul_ps(e, _mm_shuffle_ps(e, e, _MM_SHUFFLE(3, 0, 2, 1)));  // xy, yz, zx, 0
  const __m128 s = _mm_add_ps(p, _mm_movehl_ps(p, p));                            // xy + zx, yz + 0
  return _mm_cvtss_f32(_mm_add_ss(s, _mm_shuffle_ps(s, s, _MM_SHUFFLE(1, 1, 1, 1))));
}

struct Box4 {
  __m128 lo = _mm_set1_ps(kInf);
  __m128 hi = _mm_set1_ps(-kInf);
  void grow(__m128 l, __m128 h) {
    lo = _mm_min_ps(lo, l);
    hi = _mm_max_ps(hi, h);
  }
  void grow(const Box4& b) { grow(b.lo, b.hi); }
  void grow_point(__m128 p) { grow(p, p); }
};

/// A bin: a box whose hi lane 3 holds the primitive count as integer bits. Counting inside the box saves
/// a separate load-increment-store per axis and primitive in the binning loop, the builder's hottest code.
/// The count lane is positive (a denormal or small normal as a float), so max_ps keeps it; it is masked
/// off before any arithmetic on the box.
struct Bin {
  __m128 lo = _mm_set1_ps(kInf);
  __m128 hi = _mm_castsi128_ps(_mm_set_epi32(0, static_cast<int>(0xff800000u), static_cast<int>(0xff800000u),
                                             static_cast<int>(0xff800000u)));  // -inf x3, count 0
  /// Adds a primitive whose lane 3 is 0 in both corners.
  void add(__m128 l, __m128 h) {
    lo = _mm_min_ps(lo, l);
    hi = _mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(_mm_max_ps(hi, h)), _mm_set_epi32(1, 0, 0, 0)));
  }
  uint32_t count() const {
    return static_cast<uint32_t>(_mm_cvtsi128_si32(_mm_shuffle_epi32(_mm_castps_si128(hi), 0xff)));
  }
  __m128 box_hi() const { return _mm_and_ps(hi, _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1))); }
  void merge(const Bin& o) {
    const __m128i c = _mm_add_epi32(_mm_castps_si128(hi), _mm_shuffle_epi32(_mm_castps_si128(o.hi), 0xff));
    lo = _mm_min_ps(lo, o.lo);
    const __m128 m = _mm_max_ps(box_hi(), o.box_hi());
    // Lanes 0-2 from the max, lane 3 the summed count.
    hi = _mm_or_ps(m, _mm_and_ps(_mm_castsi128_ps(c), _mm_castsi128_ps(_mm_set_epi32(-1, 0, 0, 0))));
  }
};

/// A primitive range with its bounds and the bounds of its doubled centroids (lo + hi).
struct Range {
  Box4 box, cbox;
  uint32_t begin = 0, end = 0;
};

/// One SSE register in memory (a vector of __m128 itself would drop its alignment attribute).
struct Lanes {
  __m128 v;
};

/// Per-thread scratch, allocated once per worker so that nodes allocate nothing.
struct Scratch {
  explicit Scratch(int buckets) : bins(6 * buckets), empty_bins(6 * buckets), right_cost(buckets), soa(8 * buckets) {}
  std::vector<Bin> bins;        // [set * 3 * buckets + axis * buckets + bin], two sets (see the binning loop)
  std::vector<Bin> empty_bins;  // as many empty bins, copied over `bins` at each node
  std::vector<float> right_cost;
  // The three-axis sweep: N_B * S_B per bin (lane = axis), and the bins transposed to lane = axis
  // (lo x, y, z, hi x, y, z, count per bin).
  std::vector<Lanes> soa;
  /// Where this worker appends its nodes (depth first), and the deepest leaf it wrote.
  std::vector<gpu::BvhNode>* out = nullptr;
  int max_depth = 0;
};

/// Bin index per axis for doubled centroid c: floor((c - cmin) * scale), clamped to the last bin. The same
/// function serves binning and partitioning, so both always agree on a primitive's bin.
inline __m128i bin_index(__m128 c, __m128 cmin, __m128 scale, __m128 last) {
  return _mm_cvttps_epi32(_mm_min_ps(_mm_mul_ps(_mm_sub_ps(c, cmin), scale), last));
}

/// Nodes at least this large are binned in runs (bin_runs). Below it runs are short and their ends hard to
/// predict; two bin sets (see the binning loop) were measured faster there (docs/bvh-performance.md).
constexpr uint32_t kRunBinning = 1024;
/// Nodes at most this large are partitioned through a bit mask (partition_small).
constexpr uint32_t kSmallPartition = 64;
/// Nodes at least this large are binned in two halves on two threads when a worker slot is free: in a threaded
/// build only the root (and on more threads the nodes just below it) qualify, whose binning is otherwise serial.
constexpr uint32_t kParallelBinning = 131072;

class BinnedBuilder {
 public:
  BinnedBuilder(std::span<PrimRef> prims, const BuildParams& p) : prims_(prims), p_(p), forker_(p.threads) {}

  /// `given`: the references' bounds folded by the caller, or null.
  PairTree run(const RefBounds* given) {
    start_ = std::chrono::steady_clock::now();
    Range root;
    RefBounds all;
    if (given != nullptr && !given->signed_zeros()) {
      all = *given;  // without -0.0 every fold order gives the same bits
    } else {
      // The reference order of the folds: chunks in order, each in primitive order.
      std::vector<RefBounds> parts(std::max(1, p_.threads));
      Forker::parallel_chunks(prims_.size(), p_.threads, [&](std::size_t b, std::size_t e, std::size_t c) {
        RefBounds part;
        for (std::size_t i = b; i < e; ++i) part.add(prims_[i]);
        parts[c] = part;
      });
      for (const RefBounds& part : parts) all.add(part);
    }
    root.box.lo = all.lo;
    root.box.hi = all.hi;
    root.cbox.lo = all.clo;
    root.cbox.hi = all.chi;
    signed_zeros_ = all.signed_zeros();
    root.begin = 0;
    root.end = static_cast<uint32_t>(prims_.size());
    // Nodes are appended depth first, in the final layout (a node's first child right after it, the second
    // after the first's subtree). A tree over N primitives has at most 2N - 1 nodes, so the reserve never
    // reallocates, and its pages are touched only as nodes are written.
    std::vector<gpu::BvhNode> flat;
    reserve_nodes(flat, prims_.size());
    flat.emplace_back();
    PairTree tree;
    tree.order.resize(prims_.size());
    order_ = tree.order.data();
    Scratch scratch(p_.buckets);
    scratch.out = &flat;
    build(0, root, 0, scratch);
    tree.flat = std::move(flat);
    tree.flat_max_depth = scratch.max_depth;
    tree.depth_limited_splits = depth_limited_.load();
    tree.phases = phases_;
    return tree;
  }

 private:
  static glm::vec3 to_vec3(__m128 v) {
    alignas(16) float f[4];
    _mm_store_ps(f, v);
    return glm::vec3(f[0], f[1], f[2]);
  }
  /// A leaf's primitives are in their final place (and in cache): their scene indices go to the order here.
  void leaf(uint32_t index, const Range& r, int depth, Scratch& s) {
    (*s.out)[index] = make_leaf(to_vec3(r.box.lo), to_vec3(r.box.hi), r.begin, r.end - r.begin);
    for (uint32_t i = r.begin; i < r.end; ++i) order_[i] = prims_[i].id;
    s.max_depth = std::max(s.max_depth, depth);
  }
  static void reserve_nodes(std::vector<gpu::BvhNode>& v, std::size_t prims) {
    const std::size_t capacity = std::max<std::size_t>(1, 2 * prims);
    v.reserve(capacity);
    advise_huge_pages(v.data(), capacity * sizeof(gpu::BvhNode));
  }

  Range range_of(uint32_t begin, uint32_t end) const {
    Range r;
    for (uint32_t i = begin; i < end; ++i) {
      const __m128 lo = load3(prims_[i].lo), hi = load3(prims_[i].hi);
      r.box.grow(lo, hi);
      r.cbox.grow_point(_mm_add_ps(lo, hi));
    }
    r.begin = begin;
    r.end = end;
    return r;
  }

  /// Splits at the middle after ordering by centroid along `axis`: each child gets at most ceil(N/2)
  /// primitives, which is what the depth bound relies on. With coincident centroids the order is arbitrary
  /// and this is a plain count split.
  void median_split(const Range& r, int axis, Range& left, Range& right) {
    const uint32_t mid = r.begin + (r.end - r.begin) / 2;
    std::nth_element(prims_.begin() + r.begin, prims_.begin() + mid, prims_.begin() + r.end,
                     [axis](const PrimRef& a, const PrimRef& b) {
                       return a.lo[axis] + a.hi[axis] < b.lo[axis] + b.hi[axis];
                     });
    left = range_of(r.begin, mid);
    right = range_of(mid, r.end);
  }

  void build(uint32_t index, const Range& r, int depth, Scratch& s) {
    const uint32_t n = r.end - r.begin;
    if (n <= 1) return leaf(index, r, depth, s);
    // A split puts its children at depth + 1; with n <= max_leaf a leaf is always allowed instead.
    if (n <= p_.max_leaf && depth + 1 > p_.max_depth) return leaf(index, r, depth, s);

    alignas(16) float cmin[4], cext[4];
    _mm_store_ps(cmin, r.cbox.lo);
    _mm_store_ps(cext, _mm_sub_ps(r.cbox.hi, r.cbox.lo));
    int widest = 0;
    if (cext[1] > cext[widest]) widest = 1;
    if (cext[2] > cext[widest]) widest = 2;

    // Never more bins than primitives: a node of n primitives has at most n non-empty bins anyway, and the
    // per-node sweeps over empty bins would otherwise dominate the many small nodes near the leaves.
    const int nb = std::min<int>(p_.buckets, static_cast<int>(n));
    alignas(16) float scale[4] = {0, 0, 0, 0};
    int first_axis = -1;
    for (int a = 0; a < 3; ++a) {
      if (!p_.all_axes && a != widest) continue;
      const float sc = static_cast<float>(nb) / cext[a];
      // A zero (or underflowing) spread cannot be binned: that axis offers no split.
      if (cext[a] > 0.0f && std::isfinite(sc)) {
        scale[a] = sc;
        if (first_axis < 0) first_axis = a;
      }
    }
    Range left, right;
    if (first_axis < 0) {
      if (n <= p_.max_leaf) return leaf(index, r, depth, s);
      median_split(r, widest, left, right);
      return finish_interior(index, r, widest, left, right, depth, s);
    }
    if (n == 2) return build_pair(index, r, depth, first_axis, s);

    // Binning.
    const __m128 vmin = r.cbox.lo, vscale = _mm_load_ps(scale), vlast = _mm_set1_ps(static_cast<float>(nb - 1));
    const bool runs = p_.all_axes && n >= kRunBinning && !signed_zeros_;
    const std::size_t used = (p_.all_axes && n >= 64 && !runs ? 6 : 3) * static_cast<std::size_t>(nb);
    std::memcpy(static_cast<void*>(s.bins.data()), s.empty_bins.data(), used * sizeof(Bin));
    Bin* bins = s.bins.data();
    if (p_.all_axes) {
      // Two bin sets, even and odd primitives: neighbouring primitives usually land in the same bin, and
      // alternating sets halves the chain of dependent loads and stores through that bin.
      Bin* bins2 = bins + 3 * nb;
      const auto bin_one = [&](const PrimRef& pr, Bin* bs) {
        const __m128 lo = load3(pr.lo), hi = load3(pr.hi);
        alignas(16) int32_t b[4];
        _mm_store_si128(reinterpret_cast<__m128i*>(b), bin_index(_mm_add_ps(lo, hi), vmin, vscale, vlast));
        bs[b[0]].add(lo, hi);
        bs[nb + b[1]].add(lo, hi);
        bs[2 * nb + b[2]].add(lo, hi);
      };
      uint32_t i = r.begin;
      if (runs) {
        if (n >= kParallelBinning && forker_.try_fork(n)) {
          // A large node with a worker slot free (the root of a threaded build): the back half is binned on
          // another thread into the second bin set, then merged. min/max are exact and the counts add, so the
          // bins are those of one pass (runs are only taken without signed zeros).
          std::memcpy(static_cast<void*>(bins2), s.empty_bins.data(), 3 * static_cast<std::size_t>(nb) * sizeof(Bin));
          Range front = r, back = r;
          front.end = back.begin = r.begin + n / 2;
          std::thread t([&] { bin_runs(back, nb, vmin, vscale, vlast, bins2); });
          bin_runs(front, nb, vmin, vscale, vlast, bins);
          t.join();
          forker_.release();
          for (int b = 0; b < 3 * nb; ++b) bins[b].merge(bins2[b]);
        } else {
          bin_runs(r, nb, vmin, vscale, vlast, bins);
        }
        i = r.end;
      } else if (n >= 64) {
        for (; i + 1 < r.end; i += 2) {
          bin_one(prims_[i], bins);
          bin_one(prims_[i + 1], bins2);
        }
        for (int b = 0; b < 3 * nb; ++b) bins[b].merge(bins2[b]);
      }
      for (; i < r.end; ++i) bin_one(prims_[i], bins);
    } else {
      Bin* abins = bins + widest * nb;
      for (uint32_t i = r.begin; i < r.end; ++i) {
        const __m128 lo = load3(prims_[i].lo), hi = load3(prims_[i].hi);
        alignas(16) int32_t b[4];
        _mm_store_si128(reinterpret_cast<__m128i*>(b), bin_index(_mm_add_ps(lo, hi), vmin, vscale, vlast));
        abins[b[widest]].add(lo, hi);
      }
    }

    // Per axis: sweep from the right for N_B * S_B, then from the left for the total.
    int best_axis = -1, best_bin = -1;
    float best_cost = kInf;
    uint32_t best_left_count = 0;
    if (p_.all_axes) {
      sweep3(bins, nb, n, scale, s, best_axis, best_bin, best_cost, best_left_count);
    } else {
      sweep1(bins, nb, n, scale, s, best_axis, best_bin, best_cost, best_left_count);
    }

    // Compared in units of area times cost (no division, so a zero-area node stays finite).
    const float node_area = half_area4(r.box.lo, r.box.hi);
    const float split_cost = p_.traversal_cost * node_area + best_cost;
    const float leaf_cost = static_cast<float>(n) * node_area;
    if (n <= p_.max_leaf && (best_axis < 0 || leaf_cost <= split_cost)) return leaf(index, r, depth, s);

    const uint32_t larger_child = best_axis < 0 ? n : std::max(best_left_count, n - best_left_count);
    if (best_axis < 0 || depth + 1 + levels_needed(larger_child, p_.max_leaf) > p_.max_depth) {
      // The SAH split could not be finished within the depth left (or there is none): a median split
      // halves the count, which always fits because this node's own range did.
      if (n <= p_.max_leaf) return leaf(index, r, depth, s);
      if (best_axis >= 0) depth_limited_.fetch_add(1, std::memory_order_relaxed);
      median_split(r, widest, left, right);
      return finish_interior(index, r, widest, left, right, depth, s);
    }

    // Partition in place (Hoare), collecting the children's centroid bounds on the way. A primitive goes
    // left when its bin index on best_axis is <= best_bin, i.e. when the unclamped bin coordinate is below
    // best_bin + 1 (the clamp to the last bin never matters since best_bin + 1 <= buckets - 1): the same
    // float arithmetic as bin_index, so binning and partitioning agree exactly.
    const float part_min = cmin[best_axis], part_scale = scale[best_axis];
    const float part_limit = static_cast<float>(best_bin + 1);
    // The scalar lane of the same sum: (lo + hi) on one axis is the same float in a register lane or alone.
    const auto goes_left = [&](const PrimRef* q) {
      return ((&q->lo.x)[best_axis] + (&q->hi.x)[best_axis] - part_min) * part_scale < part_limit;
    };
    Box4 lc, rc;  // the children's centroid bounds
    if (n <= kSmallPartition) {
      partition_small(r, best_axis, vmin, vscale, part_limit, best_left_count, lc, rc);
    } else {
      PrimRef* lp = prims_.data() + r.begin;
      PrimRef* rp = prims_.data() + r.end;
      for (;;) {
        while (lp < rp) {
          if (!goes_left(lp)) break;
          lc.grow_point(_mm_add_ps(load3(lp->lo), load3(lp->hi)));
          ++lp;
        }
        while (lp < rp) {
          if (goes_left(rp - 1)) break;
          rc.grow_point(_mm_add_ps(load3((rp - 1)->lo), load3((rp - 1)->hi)));
          --rp;
        }
        if (lp >= rp) break;
        std::swap(*lp, *(rp - 1));  // now *lp goes left and *(rp - 1) right; the loops above take them
      }
    }
    left.cbox = lc;
    right.cbox = rc;
    const Bin* ab = bins + best_axis * nb;
    for (int b = 0; b < nb; ++b) (b <= best_bin ? left : right).box.grow(ab[b].lo, ab[b].box_hi());
    left.begin = r.begin;
    left.end = r.begin + best_left_count;  // where the partition ends: the bins counted the left side
    right.begin = left.end;
    right.end = r.end;
    finish_interior(index, r, best_axis, left, right, depth, s);
  }

  /// The Hoare partition above, to the same permutation and the same centroid folds, for a node small enough for
  /// a bit mask. Its branches on each primitive's side are hard to predict in small nodes; here the sides go to a
  /// mask first, then Hoare's swaps are read off it: the i-th primitive from the start that is left of k =
  /// left_count but goes right trades places with the i-th from the end that is right of k but goes left. Hoare
  /// grows the left centroid bounds over the final [begin, begin + k) in ascending order and the right ones over
  /// the rest in descending order, and so does this.
  void partition_small(const Range& r, int axis, __m128 vmin, __m128 vscale, float limit, uint32_t left_count, Box4& lc,
                       Box4& rc) {
    PrimRef* p = prims_.data() + r.begin;
    const uint32_t n = r.end - r.begin;
    const __m128 vlimit = _mm_set1_ps(limit);
    uint64_t goes_left = 0;
    // Lane `axis` of the vector test is the scalar test of goes_left (the same three operations).
    for (uint32_t i = 0; i < n; ++i) {
      const __m128 c = _mm_add_ps(load3(p[i].lo), load3(p[i].hi));
      const auto m =
          static_cast<uint32_t>(_mm_movemask_ps(_mm_cmplt_ps(_mm_mul_ps(_mm_sub_ps(c, vmin), vscale), vlimit)));
      goes_left |= static_cast<uint64_t>((m >> axis) & 1u) << i;
    }
    const uint64_t low = (uint64_t{1} << left_count) - 1;  // left_count < n <= 64
    uint64_t stray_left = ~goes_left & low;                // in [0, k) but going right
    uint64_t stray_right = goes_left & ~low;               // in [k, n) but going left
    while (stray_left != 0) {
      const int i = __builtin_ctzll(stray_left);
      const int j = 63 - __builtin_clzll(stray_right);
      std::swap(p[i], p[j]);
      stray_left &= stray_left - 1;
      stray_right ^= uint64_t{1} << j;
    }
    for (uint32_t i = 0; i < left_count; ++i) lc.grow_point(_mm_add_ps(load3(p[i].lo), load3(p[i].hi)));
    for (uint32_t i = n; i-- > left_count;) rc.grow_point(_mm_add_ps(load3(p[i].lo), load3(p[i].hi)));
  }

  /// Binning of a large node as runs: consecutive primitives usually fall into the same bin on all three
  /// axes (the range was partitioned spatially just before), so a run's box and count grow in registers
  /// and reach the bins once per run instead of once per primitive. min/max are exact, so only the zero
  /// signs could depend on the grouping (see signed_zeros_).
  void bin_runs(const Range& r, int nb, __m128 vmin, __m128 vscale, __m128 vlast, Bin* bins) const {
    const PrimRef* p = prims_.data() + r.begin;
    const PrimRef* end = prims_.data() + r.end;
    const __m128i axis_off = _mm_setr_epi32(0, nb, 2 * nb, 0);
    __m128 run_lo = load3(p->lo), run_hi = load3(p->hi);
    __m128i key = _mm_add_epi32(bin_index(_mm_add_ps(run_lo, run_hi), vmin, vscale, vlast), axis_off);
    int32_t run_count = 1;
    const auto flush = [&] {
      alignas(16) int32_t b[4];
      _mm_store_si128(reinterpret_cast<__m128i*>(b), key);
      const __m128i add = _mm_setr_epi32(0, 0, 0, run_count);
      for (int a = 0; a < 3; ++a) {
        Bin& bin = bins[b[a]];
        bin.lo = _mm_min_ps(bin.lo, run_lo);
        bin.hi = _mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(_mm_max_ps(bin.hi, run_hi)), add));
      }
    };
    for (++p; p < end; ++p) {
      const __m128 lo = load3(p->lo), hi = load3(p->hi);
      const __m128i k = _mm_add_epi32(bin_index(_mm_add_ps(lo, hi), vmin, vscale, vlast), axis_off);
      if (_mm_movemask_epi8(_mm_cmpeq_epi32(k, key)) == 0xffff) {
        run_lo = _mm_min_ps(run_lo, lo);
        run_hi = _mm_max_ps(run_hi, hi);
        ++run_count;
        continue;
      }
      flush();
      key = k;
      run_lo = lo;
      run_hi = hi;
      run_count = 1;
    }
    flush();
  }

  /// The sweep of one axis at a time (the largest-axis rule bins a single axis).
  void sweep1(const Bin* bins, int nb, uint32_t n, const float* scale, Scratch& s, int& best_axis, int& best_bin,
              float& best_cost, uint32_t& best_left_count) const {
    for (int a = 0; a < 3; ++a) {
      if (scale[a] == 0.0f) continue;
      const Bin* ab = bins + a * nb;
      Box4 acc;
      uint32_t count = 0;
      for (int b = nb - 1; b > 0; --b) {
        acc.grow(ab[b].lo, ab[b].box_hi());
        count += ab[b].count();
        s.right_cost[b - 1] = count ? static_cast<float>(count) * half_area4(acc.lo, acc.hi) : 0.0f;
      }
      acc = Box4{};
      count = 0;
      for (int b = 0; b < nb - 1; ++b) {
        acc.grow(ab[b].lo, ab[b].box_hi());
        count += ab[b].count();
        if (count == 0 || count == n) continue;
        const float cost = static_cast<float>(count) * half_area4(acc.lo, acc.hi) + s.right_cost[b];
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = a;
          best_bin = b;
          best_left_count = count;
        }
      }
    }
  }

  /// All three axes at once, one SSE lane per axis: the same operations in the same order per lane as
  /// sweep1, so the same costs to the bit, and the same winner (axis-major order, first strict minimum).
  /// Half area of a box is (ex * ey + ez * ex) + (ey * ez + 0), exactly as half_area4 evaluates it.
  void sweep3(const Bin* bins, int nb, uint32_t n, const float* scale, Scratch& s, int& best_axis, int& best_bin,
              float& best_cost, uint32_t& best_left_count) const {
    __m128* soa = &s.soa.data()->v;
    const __m128 zero = _mm_setzero_ps();
    // Transpose: for bin b, lanes 0..2 = axes 0..2.
    for (int b = 0; b < nb; ++b) {
      const Bin& b0 = bins[b];
      const Bin& b1 = bins[nb + b];
      const Bin& b2 = bins[2 * nb + b];
      // lo: (x0 y0 z0 .) (x1 y1 z1 .) (x2 y2 z2 .) -> (x0 x1 x2 .) (y0 y1 y2 .) (z0 z1 z2 .)
      const __m128 l01lo = _mm_unpacklo_ps(b0.lo, b1.lo);  // x0 x1 y0 y1
      const __m128 l01hi = _mm_unpackhi_ps(b0.lo, b1.lo);  // z0 z1 . .
      const __m128 l2lo = _mm_unpacklo_ps(b2.lo, zero);    // x2 0 y2 0
      const __m128 l2hi = _mm_unpackhi_ps(b2.lo, zero);    // z2 0 . 0
      soa[7 * b + 0] = _mm_movelh_ps(l01lo, l2lo);
      soa[7 * b + 1] = _mm_movehl_ps(l2lo, l01lo);
      soa[7 * b + 2] = _mm_movelh_ps(l01hi, l2hi);
      const __m128 h01lo = _mm_unpacklo_ps(b0.hi, b1.hi);
      const __m128 h01hi = _mm_unpackhi_ps(b0.hi, b1.hi);  // z0 z1 c0 c1
      const __m128 h2lo = _mm_unpacklo_ps(b2.hi, zero);
      const __m128 h2hi = _mm_unpackhi_ps(b2.hi, zero);  // z2 0 c2 0
      soa[7 * b + 3] = _mm_movelh_ps(h01lo, h2lo);
      soa[7 * b + 4] = _mm_movehl_ps(h2lo, h01lo);
      soa[7 * b + 5] = _mm_movelh_ps(h01hi, h2hi);
      soa[7 * b + 6] = _mm_movehl_ps(h2hi, h01hi);  // counts c0 c1 c2 0 as integer bits
    }
    const auto area = [](__m128 lx, __m128 ly, __m128 lz, __m128 hx, __m128 hy, __m128 hz) {
      const __m128 ex = _mm_sub_ps(hx, lx), ey = _mm_sub_ps(hy, ly), ez = _mm_sub_ps(hz, lz);
      const __m128 a = _mm_add_ps(_mm_mul_ps(ex, ey), _mm_mul_ps(ez, ex));
      return _mm_add_ps(a, _mm_add_ps(_mm_mul_ps(ey, ez), _mm_setzero_ps()));
    };
    const __m128 inf = _mm_set1_ps(kInf), ninf = _mm_set1_ps(-kInf);
    __m128 lx = inf, ly = inf, lz = inf, hx = ninf, hy = ninf, hz = ninf;
    __m128i count = _mm_setzero_si128();
    // Grows the running bounds and count of the three axes by one bin (the same operations both ways).
    auto grow = [&](const __m128* q) {
      lx = _mm_min_ps(lx, q[0]);
      ly = _mm_min_ps(ly, q[1]);
      lz = _mm_min_ps(lz, q[2]);
      hx = _mm_max_ps(hx, q[3]);
      hy = _mm_max_ps(hy, q[4]);
      hz = _mm_max_ps(hz, q[5]);
      count = _mm_add_epi32(count, _mm_castps_si128(q[6]));
    };
    __m128* right = soa + 7 * nb;
    for (int b = nb - 1; b > 0; --b) {
      grow(soa + 7 * b);
      const __m128 nonzero =
          _mm_castsi128_ps(_mm_xor_si128(_mm_cmpeq_epi32(count, _mm_setzero_si128()), _mm_set1_epi32(-1)));
      right[b - 1] = _mm_and_ps(nonzero, _mm_mul_ps(_mm_cvtepi32_ps(count), area(lx, ly, lz, hx, hy, hz)));
    }
    lx = inf, ly = inf, lz = inf, hx = ninf, hy = ninf, hz = ninf;
    count = _mm_setzero_si128();
    // Lanes of axes that offer no split never win.
    const __m128i axis_ok = _mm_castps_si128(_mm_cmpneq_ps(_mm_load_ps(scale), _mm_setzero_ps()));
    const __m128i vn = _mm_set1_epi32(static_cast<int>(n));
    __m128 lane_best = inf;
    __m128i lane_bin = _mm_set1_epi32(-1), lane_count = _mm_setzero_si128();
    for (int b = 0; b < nb - 1; ++b) {
      grow(soa + 7 * b);
      const __m128 cost = _mm_add_ps(_mm_mul_ps(_mm_cvtepi32_ps(count), area(lx, ly, lz, hx, hy, hz)), right[b]);
      const __m128i valid =
          _mm_andnot_si128(_mm_or_si128(_mm_cmpeq_epi32(count, _mm_setzero_si128()), _mm_cmpeq_epi32(count, vn)),
                           axis_ok);
      const __m128i better = _mm_and_si128(valid, _mm_castps_si128(_mm_cmplt_ps(cost, lane_best)));
      const __m128 bf = _mm_castsi128_ps(better);
      lane_best = select(bf, cost, lane_best);
      lane_bin = _mm_castps_si128(select(bf, _mm_castsi128_ps(_mm_set1_epi32(b)), _mm_castsi128_ps(lane_bin)));
      lane_count = _mm_castps_si128(select(bf, _mm_castsi128_ps(count), _mm_castsi128_ps(lane_count)));
    }
    alignas(16) float lb[4];
    alignas(16) int32_t lbin[4], lcount[4];
    _mm_store_ps(lb, lane_best);
    _mm_store_si128(reinterpret_cast<__m128i*>(lbin), lane_bin);
    _mm_store_si128(reinterpret_cast<__m128i*>(lcount), lane_count);
    for (int a = 0; a < 3; ++a) {
      if (lbin[a] >= 0 && lb[a] < best_cost) {
        best_cost = lb[a];
        best_axis = a;
        best_bin = lbin[a];
        best_left_count = static_cast<uint32_t>(lcount[a]);
      }
    }
  }

  /// Two primitives, about a third of all nodes: the binned search above would put them in bins 0 and 1
  /// of every axis that has a spread, all with the same cost, so the first such axis wins and the one with
  /// the smaller centroid goes left. This computes exactly that (same arithmetic, so the same tree) without
  /// filling and sweeping 3 x 2 bins.
  void build_pair(uint32_t index, const Range& r, int depth, int axis, Scratch& s) {
    PrimRef* p = prims_.data() + r.begin;
    const __m128 lo0 = load3(p[0].lo), hi0 = load3(p[0].hi), lo1 = load3(p[1].lo), hi1 = load3(p[1].hi);
    const bool swap = lane(_mm_add_ps(lo0, hi0), axis) > lane(_mm_add_ps(lo1, hi1), axis);
    const float a_left = half_area4(swap ? lo1 : lo0, swap ? hi1 : hi0);
    const float a_right = half_area4(swap ? lo0 : lo1, swap ? hi0 : hi1);
    const float node_area = half_area4(r.box.lo, r.box.hi);
    const float split_cost = p_.traversal_cost * node_area + (1.0f * a_left + 1.0f * a_right);
    if (2 <= p_.max_leaf && 2.0f * node_area <= split_cost) return leaf(index, r, depth, s);
    // Splitting is within the depth bound: build() made a leaf when n <= max_leaf and depth + 1 exceeded
    // it, and with max_leaf = 1 the invariant depth + levels_needed(2) <= max_depth guarantees it.
    if (swap) std::swap(p[0], p[1]);
    Range left, right;
    left.box.grow(swap ? lo1 : lo0, swap ? hi1 : hi0);
    left.cbox.grow_point(_mm_add_ps(swap ? lo1 : lo0, swap ? hi1 : hi0));
    right.box.grow(swap ? lo0 : lo1, swap ? hi0 : hi1);
    right.cbox.grow_point(_mm_add_ps(swap ? lo0 : lo1, swap ? hi0 : hi1));
    left.begin = r.begin;
    left.end = right.begin = r.begin + 1;
    right.end = r.end;
    finish_interior(index, r, axis, left, right, depth, s);
  }

  static float lane(__m128 v, int i) {
    alignas(16) float f[4];
    _mm_store_ps(f, v);
    return f[i];
  }

  void finish_interior(uint32_t index, const Range& r, int axis, const Range& left, const Range& right, int depth,
                       Scratch& s) {
    std::vector<gpu::BvhNode>& out = *s.out;
    out[index] = make_interior(to_vec3(r.box.lo), to_vec3(r.box.hi), 0, static_cast<uint32_t>(axis));
    const auto first = static_cast<uint32_t>(out.size());
    out.emplace_back();
    const uint32_t nr = right.end - right.begin;
    if (!forker_.try_fork(nr)) {
      build(first, left, depth + 1, s);
      const auto second = static_cast<uint32_t>(out.size());
      out.emplace_back();
      out[index].offset = static_cast<int>(second);
      build(second, right, depth + 1, s);
      return;
    }
    fork_second(index, first, left, right, depth, s);
  }

  /// The second child on a new thread (which holds a worker slot), depth first into a buffer of its own;
  /// the first child here. The buffer is appended after the first child's subtree, its interior offsets
  /// moved by where it lands. Out of line, so that the one-thread recursion stays small.
  [[gnu::noinline]] void fork_second(uint32_t index, uint32_t first, const Range& left, const Range& right, int depth,
                                     Scratch& s) {
    std::vector<gpu::BvhNode>& out = *s.out;
    const uint32_t nr = right.end - right.begin;
    std::vector<gpu::BvhNode> sub;
    std::exception_ptr error;
    int right_depth = 0;
    // The build's first fork (always on the thread that called run(), before any other exists) is timed.
    using Clock = std::chrono::steady_clock;
    const bool timed = !phases_.forked;
    const Clock::time_point fork_at = Clock::now();
    double second_ms = 0.0;
    if (timed) {
      phases_.forked = true;
      phases_.top_ms = ms_between(start_, fork_at);
      phases_.first_primitives = left.end - left.begin;
      phases_.second_primitives = nr;
    }
    std::atomic<bool> second_done{false};
    std::thread t([&] {
      try {
        reserve_nodes(sub, nr);
        sub.emplace_back();
        Scratch own(p_.buckets);
        own.out = &sub;
        build(0, right, depth + 1, own);
        right_depth = own.max_depth;
        second_ms = ms_between(fork_at, Clock::now());
      } catch (...) {
        error = std::current_exception();
      }
      second_done.store(true, std::memory_order_release);
      forker_.release();
    });
    try {
      build(first, left, depth + 1, s);
    } catch (...) {
      t.join();
      throw;
    }
    const double first_ms = ms_between(fork_at, Clock::now());
    if (!second_done.load(std::memory_order_acquire)) {
      // Waiting anyway: fault in the pages the append will write, as many nodes as the second subtree should
      // need at this subtree's nodes per primitive, so that the copy at the join takes no page faults. Done
      // from the forked thread when it ends first, the same call took up to 60 ms on a VM (bvh-performance.md).
      const std::size_t at = out.size();
      const double per_prim = static_cast<double>(at - first) / (left.end - left.begin);
      const std::size_t end = std::min(out.capacity(), at + static_cast<std::size_t>(1.02 * per_prim * nr));
      if (end > at) populate_for_write(out.data() + at, (end - at) * sizeof(gpu::BvhNode));
    }
    t.join();
    if (error) std::rethrow_exception(error);
    const Clock::time_point append_at = Clock::now();
    s.max_depth = std::max(s.max_depth, right_depth);
    const auto second = static_cast<uint32_t>(out.size());
    out[index].offset = static_cast<int>(second);
    out.insert(out.end(), sub.begin(), sub.end());
    for (std::size_t i = second; i < out.size(); ++i) {
      if ((out[i].prim_axis >> HP_BVH_AXIS_BITS) == 0) out[i].offset += static_cast<int>(second);
    }
    if (timed) {
      phases_.first_ms = first_ms;
      phases_.second_ms = second_ms;
      phases_.append_ms = ms_between(append_at, Clock::now());
    }
  }

  std::span<PrimRef> prims_;
  uint32_t* order_ = nullptr;  // the tree's order: each leaf writes its own range
  BuildParams p_;
  Forker forker_;
  std::atomic<std::size_t> depth_limited_{0};
  std::chrono::steady_clock::time_point start_;
  /// Written by the thread that called run() only: at its first fork (before the forked thread exists) and after
  /// that fork's join. Later forks, on any thread, only read `forked`.
  BuildPhases phases_;
  /// Some primitive bound is -0.0. Folding boxes with min/max in another order can then change a box's
  /// zero sign (min and max keep their second operand on ties), so the builder keeps the reference order:
  /// the paths that regroup the folds are only taken without signed zeros, where every order gives the
  /// same bits.
  bool signed_zeros_ = false;
};
