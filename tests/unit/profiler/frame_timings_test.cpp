#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "timing/frame_timings.hpp"
#include "timing_fixture.hpp"

namespace hp {
namespace {

TEST(FrameTimings, DiscardsWarmupAndStopsAtMeasuredCount) {
  FrameTimings t(3, 4, TimingSource::GpuTimestamps);
  int calls = 0;
  // Warm-up frames are made 10x slower, as a first lavapipe run can be; none may reach the result.
  for (;;) {
    FrameSample f = test::synthetic_frame(static_cast<std::uint64_t>(calls));
    if (calls < 3) f.passes[0].end_ns += 10'000'000;
    ++calls;
    if (!t.add(std::move(f))) break;
  }
  EXPECT_EQ(calls, 7);
  EXPECT_TRUE(t.complete());
  EXPECT_EQ(t.warmup_seen(), 3u);
  ASSERT_EQ(t.measured().size(), 4u);
  // The first kept frame is call 3 (its gbuffer lasts 100'000 + 3 ns).
  EXPECT_EQ(t.measured().front().passes[0].duration_ns(), 100'003u);
  EXPECT_THROW(t.add(test::synthetic_frame(99)), std::logic_error);

  const TimingSummary s = t.summarize();
  EXPECT_EQ(s.warmup_frames, 3u);
  EXPECT_EQ(s.measured_frames, 4u);
  ASSERT_EQ(s.passes.size(), 3u);
  EXPECT_EQ(s.passes[0].pass, "gbuffer");
  EXPECT_EQ(s.passes[1].pass, "shadows");
  EXPECT_EQ(s.passes[2].pass, "reflections");
  // gbuffer durations 100003..100006: max 100006 proves the 10 ms warm-up frames were dropped.
  EXPECT_DOUBLE_EQ(s.passes[0].duration_ns.min, 100'003);
  EXPECT_DOUBLE_EQ(s.passes[0].duration_ns.max, 100'006);
  EXPECT_DOUBLE_EQ(s.passes[0].duration_ns.median, 100'004.5);
  EXPECT_DOUBLE_EQ(s.passes[1].duration_ns.median, 200'000);
  // Frame span: first begin to last end = 600'000 + i ns.
  EXPECT_DOUBLE_EQ(s.frame_ns.min, 600'003);
  EXPECT_DOUBLE_EQ(s.cpu_wall_ns.max, 700'060);
  EXPECT_EQ(s.source, TimingSource::GpuTimestamps);
}

// The rounds of an interleaved cell pooled: frames in round order, each marked with its round; the
// overlapped frames and the query-overhead pairs of every round together; warm-up and invocations of the
// first round.
TEST(FrameTimings, PoolRoundsKeepsEveryRoundsFrames) {
  std::vector<FrameTimings> rounds;
  std::vector<QueryOverheadSamples> overhead;
  std::uint64_t call = 0;
  for (std::uint32_t r = 0; r < 3; ++r) {
    FrameTimings t(r == 0 ? 2 : 1, r == 0 ? 2 : 1, TimingSource::GpuTimestamps);
    while (t.add(test::synthetic_frame(call++))) {
    }
    for (std::size_t i = 0; i < t.measured().size(); ++i) t.add_overlapped({0, 1000});
    if (r == 0) {
      Counters inv;
      inv.set("shadows", counter::compute_invocations, 64);
      t.set_frame_invocations(inv);
    }
    rounds.push_back(std::move(t));
    overhead.push_back({std::vector<double>(rounds.back().measured().size(), 110.0),
                        std::vector<double>(rounds.back().measured().size(), 100.0)});
  }
  const FrameTimings pooled = FrameTimings::pool_rounds(rounds, overhead);
  ASSERT_EQ(pooled.measured().size(), 4u);
  std::vector<std::uint32_t> marks;
  for (const FrameSample& f : pooled.measured()) marks.push_back(f.round);
  EXPECT_EQ(marks, (std::vector<std::uint32_t>{0, 0, 1, 2}));
  EXPECT_EQ(pooled.measured()[2].passes, rounds[1].measured()[0].passes);
  EXPECT_EQ(pooled.overlapped().size(), 4u);
  EXPECT_EQ(pooled.warmup_frames(), 2u);
  EXPECT_EQ(pooled.frame_invocations().get("shadows", counter::compute_invocations), 64u);
  ASSERT_TRUE(pooled.query_overhead());
  EXPECT_EQ(pooled.query_overhead()->frames, 4u);
  EXPECT_NEAR(*pooled.query_overhead()->paired_fraction, 0.1, 1e-12);
  EXPECT_EQ(pooled.summarize().measured_frames, 4u);
  EXPECT_THROW(FrameTimings::pool_rounds({}, {}), std::invalid_argument);
  EXPECT_THROW(FrameTimings::pool_rounds(rounds, {}), std::invalid_argument);
}

TEST(FrameTimings, ZeroWarmupKeepsEverything) {
  FrameTimings t(0, 2, TimingSource::CpuWall);
  EXPECT_TRUE(t.add(test::synthetic_frame(0)));
  EXPECT_FALSE(t.add(test::synthetic_frame(1)));
  EXPECT_EQ(t.measured().size(), 2u);
  EXPECT_EQ(t.summarize().source, TimingSource::CpuWall);
}

TEST(FrameTimings, RepeatedPassNamesAreSummedPerFrameAndExplicitSpanWins) {
  FrameTimings t(0, 1, TimingSource::GpuTimestamps);
  FrameSample f;
  f.passes.push_back({"blur", 1000, 1100});
  f.passes.push_back({"blur", 1200, 1250});
  f.begin_ns = 900;
  f.end_ns = 1400;
  t.add(f);
  const TimingSummary s = t.summarize();
  ASSERT_EQ(s.passes.size(), 1u);
  EXPECT_DOUBLE_EQ(s.passes[0].duration_ns.median, 150);
  EXPECT_DOUBLE_EQ(s.frame_ns.median, 500);
}

TEST(FrameTimings, RejectsBackwardsPassAndEmptySummary) {
  FrameTimings t(0, 1, TimingSource::GpuTimestamps);
  EXPECT_THROW(t.summarize(), std::logic_error);
  FrameSample bad;
  bad.passes.push_back({"gbuffer", 200, 100});
  EXPECT_THROW(t.add(bad), std::invalid_argument);
}

TEST(FrameTimings, SourceLabels) {
  EXPECT_EQ(to_string(TimingSource::GpuTimestamps), "gpu-timestamps");
  EXPECT_EQ(to_string(TimingSource::CpuWall), "cpu-wall");
  EXPECT_EQ(timing_source_from_string("cpu-wall"), TimingSource::CpuWall);
  EXPECT_THROW(timing_source_from_string("gpu"), std::invalid_argument);
}

TEST(FrameTimings, QueryOverhead) {
  const QueryOverhead q{1'010'000.0, 1'000'000.0, 50};
  EXPECT_DOUBLE_EQ(q.overhead_ns(), 10'000.0);
  EXPECT_DOUBLE_EQ(q.overhead_fraction(), 0.01);
  FrameTimings t(0, 1, TimingSource::GpuTimestamps);
  t.add(test::synthetic_frame(0));
  EXPECT_FALSE(t.summarize().query_overhead.has_value());
  t.set_query_overhead(q);
  EXPECT_EQ(t.summarize().query_overhead, q);
}

TEST(FrameTimings, PairedQueryOverheadIsTheMedianRelativeDifferenceWithItsCi) {
  // Relative differences 0.10, 0.02, -0.01, 0.05, 0.01, 0.03, 0.00: sorted, the median is the 4th, 0.02;
  // with 7 pairs the 95% order-statistic CI is [1st, 7th] (coverage 1 - 2/128).
  const std::vector<double> without(7, 100.0), with = {110.0, 102.0, 99.0, 105.0, 101.0, 103.0, 100.0};
  const QueryOverhead q = paired_query_overhead(with, without);
  ASSERT_TRUE(q.paired_fraction.has_value());
  EXPECT_NEAR(*q.paired_fraction, 0.02, 1e-12);
  EXPECT_TRUE(q.paired_fraction_ci.valid);
  EXPECT_NEAR(q.paired_fraction_ci.low, -0.01, 1e-12);
  EXPECT_NEAR(q.paired_fraction_ci.high, 0.10, 1e-12);
  EXPECT_NEAR(q.paired_fraction_ci.coverage, 1.0 - 2.0 / 128.0, 1e-12);
  EXPECT_EQ(q.frames, 7u);
  EXPECT_DOUBLE_EQ(q.frame_ns_with_queries, 102.0);
  EXPECT_DOUBLE_EQ(q.frame_ns_without_queries, 100.0);
  EXPECT_THROW(paired_query_overhead(with, std::vector<double>(6, 100.0)), std::invalid_argument);
}

TEST(FrameTimings, PairingCancelsTheDriftBetweenPairs) {
  // Frame times swing by +-50% through the run (a shared machine), each pair's two frames share the swing,
  // and the queries cost 1%: the paired estimate and its CI stay within 0.2 points of 1%. Pairing frames
  // one apart (a misaligned pairing) would see the swing between frames, several percent.
  std::vector<double> with, without;
  uint32_t state = 12345;
  auto noise = [&] {  // deterministic, uniform in [-0.05, 0.05)
    state = state * 1664525u + 1013904223u;
    return (double(state >> 8) / double(1u << 24) - 0.5) * 0.1;
  };
  for (int i = 0; i < 60; ++i) {
    const double drift = 100.0 + 50.0 * std::sin(i / 3.0);
    without.push_back(drift + noise());
    with.push_back((drift + noise()) * 1.01);
  }
  const QueryOverhead q = paired_query_overhead(with, without);
  ASSERT_TRUE(q.paired_fraction_ci.valid);
  EXPECT_NEAR(*q.paired_fraction, 0.01, 0.002);
  EXPECT_LE(q.paired_fraction_ci.low, 0.01);
  EXPECT_GE(q.paired_fraction_ci.high, 0.01);
  EXPECT_GT(q.paired_fraction_ci.low, 0.008);
  EXPECT_LT(q.paired_fraction_ci.high, 0.012);
  std::vector<double> shifted(with.begin() + 1, with.end());
  shifted.push_back(with.front());
  const QueryOverhead misaligned = paired_query_overhead(shifted, without);
  EXPECT_GT(misaligned.paired_fraction_ci.high - misaligned.paired_fraction_ci.low, 0.05);
}

TEST(FrameTimings, PairedOverlapIsTheMedianSavingWithItsCi) {
  // Serialized sums 100..106, overlapped spans with savings 10, 2, -1, 5, 1, 3, 0 (sorted: -1 0 1 2 3 5 10):
  // median 2, 95% CI [-1, 10] over 7 pairs.
  const std::vector<double> serialized = {100, 101, 102, 103, 104, 105, 106};
  const std::vector<double> overlapped = {90, 99, 103, 98, 103, 102, 106};
  const OverlapSummary o = paired_overlap(serialized, overlapped);
  EXPECT_EQ(o.frames, 7u);
  ASSERT_TRUE(o.saving_ns.has_value());
  EXPECT_DOUBLE_EQ(*o.saving_ns, 2.0);
  EXPECT_TRUE(o.saving_ns_ci.valid);
  EXPECT_DOUBLE_EQ(o.saving_ns_ci.low, -1.0);
  EXPECT_DOUBLE_EQ(o.saving_ns_ci.high, 10.0);
  // Fractions -1/102, 0/106, 1/104, 2/101, 3/105, 5/103, 10/100: the median is frame 2's own, 2/101.
  EXPECT_NEAR(*o.saving_fraction, 2.0 / 101.0, 1e-12);
  EXPECT_DOUBLE_EQ(o.serialized_sum_ns.median, 103.0);
  EXPECT_DOUBLE_EQ(o.overlapped_frame_ns.median, 102.0);
  EXPECT_THROW(paired_overlap(serialized, std::vector<double>(6, 1.0)), std::invalid_argument);
}

TEST(FrameTimings, OverlapIsSummarizedOnlyWithOneFramePerMeasuredFrame) {
  FrameTimings t(0, 3, TimingSource::GpuTimestamps);
  for (std::uint64_t i = 0; t.add(test::synthetic_frame(i)); ++i) {
  }
  EXPECT_EQ(t.pass_isolation(), PassIsolation::Serialized);
  EXPECT_EQ(FrameTimings(0, 1, TimingSource::CpuWall).pass_isolation(), PassIsolation::HostSubmissions);
  t.add_overlapped({0, 500'000});
  t.add_overlapped({0, 500'001});
  EXPECT_FALSE(t.summarize().overlap.has_value()) << "2 overlapped frames for 3 measured ones";
  t.add_overlapped({0, 500'002});
  const TimingSummary s = t.summarize();
  ASSERT_TRUE(s.overlap.has_value());
  // Frame i's passes sum to 600,000 + i ns (synthetic_frame), the overlapped frames span 500,000 + i.
  EXPECT_DOUBLE_EQ(*s.overlap->saving_ns, 100'000.0);
  EXPECT_FALSE(s.overlap->saving_ns_ci.valid) << "3 pairs are too few for a 95% CI";
  for (PassIsolation p : {PassIsolation::Serialized, PassIsolation::HostSubmissions, PassIsolation::Unisolated})
    EXPECT_EQ(pass_isolation_from_string(to_string(p)), p);
  EXPECT_THROW(pass_isolation_from_string("overlapped"), std::invalid_argument);
}

TEST(FrameTimings, TotalCountersSumFrames) {
  FrameTimings t(1, 3, TimingSource::GpuTimestamps);
  for (std::uint64_t i = 0; t.add(test::synthetic_frame(i)); ++i) {
  }
  const Counters c = t.total_counters();
  EXPECT_EQ(c.get("shadows", counter::rays_cast), 3u * 4096u);  // warm-up frame not counted
  EXPECT_EQ(c.total(counter::nodes_visited), 3u * 130'000u);
}

}  // namespace
}  // namespace hp
