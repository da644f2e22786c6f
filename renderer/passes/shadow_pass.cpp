#include "passes/shadow_pass.hpp"

#include "shaders/shadows_comp.h"
#include "shaders/shadows_rgen.h"
#include "shaders/shadows_rq_comp.h"
#include "shaders/shadows_rq_traced_comp.h"
#include "shaders/shadows_traced_comp.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hp {

ShadowPass::ShadowPass(vk::Context& ctx, RtResources& rt)
    : rt_(rt), program_(rt.create_program(ctx, shadows_comp, shadows_rq_comp, shadows_rgen)) {}

void ShadowPass::record(VkCommandBuffer cmd, bool then_barrier) const {
  const RayTracingOptions& o = rt_.options();
  const uint32_t h = rt_.height();
  const uint32_t rows =
      o.inject_shadow_fraction > 0.0f ? std::min(h, uint32_t(std::ceil(h * o.inject_shadow_fraction))) : 0u;
  // The injected re-trace writes the same texels: a barrier between the two dispatches.
  rt_.dispatch(cmd, program_, rt_.width(), h, then_barrier || rows > 0);
  if (rows > 0) rt_.dispatch(cmd, program_, rt_.width(), rows, then_barrier);
}

glm::uvec2 ShadowPass::workgroups() const { return {(rt_.width() + 7) / 8, (rt_.height() + 7) / 8}; }

void ShadowPass::attach_trace(vk::Context& ctx) {
  if (!traced_.handle()) traced_ = rt_.create_traced_pipeline(ctx, shadows_traced_comp, shadows_rq_traced_comp);
}

void ShadowPass::record_traced_slice(VkCommandBuffer cmd, uint32_t first_row, uint32_t rows, uint32_t sharing) const {
  rt_.dispatch_traced_rows(cmd, traced_, workgroups(), first_row, rows, sharing,
                           "ShadowPass::record_traced_slice: attach_trace first");
}

}  // namespace hp
