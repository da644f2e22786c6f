// Tests of the image error metrics (MSE, relMSE, PSNR, max abs, over-threshold, non-finite) and LDR-FLIP.
#include "image/metrics.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

namespace hp {
namespace {

void set_rgb(Image4f& im, uint32_t x, uint32_t y, float r, float g, float b) {
  float* p = im.at(x, y);
  p[0] = r;
  p[1] = g;
  p[2] = b;
  p[3] = 1.0f;
}

Image4f uniform(uint32_t w, uint32_t h, float v) {
  Image4f im(w, h);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) set_rgb(im, x, y, v, v, v);
  return im;
}

Image4f random_image(uint32_t w, uint32_t h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Image4f im(w, h);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) set_rgb(im, x, y, u(rng), u(rng), u(rng));
  return im;
}

float map_at(const Image4f& map, uint32_t x, uint32_t y) { return map.at(x, y)[0]; }

float map_max(const Image4f& map) {
  float m = 0;
  for (std::size_t i = 0; i < map.rgba.size(); i += 4) m = std::max(m, map.rgba[i]);
  return m;
}

// The hand-computed 2x2 case. Differences (test - reference), all exactly representable:
//   p(0,0): ( 0,    0,  0     )   reference (0.5, 0.5, 0.5)
//   p(1,0): ( 0.25, 0,  0     )   reference (0,   0,   0  )
//   p(0,1): ( 0,    0, -0.5   )   reference (1,   1,   1  )
//   p(1,1): ( 0,    0,  0.0625)   reference (0.25, 0.5, 0.75)
struct TwoByTwo {
  Image4f test{2, 2}, ref{2, 2};
  TwoByTwo() {
    set_rgb(ref, 0, 0, 0.5f, 0.5f, 0.5f);
    set_rgb(test, 0, 0, 0.5f, 0.5f, 0.5f);
    set_rgb(ref, 1, 0, 0.0f, 0.0f, 0.0f);
    set_rgb(test, 1, 0, 0.25f, 0.0f, 0.0f);
    set_rgb(ref, 0, 1, 1.0f, 1.0f, 1.0f);
    set_rgb(test, 0, 1, 1.0f, 1.0f, 0.5f);
    set_rgb(ref, 1, 1, 0.25f, 0.5f, 0.75f);
    set_rgb(test, 1, 1, 0.25f, 0.5f, 0.8125f);
  }
};
constexpr double kSumSq = 0.0625 + 0.25 + 0.00390625;

ErrorOptions no_flip() {
  ErrorOptions o;
  o.flip = false;
  return o;
}

// ------------------------------------------------------------------------------------------------
// Plain metrics

TEST(CompareImages, IdenticalImagesHaveZeroError) {
  const Image4f a = random_image(17, 9, 1);
  const ErrorMetrics m = compare_images(a, a);
  EXPECT_EQ(m.pixels, 17u * 9u);
  EXPECT_EQ(m.mse, 0.0);
  EXPECT_EQ(m.relmse, 0.0);
  EXPECT_TRUE(std::isinf(m.psnr_db) && m.psnr_db > 0);
  EXPECT_EQ(m.max_abs, 0.0);
  EXPECT_EQ(m.over_threshold, 0u);
  EXPECT_EQ(m.non_finite, 0u);
  EXPECT_EQ(m.flip_mean, 0.0);
}

TEST(CompareImages, HandComputedTwoByTwo) {
  const TwoByTwo c;
  const ErrorMetrics m = compare_images(c.test, c.ref, no_flip());
  EXPECT_EQ(m.pixels, 4u);
  EXPECT_DOUBLE_EQ(m.mse, kSumSq / 12.0);  // 0.0263671875
  const double rel = (0.0625 / (0.0 + 0.01) + 0.25 / (1.0 + 0.01) + 0.00390625 / (0.5625 + 0.01)) / 12.0;
  EXPECT_NEAR(m.relmse, rel, 1e-9);  // float eps in the denominator: 0.01 is used as double
  EXPECT_NEAR(m.psnr_db, 10.0 * std::log10(1.0 / (kSumSq / 12.0)), 1e-9);
  EXPECT_NEAR(m.psnr_db, 15.789, 1e-3);
  EXPECT_EQ(m.max_abs, 0.5);
  EXPECT_EQ(m.over_threshold, 2u);  // 0.25 and 0.5 exceed 0.1; 0.0625 does not
  EXPECT_EQ(m.non_finite, 0u);
  EXPECT_EQ(m.flip_mean, -1.0);  // not computed
  // The options are echoed.
  EXPECT_EQ(m.relmse_eps, 0.01);
  EXPECT_EQ(m.psnr_peak, 1.0);
  EXPECT_EQ(m.threshold, 0.1);
}

TEST(CompareImages, OptionsChangeRelmsePsnrAndThreshold) {
  const TwoByTwo c;
  ErrorOptions o = no_flip();
  o.relmse_eps = 1.0;
  o.psnr_peak = 2.0;
  o.threshold = 0.25;  // strictly greater: the 0.25 difference is not over
  const ErrorMetrics m = compare_images(c.test, c.ref, o);
  EXPECT_DOUBLE_EQ(m.relmse, (0.0625 / 1.0 + 0.25 / 2.0 + 0.00390625 / 1.5625) / 12.0);
  EXPECT_NEAR(m.psnr_db, 10.0 * std::log10(4.0 / (kSumSq / 12.0)), 1e-9);
  // The stated peak is used as is (not max(1, peak) of the data): peak 0.5 lowers PSNR by 20log10(2).
  o.psnr_peak = 0.5;
  const ErrorMetrics half = compare_images(c.test, c.ref, o);
  EXPECT_NEAR(m.psnr_db - half.psnr_db, 20.0 * std::log10(4.0), 1e-9);
  EXPECT_EQ(m.over_threshold, 1u);
  EXPECT_EQ(m.relmse_eps, 1.0);
  EXPECT_EQ(m.psnr_peak, 2.0);
  EXPECT_EQ(m.threshold, 0.25);
}

TEST(CompareImages, RelmseWeightsDarkPixelsByEps) {
  // The same absolute error 0.1 on a black and on a white reference pixel.
  Image4f ref = uniform(2, 1, 0.0f), test = uniform(2, 1, 0.0f);
  set_rgb(ref, 1, 0, 1.0f, 1.0f, 1.0f);
  set_rgb(test, 0, 0, 0.5f, 0.5f, 0.5f);
  set_rgb(test, 1, 0, 0.5f, 0.5f, 0.5f);
  const ErrorMetrics m = compare_images(test, ref, no_flip());
  EXPECT_NEAR(m.relmse, (0.25 / 0.01 + 0.25 / 1.01) / 2.0, 1e-9);
  ErrorOptions o = no_flip();
  o.relmse_eps = 0.25;
  EXPECT_NEAR(compare_images(test, ref, o).relmse, (0.25 / 0.25 + 0.25 / 1.25) / 2.0, 1e-9);
  EXPECT_DOUBLE_EQ(m.mse, 0.25);
}

TEST(CompareImages, MaskExcludesPixels) {
  const TwoByTwo c;
  std::vector<uint8_t> mask = {1, 0, 0, 7};  // keep (0,0) and (1,1): nonzero means compare
  const ErrorMetrics m = compare_images(c.test, c.ref, no_flip(), &mask);
  EXPECT_EQ(m.pixels, 2u);
  EXPECT_DOUBLE_EQ(m.mse, 0.00390625 / 6.0);
  EXPECT_EQ(m.max_abs, 0.0625);
  EXPECT_EQ(m.over_threshold, 0u);

  std::vector<uint8_t> none(4, 0);
  const ErrorMetrics e = compare_images(c.test, c.ref, ErrorOptions{}, &none);
  EXPECT_EQ(e.pixels, 0u);
  EXPECT_TRUE(std::isnan(e.mse));
  EXPECT_TRUE(std::isnan(e.psnr_db));
  EXPECT_TRUE(std::isnan(e.flip_mean));
}

TEST(CompareImages, SizeMismatchThrowsNamingBothSizes) {
  const Image4f a(2, 2), b(3, 2);
  try {
    compare_images(a, b);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("2x2"), std::string::npos) << what;
    EXPECT_NE(what.find("3x2"), std::string::npos) << what;
  }
  EXPECT_THROW(flip_error_map(a, b), std::invalid_argument);
  std::vector<uint8_t> short_mask(3, 1);
  EXPECT_THROW(compare_images(a, a, ErrorOptions{}, &short_mask), std::invalid_argument);
  EXPECT_THROW(flip_error_map(a, a, 0.0), std::invalid_argument);
}

TEST(CompareImages, NonFinitePixelsAreCountedAndLeftOutOfMse) {
  TwoByTwo c;
  c.test.at(0, 0)[1] = std::numeric_limits<float>::quiet_NaN();
  const ErrorMetrics m = compare_images(c.test, c.ref);
  EXPECT_EQ(m.pixels, 4u);
  EXPECT_EQ(m.non_finite, 1u);
  EXPECT_EQ(m.over_threshold, 3u);  // the NaN pixel plus the two real ones
  EXPECT_TRUE(std::isinf(m.max_abs));
  EXPECT_DOUBLE_EQ(m.mse, kSumSq / 9.0);  // three finite pixels
  EXPECT_TRUE(std::isfinite(m.relmse));
  EXPECT_TRUE(std::isfinite(m.flip_mean));  // FLIP sanitises NaN
  EXPECT_GE(m.flip_mean, 0.0);
  EXPECT_LE(m.flip_mean, 1.0);

  c.test.at(1, 1)[0] = std::numeric_limits<float>::infinity();
  const ErrorMetrics m2 = compare_images(c.test, c.ref, no_flip());
  EXPECT_EQ(m2.non_finite, 2u);
  EXPECT_DOUBLE_EQ(m2.mse, (0.0625 + 0.25) / 6.0);
  // Alpha is ignored, even when it is NaN.
  TwoByTwo d;
  d.test.at(0, 0)[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(compare_images(d.test, d.ref, no_flip()).non_finite, 0u);
}

// ------------------------------------------------------------------------------------------------
// LDR-FLIP

// Standard CIELAB (D65) of the linear sRGB primaries green (0,1,0) and blue (0,0,1), to two decimals;
// used to check the colour pipeline and cmax independently of the implementation.
double expected_cmax() {
  const double gl = 87.73, ga = -86.18, gb = 83.18, bl = 32.30, ba = 79.19, bb = -107.86;
  const double da = 0.01 * gl * ga - 0.01 * bl * ba, db = 0.01 * gl * gb - 0.01 * bl * bb;
  return std::pow(std::abs(gl - bl) + std::sqrt(da * da + db * db), 0.7);
}

double expected_ec(double delta_l) {  // grey vs grey: only L differs; HyAB = |dL|
  const double cmax = expected_cmax(), e = std::pow(delta_l, 0.7);
  return e < 0.4 * cmax ? 0.95 / (0.4 * cmax) * e : 0.95 + (e - 0.4 * cmax) / (0.6 * cmax) * 0.05;
}

double lstar(double y) { return 116.0 * std::cbrt(y) - 16.0; }  // for y > 0.008856

TEST(Flip, IdenticalImagesAreZero) {
  const Image4f a = random_image(40, 30, 2);
  const Image4f map = flip_error_map(a, a);
  ASSERT_EQ(map.width, 40u);
  ASSERT_EQ(map.height, 30u);
  for (std::size_t i = 0; i < map.rgba.size(); i += 4) {
    ASSERT_EQ(map.rgba[i], 0.0f);
    ASSERT_EQ(map.rgba[i + 1], 0.0f);
    ASSERT_EQ(map.rgba[i + 2], 0.0f);
    ASSERT_EQ(map.rgba[i + 3], 1.0f);
  }
}

TEST(Flip, UniformBlackVsWhiteMatchesHandComputedValue) {
  // Uniform images: the CSF filters and the feature detectors are neutral, so E = Ec(HyAB = 100).
  const Image4f map = flip_error_map(uniform(8, 8, 0.0f), uniform(8, 8, 1.0f));
  const double expected = expected_ec(100.0);
  EXPECT_NEAR(expected, 0.9674, 1e-3);  // "near 1", above pt = 0.95
  for (std::size_t i = 0; i < map.rgba.size(); i += 4) ASSERT_NEAR(map.rgba[i], expected, 2e-4);
}

TEST(Flip, UniformGreysMatchHandComputedValues) {
  // Below the knee: Ec = pt / (pc cmax) * dL^qc.
  for (const float t : {0.4f, 0.6f, 0.45f}) {
    const double expected = expected_ec(std::abs(lstar(t) - lstar(0.5)));
    const Image4f map = flip_error_map(uniform(6, 5, t), uniform(6, 5, 0.5f));
    EXPECT_NEAR(map_at(map, 3, 2), expected, 2e-4) << "grey " << t;
    EXPECT_NEAR(map_at(map, 0, 0), expected, 2e-4) << "grey " << t;
  }
  // Above the knee (dL^0.7 > 0.4 cmax ~ 16.5, i.e. dL > ~55): black vs 0.5 grey.
  const double dl = lstar(0.5);
  EXPECT_GT(std::pow(dl, 0.7), 0.4 * expected_cmax());
  EXPECT_NEAR(map_at(flip_error_map(uniform(4, 4, 0.0f), uniform(4, 4, 0.5f)), 1, 1), expected_ec(dl), 2e-4);
}

// Independent CIELAB (D65, white = XYZ of linear RGB (1,1,1)) for the colour checks below.
struct Lab {
  double l, a, b;
};
Lab lab_of(double r, double g, double b) {
  const double x = 0.4124564 * r + 0.3575761 * g + 0.1804375 * b;
  const double y = 0.2126729 * r + 0.7151522 * g + 0.0721750 * b;
  const double z = 0.0193339 * r + 0.1191920 * g + 0.9503041 * b;
  const auto f = [](double t) { return t > 216.0 / 24389.0 ? std::cbrt(t) : (24389.0 / 27.0 * t + 16.0) / 116.0; };
  const double fx = f(x / 0.9504700), fy = f(y / 1.0), fz = f(z / 1.0888300);
  return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}
double expected_uniform_flip(Lab p, Lab q) {  // Hunt-adjusted HyAB, then the qc/pc/pt remap
  const double da = 0.01 * (p.l * p.a - q.l * q.a), db = 0.01 * (p.l * p.b - q.l * q.b);
  const double e = std::pow(std::abs(p.l - q.l) + std::sqrt(da * da + db * db), 0.7), cmax = expected_cmax();
  return e < 0.4 * cmax ? 0.95 / (0.4 * cmax) * e : 0.95 + (e - 0.4 * cmax) / (0.6 * cmax) * 0.05;
}

TEST(Flip, UniformColoursMatchHuntAdjustedHyAB) {
  // Chromatic pairs exercise the YCxCz round trip and the a/b terms (Hunt adjustment, HyAB).
  struct Pair {
    float t[3], r[3];
  };
  const Pair pairs[] = {{{1, 0, 0}, {0, 1, 0}},                     // red vs green: above the knee
                        {{0.55f, 0.5f, 0.5f}, {0.5f, 0.5f, 0.5f}},  // slightly reddish grey: below
                        {{0.2f, 0.3f, 0.6f}, {0.25f, 0.3f, 0.5f}},
                        {{0.9f, 0.8f, 0.1f}, {0.1f, 0.2f, 0.9f}}};  // yellow vs blue
  for (const Pair& p : pairs) {
    Image4f t(5, 4), r(5, 4);
    for (uint32_t y = 0; y < 4; ++y)
      for (uint32_t x = 0; x < 5; ++x) {
        set_rgb(t, x, y, p.t[0], p.t[1], p.t[2]);
        set_rgb(r, x, y, p.r[0], p.r[1], p.r[2]);
      }
    const double expected = expected_uniform_flip(lab_of(p.t[0], p.t[1], p.t[2]), lab_of(p.r[0], p.r[1], p.r[2]));
    EXPECT_NEAR(map_at(flip_error_map(t, r), 2, 2), expected, 5e-4) << p.t[0] << "," << p.t[1] << "," << p.t[2];
  }
  EXPECT_GT(expected_uniform_flip(lab_of(1, 0, 0), lab_of(0, 1, 0)), 0.95);
}

TEST(Flip, InRangeAndSymmetricForArbitraryInput) {
  Image4f a = random_image(33, 21, 3), b = random_image(33, 21, 4);
  // Out-of-range and non-finite input is clamped / sanitised.
  a.at(5, 5)[0] = 7.0f;
  a.at(6, 5)[1] = -3.0f;
  b.at(7, 7)[2] = std::numeric_limits<float>::quiet_NaN();
  b.at(8, 7)[0] = std::numeric_limits<float>::infinity();
  const Image4f ab = flip_error_map(a, b), ba = flip_error_map(b, a);
  double mean = 0;
  for (std::size_t i = 0; i < ab.rgba.size(); i += 4) {
    ASSERT_TRUE(std::isfinite(ab.rgba[i]));
    ASSERT_GE(ab.rgba[i], 0.0f);
    ASSERT_LE(ab.rgba[i], 1.0f);
    ASSERT_NEAR(ab.rgba[i], ba.rgba[i], 1e-5);  // HyAB and the feature difference are symmetric
    mean += ab.rgba[i];
  }
  mean /= 33.0 * 21.0;
  EXPECT_GT(mean, 0.2);  // unrelated random images differ a lot
  // Clamping: a value of 7 is treated as 1 (LDR).
  Image4f c = random_image(12, 12, 5), d = c;
  for (std::size_t i = 0; i < d.rgba.size(); i += 4) d.rgba[i] = c.rgba[i] = 1.0f;
  for (std::size_t i = 0; i < d.rgba.size(); i += 4) d.rgba[i] = 7.0f;
  EXPECT_EQ(map_max(flip_error_map(d, c)), 0.0f);
}

TEST(Flip, MonotoneInPerturbationSize) {
  const Image4f ref = uniform(48, 48, 0.5f);
  std::mt19937 rng(6);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> noise(48 * 48);
  for (float& v : noise) v = u(rng);
  double prev = 0;
  for (const float k : {0.01f, 0.02f, 0.05f, 0.1f, 0.2f, 0.4f}) {
    Image4f t = ref;
    for (std::size_t i = 0; i < noise.size(); ++i)
      for (int c = 0; c < 3; ++c) t.rgba[i * 4 + c] += k * noise[i];
    const double f = compare_images(t, ref).flip_mean;
    EXPECT_GT(f, prev * 1.2) << "amplitude " << k;
    prev = f;
  }
}

TEST(Flip, FineCheckerboardFadesWithViewingDistance) {
  // A 1-pixel checkerboard (+-0.1 around 0.5) is filtered out by the CSF when pixels are small
  // (high ppd), but a uniform shift of the same amplitude does not depend on ppd.
  const uint32_t n = 64;
  const Image4f ref = uniform(n, n, 0.5f), shift = uniform(n, n, 0.6f);
  Image4f checker(n, n);
  for (uint32_t y = 0; y < n; ++y)
    for (uint32_t x = 0; x < n; ++x) {
      const float v = ((x + y) & 1) ? 0.6f : 0.4f;
      set_rgb(checker, x, y, v, v, v);
    }
  ErrorOptions o;
  double prev = 2.0;
  const double shift_expected = expected_ec(lstar(0.6) - lstar(0.5));
  for (const double ppd : {10.0, 30.0, 67.0}) {
    o.flip_ppd = ppd;
    const double c = compare_images(checker, ref, o).flip_mean;
    EXPECT_LT(c, prev * 0.5) << "ppd " << ppd;
    prev = c;
    EXPECT_NEAR(compare_images(shift, ref, o).flip_mean, shift_expected, 2e-4) << "ppd " << ppd;
  }
  EXPECT_LT(prev, 0.01);  // at 67 ppd a 1-px checkerboard is (nearly) invisible
  o.flip_ppd = 10.0;
  EXPECT_GT(compare_images(checker, ref, o).flip_mean, shift_expected);  // at 10 ppd it is clearly visible
}

TEST(Flip, BlueYellowHasTheWidestContrastSensitivityFilter) {
  // 1-pixel checkerboards around grey 0.5 along three colour directions, at 20 ppd, each relative to
  // the uniform shift along the same direction. The blue-yellow CSF (b up to 0.04 deg^2) is much wider
  // than the achromatic (0.0047) and red-green (0.0053) ones, so it removes the most of its pattern.
  const uint32_t n = 64;
  const auto pattern = [n](const float d[3], bool checker) {
    Image4f im(n, n);
    for (uint32_t y = 0; y < n; ++y)
      for (uint32_t x = 0; x < n; ++x) {
        const float s = (checker && ((x + y) & 1)) ? -1.0f : 1.0f;
        set_rgb(im, x, y, 0.5f + s * d[0], 0.5f + s * d[1], 0.5f + s * d[2]);
      }
    return im;
  };
  const float achromatic[3] = {0.1f, 0.1f, 0.1f}, red_green[3] = {0.1f, -0.1f, 0.0f},
              blue_yellow[3] = {0.05f, 0.05f, -0.15f};
  const Image4f ref = uniform(n, n, 0.5f);
  ErrorOptions o;
  o.flip_ppd = 20.0;
  const auto ratio = [&](const float d[3]) {
    return compare_images(pattern(d, true), ref, o).flip_mean / compare_images(pattern(d, false), ref, o).flip_mean;
  };
  const double ach = ratio(achromatic), rg = ratio(red_green), by = ratio(blue_yellow);
  EXPECT_LT(by, 0.75);
  EXPECT_LT(by, 0.7 * rg);
  EXPECT_LT(by, 0.7 * ach);
}

TEST(Flip, EdgesRaiseTheErrorAboveTheColourTerm) {
  // Reference uniform 0.5; test 0.6 on the right half. Far from the step the error is the uniform-shift
  // colour error; near the step the blurred colour difference is smaller, yet the feature (edge) term
  // raises the error above it. Without a feature term no pixel could exceed the uniform value.
  const uint32_t n = 64;
  const Image4f ref = uniform(n, n, 0.5f);
  Image4f test = ref;
  for (uint32_t y = 0; y < n; ++y)
    for (uint32_t x = n / 2; x < n; ++x) set_rgb(test, x, y, 0.6f, 0.6f, 0.6f);
  const Image4f map = flip_error_map(test, ref);
  const double uniform_err = expected_ec(lstar(0.6) - lstar(0.5));
  EXPECT_NEAR(map_at(map, n - 3, n / 2), uniform_err, 2e-3);  // far from the step
  EXPECT_LT(map_at(map, 10, n / 2), 1e-3);                    // far on the unchanged side
  EXPECT_GT(map_max(map), 1.3 * uniform_err);                 // near the step
  float best = 0;
  uint32_t best_x = 0;
  for (uint32_t x = 0; x < n; ++x)
    if (map_at(map, x, n / 2) > best) best = map_at(map, x, n / 2), best_x = x;
  EXPECT_GE(best_x, n / 2 - 1);
  EXPECT_LE(best_x, n / 2 + 3);
}

TEST(Flip, ThinLineIsWorseLocallyThanTheSameChangeSpreadOut) {
  // One column brightened by 0.5 vs the same total (mean) luminance change spread over the image as a
  // smooth low-frequency variation. The line's peak error is far higher. (The mean of FLIP is NOT higher
  // for the line: the power remap qc = 0.7 is concave, so spreading a change thinly over many pixels
  // raises the pooled mean; a check on the mean would fail for a correct FLIP.)
  const uint32_t n = 64;
  const Image4f ref = uniform(n, n, 0.5f);
  Image4f line = ref, spread = ref;
  for (uint32_t y = 0; y < n; ++y) set_rgb(line, n / 2, y, 1.0f, 1.0f, 1.0f);
  const double pi = std::acos(-1.0);
  for (uint32_t y = 0; y < n; ++y)
    for (uint32_t x = 0; x < n; ++x) {
      const double s = std::sin(2 * pi * x / n) * std::sin(2 * pi * y / n);
      const float v = 0.5f + 0.5f / n * float(1.0 + 0.5 * s);
      set_rgb(spread, x, y, v, v, v);
    }
  const Image4f ml = flip_error_map(line, ref), ms = flip_error_map(spread, ref);
  EXPECT_GT(map_max(ml), 0.3);
  EXPECT_LT(map_max(ms), 0.1);
  EXPECT_GT(map_max(ml), 5.0 * map_max(ms));
  // The error is concentrated around the line (CSF blur + feature support), symmetric left/right.
  EXPECT_NEAR(map_at(ml, n / 2 - 2, 10), map_at(ml, n / 2 + 2, 10), 1e-5);
  EXPECT_LT(map_at(ml, n / 2 - 12, 10), 1e-3);
}

TEST(Flip, MeanUsesOnlyMaskedPixels) {
  const uint32_t w = 80, h = 16;
  const Image4f ref = uniform(w, h, 0.5f);
  Image4f test = ref;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < 20; ++x) set_rgb(test, x, y, 0.8f, 0.2f, 0.5f);
  std::vector<uint8_t> left(w * h, 0), right(w * h, 0);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) (x < 20 ? left : right)[y * w + x] = x < 20 || x >= 50;
  const double all = compare_images(test, ref).flip_mean;
  const double l = compare_images(test, ref, ErrorOptions{}, &left).flip_mean;
  const double r = compare_images(test, ref, ErrorOptions{}, &right).flip_mean;
  EXPECT_GT(l, all);
  EXPECT_GT(all, 0.0);
  EXPECT_EQ(r, 0.0);  // 30+ pixels from the change: beyond every filter's reach
}

// A full 720p image runs through (its speed is measured by hp_bench_reference, not here).
TEST(Flip, HandlesA720pImage) {
  const Image4f a = random_image(1280, 720, 7);
  Image4f b = a;
  std::mt19937 rng(8);
  std::normal_distribution<float> g(0.0f, 0.05f);
  for (std::size_t i = 0; i < b.rgba.size(); i += 4)
    for (int c = 0; c < 3; ++c) b.rgba[i + c] += g(rng);
  const Image4f map = flip_error_map(b, a);
  ASSERT_EQ(map.width, 1280u);
  ASSERT_EQ(map.height, 720u);
  EXPECT_GT(map_max(map), 0.0f);
  EXPECT_LE(map_max(map), 1.0f);
}

}  // namespace
}  // namespace hp
