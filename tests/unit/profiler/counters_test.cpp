#include <gtest/gtest.h>

#include "timing/counters.hpp"
#include "timing_fixture.hpp"

namespace hp {
namespace {

TEST(Counters, SameWorkCompareEqual) {
  // Two "runs" of the same frame; insertion order differs, which must not matter.
  Counters a = test::synthetic_frame(1).counters;
  Counters b;
  b.set("reflections", counter::triangles_tested, 12'345);
  b.set("reflections", counter::nodes_visited, 80'000);
  b.set("reflections", counter::rays_cast, 4096);
  b.set("shadows", counter::nodes_visited, 50'000);
  b.set("shadows", counter::rays_cast, 4096);
  EXPECT_EQ(a, b);
  EXPECT_TRUE(counter_differences(a, b).empty());
}

TEST(Counters, OneCountOffIsDifferent) {
  Counters a = test::synthetic_frame(1).counters;
  Counters b = a;
  b.add("shadows", counter::nodes_visited, 1);
  EXPECT_NE(a, b);
  const auto diff = counter_differences(a, b);
  ASSERT_EQ(diff.size(), 1u);
  EXPECT_EQ(diff[0], "shadows/nodes_visited: 50000 != 50001");
}

TEST(Counters, ExplicitZeroDiffersFromAbsent) {
  Counters a, b;
  a.set("composite", counter::compute_invocations, 0);
  EXPECT_NE(a, b);
  EXPECT_EQ(a.get("composite", counter::compute_invocations), b.get("composite", counter::compute_invocations));
  const auto diff = counter_differences(a, b);
  ASSERT_EQ(diff.size(), 1u);
  EXPECT_EQ(diff[0], "composite/compute_invocations: missing on the right");
  EXPECT_EQ(counter_differences(b, a)[0], "composite/compute_invocations: missing on the left");
}

TEST(Counters, AddAndTotals) {
  Counters a;
  a.add("shadows", counter::rays_cast, 10);
  a.add("shadows", counter::rays_cast, 5);
  a.set("reflections", counter::rays_cast, 7);
  EXPECT_EQ(a.get("shadows", counter::rays_cast), 15u);
  EXPECT_EQ(a.total(counter::rays_cast), 22u);
  EXPECT_EQ(a.total(counter::nodes_visited), 0u);
  Counters sum;
  sum.add(a);
  sum.add(a);
  EXPECT_EQ(sum.total(counter::rays_cast), 44u);
  EXPECT_EQ(a.get("missing", "x"), 0u);
}

}  // namespace
}  // namespace hp
