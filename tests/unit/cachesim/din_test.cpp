#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "cachesim/din_replay.hpp"
#include "error.hpp"
#include "trace/din.hpp"

namespace hp {
namespace {

std::string din_error(const std::string& text) {
  std::istringstream in(text);
  try {
    trace::parse_din(in, "t.din");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Din, ParsesAndRoundTrips) {
  std::istringstream in("r 1000 4\n\n# comment\nw 0x2a 10\n0 ff 1\n");
  auto a = trace::parse_din(in, "t.din");
  ASSERT_EQ(a.size(), 3u);
  EXPECT_FALSE(a[0].write);
  EXPECT_EQ(a[0].address, 0x1000u);
  EXPECT_TRUE(a[1].write);
  EXPECT_EQ(a[1].address, 0x2au);
  EXPECT_EQ(a[1].size, 16u);
  std::ostringstream out;
  trace::write_din(out, a);
  EXPECT_EQ(out.str(), "r 1000 4\nw 2a 10\nr ff 1\n");
}

TEST(Din, ErrorsNameFileAndLine) {
  EXPECT_EQ(din_error("r 10 4\nx 10 4\n"), "t.din:2: unsupported access label 'x' (expected r or w)");
  EXPECT_EQ(din_error("r 1g 4\n"), "t.din:1: bad hexadecimal address '1g'");
  EXPECT_EQ(din_error("r 10\n"), "t.din:1: missing size");
  EXPECT_EQ(din_error("\nr 10 0\n"), "t.din:2: bad size '0'");
  EXPECT_EQ(din_error("w 10 4 9\n"), "t.din:1: extra field after the size");
  EXPECT_THROW(trace::read_din("/nonexistent/x.din"), InputError);
}

TEST(Din, CacheSpecParsing) {
  auto c = cachesim::parse_cache_spec("16k:64:4", "--l1");
  EXPECT_EQ(c.size_bytes, 16384u);
  EXPECT_EQ(c.line_bytes, 64u);
  EXPECT_EQ(c.ways, 4u);
  EXPECT_EQ(cachesim::parse_cache_spec("4m:64:16", "--l2").size_bytes, 4u << 20);
  for (const char* bad : {"16k:64", "16k:48:4", "16x:64:4", "1000:64:4", "16k:64:4:1", "16k:64:0"}) {
    try {
      cachesim::parse_cache_spec(bad, "--l1");
      ADD_FAILURE() << bad;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("--l1 '" + std::string(bad) + "'", 0), 0u) << e.what();
    }
  }
}

TEST(Din, ReplayCountsLikeDinero) {
  // L1: 2 lines of 64 B, direct-mapped... here 128 B, 64 B lines, 1 way = 2 sets. L2: 1 KiB 4-way.
  auto l1 = cachesim::parse_cache_spec("128:64:1", "--l1");
  auto l2 = cachesim::parse_cache_spec("1k:64:4", "--l2");
  std::vector<trace::DinAccess> a = {
      {false, 0, 4},   // block 0: L1 miss, L2 miss
      {false, 60, 8},  // spans blocks 0 and 1: two fetches; 0 hits, 1 misses (L2 miss)
      {true, 128, 4},  // block 2 -> set 0, evicts block 0; write-allocate: miss, L2 miss
      {false, 0, 4},   // block 0 again: L1 miss (evicted), L2 hit
      {true, 130, 2},  // block 2: evicted by block 0 just now -> L1 miss, L2 hit
  };
  auto r = cachesim::replay_din(a, l1, l2);
  EXPECT_EQ(r.l1.fetches, 6u);
  EXPECT_EQ(r.l1.read_fetches, 4u);
  EXPECT_EQ(r.l1.write_fetches, 2u);
  EXPECT_EQ(r.l1.misses, 5u);
  EXPECT_EQ(r.l1.write_misses, 2u);
  EXPECT_EQ(r.l2.fetches, r.l1.misses);  // L2 demand fetches are the L1 misses
  EXPECT_EQ(r.l2.misses, 3u);
  EXPECT_EQ(r.l1_copies_back, 1u);  // block 2 was dirty when block 0 evicted it
}

TEST(Din, L2BlocksSmallerThanL1BlocksFetchEach) {
  auto l1 = cachesim::parse_cache_spec("1k:128:2", "--l1");
  auto l2 = cachesim::parse_cache_spec("4k:32:4", "--l2");
  auto r = cachesim::replay_din(std::vector<trace::DinAccess>{{false, 0, 4}}, l1, l2);
  EXPECT_EQ(r.l2.fetches, 4u);
  EXPECT_EQ(r.l2.misses, 4u);
}

}  // namespace
}  // namespace hp
