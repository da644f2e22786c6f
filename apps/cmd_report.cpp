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
  CLI::App* cmd =
      app.add_subcommand("report", "write OUT/report.md (tables, charts, comparisons) from OUT/results.jsonl");
  cmd->add_option("dir", a->dir, "output folder of `hybridprof run`")->required();
  cmd->add_option("--format", a->format, "markdown (report.md + charts/) or gbench (Google Benchmark JSON)")
      ->capture_default_str();
  auto* output = cmd->add_option("--output", a->output, "gbench: the JSON file to write (default OUT/gbench.json)");
  auto* unit = cmd->add_option("--time-unit", a->time_unit, "gbench: ns, us, ms or s")->capture_default_str();
  cmd->callback([a, output, unit] {
    if (a->format == "markdown") {
      // The gbench options given to a markdown report would be ignored: say so instead.
      if (output->count() > 0) throw InputError("--output: only with --format gbench (markdown goes to OUT/report.md)");
      if (unit->count() > 0) throw InputError("--time-unit: only with --format gbench");
      std::printf("report: %s\n", write_report(a->dir).c_str());
    } else if (a->format == "gbench") {
      std::printf("gbench: %s\n", write_gbench_export(a->dir, a->output, a->time_unit).c_str());
    } else {
      throw InputError("--format: '" + a->format + "' is not markdown or gbench");
    }
  });
}

}  // namespace hp::cli
