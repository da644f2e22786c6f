// `hybridprof gate`: compare a candidate run with a baseline run; exit 0 pass, 1 regression, 4 inconclusive, 2 cannot
// compare. Either two run folders, or --ab: both binaries run alternately in fresh processes here.
#include "apps/cli_util.hpp"
#include "apps/commands.hpp"
#include "error.hpp"
#include "gate.hpp"

#include <cstdio>
#include <cstdlib>
#include <memory>

namespace hp::cli {

void add_gate_command(CLI::App& app) {
  struct Args {
    std::string baseline, candidate, policy, baseline_cmd, candidate_cmd, scenario, work_dir;
    double threshold = 0.10, warn = 0.05, alpha = 0.05;
    int trials = 11;  // 7 caught a +15-20% slowdown in 15 of 20 trials on a quiet VM, 11 in 19 (docs/gate.md)
    bool ab = false, keep = false, deterministic_only = false, verbose = false, quiet = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "gate", "regression gate: exit 0 pass, 1 regression, 2 cannot compare, 4 inconclusive (too few samples to fail)");
  cmd->add_option("--baseline", a->baseline, "baseline run folder (results.jsonl)");
  cmd->add_option("--candidate", a->candidate, "candidate run folder");
  cmd->add_option("--policy", a->policy, "policy JSON: threshold, warn, alpha, tolerances {metric: fraction}");
  cmd->add_option("--threshold", a->threshold, "fail above this significant slowdown (0.10 = 10%)")
      ->capture_default_str();
  cmd->add_option("--warn", a->warn, "warn above this significant slowdown")->capture_default_str();
  cmd->add_option("--alpha", a->alpha, "family-wise level of the Holm-corrected U tests")->capture_default_str();
  cmd->add_flag("--deterministic-only", a->deterministic_only,
                "compare only counters, BVH and cache counts (e.g. against a baseline from another machine)");
  cmd->add_flag("--verbose", a->verbose, "list identical deterministic metrics too");
  auto* ab = cmd->add_flag("--ab", a->ab, "run both commands alternately in fresh processes and compare those runs");
  // The --ab options without --ab would be ignored: they are errors instead.
  cmd->add_option("--baseline-cmd", a->baseline_cmd,
                  "--ab: baseline hybridprof command (run as `CMD run FILE --out DIR`)")
      ->needs(ab);
  cmd->add_option("--candidate-cmd", a->candidate_cmd, "--ab: candidate hybridprof command")->needs(ab);
  cmd->add_option("--scenario", a->scenario, "--ab: scenario or matrix file both commands run")->needs(ab);
  cmd->add_option("--trials", a->trials, "--ab: fresh processes per side")->capture_default_str()->needs(ab);
  cmd->add_option("--work-dir", a->work_dir, "--ab: folder for the runs (default: a temporary folder, removed after)")
      ->needs(ab);
  cmd->add_flag("--keep", a->keep, "--ab: keep the run folders")->needs(ab);
  cmd->add_flag("--quiet", a->quiet, "--ab: no progress lines on stderr")->needs(ab);
  cmd->callback([a, cmd] {
    GateOptions o;
    // Precedence: defaults < policy file < options given on the command line.
    if (!a->policy.empty()) o.policy = load_policy(a->policy);
    if (cmd->count("--threshold")) o.policy.threshold = a->threshold;
    if (cmd->count("--warn")) o.policy.warn = a->warn;
    if (cmd->count("--alpha")) o.policy.alpha = a->alpha;
    validate_policy(o.policy, "gate options");
    o.deterministic_only = a->deterministic_only;
    o.verbose = a->verbose;
    GateSide base, cand;
    if (a->ab) {
      if (!a->baseline.empty() || !a->candidate.empty())
        throw InputError("gate: --ab runs the commands itself; give --baseline-cmd/--candidate-cmd, not folders");
      AbOptions ab;
      ab.baseline_cmd = a->baseline_cmd;
      ab.candidate_cmd = a->candidate_cmd;
      ab.scenario = a->scenario;
      ab.trials = a->trials;
      ab.work_dir = a->work_dir;
      ab.keep = a->keep;
      // Progress per finished process, with an ETA: in place on a terminal, a plain line every 5 s in a log.
      Progress progress("gate --ab: processes", a->quiet);
      ab.on_process = [&](int done, int total, const std::string& process) {
        progress.update(uint64_t(done), uint64_t(total), process + " done");
      };
      std::tie(base, cand) = run_ab(ab);
    } else {
      if (a->baseline.empty() || a->candidate.empty())
        throw InputError("gate: give --baseline DIR and --candidate DIR (or --ab with commands)");
      base = side_from_dir(a->baseline);
      cand = side_from_dir(a->candidate);
    }
    const GateOutcome out = run_gate(base, cand, o);
    std::fputs(format_gate(out).c_str(), stdout);
    std::fflush(stdout);
    // The exit code is the answer; CLI11 has no other way to return one from a callback.
    std::exit(out.exit_code);
  });
}

}  // namespace hp::cli
