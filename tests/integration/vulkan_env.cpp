#include "vulkan_env.hpp"

#include <cstdlib>

#include "error.hpp"

#include <cstdio>

namespace hp::test {

bool vulkan_required() {
  const char* v = std::getenv("HP_TESTS_REQUIRE_VULKAN");
  return v && std::string(v) == "1";
}

vk::Context* vulkan_context(std::string* why_not) {
  static std::string reason;
  static std::unique_ptr<vk::Context> ctx = [] {
    try {
      vk::ContextOptions o;
      o.validate = vk::validation_layer_available();
      if (!o.validate && vulkan_required()) {
        reason = "VK_LAYER_KHRONOS_validation is not installed (Debian: vulkan-validationlayers)";
        return std::unique_ptr<vk::Context>();
      }
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
