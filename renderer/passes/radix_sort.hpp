// A GPU radix sort of (uint key, uint value) pairs: stable, least-significant digit first, 4 bits per
// pass, as many passes as the caller's significant key bits need (ceil(key_bits / 4)). The number of
// elements is read on the GPU from a count buffer, so a count produced by an atomic counter can be sorted
// without a CPU readback: the dispatches are sized for the capacity and the kernels skip what lies past
// the live count. See shaders/sort/ for the kernels.
#pragma once

#include "vk/pipeline.hpp"
#include "vk/resources.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace hp {

class RadixSort {
 public:
  /// Builds the pipelines and the scratch buffers (two ping-pong buffers of `capacity` uints, the
  /// per-block histograms). Throws hp::InputError when `capacity` is 0 or a capacity-sized buffer would
  /// exceed the device's maxStorageBufferRange; hp::DeviceError when the device cannot run 256-thread
  /// workgroups with ~17 KiB of shared memory.
  RadixSort(vk::Context& ctx, uint32_t capacity);

  uint32_t capacity() const { return capacity_; }
  /// Digit passes for `key_bits` significant bits (0 for 0 bits).
  static uint32_t pass_count(uint32_t key_bits);

  /// Records the sort of the first min(count, capacity) pairs of `keys`/`values` by the low `key_bits`
  /// bits of the key (higher bits are carried along but ignored: equal low bits keep input order).
  /// `count` holds the element count as a uint at offset 0. The sorted pairs end in `keys`/`values`
  /// (after an odd number of passes a final copy kernel moves them back from the scratch buffers);
  /// elements past the count are left untouched. All three buffers need STORAGE_BUFFER usage; `keys` and
  /// `values` must hold at least `capacity` uints.
  ///
  /// Barriers: the recording starts with one that makes all earlier writes (any stage) visible to the
  /// sort, and ends with one that makes the sorted buffers visible to any later stage.
  ///
  /// Descriptor sets are rewritten only when the buffers differ from the previous call; a call with
  /// different buffers must not be made while a command buffer recorded with the old ones is pending.
  void record(VkCommandBuffer cmd, const vk::Buffer& keys, const vk::Buffer& values, const vk::Buffer& count,
              uint32_t key_bits);

  // ---- memory-trace capture (Frame::render_captured) ---------------------------------------------------
  /// One dispatch of a sort, as a capture traces it: the digit pass's histogram, scan and scatter, then the
  /// final copy after an odd number of passes. `name` is the traced pass's ("sort_scatter_1").
  struct Step {
    enum class Kernel { histogram, scan, scatter, copy } kernel;
    uint32_t digit_pass = 0;
    uint32_t groups = 0;  ///< workgroups of the dispatch (256 threads each)
    std::string name;
  };
  /// The dispatches record() makes for `key_bits`, in order.
  std::vector<Step> steps(uint32_t key_bits) const;
  /// Binds the trace buffer (HP_BIND_TRACE_RECORDS) and builds the instrumented variants of the kernels.
  void attach_trace_buffer(vk::Context& ctx, const vk::Buffer& trace_buffer);
  /// Records workgroups [first_group, first_group + groups) of one step with its instrumented variant, with
  /// the workgroup sampling word of the capture, between barriers (each step is its own submission).
  void record_traced_step(VkCommandBuffer cmd, const Step& step, const vk::Buffer& keys, const vk::Buffer& values,
                          const vk::Buffer& count, uint32_t key_bits, uint32_t first_group, uint32_t groups,
                          uint32_t sampling);
  uint64_t scratch_bytes() const { return scratch_keys_.size(); }
  uint64_t histogram_bytes() const { return histograms_.size(); }

 private:
  void bind(const vk::Buffer& keys, const vk::Buffer& values, const vk::Buffer& count);
  /// One step's set, push constants, pipeline (plain or instrumented) and dispatch, no barriers.
  void record_step(VkCommandBuffer cmd, const Step& step, uint32_t key_bits, uint32_t first_group, uint32_t groups,
                   uint32_t sampling, bool traced) const;

  uint32_t capacity_ = 0;
  uint32_t blocks_ = 0;  ///< workgroups of the block kernels, covering the capacity
  vk::Buffer scratch_keys_;
  vk::Buffer scratch_values_;
  vk::Buffer histograms_;
  // Same (identically defined) layout: `to_scratch_` reads the caller's buffers and writes the scratch
  // ones, `to_caller_` the reverse. The pipelines are built on to_scratch_'s pipeline layout, which is
  // compatible with both sets.
  vk::DescriptorSet to_scratch_;
  vk::DescriptorSet to_caller_;
  vk::Pipeline histogram_;
  vk::Pipeline scan_;
  vk::Pipeline scatter_;
  vk::Pipeline copy_;
  vk::Pipeline histogram_traced_, scan_traced_, scatter_traced_, copy_traced_;
  vk::Buffer no_trace_;  ///< binding 21 until a trace buffer is attached (the plain kernels never read it)
  VkBuffer bound_keys_ = VK_NULL_HANDLE;
  VkBuffer bound_values_ = VK_NULL_HANDLE;
  VkBuffer bound_count_ = VK_NULL_HANDLE;
};

}  // namespace hp
