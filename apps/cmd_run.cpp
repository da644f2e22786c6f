// `hybridprof run` (a scenario or matrix file into OUT/results.jsonl) and `hybridprof merge` (shards).
#include "apps/commands.hpp"
#include "error.hpp"
#include "runner.hpp"
#include "scenario_keys.hpp"

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <signal.h>
#include <unistd.h>

namespace hp::cli {

void add_run_command(CLI::App& app) {
  struct Args {
    std::string file, out, shard = "1/1", device;
    bool validate = false, list = false;
    std::vector<std::string> filters;
    std::uint32_t rounds = 0;
    size_t live_frames = 8;
    bool reuse_stale = false, quiet = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand("run", "run every cell of a scenario matrix; resumable, shardable");
  cmd->add_option("file", a->file, "scenario or matrix JSON file")->required();
  cmd->add_option("--out", a->out, "output folder (results.jsonl, cells/<id>/ images)");
  cmd->add_option("--shard", a->shard,
                  "run only shard K of N (cells with index % N == K-1); auto: from HP_SHARD_INDEX/HP_SHARD_COUNT "
                  "or a Slurm job array")
      ->capture_default_str();
  cmd->add_option("--device", a->device, "Vulkan device: index or name substring");
  cmd->add_flag("--validate", a->validate, "Khronos validation layer; any message fails");
  cmd->add_flag("--list", a->list, "print the expanded cells (id and axis values) and exit");
  // Handled as the flag is parsed (as --help is), so it needs no scenario file.
  cmd->add_flag_callback(
      "--list-keys",
      [] {
        std::fputs(scenario_keys_markdown().c_str(), stdout);
        throw CLI::Success();
      },
      "print every scenario key (type, range, default, meaning) as a markdown table and exit");
  cmd->add_option("--filter", a->filters,
                  "only the cells with this id, or with AXIS=VALUE (e.g. geometry=soup, resolution=128x72); "
                  "repeat to narrow");
  cmd->add_option("--rounds", a->rounds,
                  "interleaved rounds (default: the matrix's \"rounds\"): each round times every cell's share of "
                  "its frames, cells in a fresh shuffled order");
  cmd->add_option("--live-frames", a->live_frames,
                  "cells' frames kept alive between their rounds; more are rebuilt at each visit")
      ->capture_default_str()
      ->check(CLI::Range(size_t(1), size_t(4096)));
  cmd->add_flag("--reuse-stale", a->reuse_stale,
                "keep finished cells measured by another build or driver, marked stale (the report compares no "
                "time with them), instead of running them again");
  cmd->add_flag("--quiet", a->quiet, "no progress lines on stderr");
  cmd->callback([a] {
    Matrix m = load_matrix(a->file);
    if (a->rounds != 0) set_rounds(m, a->rounds, "run --rounds");
    const Shard shard = parse_shard(a->shard);
    const std::vector<bool> selected = select_cells(m, a->filters);
    if (a->list) {
      for (size_t i = 0; i < m.cells.size(); ++i) {
        if (!selected[i]) continue;
        std::printf("%s%s %s\n", m.cells[i].id().c_str(), shard.contains(i) ? "" : " (other shard)",
                    m.cell_axis_values[i].dump().c_str());
      }
      return;
    }
    if (a->out.empty()) throw InputError("run: --out is required (the output folder)");
    RunOptions o;
    o.out_dir = a->out;
    o.shard = shard;
    o.device = a->device;
    o.validate = a->validate;
    o.filters = a->filters;
    o.live_frames = a->live_frames;
    o.reuse_stale = a->reuse_stale;
    o.progress = !a->quiet;
    // Ctrl-C (or a SIGTERM from a job scheduler) stops between two visits: the visit under way finishes and is
    // journalled, then the run says what it kept and exits 130; running it again resumes.
    static std::atomic<bool> stop{false};
    o.stop = &stop;
    struct sigaction sa {};
    sa.sa_handler = [](int) {
      stop.store(true);
      const char msg[] = "\nhybridprof run: stopping after the visit under way (again to stop at once)\n";
      [[maybe_unused]] const ssize_t n = ::write(2, msg, sizeof(msg) - 1);
    };
    sa.sa_flags = SA_RESETHAND;  // a second signal takes the default action
    sigemptyset(&sa.sa_mask);
    ::sigaction(SIGINT, &sa, nullptr);
    ::sigaction(SIGTERM, &sa, nullptr);
    const RunSummary s = run_matrix(m, o);
    if (s.interrupted) {
      std::fprintf(stderr,
                   "hybridprof run: interrupted: %zu cell(s) finished this run, %zu finished round(s) of unfinished "
                   "cells kept in %s/rounds.jsonl; run the same command again to resume\n",
                   s.ran, s.rounds_journalled, a->out.c_str());
      std::exit(130);
    }
    std::printf("%s: %zu cells, %zu in shard %u/%u%s, %zu already done, %zu run%s -> %s/results.jsonl\n",
                a->file.c_str(), s.cells, s.in_shard, shard.index, shard.count,
                a->filters.empty() ? "" : " selected by --filter", s.already_done, s.ran,
                s.stale
                    ? (" (" + std::to_string(s.stale) + " of them again: measured by another build or driver)").c_str()
                : s.stale_reused
                    ? (" (" + std::to_string(s.stale_reused) + " stale cell(s) kept: --reuse-stale)").c_str()
                    : "",
                a->out.c_str());
    for (const std::string& u : s.unsupported) {
      std::fprintf(stderr, "hybridprof run: not run on this device (unsupported): %s\n", u.c_str());
    }
    // Cells with expectations (a matrix's "expect", e.g. hard_cases.json): every unmet one is reported,
    // resumed cells included, and the exit code is 1, as the gate's for a regression.
    size_t unmet = 0;
    for (const nlohmann::json& line : read_results(a->out)) {
      if (!line.contains("expect")) continue;
      for (const auto& u : line["expect"]["unmet"]) {
        std::fprintf(stderr, "hybridprof: expectation unmet: %s: %s\n", line.value("name", "").c_str(),
                     u.get<std::string>().c_str());
        ++unmet;
      }
    }
    if (unmet > 0) std::exit(1);
  });
}

void add_merge_command(CLI::App& app) {
  struct Args {
    std::string out;
    std::vector<std::string> shards;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand("merge", "join the output folders of shards into one");
  cmd->add_option("--out", a->out, "merged output folder")->required();
  cmd->add_option("shards", a->shards, "shard output folders")->required();
  cmd->callback([a] {
    const size_t n = merge_results(a->out, a->shards);
    std::printf("merged %zu cell(s) into %s/results.jsonl\n", n, a->out.c_str());
  });
}

}  // namespace hp::cli
