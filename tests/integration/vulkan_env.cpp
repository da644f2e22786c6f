#include "vulkan_env.hpp"

#include "error.hpp"

#include <cstdio>

namespace hp::test {

vk::Context* vulkan_context(std::string* why_not) {
  static std::string reason;
  static std::unique_ptr<vk::Context> ctx = [] {
    try {
      vk::ContextOptions o;
      o.validate = vk::validation_layer_available();
      if (!o.validate) std::fprintf(stderr, "note: VK_LAYER_KHRONOS_validation not installed; running without it\n");
      return std::make_unique<vk::Context>(o);
    } catch (const DeviceError& e) {
      reason = e.what();
      return std::unique_ptr<vk::Context>();
    }
  }();
  if (!ctx && why_not) *why_not = reason;
  return ctx.get();
}

}  // namespace hp::test
