// The GPU radix sort (renderer/passes/radix_sort.*) vs std::stable_sort on 1 M (key, index) pairs at 8,
// 16 and 30 significant key bits. The GPU figure is the device time between two timestamps around the
// recorded sort (manual time); the keys are re-uploaded outside the timed interval each iteration so
// every iteration sorts the same unsorted input. The CPU figure sorts a fresh copy of an index array by
// key, which is what the GPU computes (key and original index per element).
#include "passes/radix_sort.hpp"
#include "vk/context.hpp"
#include "vk/resources.hpp"
#include "vk/timestamps.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <memory>
#include <numeric>
#include <random>
#include <vector>

namespace {

constexpr uint32_t kCount = 1u << 20;

std::vector<uint32_t> random_keys(uint32_t key_bits) {
  std::mt19937 rng(1234 + key_bits);
  const uint32_t mask = key_bits >= 32 ? 0xFFFFFFFFu : ((1u << key_bits) - 1u);
  std::vector<uint32_t> k(kCount);
  for (auto& x : k) x = rng() & mask;
  return k;
}

hp::vk::Context* context() {
  static std::unique_ptr<hp::vk::Context> ctx = [] {
    try {
      return std::make_unique<hp::vk::Context>();
    } catch (const std::exception&) {
      return std::unique_ptr<hp::vk::Context>();
    }
  }();
  return ctx.get();
}

void BM_GpuRadixSort(benchmark::State& state) {
  hp::vk::Context* ctx = context();
  if (!ctx) {
    state.SkipWithError("no Vulkan device");
    return;
  }
  const uint32_t key_bits = static_cast<uint32_t>(state.range(0));
  const std::vector<uint32_t> keys = random_keys(key_bits);
  std::vector<uint32_t> values(kCount);
  std::iota(values.begin(), values.end(), 0u);
  const VkBufferUsageFlags usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  hp::vk::Buffer src_keys = hp::vk::upload_vector(*ctx, keys, VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
  hp::vk::Buffer src_values = hp::vk::upload_vector(*ctx, values, VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
  hp::vk::Buffer kb(*ctx, kCount * sizeof(uint32_t), usage, false);
  hp::vk::Buffer vb(*ctx, kCount * sizeof(uint32_t), usage, false);
  hp::vk::Buffer cb = hp::vk::upload_vector(*ctx, std::vector<uint32_t>{kCount}, usage);
  hp::RadixSort sort(*ctx, kCount);
  hp::vk::TimestampQueries ts(*ctx, 1);
  if (!ts.supported()) {
    state.SkipWithError("no timestamp support");
    return;
  }
  for (auto _ : state) {
    ctx->submit_and_wait([&](VkCommandBuffer cmd) {
      const VkBufferCopy region{0, 0, kCount * sizeof(uint32_t)};
      vkCmdCopyBuffer(cmd, src_keys.handle(), kb.handle(), 1, &region);
      vkCmdCopyBuffer(cmd, src_values.handle(), vb.handle(), 1, &region);
      ts.reset(cmd);
      ts.begin(cmd, "radix_sort");
      sort.record(cmd, kb, vb, cb, key_bits);
      ts.end(cmd);
    });
    const auto intervals = ts.read(*ctx);
    state.SetIterationTime(double(intervals.at(0).end_ns - intervals.at(0).begin_ns) * 1e-9);
  }
  state.counters["keys"] = benchmark::Counter(double(kCount), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["passes"] = hp::RadixSort::pass_count(key_bits);
  state.SetLabel(ctx->info().name);
}

void BM_CpuStableSort(benchmark::State& state) {
  const uint32_t key_bits = static_cast<uint32_t>(state.range(0));
  const std::vector<uint32_t> keys = random_keys(key_bits);
  std::vector<uint32_t> order(kCount);
  for (auto _ : state) {
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return keys[a] < keys[b]; });
    benchmark::DoNotOptimize(order.data());
  }
  state.counters["keys"] = benchmark::Counter(double(kCount), benchmark::Counter::kIsIterationInvariantRate);
}

BENCHMARK(BM_GpuRadixSort)->Arg(8)->Arg(16)->Arg(30)->UseManualTime()->Unit(benchmark::kMillisecond)->Iterations(5);
BENCHMARK(BM_CpuStableSort)->Arg(8)->Arg(16)->Arg(30)->Unit(benchmark::kMillisecond)->Iterations(5);

}  // namespace

BENCHMARK_MAIN();
