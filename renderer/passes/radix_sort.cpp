#include "passes/radix_sort.hpp"

#include "error.hpp"
#include "gpu/bindings.h"
#include "gpu/radix_config.h"
#include "shaders/sort_radix_copy_comp.h"
#include "shaders/sort_radix_copy_traced_comp.h"
#include "shaders/sort_radix_histogram_comp.h"
#include "shaders/sort_radix_histogram_traced_comp.h"
#include "shaders/sort_radix_scan_comp.h"
#include "shaders/sort_radix_scan_traced_comp.h"
#include "shaders/sort_radix_scatter_comp.h"
#include "shaders/sort_radix_scatter_traced_comp.h"

#include <stdexcept>
#include <string>
#include <vector>

namespace hp {
namespace {

// radix_common.glsl's push constants.
struct RadixPush {
  uint32_t shift;
  uint32_t capacity;
  uint32_t key_mask;
  uint32_t first_group = 0;  ///< a traced slice's first block
  uint32_t sampling = 0;     ///< the capture's workgroup sampling (traced variants)
  uint32_t to_caller = 0;    ///< the set reads the scratch buffers (trace buffer ids)
};

// The kernels' buffers, and the trace buffer of the instrumented variants (common/trace_capture.glsl).
std::vector<VkDescriptorSetLayoutBinding> sort_bindings() {
  std::vector<VkDescriptorSetLayoutBinding> b;
  for (uint32_t i : gpu::kSortSetBindings)
    b.push_back({i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  return b;
}

// Whatever produced the keys, values or count (a compute pass, a transfer) finishes before the sort ...
void before_sort(VkCommandBuffer cmd) {
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
}

// ... and the sorted buffers are visible to whatever comes after.
void after_sort(VkCommandBuffer cmd) {
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_READ_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT);
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
  const uint32_t shared_bytes =
      (RADIX_DIGITS * RADIX_THREADS + RADIX_THREADS + RADIX_THREADS / 16 + RADIX_DIGITS) * sizeof(uint32_t);
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
  no_trace_ = vk::Buffer(ctx, 16, usage, false);
  for (vk::DescriptorSet* set : {&to_scratch_, &to_caller_}) {
    set->write_buffer(HP_BIND_TRACE_RECORDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, no_trace_.handle());
  }
}

std::vector<RadixSort::Step> RadixSort::steps(uint32_t key_bits) const {
  std::vector<Step> out;
  const uint32_t passes = pass_count(key_bits);
  for (uint32_t p = 0; p < passes; ++p) {
    const std::string d = std::to_string(p);
    out.push_back({Step::Kernel::histogram, p, blocks_, "sort_histogram_" + d});
    out.push_back({Step::Kernel::scan, p, 1, "sort_scan_" + d});
    out.push_back({Step::Kernel::scatter, p, blocks_, "sort_scatter_" + d});
  }
  if (passes % 2 == 1) out.push_back({Step::Kernel::copy, passes, blocks_, "sort_copy"});
  return out;
}

void RadixSort::attach_trace_buffer(vk::Context& ctx, const vk::Buffer& trace_buffer) {
  for (vk::DescriptorSet* set : {&to_scratch_, &to_caller_}) {
    set->write_buffer(HP_BIND_TRACE_RECORDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, trace_buffer.handle());
  }
  if (histogram_traced_.handle()) return;
  const VkPipelineLayout layout = to_scratch_.pipeline_layout();
  histogram_traced_ = vk::create_compute_pipeline(ctx, sort_radix_histogram_traced_comp, layout);
  scan_traced_ = vk::create_compute_pipeline(ctx, sort_radix_scan_traced_comp, layout);
  scatter_traced_ = vk::create_compute_pipeline(ctx, sort_radix_scatter_traced_comp, layout);
  copy_traced_ = vk::create_compute_pipeline(ctx, sort_radix_copy_traced_comp, layout);
}

void RadixSort::record_traced_step(VkCommandBuffer cmd, const Step& step, const vk::Buffer& keys,
                                   const vk::Buffer& values, const vk::Buffer& count, uint32_t key_bits,
                                   uint32_t first_group, uint32_t groups, uint32_t sampling) {
  if (!histogram_traced_.handle()) throw std::logic_error("RadixSort::record_traced_step: attach_trace_buffer first");
  bind(keys, values, count);
  before_sort(cmd);
  record_step(cmd, step, key_bits, first_group, groups, sampling, true);
  after_sort(cmd);
}

void RadixSort::record_step(VkCommandBuffer cmd, const Step& step, uint32_t key_bits, uint32_t first_group,
                            uint32_t groups, uint32_t sampling, bool traced) const {
  const VkPipelineLayout layout = to_scratch_.pipeline_layout();
  // Digit pass p reads the caller's buffers when p is even and the scratch ones when odd (ping-pong); the
  // final copy reads the scratch buffers.
  const bool to_caller = step.kernel == Step::Kernel::copy || step.digit_pass % 2 == 1;
  const VkDescriptorSet set = (to_caller ? to_caller_ : to_scratch_).set();
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &set, 0, nullptr);
  const uint32_t key_mask = key_bits >= 32 ? 0xFFFFFFFFu : ((1u << key_bits) - 1u);
  const RadixPush push{step.kernel == Step::Kernel::copy ? 0u : step.digit_pass * RADIX_BITS,
                       capacity_,
                       key_mask,
                       first_group,
                       sampling,
                       to_caller ? 1u : 0u};
  vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(push), &push);
  const vk::Pipeline* plain[] = {&histogram_, &scan_, &scatter_, &copy_};
  const vk::Pipeline* instrumented[] = {&histogram_traced_, &scan_traced_, &scatter_traced_, &copy_traced_};
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, (traced ? instrumented : plain)[int(step.kernel)]->handle());
  vkCmdDispatch(cmd, groups, 1, 1);
}

void RadixSort::bind(const vk::Buffer& keys, const vk::Buffer& values, const vk::Buffer& count) {
  if (keys.handle() == bound_keys_ && values.handle() == bound_values_ && count.handle() == bound_count_) return;
  const VkDeviceSize bytes = VkDeviceSize(capacity_) * sizeof(uint32_t);
  if (keys.size() < bytes || values.size() < bytes)
    throw InputError("radix sort: keys (" + std::to_string(keys.size()) + " bytes) and values (" +
                     std::to_string(values.size()) + " bytes) must hold the capacity of " + std::to_string(capacity_) +
                     " uints");
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

void RadixSort::record(VkCommandBuffer cmd, const vk::Buffer& keys, const vk::Buffer& values, const vk::Buffer& count,
                       uint32_t key_bits) {
  if (key_bits > 32) throw InputError("radix sort: key_bits " + std::to_string(key_bits) + " exceeds 32");
  const std::vector<Step> all = steps(key_bits);
  if (all.empty()) return;  // no significant bits: the stable order is the input order
  bind(keys, values, count);
  before_sort(cmd);
  for (size_t i = 0; i < all.size(); ++i) {
    if (i > 0) compute_to_compute(cmd);
    record_step(cmd, all[i], key_bits, 0, all[i].groups, 0, false);
  }
  after_sort(cmd);
}

}  // namespace hp
