#include "passes/radix_sort.hpp"

#include "error.hpp"
#include "shaders/sort_radix_copy_comp.h"
#include "shaders/sort_radix_histogram_comp.h"
#include "shaders/sort_radix_scan_comp.h"
#include "shaders/sort_radix_scatter_comp.h"
#include "sort/radix_config.h"

#include <string>
#include <vector>

namespace hp {
namespace {

struct RadixPush {
  uint32_t shift;
  uint32_t capacity;
  uint32_t key_mask;
};

std::vector<VkDescriptorSetLayoutBinding> sort_bindings() {
  std::vector<VkDescriptorSetLayoutBinding> b;
  for (uint32_t i = 0; i < 6; ++i)
    b.push_back({i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  return b;
}

void compute_to_compute(VkCommandBuffer cmd) {
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
}

}  // namespace

uint32_t RadixSort::pass_count(uint32_t key_bits) { return (key_bits + RADIX_BITS - 1) / RADIX_BITS; }

RadixSort::RadixSort(vk::Context& ctx, uint32_t capacity) : capacity_(capacity) {
  if (capacity == 0) throw InputError("radix sort: capacity must be at least 1 element");
  const uint64_t limit = ctx.properties().limits.maxStorageBufferRange;
  const uint64_t bytes = uint64_t(capacity) * sizeof(uint32_t);
  if (bytes > limit)
    throw InputError("radix sort: capacity " + std::to_string(capacity) + " elements (" + std::to_string(bytes) +
                     " bytes per buffer) exceeds the device's maxStorageBufferRange of " + std::to_string(limit) +
                     " bytes");
  // The kernels use 256-thread workgroups and the scatter ~17 KiB of shared memory (radix_scatter.comp): above Vulkan's
  // guaranteed minimums (128 invocations, 16 KiB), within lavapipe's and every desktop GPU's limits.
  const VkPhysicalDeviceLimits& lim = ctx.properties().limits;
  const uint32_t shared_bytes = (RADIX_DIGITS * RADIX_THREADS + RADIX_THREADS + RADIX_THREADS / 16 + RADIX_DIGITS) * sizeof(uint32_t);
  if (lim.maxComputeWorkGroupInvocations < RADIX_THREADS || lim.maxComputeWorkGroupSize[0] < RADIX_THREADS ||
      lim.maxComputeSharedMemorySize < shared_bytes)
    throw DeviceError("radix sort: needs " + std::to_string(RADIX_THREADS) + "-invocation workgroups and " +
                      std::to_string(shared_bytes) + " bytes of shared memory; the device allows " +
                      std::to_string(lim.maxComputeWorkGroupInvocations) + " and " +
                      std::to_string(lim.maxComputeSharedMemorySize));
  blocks_ = static_cast<uint32_t>((uint64_t(capacity) + RADIX_BLOCK - 1) / RADIX_BLOCK);

  const VkBufferUsageFlags usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  scratch_keys_ = vk::Buffer(ctx, bytes, usage, false);
  scratch_values_ = vk::Buffer(ctx, bytes, usage, false);
  histograms_ = vk::Buffer(ctx, uint64_t(blocks_) * RADIX_DIGITS * sizeof(uint32_t), usage, false);

  to_scratch_ = vk::DescriptorSet(ctx, sort_bindings(), sizeof(RadixPush), VK_SHADER_STAGE_COMPUTE_BIT);
  to_caller_ = vk::DescriptorSet(ctx, sort_bindings(), sizeof(RadixPush), VK_SHADER_STAGE_COMPUTE_BIT);
  const VkPipelineLayout layout = to_scratch_.pipeline_layout();
  histogram_ = vk::create_compute_pipeline(ctx, sort_radix_histogram_comp, layout);
  scan_ = vk::create_compute_pipeline(ctx, sort_radix_scan_comp, layout);
  scatter_ = vk::create_compute_pipeline(ctx, sort_radix_scatter_comp, layout);
  copy_ = vk::create_compute_pipeline(ctx, sort_radix_copy_comp, layout);
}

void RadixSort::bind(const vk::Buffer& keys, const vk::Buffer& values, const vk::Buffer& count) {
  if (keys.handle() == bound_keys_ && values.handle() == bound_values_ && count.handle() == bound_count_) return;
  const VkDeviceSize bytes = VkDeviceSize(capacity_) * sizeof(uint32_t);
  if (keys.size() < bytes || values.size() < bytes)
    throw InputError("radix sort: keys (" + std::to_string(keys.size()) + " bytes) and values (" +
                     std::to_string(values.size()) + " bytes) must hold the capacity of " +
                     std::to_string(capacity_) + " uints");
  if (count.size() < sizeof(uint32_t)) throw InputError("radix sort: the count buffer must hold one uint");
  const VkDescriptorType sb = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  // Ranges are the capacity, not VK_WHOLE_SIZE: a caller's larger buffer may exceed maxStorageBufferRange.
  auto write = [&](vk::DescriptorSet& set, VkBuffer kin, VkBuffer vin, VkBuffer kout, VkBuffer vout) {
    set.write_buffer(0, sb, kin, bytes);
    set.write_buffer(1, sb, vin, bytes);
    set.write_buffer(2, sb, kout, bytes);
    set.write_buffer(3, sb, vout, bytes);
    set.write_buffer(4, sb, histograms_.handle());
    set.write_buffer(5, sb, count.handle(), sizeof(uint32_t));
  };
  write(to_scratch_, keys.handle(), values.handle(), scratch_keys_.handle(), scratch_values_.handle());
  write(to_caller_, scratch_keys_.handle(), scratch_values_.handle(), keys.handle(), values.handle());
  bound_keys_ = keys.handle();
  bound_values_ = values.handle();
  bound_count_ = count.handle();
}

void RadixSort::record(VkCommandBuffer cmd, const vk::Buffer& keys, const vk::Buffer& values,
                       const vk::Buffer& count, uint32_t key_bits) {
  if (key_bits > 32) throw InputError("radix sort: key_bits " + std::to_string(key_bits) + " exceeds 32");
  const uint32_t passes = pass_count(key_bits);
  if (passes == 0) return;  // no significant bits: the stable order is the input order
  bind(keys, values, count);

  const VkPipelineLayout layout = to_scratch_.pipeline_layout();
  const uint32_t key_mask = key_bits >= 32 ? 0xFFFFFFFFu : ((1u << key_bits) - 1u);
  // Whatever produced the keys, values or count (a compute pass, a transfer) must finish first.
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
  auto bind_set = [&](const vk::DescriptorSet& set) {
    VkDescriptorSet s = set.set();
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &s, 0, nullptr);
  };
  auto dispatch = [&](const vk::Pipeline& p, uint32_t groups) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, p.handle());
    vkCmdDispatch(cmd, groups, 1, 1);
  };
  for (uint32_t pass = 0; pass < passes; ++pass) {
    bind_set(pass % 2 == 0 ? to_scratch_ : to_caller_);
    const RadixPush push{pass * RADIX_BITS, capacity_, key_mask};
    vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
    dispatch(histogram_, blocks_);
    compute_to_compute(cmd);
    dispatch(scan_, 1);
    compute_to_compute(cmd);
    dispatch(scatter_, blocks_);
    compute_to_compute(cmd);
  }
  if (passes % 2 == 1) {
    // The last pass wrote the scratch buffers; to_caller_ reads them and writes the caller's.
    bind_set(to_caller_);
    const RadixPush push{0, capacity_, key_mask};
    vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
    dispatch(copy_, blocks_);
  }
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_READ_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT);
}

}  // namespace hp
