#include "timing/frame_timings.hpp"

#include <algorithm>
#include <limits>
#include <map>
#include <stdexcept>

namespace hp {

std::uint64_t FrameSample::span_begin_ns() const {
  if (begin_ns) return *begin_ns;
  if (passes.empty()) return end_ns.value_or(0);
  std::uint64_t b = std::numeric_limits<std::uint64_t>::max();
  for (const PassSample& p : passes) b = std::min(b, p.begin_ns);
  return b;
}

std::uint64_t FrameSample::span_end_ns() const {
  std::uint64_t e = 0;
  if (end_ns) {
    e = *end_ns;
  } else if (passes.empty()) {
    e = begin_ns.value_or(0);
  } else {
    for (const PassSample& p : passes) e = std::max(e, p.end_ns);
  }
  // A span never runs backwards (a bad explicit end would otherwise wrap the duration).
  return std::max(e, span_begin_ns());
}

std::string_view to_string(TimingSource source) {
  switch (source) {
    case TimingSource::GpuTimestamps: return "gpu-timestamps";
    case TimingSource::CpuWall: return "cpu-wall";
  }
  return "unknown";
}

TimingSource timing_source_from_string(std::string_view text) {
  if (text == "gpu-timestamps") return TimingSource::GpuTimestamps;
  if (text == "cpu-wall") return TimingSource::CpuWall;
  throw std::invalid_argument("unknown timing source '" + std::string(text) + "'");
}

std::string_view to_string(PassIsolation isolation) {
  switch (isolation) {
    case PassIsolation::Serialized: return "serialized";
    case PassIsolation::HostSubmissions: return "host-submissions";
    case PassIsolation::Unisolated: return "unisolated";
  }
  return "unknown";
}

PassIsolation pass_isolation_from_string(std::string_view text) {
  if (text == "serialized") return PassIsolation::Serialized;
  if (text == "host-submissions") return PassIsolation::HostSubmissions;
  if (text == "unisolated") return PassIsolation::Unisolated;
  throw std::invalid_argument("unknown pass isolation '" + std::string(text) + "'");
}

OverlapSummary paired_overlap(std::span<const double> serialized_sum_ns, std::span<const double> overlapped_ns) {
  if (serialized_sum_ns.size() != overlapped_ns.size())
    throw std::invalid_argument("paired_overlap: " + std::to_string(serialized_sum_ns.size()) + " serialized frames, " +
                                std::to_string(overlapped_ns.size()) + " overlapped");
  OverlapSummary o;
  o.frames = std::uint32_t(overlapped_ns.size());
  if (overlapped_ns.empty()) return o;
  o.overlapped_frame_ns = summarize(overlapped_ns);
  o.serialized_sum_ns = summarize(serialized_sum_ns);
  std::vector<double> d, f;
  for (std::size_t i = 0; i < overlapped_ns.size(); ++i) {
    d.push_back(serialized_sum_ns[i] - overlapped_ns[i]);
    if (serialized_sum_ns[i] > 0.0) f.push_back((serialized_sum_ns[i] - overlapped_ns[i]) / serialized_sum_ns[i]);
  }
  std::sort(d.begin(), d.end());
  o.saving_ns = quantile_sorted(d, 0.5);
  o.saving_ns_ci = median_ci_order_statistic(d);
  if (!f.empty()) {
    std::sort(f.begin(), f.end());
    o.saving_fraction = quantile_sorted(f, 0.5);
    o.saving_fraction_ci = median_ci_order_statistic(f);
  }
  return o;
}

double QueryOverhead::overhead_fraction() const {
  return frame_ns_without_queries > 0.0 ? overhead_ns() / frame_ns_without_queries : 0.0;
}

QueryOverhead paired_query_overhead(std::span<const double> with_queries, std::span<const double> without_queries) {
  if (with_queries.size() != without_queries.size())
    throw std::invalid_argument("paired_query_overhead: " + std::to_string(with_queries.size()) +
                                " frames with queries, " + std::to_string(without_queries.size()) + " without");
  QueryOverhead q;
  q.frames = std::uint32_t(without_queries.size());
  if (with_queries.empty()) return q;
  q.frame_ns_with_queries = quantile(with_queries, 0.5);
  q.frame_ns_without_queries = quantile(without_queries, 0.5);
  std::vector<double> d;
  for (std::size_t i = 0; i < with_queries.size(); ++i)
    if (without_queries[i] > 0.0) d.push_back((with_queries[i] - without_queries[i]) / without_queries[i]);
  if (d.empty()) return q;
  std::sort(d.begin(), d.end());
  q.paired_fraction = quantile_sorted(d, 0.5);
  q.paired_fraction_ci = median_ci_order_statistic(d);
  return q;
}

FrameTimings::FrameTimings(std::uint32_t warmup, std::uint32_t measured, TimingSource source)
    : warmup_wanted_(warmup),
      measured_wanted_(measured),
      source_(source),
      isolation_(source == TimingSource::CpuWall ? PassIsolation::HostSubmissions : PassIsolation::Serialized) {
  measured_.reserve(measured);
}

bool FrameTimings::add(FrameSample frame) {
  if (complete()) throw std::logic_error("FrameTimings::add: the run already has all its frames");
  for (const PassSample& p : frame.passes) {
    if (p.end_ns < p.begin_ns) {
      throw std::invalid_argument("FrameTimings::add: pass '" + p.pass + "' ends before it begins");
    }
  }
  if (warmup_seen_ < warmup_wanted_) {
    ++warmup_seen_;
  } else {
    measured_.push_back(std::move(frame));
  }
  return !complete();
}

TimingSummary FrameTimings::summarize(const SummaryOptions& options) const {
  if (measured_.empty()) throw std::logic_error("FrameTimings::summarize: no measured frames");
  TimingSummary s;
  s.source = source_;
  s.warmup_frames = warmup_seen_;
  s.measured_frames = static_cast<std::uint32_t>(measured_.size());
  s.query_overhead = overhead_;
  s.pass_isolation = isolation_;

  std::vector<std::string> order;
  std::map<std::string, std::vector<double>> per_pass;
  std::vector<double> frame_ns;
  std::vector<double> wall_ns;
  std::vector<double> pass_sum_ns;
  for (const FrameSample& f : measured_) {
    std::map<std::string, std::uint64_t> in_frame;  // summed per name within the frame
    std::uint64_t sum = 0;
    for (const PassSample& p : f.passes) {
      if (!per_pass.contains(p.pass)) {
        per_pass[p.pass];
        order.push_back(p.pass);
      }
      in_frame[p.pass] += p.duration_ns();
      sum += p.duration_ns();
    }
    pass_sum_ns.push_back(static_cast<double>(sum));
    for (const auto& [name, ns] : in_frame) per_pass[name].push_back(static_cast<double>(ns));
    frame_ns.push_back(static_cast<double>(f.duration_ns()));
    wall_ns.push_back(static_cast<double>(f.cpu_wall_ns));
  }
  for (const std::string& name : order) {
    s.passes.push_back({name, hp::summarize(per_pass[name], options)});
  }
  s.frame_ns = hp::summarize(frame_ns, options);
  s.cpu_wall_ns = hp::summarize(wall_ns, options);
  if (!overlapped_.empty() && overlapped_.size() == measured_.size()) {
    std::vector<double> spans;
    for (const FrameSpan& o : overlapped_) spans.push_back(static_cast<double>(o.duration_ns()));
    s.overlap = paired_overlap(pass_sum_ns, spans);
  }
  return s;
}

Counters FrameTimings::total_counters() const {
  Counters total;
  for (const FrameSample& f : measured_) total.add(f.counters);
  return total;
}

FrameTimings FrameTimings::from_measured(std::uint32_t warmup, TimingSource source, std::vector<FrameSample> measured,
                                         std::optional<QueryOverhead> overhead, Counters frame_invocations,
                                         std::vector<FrameSpan> overlapped, std::optional<PassIsolation> isolation) {
  FrameTimings t(warmup, static_cast<std::uint32_t>(measured.size()), source);
  if (isolation) t.isolation_ = *isolation;
  t.overlapped_ = std::move(overlapped);
  t.invocations_ = std::move(frame_invocations);
  t.warmup_seen_ = warmup;
  t.measured_ = std::move(measured);
  t.overhead_ = overhead;
  return t;
}

FrameTimings FrameTimings::pool_rounds(const std::vector<FrameTimings>& rounds,
                                       const std::vector<QueryOverheadSamples>& overhead) {
  if (rounds.empty()) throw std::invalid_argument("pool_rounds: no rounds");
  if (overhead.size() != rounds.size())
    throw std::invalid_argument("pool_rounds: " + std::to_string(overhead.size()) + " overhead entries for " +
                                std::to_string(rounds.size()) + " rounds");
  const FrameTimings& first = rounds.front();
  std::vector<FrameSample> frames;
  std::vector<FrameSpan> overlapped;
  std::vector<double> with_queries, without_queries;
  for (std::size_t r = 0; r < rounds.size(); ++r) {
    const FrameTimings& t = rounds[r];
    if (t.source() != first.source() || t.pass_isolation() != first.pass_isolation())
      throw std::invalid_argument("pool_rounds: round " + std::to_string(r) + " was timed another way");
    if (!t.complete()) throw std::invalid_argument("pool_rounds: round " + std::to_string(r) + " is incomplete");
    for (FrameSample f : t.measured()) {
      f.round = static_cast<std::uint32_t>(r);
      frames.push_back(std::move(f));
    }
    overlapped.insert(overlapped.end(), t.overlapped().begin(), t.overlapped().end());
    with_queries.insert(with_queries.end(), overhead[r].with_queries.begin(), overhead[r].with_queries.end());
    without_queries.insert(without_queries.end(), overhead[r].without_queries.begin(),
                           overhead[r].without_queries.end());
  }
  // Overlapped frames pair with measured frames by index: only when every round has them.
  if (overlapped.size() != frames.size()) overlapped.clear();
  std::optional<QueryOverhead> pooled;
  if (!with_queries.empty() && with_queries.size() == without_queries.size())
    pooled = paired_query_overhead(with_queries, without_queries);
  return from_measured(first.warmup_frames(), first.source(), std::move(frames), pooled, first.frame_invocations(),
                       std::move(overlapped), first.pass_isolation());
}

}  // namespace hp
