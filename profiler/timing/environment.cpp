#include "timing/environment.hpp"

#include <sys/utsname.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

// The commit from the header the build refreshes (cmake/git_commit.cmake), the build type from
// profiler/CMakeLists.txt; the fallback keeps a stray build of this file honest.
#include "hp_git_commit.hpp"
#ifndef HP_BUILD_TYPE
#define HP_BUILD_TYPE "unknown"
#endif

namespace hp {
namespace {

std::string trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r\n");
  return std::string(s.substr(first, last - first + 1));
}

std::string or_unknown(std::string s) { return s.empty() ? "unknown" : s; }

}  // namespace

std::string parse_cpu_model(std::string_view cpuinfo) {
  // Preference order: x86's "model name" first; Arm kernels print "Model" or "Hardware" (and a
  // "Processor" line on older ones), MIPS "cpu model".
  static constexpr std::string_view keys[] = {"model name", "Model", "Hardware", "cpu model", "Processor"};
  for (std::string_view key : keys) {
    std::size_t pos = 0;
    while (pos < cpuinfo.size()) {
      std::size_t eol = cpuinfo.find('\n', pos);
      if (eol == std::string_view::npos) eol = cpuinfo.size();
      const std::string_view line = cpuinfo.substr(pos, eol - pos);
      pos = eol + 1;
      const std::size_t colon = line.find(':');
      if (colon == std::string_view::npos) continue;
      if (trim(line.substr(0, colon)) != key) continue;
      std::string value = trim(line.substr(colon + 1));
      if (!value.empty()) return value;
    }
  }
  return "unknown";
}

std::string compiler_id() {
  char buf[64];
#if defined(__clang__)
  std::snprintf(buf, sizeof buf, "clang %d.%d.%d", __clang_major__, __clang_minor__, __clang_patchlevel__);
#elif defined(__GNUC__)
  std::snprintf(buf, sizeof buf, "gcc %d.%d.%d", __GNUC__, __GNUC_MINOR__, __GNUC_PATCHLEVEL__);
#elif defined(_MSC_VER)
  std::snprintf(buf, sizeof buf, "msvc %d", _MSC_FULL_VER);
#else
  std::snprintf(buf, sizeof buf, "unknown");
#endif
  return buf;
}

std::string iso8601_utc(std::int64_t unix_seconds) {
  const auto t = static_cast<std::time_t>(unix_seconds);
  std::tm tm{};
  if (gmtime_r(&t, &tm) == nullptr) return "unknown";
  char buf[32];
  if (std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm) == 0) return "unknown";
  return buf;
}

std::optional<double> parse_load_1min(std::string_view text) {
  const std::string first(text.substr(0, text.find(' ')));
  if (first.empty()) return std::nullopt;
  char* end = nullptr;
  const double v = std::strtod(first.c_str(), &end);
  if (end != first.c_str() + first.size() || !(v >= 0.0) || v > 1e6) return std::nullopt;
  return v;
}

std::optional<double> read_load_1min() {
  std::ifstream in("/proc/loadavg");
  std::string line;
  if (!in || !std::getline(in, line)) return std::nullopt;
  return parse_load_1min(line);
}

Environment capture_environment(const DeviceDescription& device) {
  Environment env;
  env.cpu_model = "unknown";
  if (std::ifstream in("/proc/cpuinfo"); in) {
    std::stringstream ss;
    ss << in.rdbuf();
    env.cpu_model = parse_cpu_model(ss.str());
  }
  env.core_count = std::thread::hardware_concurrency();
  const char* lp = std::getenv("LP_NUM_THREADS");
  env.lp_num_threads = lp != nullptr ? std::string(lp) : "unset";
  env.build_type = or_unknown(HP_BUILD_TYPE);
  env.compiler = compiler_id();
  env.git_commit = or_unknown(HP_GIT_COMMIT);
  const auto now = std::chrono::system_clock::now();
  env.date_utc = iso8601_utc(std::chrono::duration_cast<std::chrono::seconds>(now.time_since_epoch()).count());
  char host[256] = {};
  env.hostname = gethostname(host, sizeof host - 1) == 0 ? or_unknown(host) : "unknown";
  utsname u{};
  if (uname(&u) == 0) {
    env.os = std::string(u.sysname) + " " + u.release + " " + u.machine;
  } else {
    env.os = "unknown";
  }
  env.load_1min = read_load_1min();
  env.cpu_governor = "unknown";
  if (std::ifstream g("/sys/devices/system/cpu/cpu0/cpufreq/scaling_governor"); g) {
    std::string v;
    if (std::getline(g, v) && !v.empty()) env.cpu_governor = v;
  }
  env.device = device;
  return env;
}

}  // namespace hp
