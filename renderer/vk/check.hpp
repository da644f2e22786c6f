// VkResult checking: a failed call is an internal error naming the call, except for the few results that
// mean "this device cannot do it" (those become hp::DeviceError).
#pragma once

#include <vulkan/vulkan.h>

#include <string>

namespace hp::vk {

const char* result_name(VkResult r);
[[noreturn]] void fail(VkResult r, const char* call, const char* file, int line);

}  // namespace hp::vk

#define HP_VK(call)                                                                  \
  do {                                                                               \
    VkResult hp_vk_r_ = (call);                                                      \
    if (hp_vk_r_ != VK_SUCCESS) ::hp::vk::fail(hp_vk_r_, #call, __FILE__, __LINE__); \
  } while (0)
