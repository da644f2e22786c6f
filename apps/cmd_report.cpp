// `hybridprof report OUT`: OUT/report.md with charts beside it, or (--format gbench) the timings as
// Google Benchmark JSON.
#include "apps/commands.hpp"
#include "error.hpp"
#include "gbench_export.hpp"
#include "report.hpp"

#include <cstdio>
#include <memory>

namespace hp::cli {

void add_report_command(CLI::App& app) {
  struct Args {
    std::string dir, format = "markdown", output, time_unit = "ms";
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand("report", "write OUT/report.md (tables, charts, comparisons) from OUT/results.jsonl");
  cmd->add_option("dir", a->dir, "output folder of `hybridprof run`")->required();
  cmd->add_option("--format", a->format, "markdown (report.md + charts/) or gbench (Google Benchmark JSON)")
      ->capture_default_str();
  cmd->add_option("--output", a->output, "gbench: the JSON file to write (default OUT/gbench.json)");
  cmd->add_option("--time-unit", a->time_unit, "gbench: ns, us, ms or s")->capture_default_str();
  cmd->callback([a] {
    if (a->format == "markdown") {
      std::printf("report: %s\n", write_report(a->dir).c_str());
    } else if (a->format == "gbench") {
      std::printf("gbench: %s\n", write_gbench_export(a->dir, a->output, a->time_unit).c_str());
    } else {
      throw InputError("--format: '" + a->format + "' is not markdown or gbench");
    }
  });
}

}  // namespace hp::cli
