#include "passes/compaction_path.hpp"

#include "vk/check.hpp"

#include "shaders/compact_args_comp.h"
#include "shaders/compact_comp.h"
#include "shaders/compact_traced_comp.h"
#include "shaders/consume_comp.h"
#include "shaders/consume_rgen.h"
#include "shaders/consume_rq_comp.h"
#include "shaders/consume_rq_traced_comp.h"
#include "shaders/consume_traced_comp.h"

#include <algorithm>
#include <stdexcept>

namespace hp {

CompactionPath::CompactionPath(vk::Context& ctx, RtResources& rt)
    : rt_(rt),
      compact_(rt.create_pipeline(ctx, compact_comp)),
      args_(rt.create_pipeline(ctx, compact_args_comp)),
      consume_(rt.create_program(ctx, consume_comp, consume_rq_comp, consume_rgen)) {
  if (rt.options().sort != SortKey::none) {
    sorter_ = std::make_unique<RadixSort>(ctx, uint32_t(uint64_t(rt.grid_width()) * rt.grid_height()));
  }
}

void CompactionPath::record_compact(VkCommandBuffer cmd) const {
  vkCmdFillBuffer(cmd, rt_.ray_count().handle(), 0, VK_WHOLE_SIZE, 0);
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
  rt_.dispatch(cmd, compact_, rt_.grid_width(), rt_.grid_height());
  record_args(cmd);
}

void CompactionPath::record_args(VkCommandBuffer cmd) const {
  rt_.bind(cmd, args_);
  vkCmdDispatch(cmd, 1, 1, 1);
  // Read as indirect arguments (the frame), by shaders and by a host readback (the capture).
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT | VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT |
                         VK_PIPELINE_STAGE_2_COPY_BIT,
                     VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_READ_BIT |
                         VK_ACCESS_2_TRANSFER_READ_BIT);
}

void CompactionPath::record_reset_count(VkCommandBuffer cmd, uint32_t count) const {
  vkCmdUpdateBuffer(cmd, rt_.ray_count().handle(), 0, sizeof(count), &count);
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT | VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT);
}

void CompactionPath::record_sort(VkCommandBuffer cmd) {
  if (!sorter_) return;
  sorter_->record(cmd, rt_.sort_keys(), rt_.sort_values(), rt_.ray_count(), sort_key_bits(rt_.options().sort));
}

void CompactionPath::record_consume(VkCommandBuffer cmd) const {
  if (consume_.trace.handle()) {
    rt_.trace_indirect(cmd, consume_, 16);  // consume_launch_w/h/d (common/compaction.glsl)
    return;
  }
  rt_.bind(cmd, consume_.compute);
  vkCmdDispatchIndirect(cmd, rt_.ray_count().handle(), 4);  // consume_groups_x/y/z follow the count
  vk::memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT,
                     VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_COPY_BIT,
                     VK_ACCESS_2_SHADER_STORAGE_READ_BIT | VK_ACCESS_2_SHADER_STORAGE_WRITE_BIT |
                         VK_ACCESS_2_TRANSFER_READ_BIT);
}

glm::uvec2 CompactionPath::compact_workgroups() const {
  return {(rt_.grid_width() + 7) / 8, (rt_.grid_height() + 7) / 8};
}

std::vector<RadixSort::Step> CompactionPath::sort_steps() const {
  return sorter_ ? sorter_->steps(sort_key_bits(rt_.options().sort)) : std::vector<RadixSort::Step>{};
}

void CompactionPath::attach_trace_compact(vk::Context& ctx) {
  if (!compact_traced_.handle()) compact_traced_ = rt_.create_pipeline(ctx, compact_traced_comp);
}

void CompactionPath::attach_trace_consume(vk::Context& ctx) {
  if (!consume_traced_.handle())
    consume_traced_ = rt_.create_traced_pipeline(ctx, consume_traced_comp, consume_rq_traced_comp);
}

void CompactionPath::attach_trace_sort(vk::Context& ctx, const vk::Buffer& trace_buffer) {
  if (sorter_) sorter_->attach_trace_buffer(ctx, trace_buffer);
}

void CompactionPath::record_traced_compact(VkCommandBuffer cmd, uint32_t first_row, uint32_t rows) const {
  rt_.dispatch_traced_rows(cmd, compact_traced_, compact_workgroups(), first_row, rows, 0,
                           "CompactionPath: attach_trace_compact first");
}

void CompactionPath::record_traced_consume(VkCommandBuffer cmd, uint32_t groups) const {
  if (!consume_traced_.handle()) throw std::logic_error("CompactionPath: attach_trace_consume first");
  rt_.dispatch_traced(cmd, consume_traced_, groups, 1);  // a slice of the one row of groups, offset by frame.z
}

void CompactionPath::record_traced_sort_step(VkCommandBuffer cmd, const RadixSort::Step& step, uint32_t first_group,
                                             uint32_t groups, uint32_t sampling) {
  sorter_->record_traced_step(cmd, step, rt_.sort_keys(), rt_.sort_values(), rt_.ray_count(),
                              sort_key_bits(rt_.options().sort), first_group, groups, sampling);
}

}  // namespace hp
