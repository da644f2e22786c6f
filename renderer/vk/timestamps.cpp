#include "vk/timestamps.hpp"

#include "vk/check.hpp"

#include <cmath>
#include <stdexcept>

namespace hp::vk {

TimestampQueries::TimestampQueries(Context& ctx, uint32_t max_passes)
    : device_(ctx.device()), capacity_(2 * max_passes) {
  const uint32_t bits = ctx.info().timestamp_valid_bits;
  if (bits == 0 || max_passes == 0) return;  // unsupported or not wanted: supported() is false
  mask_ = bits >= 64 ? ~uint64_t(0) : ((uint64_t(1) << bits) - 1);
  period_ns_ = ctx.info().timestamp_period_ns;
  VkQueryPoolCreateInfo ci{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
  ci.queryType = VK_QUERY_TYPE_TIMESTAMP;
  ci.queryCount = capacity_;
  HP_VK(vkCreateQueryPool(device_, &ci, nullptr, &pool_));
}

TimestampQueries::~TimestampQueries() {
  if (pool_) vkDestroyQueryPool(device_, pool_, nullptr);
}

void TimestampQueries::reset(VkCommandBuffer cmd) {
  used_ = 0;
  names_.clear();
  slots_.clear();
  open_ = boundary_ = false;
  if (pool_) vkCmdResetQueryPool(cmd, pool_, 0, capacity_);
}

bool TimestampQueries::begin(VkCommandBuffer cmd, const std::string& pass) {
  if (!pool_) return false;
  if (open_) throw std::logic_error("TimestampQueries: begin() inside an open pass");
  names_.push_back(pass);
  open_ = true;
  if (boundary_) {  // the previous pass's end timestamp is this pass's begin
    slots_.push_back({used_ - 1, 0});
    return false;
  }
  if (used_ + 2 > capacity_) throw std::logic_error("TimestampQueries: more passes than the pool holds");
  slots_.push_back({used_, 0});
  vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, pool_, used_++);
  return true;
}

void TimestampQueries::end(VkCommandBuffer cmd) {
  if (!pool_) return;
  if (!open_) throw std::logic_error("TimestampQueries: end() without begin()");
  if (used_ + 1 > capacity_) throw std::logic_error("TimestampQueries: more passes than the pool holds");
  slots_.back().second = used_;
  vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, pool_, used_++);
  open_ = false;
  boundary_ = true;
}

std::vector<TimestampQueries::Interval> TimestampQueries::read(Context&) const {
  std::vector<Interval> out;
  if (!pool_ || used_ == 0) return out;
  std::vector<uint64_t> ticks(used_);
  HP_VK(vkGetQueryPoolResults(device_, pool_, 0, used_, ticks.size() * sizeof(uint64_t), ticks.data(), sizeof(uint64_t),
                              VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
  auto unwrap = [&](uint64_t t) { return unwrapped_timestamp_ns(t, ticks[0], mask_, period_ns_); };
  for (size_t p = 0; p < slots_.size(); ++p) {
    Interval iv;
    iv.pass = names_[p];
    iv.begin_ns = static_cast<uint64_t>(std::llround(unwrap(ticks[slots_[p].first])));
    iv.end_ns = static_cast<uint64_t>(std::llround(unwrap(ticks[slots_[p].second])));
    out.push_back(iv);
  }
  return out;
}

}  // namespace hp::vk
