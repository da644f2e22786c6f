#include "gate.hpp"

#include "error.hpp"
#include "input_file.hpp"
#include "json_depth.hpp"
#include "scenario.hpp"
#include "timing/stats.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sys/wait.h>

namespace hp {

using json = nlohmann::json;
namespace fs = std::filesystem;

namespace {

std::string fmt(const char* f, double v) { return format_number(f, v); }
std::string metric_value(double v) {
  if (v == std::floor(v) && std::abs(v) < 1e15) return fmt("%.0f", v);
  return fmt("%.6g", v);
}
std::string change_text(double base, double cand) {
  if (base == cand) return "0%";
  if (base == 0.0) return "new";
  return fmt("%+.2f%%", (cand / base - 1.0) * 100.0);
}

double tolerance_for(const GatePolicy& p, const std::string& metric) {
  if (auto it = p.tolerances.find(metric); it != p.tolerances.end()) return it->second;
  const size_t slash = metric.rfind('/');
  if (slash != std::string::npos) {
    if (auto it = p.tolerances.find(metric.substr(slash + 1)); it != p.tolerances.end()) return it->second;
  }
  return 0.0;
}

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char ch : s) q += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
  return q + "'";
}

double median_of(std::vector<double> v) { return quantile(v, 0.5); }

}  // namespace

GatePolicy load_policy(const std::string& path, GatePolicy p) {
  const std::string text = read_input_file(path, "gate policy file");
  check_json_depth(text, path);
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(path + ": not JSON (" + std::string(e.what()).substr(0, 100) + ")");
  }
  if (!j.is_object()) throw InputError(path + ": the policy must be a JSON object");
  for (const auto& [k, v] : j.items()) {
    if (k == "threshold" || k == "warn" || k == "alpha") {
      if (!v.is_number()) throw InputError(path + ": " + k + ": expected a number");
      (k == "threshold" ? p.threshold : k == "warn" ? p.warn : p.alpha) = v.get<double>();
    } else if (k == "tolerances") {
      if (!v.is_object()) throw InputError(path + ": tolerances: expected an object {metric: relative tolerance}");
      for (const auto& [m, t] : v.items()) {
        if (!t.is_number() || t.get<double>() < 0.0)
          throw InputError(path + ": tolerances." + m + ": expected a relative tolerance >= 0 (0.01 = 1%)");
        p.tolerances[m] = t.get<double>();
      }
    } else {
      throw InputError(path + ": " + k + ": unknown key (threshold, warn, alpha, tolerances)");
    }
  }
  validate_policy(p, path);
  return p;
}

void validate_policy(const GatePolicy& p, const std::string& where) {
  if (!(p.threshold >= 0.0) || !(p.warn >= 0.0) || p.warn > p.threshold)
    throw InputError(where + ": threshold and warn must satisfy 0 <= warn <= threshold (got warn " + fmt("%g", p.warn) +
                     ", threshold " + fmt("%g", p.threshold) + ")");
  if (!(p.alpha > 0.0 && p.alpha < 1.0)) throw InputError(where + ": alpha must be in (0, 1)");
}

GateSide side_from_dir(const std::string& dir) {
  GateSide s;
  s.label = dir;
  s.cells = load_cells(dir);
  for (const CellResult& c : s.cells) s.samples.emplace(match_key(c), pass_samples(c.timing));
  return s;
}

GateSide side_from_runs(const std::vector<std::string>& dirs, const std::string& label) {
  if (dirs.empty()) throw InputError(label + ": no runs");
  GateSide s;
  s.label = label;
  s.sample_kind = "process medians";
  s.cells = load_cells(dirs.front());
  std::map<std::string, std::map<std::string, double>> metrics;
  for (const CellResult& c : s.cells) metrics[match_key(c)] = deterministic_metrics(c);
  for (size_t r = 0; r < dirs.size(); ++r) {
    const std::vector<CellResult> cells = r == 0 ? s.cells : load_cells(dirs[r]);
    std::set<std::string> seen;
    for (const CellResult& c : cells) {
      const std::string key = match_key(c);
      seen.insert(key);
      if (!metrics.count(key)) {
        s.problems.push_back(label + ": cell " + cell_label(c) + " appears in run " + std::to_string(r + 1) + " only");
        continue;
      }
      if (deterministic_metrics(c) != metrics[key])
        s.problems.push_back(label + ": cell " + cell_label(c) +
                             ": deterministic metrics differ between run 1 and run " + std::to_string(r + 1) +
                             " (not deterministic)");
      PassSamples& pooled = s.samples[key];
      for (const auto& [pass, frames] : pass_samples(c.timing)) {
        auto it = std::find_if(pooled.begin(), pooled.end(), [&](auto& e) { return e.first == pass; });
        if (it == pooled.end()) it = pooled.insert(pooled.end(), {pass, {}});
        it->second.push_back(median_of(frames));
      }
    }
    if (seen.size() != metrics.size())
      s.problems.push_back(label + ": run " + std::to_string(r + 1) + " lacks some cells of run 1");
  }
  return s;
}

std::vector<std::string> environment_differences(const Environment& a, const Environment& b) {
  std::vector<std::string> d;
  auto check = [&](const char* what, const std::string& x, const std::string& y) {
    if (x != y) d.push_back(std::string(what) + ": '" + x + "' vs '" + y + "'");
  };
  check("device", a.device.name, b.device.name);
  check("driver", a.device.driver_name + " " + a.device.driver_info, b.device.driver_name + " " + b.device.driver_info);
  check("cores", std::to_string(a.core_count), std::to_string(b.core_count));
  check("LP_NUM_THREADS", a.lp_num_threads, b.lp_num_threads);
  return d;
}

namespace {

// The loads a run recorded: every cell's (and round's) 1-minute load at its start and end; none when a cell
// did not record them.
std::optional<std::pair<double, double>> load_range(const std::vector<CellResult>& cells) {
  double lo = 1e300, hi = -1e300;
  for (const CellResult& c : cells) {
    const json l = c.line.value("load_1min", json());
    if (!l.is_object() || !l.value("start", json()).is_number() || !l.value("end", json()).is_number())
      return std::nullopt;
    const auto r = recorded_load(c);  // start and end at least
    lo = std::min(lo, r->first);
    hi = std::max(hi, r->second);
  }
  if (cells.empty()) return std::nullopt;
  return std::pair{lo, hi};
}

}  // namespace

std::vector<std::string> machine_state_differences(const std::vector<CellResult>& base,
                                                   const std::vector<CellResult>& cand) {
  std::vector<std::string> d;
  const auto lb = load_range(base), lc = load_range(cand);
  const auto text = [](const std::pair<double, double>& r) {
    return fmt("%.2f", r.first) + " … " + fmt("%.2f", r.second);
  };
  if (!lb || !lc) {
    d.push_back("the machine's load was not recorded for every cell of the " +
                std::string(!lb ? "baseline" : "candidate"));
  } else if (!base.empty()) {
    const double cores = double(std::max<std::uint32_t>(1, base.front().timing.environment.core_count));
    const double tolerance = std::max(0.5, cores / 4.0);
    if (std::abs(lb->second - lc->second) > tolerance || std::abs(lb->first - lc->first) > tolerance)
      d.push_back("the 1-minute load was " + text(*lb) + " for the baseline and " + text(*lc) +
                  " for the candidate (more apart than " + fmt("%.2f", tolerance) + " on " + fmt("%.0f", cores) +
                  " cores)");
  }
  if (!base.empty() && !cand.empty() &&
      base.front().timing.environment.cpu_governor != cand.front().timing.environment.cpu_governor)
    d.push_back("CPU governor '" + base.front().timing.environment.cpu_governor + "' vs '" +
                cand.front().timing.environment.cpu_governor + "'");
  return d;
}

namespace {

using CellPairs = std::vector<std::pair<const CellResult*, const CellResult*>>;

// The cells of the two sides paired by match_key; cells on one side only go to out.cannot_compare.
CellPairs pair_cells(const GateSide& base, const GateSide& cand, GateOutcome& out) {
  CellPairs pairs;
  std::map<std::string, const CellResult*> cand_by_key;
  for (const CellResult& c : cand.cells) cand_by_key.emplace(match_key(c), &c);
  std::set<std::string> base_keys;
  std::string only_base, only_cand;
  for (const CellResult& b : base.cells) {
    const std::string key = match_key(b);
    if (!base_keys.insert(key).second) continue;
    auto it = cand_by_key.find(key);
    if (it == cand_by_key.end())
      only_base += (only_base.empty() ? "" : ", ") + cell_label(b) + " (" + b.id + ")";
    else
      pairs.push_back({&b, it->second});
  }
  for (const CellResult& c : cand.cells)
    if (!base_keys.count(match_key(c)))
      only_cand += (only_cand.empty() ? "" : ", ") + cell_label(c) + " (" + c.id + ")";
  if (!only_base.empty()) out.cannot_compare.push_back("cells only in the baseline (" + base.label + "): " + only_base);
  if (!only_cand.empty())
    out.cannot_compare.push_back("cells only in the candidate (" + cand.label + "): " + only_cand);
  return pairs;
}

// Deterministic metrics must be equal (or within the policy's tolerance for that metric).
void compare_deterministic(const CellPairs& pairs, const GateOptions& o, GateOutcome& out) {
  for (const auto& [b, c] : pairs) {
    const auto mb = deterministic_metrics(*b), mc = deterministic_metrics(*c);
    std::set<std::string> names;
    for (const auto& [k, v] : mb) names.insert(k);
    for (const auto& [k, v] : mc) names.insert(k);
    for (const std::string& name : names) {
      GateRow row{cell_label(*b), name, "—", "—", "", std::nullopt, std::nullopt, ""};
      const auto ib = mb.find(name), ic = mc.find(name);
      if (ib != mb.end()) row.baseline = metric_value(ib->second);
      if (ic != mc.end()) row.candidate = metric_value(ic->second);
      if (ib == mb.end() || ic == mc.end()) {
        row.change = "missing";
        row.verdict = "FAIL";
        ++out.fails;
      } else if (ib->second == ic->second) {
        ++out.identical;
        if (!o.verbose) continue;
        row.change = "0%";
        row.verdict = "identical";
      } else {
        row.change = change_text(ib->second, ic->second);
        const double rel = ib->second == 0.0 ? INFINITY : std::abs(ic->second - ib->second) / std::abs(ib->second);
        const double tol = tolerance_for(o.policy, name);
        if (rel <= tol) {
          row.verdict = "within tolerance " + fmt("%g", tol);
        } else {
          row.verdict = "FAIL";
          ++out.fails;
        }
      }
      out.rows.push_back(row);
    }
  }
}

// Timings: one U test per (cell, pass), Holm across all of them.
void compare_timings_of(const GateSide& base, const GateSide& cand, const CellPairs& pairs, const GateOptions& o,
                        GateOutcome& out) {
  struct T {
    const CellResult* cell;
    std::string pass;
    double mb, mc, p;
    double floor;  ///< fresh processes: the larger side's odd/even A/A change (0 for frames)
    size_t nb, nc;
    bool slower;  ///< the U test's direction: candidate frames above baseline frames more often than not
    bool exact;   ///< exact null distribution (no ties, fewer than 50 a side)
  };
  std::vector<T> tests;
  for (const auto& [b, c] : pairs) {
    const PassSamples& sb = base.samples.at(match_key(*b));
    const PassSamples& sc = cand.samples.at(match_key(*c));
    for (const auto& [pass, xb] : sb) {
      auto it = std::find_if(sc.begin(), sc.end(), [&](auto& e) { return e.first == pass; });
      if (it == sc.end()) {
        out.cannot_compare.push_back("pass " + pass + " of cell " + cell_label(*b) + " is only in the baseline");
        continue;
      }
      const MannWhitneyResult mw = mann_whitney_u(it->second, xb);
      // Process medians come in run order, and the runs alternate A B B A: each side's odd against its even
      // processes is an A/A measured beside the comparison.
      const bool processes = base.sample_kind == "process medians" && cand.sample_kind == "process medians";
      const auto positive = [](const std::vector<double>& v) {
        return std::all_of(v.begin(), v.end(), [](double x) { return x > 0; });
      };
      const double floor = processes && positive(xb) && positive(it->second)
                               ? std::max(odd_even_change(xb), odd_even_change(it->second))
                               : 0.0;
      tests.push_back({b, pass, median_of(xb), median_of(it->second), mw.p_value, floor, xb.size(), it->second.size(),
                       mw.u > 0.5 * double(xb.size()) * double(it->second.size()), mw.exact});
    }
    for (const auto& [pass, xc] : sc)
      if (std::none_of(sb.begin(), sb.end(), [&](auto& e) { return e.first == pass; }))
        out.cannot_compare.push_back("pass " + pass + " of cell " + cell_label(*b) + " is only in the candidate");
  }
  std::vector<double> raw;
  for (const T& t : tests) raw.push_back(t.p);
  const std::vector<double> adj = holm_adjust(raw);
  out.timing_comparisons = tests.size();
  bool undetectable = false;
  for (size_t i = 0; i < tests.size(); ++i) {
    const T& t = tests[i];
    const double ratio = t.mc / t.mb;
    const bool sig = adj[i] <= o.policy.alpha;
    GateRow row{cell_label(*t.cell),
                "time " + t.pass + " (ms)",
                fmt("%.3f", t.mb / 1e6),
                fmt("%.3f", t.mc / 1e6),
                change_text(t.mb, t.mc),
                raw[i],
                adj[i],
                "pass"};
    // The two-sided test's significance counts only in the direction the medians moved: a bimodal
    // candidate can have a higher median while its frames are mostly faster (audit find).
    // A slowdown inside what a side moves against itself (its noise floor) is not one.
    if (sig && t.slower && ratio > 1.0 + std::max(o.policy.threshold, t.floor)) {
      row.verdict = "FAIL";
      ++out.fails;
    } else if (sig && t.slower && ratio > 1.0 + std::max(o.policy.warn, t.floor)) {
      row.verdict = "WARN";
      ++out.warns;
    } else if (sig && t.slower && ratio > 1.0 + o.policy.warn) {
      row.verdict = "within noise floor " + fmt("±%.1f%%", t.floor * 100);
    } else if (sig && !t.slower && ratio < 1.0) {
      row.verdict = "pass (faster)";
    }
    // Holm tests the largest p at alpha itself: a comparison cannot fail when even its smallest possible
    // p exceeds alpha. That bound holds for the exact test; with ties the normal approximation can go
    // lower, so nothing is claimed then.
    if (t.exact && mann_whitney_min_p(t.nb, t.nc) > o.policy.alpha) {
      undetectable = true;
      ++out.cannot_fail;
      if (row.verdict == "pass") row.verdict = "cannot fail";
    }
    out.rows.push_back(row);
  }
  if (undetectable)
    out.notes.push_back(std::to_string(out.cannot_fail) + " of " + std::to_string(tests.size()) +
                        " timing comparisons have too few samples for any Holm-adjusted p-value to reach alpha " +
                        fmt("%g", o.policy.alpha) + ": they cannot fail; use more frames or --trials");
  out.notes.push_back("timings: " + std::to_string(tests.size()) + " (cell, pass) comparisons of " + base.sample_kind +
                      ", Mann-Whitney U, Holm-adjusted; fail when p <= " + fmt("%g", o.policy.alpha) +
                      " and slower by more than " + fmt("%g%%", o.policy.threshold * 100) + ", warn above " +
                      fmt("%g%%", o.policy.warn * 100) +
                      (base.sample_kind == "process medians"
                           ? ", and in both cases above the noise floor (the larger side's change between its "
                             "odd and its even processes)"
                           : std::string()));
}

}  // namespace

GateOutcome run_gate(const GateSide& base, const GateSide& cand, const GateOptions& o) {
  validate_policy(o.policy, "gate");
  GateOutcome out;
  for (const std::string& p : base.problems) out.cannot_compare.push_back(p);
  for (const std::string& p : cand.problems) out.cannot_compare.push_back(p);
  const CellPairs pairs = pair_cells(base, cand, out);
  // Environments: timings from different devices, drivers or thread counts do not compare.
  std::vector<std::string> env_diff;
  for (const auto& [b, c] : pairs)
    for (const std::string& d : environment_differences(b->timing.environment, c->timing.environment))
      if (std::find(env_diff.begin(), env_diff.end(), d) == env_diff.end()) env_diff.push_back(d);
  // Two separate runs: their frames are one process each, so only a machine in the same state makes them
  // comparable at all; fresh processes interleaved (--ab) are the design that does not need it.
  if (!o.deterministic_only && env_diff.empty() && base.sample_kind == "frames" && cand.sample_kind == "frames")
    out.incomparable = machine_state_differences(base.cells, cand.cells);
  const bool compare_timings = !o.deterministic_only && env_diff.empty() && out.incomparable.empty();
  for (const std::string& d : env_diff) {
    if (o.deterministic_only)
      out.notes.push_back("environments differ (timings are not compared anyway): " + d);
    else
      out.cannot_compare.push_back("timings not compared: the sides ran on different environments: " + d);
  }

  compare_deterministic(pairs, o, out);
  if (compare_timings) compare_timings_of(base, cand, pairs, o, out);
  // A gate whose timing comparisons could not have failed has not passed them: INCONCLUSIVE (exit 4),
  // unless a regression was found anyway.
  out.exit_code = !out.cannot_compare.empty()                        ? 2
                  : out.fails > 0                                    ? 1
                  : out.cannot_fail > 0 || !out.incomparable.empty() ? 4
                                                                     : 0;
  return out;
}

std::string format_gate(const GateOutcome& o) {
  std::vector<std::array<std::string, 7>> table = {
      {"cell", "metric", "baseline", "candidate", "change", "p (Holm)", "verdict"}};
  for (const GateRow& r : o.rows) {
    std::string p = "—";
    if (r.p_holm) p = *r.p_holm < 0.0001 ? "<0.0001" : fmt("%.4f", *r.p_holm);
    table.push_back({r.cell, r.metric, r.baseline, r.candidate, r.change, p, r.verdict});
  }
  std::array<size_t, 7> w{};
  auto width = [](const std::string& s) {  // UTF-8 aware enough for "—" and "→"
    size_t n = 0;
    for (unsigned char ch : s) n += (ch & 0xC0) != 0x80;
    return n;
  };
  for (const auto& row : table)
    for (size_t i = 0; i < 7; ++i) w[i] = std::max(w[i], width(row[i]));
  std::string s;
  for (size_t r = 0; r < table.size(); ++r) {
    for (size_t i = 0; i < 7; ++i) {
      s += table[r][i];
      if (i + 1 < 7) s += std::string(w[i] - width(table[r][i]) + 2, ' ');
    }
    s += "\n";
    if (r == 0) {
      for (size_t i = 0; i < 7; ++i) s += std::string(w[i], '-') + (i + 1 < 7 ? "  " : "");
      s += "\n";
    }
  }
  s += std::to_string(o.identical) + " deterministic metric(s) identical";
  s += o.rows.empty() ? "\n" : "; " + std::to_string(o.timing_comparisons) + " timing comparison(s)\n";
  for (const std::string& n : o.notes) s += "note: " + n + "\n";
  for (const std::string& c : o.cannot_compare) s += "cannot compare: " + c + "\n";
  if (o.exit_code == 2)
    s += "result: CANNOT COMPARE (exit 2)\n";
  else if (o.exit_code == 1)
    s += "result: REGRESSION: " + std::to_string(o.fails) + " failure(s) (exit 1)\n";
  else if (o.exit_code == 4 && !o.incomparable.empty()) {
    for (const std::string& c : o.incomparable) s += "timings not compared: " + c + "\n";
    s += "result: INCONCLUSIVE: separate runs in different machine states cannot be told apart from a "
         "regression; run `hybridprof gate --ab` to interleave fresh processes of both builds (exit 4)\n";
  } else if (o.exit_code == 4)
    s += "result: INCONCLUSIVE: " + std::to_string(o.cannot_fail) +
         " timing comparison(s) could not have failed (exit 4)\n";
  else
    s +=
        "result: PASS" + (o.warns ? " with " + std::to_string(o.warns) + " warning(s)" : std::string()) + " (exit 0)\n";
  return s;
}

std::pair<GateSide, GateSide> run_ab(const AbOptions& o) {
  if (o.trials < 1) throw InputError("--trials: must be at least 1");
  if (o.baseline_cmd.empty() || o.candidate_cmd.empty())
    throw InputError("--ab needs --baseline-cmd and --candidate-cmd");
  if (o.scenario.empty()) throw InputError("--ab needs --scenario FILE");
  (void)load_matrix(o.scenario);  // a broken scenario fails here, once, not in every trial's log
  std::string work = o.work_dir;
  if (work.empty()) {
    std::string tmpl = (fs::temp_directory_path() / "hybridprof-gate-XXXXXX").string();
    if (!::mkdtemp(tmpl.data()))
      throw InputError("cannot create a work folder under " + fs::temp_directory_path().string());
    work = tmpl;
  }
  std::error_code ec;
  fs::create_directories(work, ec);
  if (ec) throw InputError(work + ": cannot create the work folder: " + ec.message());
  std::vector<std::string> dirs[2];
  const std::string* cmds[2] = {&o.baseline_cmd, &o.candidate_cmd};
  const char* names[2] = {"baseline", "candidate"};
  for (int k = 0; k < o.trials; ++k) {
    // A B, then B A: a linear drift in load adds the same to both sides over each pair of trials.
    const int order[2] = {k % 2, 1 - k % 2};
    for (int side : order) {
      const std::string dir = (fs::path(work) / (std::string(names[side]) + "-" + std::to_string(k + 1))).string();
      fs::remove_all(dir);
      const std::string log = dir + ".log";
      const std::string cmd = *cmds[side] + " run " + shell_quote(o.scenario) + " --out " + shell_quote(dir) + " > " +
                              shell_quote(log) + " 2>&1";
      const int rc = std::system(cmd.c_str());
      if (rc != 0) {
        const int code = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
        throw InputError(std::string("--") + names[side] + "-cmd: `" + cmd + "` exited with " + std::to_string(code) +
                         " (see " + log + ")");
      }
      dirs[side].push_back(dir);
      if (o.on_process) {
        o.on_process(int(dirs[0].size() + dirs[1].size()), 2 * o.trials,
                     std::string(names[side]) + " " + std::to_string(k + 1) + "/" + std::to_string(o.trials));
      }
    }
  }
  auto result = std::make_pair(
      side_from_runs(dirs[0], "baseline (" + std::to_string(o.trials) + " runs of " + o.baseline_cmd + ")"),
      side_from_runs(dirs[1], "candidate (" + std::to_string(o.trials) + " runs of " + o.candidate_cmd + ")"));
  if (!o.keep && o.work_dir.empty()) fs::remove_all(work);
  return result;
}

}  // namespace hp
