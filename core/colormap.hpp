// The ramp of the miss heatmaps (black -> purple -> orange -> yellow), as display (sRGB) values, so that the
// heatmap images (profiler/cache_analysis.cpp) and their colour bars in the report (reports/svg_chart.cpp)
// draw the same colours.
#pragma once

#include <algorithm>
#include <array>

namespace hp {

/// The colour at t in [0, 1] (clamped): 0 black, 1 yellow, sRGB components in [0, 1].
inline std::array<float, 3> miss_ramp_srgb(float t) {
  t = std::clamp(t, 0.0f, 1.0f);
  const float r = std::clamp(1.6f * t, 0.0f, 1.0f);
  const float g = std::clamp(1.6f * t - 0.6f, 0.0f, 1.0f);
  const float b = std::clamp(t < 0.4f ? 1.5f * t : 1.2f - 1.5f * (t - 0.4f) * 2.0f, 0.0f, 1.0f);
  return {r, g, b};
}

}  // namespace hp
