// The cost of measuring error: the CPU reference renderer and the image metrics.
//   hp_bench_reference --benchmark_counters_tabular=true
#include "image/metrics.hpp"
#include "reference/reference.hpp"
#include "scene/builtin_scenes.hpp"

#include <benchmark/benchmark.h>

#include <random>

namespace {

hp::Image4f noise_image(uint32_t w, uint32_t h, unsigned seed) {
  hp::Image4f im(w, h);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (float& v : im.rgba) v = u(rng);
  return im;
}

// Reference of builtin:pica at 320x180 with `samples` reflection directions per reflective pixel, on all
// cores. Counter: rays (primary, shadow, reflection) per second.
void BM_ReferencePica(benchmark::State& state) {
  const hp::Scene scene = hp::make_pica_scene();
  const hp::Camera cam = hp::auto_frame(scene, 320.0f / 180.0f);
  hp::ReferenceSettings s;
  s.width = 320;
  s.height = 180;
  s.samples = uint32_t(state.range(0));
  uint64_t rays = 0;
  for (auto _ : state) {
    const hp::ReferenceImage r = hp::render_reference(scene, cam, s);
    rays += r.rays;
    benchmark::DoNotOptimize(r.color.rgba.data());
  }
  state.counters["rays/s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ReferencePica)->Arg(16)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Flip720p(benchmark::State& state) {
  const hp::Image4f a = noise_image(1280, 720, 1), b = noise_image(1280, 720, 2);
  for (auto _ : state) benchmark::DoNotOptimize(hp::flip_error_map(a, b).rgba.data());
  state.counters["px/s"] = benchmark::Counter(1280.0 * 720.0, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Flip720p)->Unit(benchmark::kMillisecond);

void BM_ImageMetrics720p(benchmark::State& state) {
  const hp::Image4f a = noise_image(1280, 720, 1), b = noise_image(1280, 720, 2);
  hp::ErrorOptions o;
  o.flip = false;
  for (auto _ : state) benchmark::DoNotOptimize(hp::compare_images(a, b, o).mse);
  state.counters["px/s"] = benchmark::Counter(1280.0 * 720.0, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_ImageMetrics720p)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
