// Synthetic frames for the profiler tests: a fixed, hand-checkable pattern, not random.
#pragma once

#include <cstdint>
#include <vector>

#include "timing/frame_timings.hpp"

namespace hp::test {

// Frame i starts at base + i * 1 ms. Passes back to back from the frame start: gbuffer 100 us + i ns,
// shadows 200 us, reflections 300 us; counters scale with i only through nothing (deterministic).
inline FrameSample synthetic_frame(std::uint64_t i, std::uint64_t base_ns = 5'000'000'000ull) {
  FrameSample f;
  const std::uint64_t t = base_ns + i * 1'000'000;
  f.passes.push_back({"gbuffer", t, t + 100'000 + i});
  f.passes.push_back({"shadows", t + 100'000 + i, t + 300'000 + i});
  f.passes.push_back({"reflections", t + 300'000 + i, t + 600'000 + i});
  f.cpu_wall_ns = 700'000 + 10 * i;
  f.counters.set("shadows", counter::rays_cast, 4096);
  f.counters.set("shadows", counter::nodes_visited, 50'000);
  f.counters.set("reflections", counter::rays_cast, 4096);
  f.counters.set("reflections", counter::nodes_visited, 80'000);
  f.counters.set("reflections", counter::triangles_tested, 12'345);
  return f;
}

}  // namespace hp::test
