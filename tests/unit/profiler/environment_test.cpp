#include <gtest/gtest.h>

#include <optional>
#include <regex>
#include <string>

#include "common/scoped_env.hpp"
#include "timing/environment.hpp"

namespace hp {
namespace {

TEST(Environment, CapturedFieldsAreFilled) {
  const DeviceDescription dev{"llvmpipe (LLVM 15.0.6, 256 bits)", "cpu",    "llvmpipe",
                              "Mesa 22.3.6 (LLVM 15.0.6)",        "22.3.6", "1.3.230"};
  const Environment env = capture_environment(dev);
  EXPECT_FALSE(env.cpu_model.empty());
  EXPECT_GT(env.core_count, 0u);
  EXPECT_FALSE(env.lp_num_threads.empty());
  EXPECT_FALSE(env.build_type.empty());
  EXPECT_NE(env.build_type, "unknown");  // CMake passes it; the tests are built with a build type
  // CMake's `git rev-parse --short=12`, or "unknown" when built outside a git checkout.
  EXPECT_TRUE(std::regex_match(env.git_commit, std::regex("[0-9a-f]{12}(-dirty)?|unknown"))) << env.git_commit;
  EXPECT_FALSE(env.hostname.empty());
  EXPECT_TRUE(std::regex_match(env.compiler, std::regex(R"((gcc|clang) \d+\.\d+\.\d+)"))) << env.compiler;
  EXPECT_TRUE(std::regex_match(env.date_utc, std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)"))) << env.date_utc;
  EXPECT_EQ(env.os.rfind("Linux ", 0), 0u) << env.os;
  EXPECT_EQ(env.device, dev);
}

TEST(Environment, LoadAverageIsParsedOrAbsent) {
  EXPECT_EQ(parse_load_1min("0.52 0.58 0.59 1/123 4567\n"), std::optional<double>(0.52));
  EXPECT_EQ(parse_load_1min("12.00 3 4 1/1 1"), std::optional<double>(12.0));
  EXPECT_FALSE(parse_load_1min("").has_value());
  EXPECT_FALSE(parse_load_1min("x 1 2").has_value());
  EXPECT_FALSE(parse_load_1min("-1 0 0").has_value());
  EXPECT_FALSE(parse_load_1min("nan 0 0").has_value());
  // Linux always has /proc/loadavg; the capture reads it.
  const Environment env = capture_environment();
  ASSERT_TRUE(env.load_1min.has_value());
  EXPECT_GE(*env.load_1min, 0.0);
  EXPECT_FALSE(env.cpu_governor.empty());
}

TEST(Environment, LpNumThreadsIsReadOrUnset) {
  // Restores the caller's value: the rest of the process (lavapipe included) reads it too.
  const test::ScopedEnv env("LP_NUM_THREADS");
  ASSERT_EQ(env.set("3"), 0);
  EXPECT_EQ(capture_environment().lp_num_threads, "3");
  ASSERT_EQ(env.unset(), 0);
  EXPECT_EQ(capture_environment().lp_num_threads, "unset");
}

TEST(Environment, CpuModelParsing) {
  EXPECT_EQ(parse_cpu_model("processor\t: 0\nvendor_id\t: GenuineIntel\nmodel\t\t: 85\n"
                            "model name\t: Intel(R) Xeon(R) Gold 6248 CPU @ 2.50GHz\n"),
            "Intel(R) Xeon(R) Gold 6248 CPU @ 2.50GHz");
  // Arm: no "model name"; "model" (lower case, a number on x86) must not be taken for it.
  EXPECT_EQ(parse_cpu_model("processor\t: 0\nBogoMIPS\t: 108.00\nCPU part\t: 0xd0c\n\n"
                            "Hardware\t: BCM2835\nModel\t\t: Raspberry Pi 4 Model B Rev 1.4\n"),
            "Raspberry Pi 4 Model B Rev 1.4");
  EXPECT_EQ(parse_cpu_model("Hardware\t: Qualcomm Technologies, Inc SM8150\n"), "Qualcomm Technologies, Inc SM8150");
  EXPECT_EQ(parse_cpu_model("model name\t:\nmodel\t: 85\n"), "unknown");
  EXPECT_EQ(parse_cpu_model(""), "unknown");
}

TEST(Environment, Iso8601) {
  EXPECT_EQ(iso8601_utc(0), "1970-01-01T00:00:00Z");
  EXPECT_EQ(iso8601_utc(1'700'000'000), "2023-11-14T22:13:20Z");
}

}  // namespace
}  // namespace hp
