#include "timing/result_json.hpp"

#include <fstream>
#include <limits>
#include <sstream>
#include <system_error>

#include "atomic_file.hpp"
#include "error.hpp"
#include "input_file.hpp"
#include "json_depth.hpp"
#include "output_path.hpp"

namespace hp {

using nlohmann::json;

namespace {

// Field access that names what is wrong: nlohmann's own messages do not say which field.
const json& field(const json& j, const char* name) {
  if (!j.is_object()) throw InputError("expected an object holding '" + std::string(name) + "'");
  const auto it = j.find(name);
  if (it == j.end()) throw InputError("missing field '" + std::string(name) + "'");
  return *it;
}

template <typename T>
T get(const json& j, const char* name) {
  const json& v = field(j, name);
  try {
    if constexpr (std::is_same_v<T, std::string>) {
      if (!v.is_string()) throw InputError("");
    } else if constexpr (std::is_same_v<T, bool>) {
      if (!v.is_boolean()) throw InputError("");
    } else if constexpr (std::is_integral_v<T>) {
      if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<std::int64_t>() >= 0)) throw InputError("");
      if (v.get<std::uint64_t>() > std::numeric_limits<T>::max()) throw InputError("");
    } else {
      if (!v.is_number()) throw InputError("");
    }
    return v.get<T>();
  } catch (const InputError&) {
    throw InputError("field '" + std::string(name) + "' has the wrong type or range");
  }
}

template <typename T>
std::optional<T> get_optional(const json& j, const char* name) {
  const json& v = field(j, name);
  if (v.is_null()) return std::nullopt;
  return get<T>(j, name);
}

template <typename T>
json optional_json(const std::optional<T>& v) {
  return v ? json(*v) : json(nullptr);
}

// Re-throws a parse error with the path of enclosing fields in front ("timing.passes[1]: ...").
template <typename F>
auto within(const std::string& where, F&& f) {
  try {
    return f();
  } catch (const InputError& e) {
    throw InputError(where + ": " + e.what());
  }
}

json pass_sample_json(const PassSample& p) {
  return {{"pass", p.pass}, {"queue", p.queue}, {"begin_ns", p.begin_ns}, {"end_ns", p.end_ns}};
}

}  // namespace

void to_json(json& j, const MedianCi& ci) {
  j = {{"method", ci.method},
       {"level", ci.level},
       {"low", ci.low},
       {"high", ci.high},
       {"coverage", ci.coverage},
       {"lower_rank", ci.lower_rank},
       {"upper_rank", ci.upper_rank},
       {"valid", ci.valid}};
}

void from_json(const json& j, MedianCi& ci) {
  ci.method = get<std::string>(j, "method");
  ci.level = get<double>(j, "level");
  ci.low = get<double>(j, "low");
  ci.high = get<double>(j, "high");
  ci.coverage = get<double>(j, "coverage");
  ci.lower_rank = get<std::size_t>(j, "lower_rank");
  ci.upper_rank = get<std::size_t>(j, "upper_rank");
  ci.valid = get<bool>(j, "valid");
}

void to_json(json& j, const Summary& s) {
  j = {{"count", s.count},
       {"min", s.min},
       {"max", s.max},
       {"median", s.median},
       {"mean", s.mean},
       {"p95", s.p95},
       {"stddev", optional_json(s.stddev)},
       {"cv", optional_json(s.cv)},
       {"quantile_definition", "type7"},
       {"median_ci", s.median_ci},
       {"median_ci_bootstrap", s.median_ci_bootstrap ? json(*s.median_ci_bootstrap) : json(nullptr)}};
}

void from_json(const json& j, Summary& s) {
  s.count = get<std::size_t>(j, "count");
  s.min = get<double>(j, "min");
  s.max = get<double>(j, "max");
  s.median = get<double>(j, "median");
  s.mean = get<double>(j, "mean");
  s.p95 = get<double>(j, "p95");
  s.stddev = get_optional<double>(j, "stddev");
  s.cv = get_optional<double>(j, "cv");
  s.median_ci = within("median_ci", [&] { return field(j, "median_ci").get<MedianCi>(); });
  const json& b = field(j, "median_ci_bootstrap");
  if (b.is_null()) {
    s.median_ci_bootstrap.reset();
  } else {
    s.median_ci_bootstrap = within("median_ci_bootstrap", [&] { return b.get<MedianCi>(); });
  }
}

void to_json(json& j, const Counters& c) {
  j = json::object();
  for (const auto& [pass, counters] : c.passes()) {
    json& p = j[pass];
    p = json::object();
    for (const auto& [name, value] : counters) p[name] = value;
  }
}

void from_json(const json& j, Counters& c) {
  if (!j.is_object()) throw InputError("counters must be an object of passes");
  c = Counters{};
  for (const auto& [pass, counters] : j.items()) {
    if (!counters.is_object()) throw InputError("counters of pass '" + pass + "' must be an object");
    for (const auto& [name, value] : counters.items()) {
      // Plain references: clang before 16 cannot capture structured bindings in a lambda.
      const json& pass_counters = counters;
      const std::string& counter = name;
      c.set(pass, name, within(pass, [&] { return get<std::uint64_t>(pass_counters, counter.c_str()); }));
    }
  }
}

void to_json(json& j, const DeviceDescription& d) {
  j = {{"name", d.name},
       {"type", d.type},
       {"driver_name", d.driver_name},
       {"driver_info", d.driver_info},
       {"driver_version", d.driver_version},
       {"api_version", d.api_version}};
}

void from_json(const json& j, DeviceDescription& d) {
  d.name = get<std::string>(j, "name");
  d.type = get<std::string>(j, "type");
  d.driver_name = get<std::string>(j, "driver_name");
  d.driver_info = get<std::string>(j, "driver_info");
  // Results written before the field existed carry the version only inside driver_info.
  if (j.contains("driver_version")) d.driver_version = get<std::string>(j, "driver_version");
  d.api_version = get<std::string>(j, "api_version");
}

void to_json(json& j, const Environment& e) {
  j = {{"cpu_model", e.cpu_model},
       {"core_count", e.core_count},
       {"lp_num_threads", e.lp_num_threads},
       {"build_type", e.build_type},
       {"compiler", e.compiler},
       {"git_commit", e.git_commit},
       {"date_utc", e.date_utc},
       {"hostname", e.hostname},
       {"os", e.os},
       {"load_1min", optional_json(e.load_1min)},
       {"cpu_governor", e.cpu_governor},
       {"device", e.device}};
}

void from_json(const json& j, Environment& e) {
  e.cpu_model = get<std::string>(j, "cpu_model");
  e.core_count = get<std::uint32_t>(j, "core_count");
  e.lp_num_threads = get<std::string>(j, "lp_num_threads");
  e.build_type = get<std::string>(j, "build_type");
  e.compiler = get<std::string>(j, "compiler");
  e.git_commit = get<std::string>(j, "git_commit");
  e.date_utc = get<std::string>(j, "date_utc");
  e.hostname = get<std::string>(j, "hostname");
  e.os = get<std::string>(j, "os");
  // Results written before these fields existed have neither.
  if (j.contains("load_1min")) e.load_1min = get_optional<double>(j, "load_1min");
  e.cpu_governor = j.contains("cpu_governor") ? get<std::string>(j, "cpu_governor") : "unknown";
  e.device = within("device", [&] { return field(j, "device").get<DeviceDescription>(); });
}

void to_json(json& j, const QueryOverhead& q) {
  j = {{"frame_ns_with_queries", q.frame_ns_with_queries},
       {"frame_ns_without_queries", q.frame_ns_without_queries},
       {"frames", q.frames},
       {"overhead_ns", q.overhead_ns()},
       {"overhead_fraction", q.overhead_fraction()},
       {"paired_fraction", optional_json(q.paired_fraction)},
       {"paired_fraction_ci", q.paired_fraction ? json(q.paired_fraction_ci) : json(nullptr)}};
}

void from_json(const json& j, QueryOverhead& q) {
  q.frame_ns_with_queries = get<double>(j, "frame_ns_with_queries");
  q.frame_ns_without_queries = get<double>(j, "frame_ns_without_queries");
  q.frames = get<std::uint32_t>(j, "frames");
  // Results written before the paired estimate existed have neither field.
  if (j.contains("paired_fraction")) q.paired_fraction = get_optional<double>(j, "paired_fraction");
  if (q.paired_fraction) {
    q.paired_fraction_ci = within("paired_fraction_ci", [&] { return field(j, "paired_fraction_ci").get<MedianCi>(); });
  }
}

void to_json(json& j, const OverlapSummary& o) {
  j = {{"frames", o.frames},
       {"overlapped_frame_ns", o.overlapped_frame_ns},
       {"serialized_sum_ns", o.serialized_sum_ns},
       {"saving_ns", optional_json(o.saving_ns)},
       {"saving_ns_ci", o.saving_ns ? json(o.saving_ns_ci) : json(nullptr)},
       {"saving_fraction", optional_json(o.saving_fraction)},
       {"saving_fraction_ci", o.saving_fraction ? json(o.saving_fraction_ci) : json(nullptr)}};
}

void from_json(const json& j, OverlapSummary& o) {
  o.frames = get<std::uint32_t>(j, "frames");
  o.overlapped_frame_ns = within("overlapped_frame_ns", [&] { return field(j, "overlapped_frame_ns").get<Summary>(); });
  o.serialized_sum_ns = within("serialized_sum_ns", [&] { return field(j, "serialized_sum_ns").get<Summary>(); });
  o.saving_ns = get_optional<double>(j, "saving_ns");
  if (o.saving_ns) o.saving_ns_ci = within("saving_ns_ci", [&] { return field(j, "saving_ns_ci").get<MedianCi>(); });
  o.saving_fraction = get_optional<double>(j, "saving_fraction");
  if (o.saving_fraction)
    o.saving_fraction_ci = within("saving_fraction_ci", [&] { return field(j, "saving_fraction_ci").get<MedianCi>(); });
}

json timing_result_json(const Environment& env, const FrameTimings& timings, const SummaryOptions& options) {
  const TimingSummary s = timings.summarize(options);
  json passes = json::array();
  for (const PassSummary& p : s.passes) passes.push_back({{"pass", p.pass}, {"duration_ns", p.duration_ns}});
  json frames = json::array();
  for (std::size_t i = 0; i < timings.measured().size(); ++i) {
    const FrameSample& f = timings.measured()[i];
    json fp = json::array();
    for (const PassSample& p : f.passes) fp.push_back(pass_sample_json(p));
    frames.push_back({{"index", i},
                      {"begin_ns", optional_json(f.begin_ns)},
                      {"end_ns", optional_json(f.end_ns)},
                      {"cpu_wall_ns", f.cpu_wall_ns},
                      {"passes", std::move(fp)},
                      {"counters", f.counters},
                      {"round", f.round}});
  }
  json overlapped = json::array();
  for (const FrameSpan& o : timings.overlapped())
    overlapped.push_back({{"begin_ns", o.begin_ns}, {"end_ns", o.end_ns}});
  return {{"schema", "hybridprof.timings"},
          {"version", 1},
          {"environment", env},
          {"timing",
           {{"source", std::string(to_string(s.source))},
            {"pass_isolation", std::string(to_string(s.pass_isolation))},
            {"overlap", s.overlap ? json(*s.overlap) : json(nullptr)},
            {"warmup_frames", s.warmup_frames},
            {"measured_frames", s.measured_frames},
            {"query_overhead", s.query_overhead ? json(*s.query_overhead) : json(nullptr)},
            {"frame_ns", s.frame_ns},
            {"cpu_wall_ns", s.cpu_wall_ns},
            {"passes", std::move(passes)}}},
          {"frames", std::move(frames)},
          {"overlapped_frames", std::move(overlapped)},
          {"counters", timings.total_counters()},
          {"invocations_per_frame", timings.frame_invocations()}};
}

TimingResult parse_timing_result(const json& doc) {
  if (!doc.is_object() || doc.value("schema", "") != "hybridprof.timings") {
    throw InputError("not a hybridprof timing result (field 'schema' is not \"hybridprof.timings\")");
  }
  if (get<int>(doc, "version") != 1) throw InputError("unsupported timing result version");

  Environment env = within("environment", [&] { return field(doc, "environment").get<Environment>(); });

  const json& t = field(doc, "timing");
  TimingSummary summary = within("timing", [&] {
    TimingSummary s;
    try {
      s.source = timing_source_from_string(get<std::string>(t, "source"));
    } catch (const std::invalid_argument& e) {
      throw InputError(std::string("field 'source': ") + e.what());
    }
    // Results written before pass isolation existed have no field: their boundary timestamps had no
    // dependency added between passes.
    s.pass_isolation = s.source == TimingSource::CpuWall ? PassIsolation::HostSubmissions : PassIsolation::Unisolated;
    if (t.contains("pass_isolation")) {
      try {
        s.pass_isolation = pass_isolation_from_string(get<std::string>(t, "pass_isolation"));
      } catch (const std::invalid_argument& e) {
        throw InputError(std::string("field 'pass_isolation': ") + e.what());
      }
    }
    if (t.contains("overlap") && !t["overlap"].is_null())
      s.overlap = within("overlap", [&] { return t["overlap"].get<OverlapSummary>(); });
    s.warmup_frames = get<std::uint32_t>(t, "warmup_frames");
    s.measured_frames = get<std::uint32_t>(t, "measured_frames");
    const json& q = field(t, "query_overhead");
    if (!q.is_null()) s.query_overhead = within("query_overhead", [&] { return q.get<QueryOverhead>(); });
    s.frame_ns = within("frame_ns", [&] { return field(t, "frame_ns").get<Summary>(); });
    s.cpu_wall_ns = within("cpu_wall_ns", [&] { return field(t, "cpu_wall_ns").get<Summary>(); });
    const json& passes = field(t, "passes");
    if (!passes.is_array()) throw InputError("field 'passes' must be an array");
    for (std::size_t i = 0; i < passes.size(); ++i) {
      s.passes.push_back(within("passes[" + std::to_string(i) + "]", [&] {
        return PassSummary{get<std::string>(passes[i], "pass"),
                           within("duration_ns", [&] { return field(passes[i], "duration_ns").get<Summary>(); })};
      }));
    }
    return s;
  });

  const json& frames_json = field(doc, "frames");
  if (!frames_json.is_array()) throw InputError("field 'frames' must be an array");
  std::vector<FrameSample> frames;
  for (std::size_t i = 0; i < frames_json.size(); ++i) {
    frames.push_back(within("frames[" + std::to_string(i) + "]", [&] {
      const json& fj = frames_json[i];
      FrameSample f;
      f.begin_ns = get_optional<std::uint64_t>(fj, "begin_ns");
      f.end_ns = get_optional<std::uint64_t>(fj, "end_ns");
      f.cpu_wall_ns = get<std::uint64_t>(fj, "cpu_wall_ns");
      const json& ps = field(fj, "passes");
      if (!ps.is_array()) throw InputError("field 'passes' must be an array");
      for (std::size_t k = 0; k < ps.size(); ++k) {
        f.passes.push_back(within("passes[" + std::to_string(k) + "]", [&] {
          PassSample p{get<std::string>(ps[k], "pass"), get<std::uint64_t>(ps[k], "begin_ns"),
                       get<std::uint64_t>(ps[k], "end_ns"), get<std::string>(ps[k], "queue")};
          if (p.end_ns < p.begin_ns) throw InputError("end_ns is before begin_ns");
          return p;
        }));
      }
      f.counters = within("counters", [&] { return field(fj, "counters").get<Counters>(); });
      // Absent in results written before runs had rounds: one round.
      if (fj.contains("round")) f.round = get<std::uint32_t>(fj, "round");
      return f;
    }));
  }
  if (frames.size() != summary.measured_frames) {
    throw InputError("field 'frames' holds " + std::to_string(frames.size()) +
                     " frames but timing.measured_frames is " + std::to_string(summary.measured_frames));
  }
  Counters counters = within("counters", [&] { return field(doc, "counters").get<Counters>(); });

  std::vector<FrameSpan> overlapped;
  if (doc.contains("overlapped_frames")) {
    const json& oj = doc["overlapped_frames"];
    if (!oj.is_array()) throw InputError("field 'overlapped_frames' must be an array");
    for (std::size_t i = 0; i < oj.size(); ++i) {
      overlapped.push_back(within("overlapped_frames[" + std::to_string(i) + "]", [&] {
        FrameSpan o{get<std::uint64_t>(oj[i], "begin_ns"), get<std::uint64_t>(oj[i], "end_ns")};
        if (o.end_ns < o.begin_ns) throw InputError("end_ns is before begin_ns");
        return o;
      }));
    }
    if (!overlapped.empty() && overlapped.size() != frames.size()) {
      throw InputError("field 'overlapped_frames' holds " + std::to_string(overlapped.size()) +
                       " frames but 'frames' holds " + std::to_string(frames.size()) + " (one per measured frame)");
    }
  }
  Counters invocations;
  if (doc.contains("invocations_per_frame"))
    invocations = within("invocations_per_frame", [&] { return doc["invocations_per_frame"].get<Counters>(); });
  FrameTimings timings =
      FrameTimings::from_measured(summary.warmup_frames, summary.source, std::move(frames), summary.query_overhead,
                                  std::move(invocations), std::move(overlapped), summary.pass_isolation);
  return TimingResult{std::move(env), std::move(timings), std::move(summary), std::move(counters)};
}

void write_json_atomically(const std::filesystem::path& path, const json& doc, int indent) {
  std::string text = doc.dump(indent);
  text += '\n';
  write_file_atomically(path, text);
}

void write_timing_result(const std::filesystem::path& path, const Environment& env, const FrameTimings& timings,
                         const SummaryOptions& options) {
  write_json_atomically(path, timing_result_json(env, timings, options));
}

TimingResult read_timing_result(const std::filesystem::path& path) {
  const std::string text = read_input_file(path, "timing result");
  check_json_depth(text, path.string());
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError("'" + path.string() + "' is not valid JSON: " + e.what());
  }
  // Appended, not "'" + string + "'": GCC 12 warns falsely (-Wrestrict, PR 105651) on that form.
  std::string where = path.string();
  where.insert(0, 1, '\'').push_back('\'');
  return within(where, [&] { return parse_timing_result(doc); });
}

}  // namespace hp
