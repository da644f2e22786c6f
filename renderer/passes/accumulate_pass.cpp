#include "passes/accumulate_pass.hpp"

#include "shaders/accumulate_comp.h"

namespace hp {

AccumulatePass::AccumulatePass(vk::Context& ctx, RtResources& rt)
    : rt_(rt), pipeline_(rt.create_pipeline(ctx, accumulate_comp)) {}

void AccumulatePass::record(VkCommandBuffer cmd) const {
  rt_.dispatch(cmd, pipeline_, rt_.grid_width(), rt_.grid_height());
}

}  // namespace hp
