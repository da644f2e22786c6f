#include "gbench_export.hpp"

#include "atomic_file.hpp"
#include "error.hpp"
#include "report.hpp"
#include "timing/stats.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>

namespace hp {

using json = nlohmann::json;

double time_unit_divisor(const std::string& unit) {
  if (unit == "ns") return 1.0;
  if (unit == "us") return 1e3;
  if (unit == "ms") return 1e6;
  if (unit == "s") return 1e9;
  throw InputError("--time-unit: '" + unit + "' is not one of ns, us, ms, s");
}

std::string gbench_name(const CellResult& c, const std::string& pass) {
  std::string name = c.matrix.empty() ? (c.name.empty() ? std::string("hybridprof") : c.name) : c.matrix;
  if (c.axes.empty()) {
    name += "/" + c.id;
  } else {
    // '/' separates name parts in Google Benchmark; keep it out of the values.
    for (const auto& [k, v] : c.axes.items()) {
      std::string value = axis_value_text(v);
      std::replace(value.begin(), value.end(), '/', '_');
      std::replace(value.begin(), value.end(), ' ', '_');
      name += '/';  // appended piece by piece: GCC 12's -Wrestrict (PR 105651) on "/" + string
      name += axis_leaf(k);
      name += ':';
      name += value;
    }
  }
  return name + "/" + pass;
}

json gbench_export(const std::vector<CellResult>& cells, const std::string& time_unit) {
  const double div = time_unit_divisor(time_unit);
  if (cells.empty()) throw InputError("gbench export: no cells");
  const Environment& env = cells.front().timing.environment;
  std::string build = env.build_type;
  std::transform(build.begin(), build.end(), build.begin(), [](unsigned char ch) { return std::tolower(ch); });
  json doc;
  doc["context"] = {{"date", env.date_utc},
                    {"host_name", env.hostname},
                    {"executable", "hybridprof"},
                    {"num_cpus", env.core_count},
                    {"mhz_per_cpu", 0},
                    {"cpu_scaling_enabled", false},
                    {"caches", json::array()},
                    {"load_avg", json::array()},
                    {"library_build_type", build.empty() ? "release" : build},
                    // Ours, beside benchmark's own keys (readers ignore keys they do not know).
                    {"hybridprof_device", env.device.name},
                    {"hybridprof_driver", env.device.driver_info},
                    {"hybridprof_commit", env.git_commit},
                    {"hybridprof_lp_num_threads", env.lp_num_threads}};
  json benchmarks = json::array();
  int family = 0;
  for (const CellResult& c : cells) {
    for (const auto& [pass, samples] : pass_samples(c.timing)) {
      const std::string run_name = gbench_name(c, pass) + "/manual_time";
      const size_t n = samples.size();
      auto entry = [&](const std::string& name, const char* run_type) {
        return json{{"name", name},         {"family_index", family}, {"per_family_instance_index", 0},
                    {"run_name", run_name}, {"run_type", run_type},   {"repetitions", n},
                    {"threads", 1},         {"label", c.id}};
      };
      for (size_t i = 0; i < n; ++i) {
        json e = entry(run_name, "iteration");
        e["repetition_index"] = i;
        e["iterations"] = 1;
        e["real_time"] = samples[i] / div;
        e["cpu_time"] = samples[i] / div;
        e["time_unit"] = time_unit;
        benchmarks.push_back(e);
      }
      const Summary s = summarize(samples);
      struct Agg {
        const char* name;
        double value;
        const char* unit;
      };
      const Agg aggs[] = {{"mean", s.mean / div, "time"},
                          {"median", s.median / div, "time"},
                          {"stddev", s.stddev.value_or(0.0) / div, "time"},
                          // benchmark writes cv as a fraction with the unit "percentage".
                          {"cv", s.cv.value_or(0.0), "percentage"}};
      for (const Agg& a : aggs) {
        json e = entry(run_name + "_" + a.name, "aggregate");
        e["aggregate_name"] = a.name;
        e["aggregate_unit"] = a.unit;
        e["iterations"] = n;
        e["real_time"] = a.value;
        e["cpu_time"] = a.value;
        e["time_unit"] = time_unit;
        benchmarks.push_back(e);
      }
      ++family;
    }
  }
  doc["benchmarks"] = benchmarks;
  return doc;
}

std::string write_gbench_export(const std::string& out_dir, const std::string& path, const std::string& time_unit) {
  const json doc = gbench_export(load_cells(out_dir), time_unit);
  const std::string target = path.empty() ? (std::filesystem::path(out_dir) / "gbench.json").string() : path;
  write_file_atomically(target, doc.dump(2) + "\n");
  return target;
}

}  // namespace hp
