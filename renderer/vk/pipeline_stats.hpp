// Compute-shader invocation counts per pass from pipeline statistics queries, where the device supports
// them (lavapipe and desktop GPUs do): a deterministic counter beside the times.
#pragma once

#include "vk/context.hpp"

#include <string>
#include <utility>
#include <vector>

namespace hp::vk {

class ComputeInvocationQueries {
 public:
  ComputeInvocationQueries(Context& ctx, uint32_t max_passes);
  ~ComputeInvocationQueries();
  ComputeInvocationQueries(const ComputeInvocationQueries&) = delete;
  ComputeInvocationQueries& operator=(const ComputeInvocationQueries&) = delete;

  bool supported() const { return pool_ != VK_NULL_HANDLE; }
  void reset(VkCommandBuffer cmd);
  void begin(VkCommandBuffer cmd, const std::string& pass);
  void end(VkCommandBuffer cmd);
  /// After the submission completed: (pass, compute shader invocations) in recording order.
  std::vector<std::pair<std::string, uint64_t>> read() const;

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueryPool pool_ = VK_NULL_HANDLE;
  uint32_t capacity_ = 0, used_ = 0;
  std::vector<std::string> names_;
};

}  // namespace hp::vk
