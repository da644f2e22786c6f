// What a result was measured on, recorded in every result so numbers from different machines,
// drivers or builds are never compared blindly.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace hp {

// The Vulkan device as plain strings, filled by the renderer (this library stays Vulkan-free).
struct DeviceDescription {
  std::string name;            // VkPhysicalDeviceProperties::deviceName
  std::string type;            // "cpu", "discrete-gpu", "integrated-gpu", ...
  std::string driver_name;     // VkPhysicalDeviceDriverProperties::driverName ("llvmpipe")
  std::string driver_info;     // driverInfo ("Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)")
  std::string driver_version;  // driverVersion decoded ("25.0.7"; vk::driver_version_string)
  std::string api_version;     // "1.3.230"

  bool operator==(const DeviceDescription&) const = default;
};

struct Environment {
  std::string cpu_model;         // /proc/cpuinfo "model name" (or the closest field there is)
  std::uint32_t core_count = 0;  // logical CPUs available (std::thread::hardware_concurrency)
  std::string lp_num_threads;    // the LP_NUM_THREADS variable, or "unset"
  std::string build_type;        // CMAKE_BUILD_TYPE of this build
  std::string compiler;          // "gcc 12.2.0", "clang 16.0.6", from predefined macros
  std::string git_commit;        // short commit at configure time, or "unknown"
  std::string date_utc;          // ISO 8601, seconds, "2026-11-23T10:42:09Z"
  std::string hostname;
  std::string os;  // uname: "Linux 6.1.0-18-amd64 x86_64"
  // The machine's 1-minute load average when captured (/proc/loadavg); absent where unreadable. A timing
  // taken at a load near or above the core count shares the cores with other work.
  std::optional<double> load_1min;
  std::string cpu_governor;  // cpufreq scaling_governor of CPU 0, or "unknown" (most VMs have none)
  DeviceDescription device;

  bool operator==(const Environment&) const = default;
};

// Captures the process's environment now; `device` is copied in as given. Never throws for a field
// it cannot read: that field becomes "unknown".
Environment capture_environment(const DeviceDescription& device = {});

// The 1-minute load average from /proc/loadavg text ("0.52 0.58 0.59 1/123 4567"); nullopt when malformed.
std::optional<double> parse_load_1min(std::string_view loadavg);
// /proc/loadavg now, parsed; nullopt where unreadable.
std::optional<double> read_load_1min();

// The CPU model from /proc/cpuinfo text: "model name" (x86), else "Model"/"Hardware"/"cpu model"/
// "Processor" (Arm, MIPS, others), else "unknown".
std::string parse_cpu_model(std::string_view cpuinfo);

// The compiler that built this library, e.g. "gcc 12.2.0".
std::string compiler_id();

// Seconds since the Unix epoch as ISO 8601 UTC, e.g. "2026-11-23T10:42:09Z".
std::string iso8601_utc(std::int64_t unix_seconds);

}  // namespace hp
