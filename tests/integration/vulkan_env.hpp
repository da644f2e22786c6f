// Shared by the tests that need a Vulkan device (lavapipe in CI): one context per test binary, with the
// validation layer whenever it is installed; any validation message fails the test that caused it.
#pragma once

#include "vk/context.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <string>

namespace hp::test {

/// HP_TESTS_REQUIRE_VULKAN=1 (scripts/test sets it under CI=true): a missing device or validation layer
/// fails the tests that need them instead of skipping them, so a broken set-up cannot pass as skips.
bool vulkan_required();

/// The process-wide context, or nullptr (with the reason) when there is no Vulkan device. Where Vulkan is
/// required, a missing validation layer is also a reason (no context).
vk::Context* vulkan_context(std::string* why_not = nullptr);

/// Skips the current test when there is no Vulkan device.
// clang-format off: clang-format 14 breaks the struct declared at the macro's end
#define HP_REQUIRE_VULKAN(ctx_var)                                               \
  std::string hp_why_;                                                           \
  ::hp::vk::Context* ctx_var = ::hp::test::vulkan_context(&hp_why_);             \
  if (!ctx_var && ::hp::test::vulkan_required())                                 \
    GTEST_FAIL() << "no Vulkan device (HP_TESTS_REQUIRE_VULKAN=1): " << hp_why_; \
  if (!ctx_var) GTEST_SKIP() << "no Vulkan device: " << hp_why_;                 \
  const uint64_t hp_msgs_before_ = ctx_var->validation_message_count();          \
  struct HpValidationCheck_ {                                                    \
    ::hp::vk::Context* c;                                                        \
    uint64_t before;                                                             \
    ~HpValidationCheck_() {                                                      \
      EXPECT_EQ(c->validation_message_count(), before)                           \
          << "validation messages; last: " << c->last_validation_message();      \
    }                                                                            \
  } hp_validation_check_ {                                                       \
    ctx_var, hp_msgs_before_                                                     \
  }
// clang-format on

}  // namespace hp::test
