// The self-check of the timing model, in a test binary of its own that CTest runs alone (RUN_SERIAL): it
// compares times, and another lavapipe test beside it on a 2-core machine would move them.
#include "vulkan_env.hpp"

#include "frame.hpp"
#include "scene/load.hpp"
#include "timing/stats.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace hp {
namespace {

// Each pass's timestamp median against the same pass timed alone on the host (one submission each,
// FrameSettings::host_timing), frames of the two kinds interleaved. Boundary timestamps alone are not
// enough: a timestamp waits for earlier work but holds back none that follows, and Mesa 25 lavapipe
// executes a timestamp only at its next flush, after the following pass, so without the dependency that
// Frame adds after each timestamp, "shadows" read 76 ms and "reflections" 3.6 ms here against 30 and
// 72 ms alone (this test, 2026-12-01). Bounds: each pass's share of the frame (its median over the sum of
// the passes' medians) within 25% of its share alone, plus 2 points; and its median within 50% of its
// median alone, plus 2 ms. The shares carry the attribution: with compilers on both cores of the machine,
// every pass read up to 35% longer by timestamps than alone on the host, in the same proportions.
// A pass timed alone on the host also holds a submission's round trip (about 0.08 ms on an H200, where the
// five passes of a 480x270 frame take 0.4 ms together), so on a fast device the frame is enlarged until its
// passes take 20 ms or more (at most 8x each way) and that round trip counts for little.
TEST(TimingSelfCheck, PassTimestampsAgreeWithPassesTimedAlone) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s;
  s.width = 480;
  s.height = 270;
  s.rt.shadows = true;
  s.rt.reflections = true;
  s.rt.reflection_divisor = 1;
  auto frame = std::make_unique<Frame>(*ctx, scene, scene.camera, s);
  if (!frame->timestamps_supported()) GTEST_SKIP() << "this queue has no timestamps";
  double sum_ns = 0;
  for (int i = 0; i < 3; ++i) {
    sum_ns = 0;
    for (const auto& p : frame->render().passes) sum_ns += double(p.duration_ns());
  }
  const double scale = std::min(8.0, std::ceil(std::sqrt(20e6 / std::max(sum_ns, 1.0))));
  if (scale > 1) {
    s.width = uint32_t(s.width * scale);
    s.height = uint32_t(s.height * scale);
    std::printf("passes of 480x270 take %.3f ms: the frame is %ux%u\n", sum_ns * 1e-6, s.width, s.height);
    frame = std::make_unique<Frame>(*ctx, scene, scene.camera, s);
  }
  Frame& gpu = *frame;
  s.host_timing = true;
  Frame host(*ctx, scene, scene.camera, s);
  std::map<std::string, std::vector<double>> by_ts, by_host;
  for (int i = 0; i < 13; ++i) {
    // Alternate which kind goes first; the first two rounds warm up (first frames run slower).
    const bool gpu_first = i % 2 == 0;
    const FrameTiming a = gpu_first ? gpu.render() : host.render();
    const FrameTiming b = gpu_first ? host.render() : gpu.render();
    if (i < 2) continue;
    for (const auto& p : (gpu_first ? a : b).passes) by_ts[p.name].push_back(double(p.duration_ns()));
    for (const auto& p : (gpu_first ? b : a).passes) by_host[p.name].push_back(double(p.duration_ns()));
  }
  ASSERT_EQ(by_ts.size(), 5u);
  std::map<std::string, double> t, h;
  double t_sum = 0, h_sum = 0;
  for (const auto& [pass, ts] : by_ts) {
    ASSERT_TRUE(by_host.count(pass)) << pass;
    t_sum += t[pass] = quantile(ts, 0.5);
    h_sum += h[pass] = quantile(by_host[pass], 0.5);
  }
  for (const auto& [pass, ts] : by_ts) {
    const double share_t = t[pass] / t_sum, share_h = h[pass] / h_sum;
    const std::string what = pass + ": timestamps " + std::to_string(t[pass] * 1e-6) + " ms (" +
                             std::to_string(100 * share_t) + "% of the frame), alone on the host " +
                             std::to_string(h[pass] * 1e-6) + " ms (" + std::to_string(100 * share_h) + "%)";
    EXPECT_LE(std::abs(share_t - share_h), 0.25 * share_h + 0.02) << what;
    EXPECT_LE(std::abs(t[pass] - h[pass]), 0.5 * h[pass] + 2e6) << what;
  }
}

}  // namespace
}  // namespace hp
