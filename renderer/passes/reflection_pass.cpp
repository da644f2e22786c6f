#include "passes/reflection_pass.hpp"

#include "shaders/reflections_comp.h"
#include "shaders/reflections_rgen.h"
#include "shaders/reflections_rq_comp.h"
#include "shaders/reflections_rq_traced_comp.h"
#include "shaders/reflections_traced_comp.h"

#include <algorithm>
#include <stdexcept>

namespace hp {

ReflectionPass::ReflectionPass(vk::Context& ctx, RtResources& rt)
    : rt_(rt), program_(rt.create_program(ctx, reflections_comp, reflections_rq_comp, reflections_rgen)) {}

void ReflectionPass::record(VkCommandBuffer cmd) const {
  rt_.dispatch(cmd, program_, rt_.grid_width(), rt_.grid_height());
}

glm::uvec2 ReflectionPass::workgroups() const { return {(rt_.grid_width() + 7) / 8, (rt_.grid_height() + 7) / 8}; }

void ReflectionPass::attach_trace(vk::Context& ctx) {
  if (!traced_.handle()) traced_ = rt_.create_traced_pipeline(ctx, reflections_traced_comp, reflections_rq_traced_comp);
}

void ReflectionPass::record_traced_slice(VkCommandBuffer cmd, uint32_t first_row, uint32_t rows,
                                         uint32_t sharing) const {
  rt_.dispatch_traced_rows(cmd, traced_, workgroups(), first_row, rows, sharing,
                           "ReflectionPass::record_traced_slice: attach_trace first");
}

}  // namespace hp
