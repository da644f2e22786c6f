// The GPU radix sort (renderer/passes/radix_sort.*) against std::stable_sort on the CPU. The values carry
// each element's original index, so comparing (key, value) pairs checks the exact permutation, stability
// included, not just that the keys come out ordered.
#include "vulkan_env.hpp"

#include "error.hpp"
#include "passes/radix_sort.hpp"
#include "vk/resources.hpp"

#include <algorithm>
#include <cstring>
#include <numeric>
#include <random>
#include <vector>

namespace hp {
namespace {

constexpr VkBufferUsageFlags kUsage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;

std::vector<uint32_t> to_uints(const std::vector<std::byte>& bytes) {
  std::vector<uint32_t> v(bytes.size() / sizeof(uint32_t));
  std::memcpy(v.data(), bytes.data(), v.size() * sizeof(uint32_t));
  return v;
}

struct Sorted {
  std::vector<uint32_t> keys, values;  // the whole capacity, read back
};

// Uploads `keys` (padded with `pad_keys` up to `capacity`) and values = index (padding values = a
// sentinel), sorts `count` of them on the GPU (the count lives in a GPU buffer), reads everything back.
Sorted gpu_sort(vk::Context& ctx, std::vector<uint32_t> keys, uint32_t key_bits, uint32_t count, uint32_t capacity) {
  keys.resize(capacity, 0xDEADBEEFu);
  std::vector<uint32_t> values(capacity);
  std::iota(values.begin(), values.end(), 0u);
  for (uint32_t i = count; i < capacity; ++i) values[i] = 0xFFFFFFF0u;
  vk::Buffer kb = vk::upload_vector(ctx, keys, kUsage);
  vk::Buffer vb = vk::upload_vector(ctx, values, kUsage);
  vk::Buffer cb = vk::upload_vector(ctx, std::vector<uint32_t>{count}, kUsage);
  RadixSort sort(ctx, capacity);
  ctx.submit_and_wait([&](VkCommandBuffer cmd) { sort.record(cmd, kb, vb, cb, key_bits); });
  return {to_uints(vk::read_buffer(ctx, kb)), to_uints(vk::read_buffer(ctx, vb))};
}

// The CPU reference: stable sort of the first `count` (key, index) pairs by the low `key_bits` bits.
void expect_matches_cpu(const std::vector<uint32_t>& keys, uint32_t key_bits, uint32_t count, const Sorted& got) {
  const uint32_t mask = key_bits >= 32 ? 0xFFFFFFFFu : ((1u << key_bits) - 1u);
  std::vector<uint32_t> order(count);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return (keys[a] & mask) < (keys[b] & mask); });
  ASSERT_GE(got.keys.size(), count);
  size_t mismatches = 0;
  for (uint32_t i = 0; i < count; ++i) {
    if (got.values[i] != order[i] || got.keys[i] != keys[order[i]]) {
      if (++mismatches <= 5)
        ADD_FAILURE() << "position " << i << ": got (key " << got.keys[i] << ", index " << got.values[i]
                      << "), want (key " << keys[order[i]] << ", index " << order[i] << ")";
    }
  }
  EXPECT_EQ(mismatches, 0u) << "of " << count << " elements, key_bits " << key_bits;
  // Past the live count nothing is touched.
  for (size_t i = count; i < got.keys.size(); ++i) {
    if (got.keys[i] != 0xDEADBEEFu || got.values[i] != 0xFFFFFFF0u) {
      ADD_FAILURE() << "element " << i << " past the count " << count << " was written";
      break;
    }
  }
}

std::vector<uint32_t> random_keys(uint32_t n, uint32_t seed, uint32_t key_bits) {
  std::mt19937 rng(seed);
  const uint32_t mask = key_bits >= 32 ? 0xFFFFFFFFu : ((1u << key_bits) - 1u);
  std::vector<uint32_t> k(n);
  for (auto& x : k) x = rng() & mask;
  return k;
}

void check(const std::vector<uint32_t>& keys, uint32_t key_bits, uint32_t capacity = 0) {
  HP_REQUIRE_VULKAN(ctx);
  const uint32_t count = static_cast<uint32_t>(keys.size());
  if (capacity == 0) capacity = std::max(count, 1u);
  const Sorted got = gpu_sort(*ctx, keys, key_bits, count, capacity);
  expect_matches_cpu(keys, key_bits, count, got);
}

TEST(RadixSort, RandomKeysOfEveryWidthAndSeveralSeeds) {
  for (uint32_t bits : {3u, 6u, 16u, 30u, 32u})
    for (uint32_t seed : {1u, 2u, 3u}) {
      SCOPED_TRACE(testing::Message() << "bits " << bits << " seed " << seed);
      check(random_keys(10'000 + seed * 777, seed * 31 + bits, bits), bits);
    }
}

TEST(RadixSort, AwkwardCounts) {
  for (uint32_t n : {1u, 7u, 255u, 256u, 257u, 4095u, 4096u, 4097u, 10'000u}) {
    SCOPED_TRACE(testing::Message() << "count " << n);
    check(random_keys(n, n, 16), 16);
  }
}

TEST(RadixSort, ZeroCountLeavesBuffersUntouched) {
  check({}, 32, 300);
  check({}, 3, 1);
}

TEST(RadixSort, AllEqualKeysKeepInputOrder) {
  check(std::vector<uint32_t>(50'000, 0x2A2A2A2Au), 32);
  check(std::vector<uint32_t>(50'000, 5u), 3);
}

TEST(RadixSort, AlreadySortedAndReversed) {
  std::vector<uint32_t> up(70'000);
  for (uint32_t i = 0; i < up.size(); ++i) up[i] = i / 3;  // runs of equal keys: stability matters
  check(up, 30);
  std::vector<uint32_t> down(up.rbegin(), up.rend());
  check(down, 30);
}

// Bits above key_bits are carried but do not take part: equal low bits keep input order.
TEST(RadixSort, IgnoresBitsAboveKeyBits) {
  check(random_keys(20'000, 99, 32), 6);
  check(random_keys(20'000, 98, 32), 16);
}

TEST(RadixSort, OneMillionKeys) { check(random_keys(1'000'003, 7, 30), 30); }

// The count comes from the GPU buffer: a capacity-sized sorter and buffers, a smaller live count.
TEST(RadixSort, CountFromGpuBufferSmallerThanCapacity) {
  check(random_keys(5'000, 11, 30), 30, 20'000);
  check(random_keys(4'097, 12, 6), 6, 9'000);  // two 4-bit passes, a partial last block
  check(random_keys(100, 13, 3), 3, 100'000);  // one pass: the result comes back through the copy kernel
}

// One sorter reused with a count written on the GPU between sorts (no descriptor rewrite, no readback).
TEST(RadixSort, ReusedSorterWithGpuWrittenCount) {
  HP_REQUIRE_VULKAN(ctx);
  const uint32_t capacity = 12'000;
  const std::vector<uint32_t> keys = random_keys(capacity, 21, 30);
  std::vector<uint32_t> values(capacity);
  std::iota(values.begin(), values.end(), 0u);
  RadixSort sort(*ctx, capacity);
  for (uint32_t count : {capacity, 3'333u, 0u}) {
    SCOPED_TRACE(testing::Message() << "count " << count);
    vk::Buffer kb = vk::upload_vector(*ctx, keys, kUsage);
    vk::Buffer vb = vk::upload_vector(*ctx, values, kUsage);
    vk::Buffer cb = vk::upload_vector(*ctx, std::vector<uint32_t>{0u}, kUsage);
    ctx->submit_and_wait([&](VkCommandBuffer cmd) {
      vkCmdFillBuffer(cmd, cb.handle(), 0, sizeof(uint32_t), count);  // the "atomic counter" of a producer
      sort.record(cmd, kb, vb, cb, 30);
    });
    const std::vector<uint32_t> gk = to_uints(vk::read_buffer(*ctx, kb));
    const std::vector<uint32_t> gv = to_uints(vk::read_buffer(*ctx, vb));
    std::vector<uint32_t> order(count);
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return keys[a] < keys[b]; });
    for (uint32_t i = 0; i < count; ++i) ASSERT_EQ(gv[i], order[i]) << "position " << i;
    for (uint32_t i = count; i < capacity; ++i) {
      ASSERT_EQ(gv[i], i) << "element " << i << " past the count was moved";
      ASSERT_EQ(gk[i], keys[i]);
    }
  }
}

TEST(RadixSort, RejectsCapacityBeyondMaxStorageBufferRange) {
  HP_REQUIRE_VULKAN(ctx);
  const uint64_t limit = ctx->properties().limits.maxStorageBufferRange;
  const uint64_t too_many = limit / sizeof(uint32_t) + 1;
  try {
    RadixSort sort(*ctx, static_cast<uint32_t>(too_many));
    FAIL() << "no error for a capacity of " << too_many;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("maxStorageBufferRange"), std::string::npos) << e.what();
  }
  EXPECT_THROW(RadixSort(*ctx, 0), InputError);
}

TEST(RadixSort, PassCount) {
  EXPECT_EQ(RadixSort::pass_count(0), 0u);
  EXPECT_EQ(RadixSort::pass_count(3), 1u);
  EXPECT_EQ(RadixSort::pass_count(6), 2u);
  EXPECT_EQ(RadixSort::pass_count(16), 4u);
  EXPECT_EQ(RadixSort::pass_count(30), 8u);
  EXPECT_EQ(RadixSort::pass_count(32), 8u);
}

}  // namespace
}  // namespace hp
