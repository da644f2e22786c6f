// Temporal accumulation: this frame's reflection grid into the running mean (shaders/accumulate.comp).
#pragma once

#include "passes/rt_resources.hpp"

namespace hp {

class AccumulatePass {
 public:
  AccumulatePass(vk::Context& ctx, RtResources& rt);
  void record(VkCommandBuffer cmd) const;

 private:
  RtResources& rt_;
  vk::Pipeline pipeline_;
};

}  // namespace hp
