#include "vk/pipeline_stats.hpp"

#include "vk/check.hpp"

#include <stdexcept>

namespace hp::vk {

ComputeInvocationQueries::ComputeInvocationQueries(Context& ctx, uint32_t max_passes)
    : device_(ctx.device()), capacity_(max_passes) {
  VkPhysicalDeviceFeatures f{};
  vkGetPhysicalDeviceFeatures(ctx.physical_device(), &f);
  if (!f.pipelineStatisticsQuery) return;  // supported() is false: the counter is simply absent
  VkQueryPoolCreateInfo ci{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  ci.queryType = VK_QUERY_TYPE_PIPELINE_STATISTICS;
  ci.queryCount = capacity_;
  ci.pipelineStatistics = VK_QUERY_PIPELINE_STATISTIC_COMPUTE_SHADER_INVOCATIONS_BIT;
  HP_VK(vkCreateQueryPool(device_, &ci, nullptr, &pool_));
}

ComputeInvocationQueries::~ComputeInvocationQueries() {
  if (pool_) vkDestroyQueryPool(device_, pool_, nullptr);
}

void ComputeInvocationQueries::reset(VkCommandBuffer cmd) {
  used_ = 0;
  names_.clear();
  if (pool_) vkCmdResetQueryPool(cmd, pool_, 0, capacity_);
}

void ComputeInvocationQueries::begin(VkCommandBuffer cmd, const std::string& pass) {
  if (!pool_) return;
  if (used_ >= capacity_) throw std::logic_error("ComputeInvocationQueries: more passes than the pool holds");
  names_.push_back(pass);
  vkCmdBeginQuery(cmd, pool_, used_, 0);
}

void ComputeInvocationQueries::end(VkCommandBuffer cmd) {
  if (!pool_) return;
  vkCmdEndQuery(cmd, pool_, used_++);
}

std::vector<std::pair<std::string, uint64_t>> ComputeInvocationQueries::read() const {
  std::vector<std::pair<std::string, uint64_t>> out;
  if (!pool_ || used_ == 0) return out;
  std::vector<uint64_t> v(used_);
  HP_VK(vkGetQueryPoolResults(device_, pool_, 0, used_, v.size() * sizeof(uint64_t), v.data(), sizeof(uint64_t),
                              VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
  for (uint32_t i = 0; i < used_; ++i) out.emplace_back(names_[i], v[i]);
  return out;
}

}  // namespace hp::vk
