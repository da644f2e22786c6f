// The reference traversal called through helpers that also trace the 8-wide CPU form (bvh8.hpp) and the
// wide4 node layout (wide.hpp, where the tree fits it) and expect their answers: the closest hit bit for
// bit, the any-hit answer (hit or miss) exactly and its hit a real one. Every hard case written against the
// reference checks the wide traversals too.
#pragma once

#include "bvh/bvh8.hpp"
#include "bvh/traverse.hpp"
#include "bvh/wide.hpp"
#include "error.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <optional>
#include <span>
#include <vector>

namespace hp::bvh::testing {

struct Built {
  Bvh bvh;
  LeafOrderTriangles lt;
  Bvh8 wide;
  /// The wide4 layout; empty where the tree does not fit it (leaves over 15, or too deep for the stack).
  std::optional<WideBvh> wide4;
  std::vector<Triangle> scene;  // scene order, to check that a 8-wide any hit is a real hit
};

inline Built wrap(Bvh bvh, std::span<const Triangle> tris) {
  Built b{std::move(bvh), {}, {}, {}, std::vector<Triangle>(tris.begin(), tris.end())};
  b.lt = leaf_order(b.bvh, tris);
  b.wide = make_bvh8(b.bvh, b.lt);
  try {
    b.wide4 = make_wide(b.bvh);
  } catch (const InputError&) {
  }
  return b;
}
inline Built build(std::span<const Triangle> tris, BuildOptions o = {}, std::span<const uint32_t> objects = {}) {
  return wrap(build_bvh(tris, o, objects), tris);
}

inline bool same_bits(const Hit& a, const Hit& b) { return std::memcmp(&a, &b, sizeof(Hit)) == 0; }

/// intersect_closest on the binary tree; the 8-wide traversal must give the same bits.
inline Hit closest(const Built& b, const Ray& r) {
  const Hit want = intersect_closest(b.bvh, b.lt, r);
  const Hit got = intersect_closest(b.wide, r);
  EXPECT_TRUE(same_bits(want, got)) << "8-wide closest hit prim " << got.prim << " t " << got.t << " u " << got.u
                                    << " v " << got.v << ", binary prim " << want.prim << " t " << want.t << " u "
                                    << want.u << " v " << want.v;
  if (b.wide4) {
    const Hit got4 = intersect_closest(*b.wide4, b.lt, r);
    EXPECT_TRUE(same_bits(want, got4)) << "wide4 closest hit prim " << got4.prim << " t " << got4.t << " u " << got4.u
                                       << " v " << got4.v << ", binary prim " << want.prim << " t " << want.t << " u "
                                       << want.u << " v " << want.v;
  }
  return want;
}

/// intersect_any on the binary tree; the 8-wide traversal must agree on hit or miss, and its hit (possibly
/// another triangle: any hit is the first found) must be that triangle's own hit within the ray's range.
inline Hit any(const Built& b, const Ray& r) {
  const Hit want = intersect_any(b.bvh, b.lt, r);
  const auto check = [&](const Hit& got, const char* what) {
    EXPECT_EQ(want.hit(), got.hit()) << what << " any hit prim " << got.prim << ", binary " << want.prim;
    if (got.hit()) {
      Hit own;
      EXPECT_TRUE(got.prim < static_cast<int32_t>(b.scene.size()) && intersect_triangle(r, b.scene[got.prim], own) &&
                  own.t == got.t && own.u == got.u && own.v == got.v)
          << what << " any hit prim " << got.prim << " t " << got.t << " is not that triangle's hit";
    }
  };
  check(intersect_any(b.wide, r), "8-wide");
  if (b.wide4) check(intersect_any(*b.wide4, b.lt, r), "wide4");
  return want;
}

}  // namespace hp::bvh::testing
