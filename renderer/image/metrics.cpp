// Image error metrics; see metrics.hpp for the formulas and the LDR-FLIP pipeline.
#include "image/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace hp {

namespace {

std::string size_text(const Image4f& im) { return std::to_string(im.width) + "x" + std::to_string(im.height); }

void check_sizes(const Image4f& test, const Image4f& reference, const char* what) {
  if (test.width != reference.width || test.height != reference.height) {
    throw std::invalid_argument(std::string(what) + ": test image is " + size_text(test) + " but reference image is " +
                                size_text(reference));
  }
  const std::size_t n = std::size_t(test.width) * test.height * 4;
  if (test.rgba.size() != n || reference.rgba.size() != n) {
    throw std::invalid_argument(std::string(what) + ": pixel buffer does not match the stated size (" +
                                size_text(test) + " / " + size_text(reference) + ")");
  }
}

// ---------------------------------------------------------------------------------------------------
// Planes and separable convolution with clamp-to-edge addressing.

struct Plane {
  int w = 0, h = 0;
  std::vector<float> v;
  Plane() = default;
  Plane(int w_, int h_) : w(w_), h(h_), v(std::size_t(w_) * h_, 0.0f) {}
  float* row(int y) { return &v[std::size_t(y) * w]; }
  const float* row(int y) const { return &v[std::size_t(y) * w]; }
};

using Kernel = std::vector<float>;  // odd length 2r+1, centred

// out(x, y) = sum_k k[k] * in(clamp(x + k - r), y)
void convolve_rows(const Plane& in, Plane& out, const Kernel& k) {
  const int r = int(k.size() / 2);
  out = Plane(in.w, in.h);
  std::vector<float> padded(std::size_t(in.w) + 2 * r);
  for (int y = 0; y < in.h; ++y) {
    const float* src = in.row(y);
    for (int i = 0; i < r; ++i) {
      padded[i] = src[0];
      padded[std::size_t(r) + in.w + i] = src[in.w - 1];
    }
    std::copy(src, src + in.w, padded.begin() + r);
    float* dst = out.row(y);
    for (int x = 0; x < in.w; ++x) {
      const float* p = &padded[x];
      float s = 0.0f;
      for (std::size_t i = 0; i < k.size(); ++i) s += k[i] * p[i];
      dst[x] = s;
    }
  }
}

// out(x, y) = sum_k k[k] * in(x, clamp(y + k - r))
void convolve_cols(const Plane& in, Plane& out, const Kernel& k) {
  const int r = int(k.size() / 2);
  out = Plane(in.w, in.h);
  for (int y = 0; y < in.h; ++y) {
    float* dst = out.row(y);
    for (std::size_t i = 0; i < k.size(); ++i) {
      const int sy = std::clamp(y + int(i) - r, 0, in.h - 1);
      const float* src = in.row(sy);
      const float wgt = k[i];
      for (int x = 0; x < in.w; ++x) dst[x] += wgt * src[x];
    }
  }
}

Plane convolve_separable(const Plane& in, const Kernel& kx, const Kernel& ky) {
  Plane tmp, out;
  convolve_rows(in, tmp, kx);
  convolve_cols(tmp, out, ky);
  return out;
}

// ---------------------------------------------------------------------------------------------------
// Colour spaces.

// Linear sRGB (D65) -> XYZ.
constexpr double kRgbToXyz[3][3] = {{0.4124564, 0.3575761, 0.1804375},
                                    {0.2126729, 0.7151522, 0.0721750},
                                    {0.0193339, 0.1191920, 0.9503041}};
// XYZ -> linear sRGB (the inverse of the matrix above).
constexpr double kXyzToRgb[3][3] = {{3.2404542, -1.5371385, -0.4985314},
                                    {-0.9692660, 1.8760108, 0.0415560},
                                    {0.0556434, -0.2040259, 1.0572252}};
// White point: XYZ of linear RGB (1, 1, 1).
constexpr double kXn = 0.4124564 + 0.3575761 + 0.1804375;
constexpr double kYn = 0.2126729 + 0.7151522 + 0.0721750;
constexpr double kZn = 0.0193339 + 0.1191920 + 0.9503041;

struct Vec3 {
  float x, y, z;
};

Vec3 rgb_to_xyz(Vec3 c) {
  return {float(kRgbToXyz[0][0] * c.x + kRgbToXyz[0][1] * c.y + kRgbToXyz[0][2] * c.z),
          float(kRgbToXyz[1][0] * c.x + kRgbToXyz[1][1] * c.y + kRgbToXyz[1][2] * c.z),
          float(kRgbToXyz[2][0] * c.x + kRgbToXyz[2][1] * c.y + kRgbToXyz[2][2] * c.z)};
}

Vec3 xyz_to_rgb(Vec3 c) {
  return {float(kXyzToRgb[0][0] * c.x + kXyzToRgb[0][1] * c.y + kXyzToRgb[0][2] * c.z),
          float(kXyzToRgb[1][0] * c.x + kXyzToRgb[1][1] * c.y + kXyzToRgb[1][2] * c.z),
          float(kXyzToRgb[2][0] * c.x + kXyzToRgb[2][1] * c.y + kXyzToRgb[2][2] * c.z)};
}

Vec3 xyz_to_ycxcz(Vec3 c) {
  const double xr = c.x / kXn, yr = c.y / kYn, zr = c.z / kZn;
  return {float(116.0 * yr - 16.0), float(500.0 * (xr - yr)), float(200.0 * (yr - zr))};
}

Vec3 ycxcz_to_xyz(Vec3 c) {
  const double yr = (c.x + 16.0) / 116.0;
  const double xr = c.y / 500.0 + yr;
  const double zr = yr - c.z / 200.0;
  return {float(xr * kXn), float(yr * kYn), float(zr * kZn)};
}

double lab_f(double t) {
  constexpr double d = 6.0 / 29.0;
  return t > d * d * d ? std::cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0;
}

Vec3 xyz_to_lab(Vec3 c) {
  const double fx = lab_f(c.x / kXn), fy = lab_f(c.y / kYn), fz = lab_f(c.z / kZn);
  return {float(116.0 * fy - 16.0), float(500.0 * (fx - fy)), float(200.0 * (fy - fz))};
}

Vec3 hunt(Vec3 lab) { return {lab.x, 0.01f * lab.x * lab.y, 0.01f * lab.x * lab.z}; }

double hyab(Vec3 a, Vec3 b) {
  const double dl = double(a.x) - b.x, da = double(a.y) - b.y, db = double(a.z) - b.z;
  return std::abs(dl) + std::sqrt(da * da + db * db);
}

float sanitize(float v) {
  if (std::isnan(v)) return 0.0f;
  return std::clamp(v, 0.0f, 1.0f);
}

// ---------------------------------------------------------------------------------------------------
// FLIP constants (paper).

constexpr double kQc = 0.7, kPc = 0.4, kPt = 0.95, kQf = 0.5, kFeatureW = 0.082;

struct CsfParams {
  double a1, b1, a2, b2;
};
constexpr CsfParams kCsf[3] = {{1.0, 0.0047, 0.0, 1e-5},    // achromatic
                               {1.0, 0.0053, 0.0, 1e-5},    // red-green
                               {34.1, 0.04, 13.5, 0.025}};  // blue-yellow

// Spatial CSF filtering of one YCxCz channel: sum of (up to) two separable Gaussians, 2D kernel
// normalised to sum 1.
Plane csf_filter(const Plane& in, const CsfParams& p, double ppd, int radius) {
  const double pi = std::numbers::pi;
  const double as[2] = {p.a1, p.a2}, bs[2] = {p.b1, p.b2};
  std::vector<double> g[2];
  double weight[2] = {0, 0}, total = 0;
  for (int j = 0; j < 2; ++j) {
    if (as[j] == 0.0) continue;
    g[j].resize(std::size_t(2 * radius + 1));
    double s = 0;
    for (int i = -radius; i <= radius; ++i) {
      const double xd = i / ppd;  // degrees
      g[j][std::size_t(i + radius)] = std::exp(-pi * pi * xd * xd / bs[j]);
      s += g[j][std::size_t(i + radius)];
    }
    weight[j] = as[j] * std::sqrt(pi / bs[j]);
    total += weight[j] * s * s;  // sum of the 2D kernel g(x) g(y) weighted
  }
  Plane out(in.w, in.h);
  for (int j = 0; j < 2; ++j) {
    if (g[j].empty()) continue;
    Kernel kx(g[j].size()), ky(g[j].size());
    for (std::size_t i = 0; i < g[j].size(); ++i) {
      kx[i] = float(g[j][i] * weight[j] / total);
      ky[i] = float(g[j][i]);
    }
    const Plane part = convolve_separable(in, kx, ky);
    for (std::size_t i = 0; i < out.v.size(); ++i) out.v[i] += part.v[i];
  }
  return out;
}

// Normalise so positive weights sum to 1 and negative weights to -1.
Kernel normalise_signed(const std::vector<double>& k) {
  double pos = 0, neg = 0;
  for (double v : k) (v > 0 ? pos : neg) += v;
  Kernel out(k.size());
  for (std::size_t i = 0; i < k.size(); ++i) {
    const double v = k[i];
    out[i] = float(v > 0 ? v / pos : (v < 0 ? v / -neg : 0.0));
  }
  return out;
}

struct FeatureKernels {
  Kernel g, d1, d2;
};

FeatureKernels feature_kernels(double ppd) {
  const double sigma = 0.5 * kFeatureW * ppd;
  const int radius = int(std::ceil(3.0 * sigma));
  std::vector<double> g(std::size_t(2 * radius + 1)), d1(g.size()), d2(g.size());
  double gs = 0;
  for (int i = -radius; i <= radius; ++i) {
    const double x = i;
    const double gv = std::exp(-x * x / (2.0 * sigma * sigma));
    g[std::size_t(i + radius)] = gv;
    d1[std::size_t(i + radius)] = -x * gv;                               // ~ first derivative
    d2[std::size_t(i + radius)] = (x * x / (sigma * sigma) - 1.0) * gv;  // ~ second derivative
    gs += gv;
  }
  FeatureKernels fk;
  fk.g.resize(g.size());
  for (std::size_t i = 0; i < g.size(); ++i) fk.g[i] = float(g[i] / gs);
  fk.d1 = normalise_signed(d1);
  fk.d2 = normalise_signed(d2);
  return fk;
}

struct FlipPrep {
  Plane lab[3];  // Hunt-adjusted L, a', b'
  Plane edge, point;
};

FlipPrep flip_prepare(const Image4f& im, double ppd, int csf_radius, const FeatureKernels& fk) {
  const int w = int(im.width), h = int(im.height);
  const std::size_t n = std::size_t(w) * h;
  Plane ycc[3] = {Plane(w, h), Plane(w, h), Plane(w, h)};
  Plane ynorm(w, h);
  for (std::size_t i = 0; i < n; ++i) {
    const float* p = &im.rgba[i * 4];
    const Vec3 c = xyz_to_ycxcz(rgb_to_xyz({sanitize(p[0]), sanitize(p[1]), sanitize(p[2])}));
    ycc[0].v[i] = c.x;
    ycc[1].v[i] = c.y;
    ycc[2].v[i] = c.z;
    ynorm.v[i] = (c.x + 16.0f) / 116.0f;
  }
  FlipPrep out;
  Plane filt[3];
  for (int c = 0; c < 3; ++c) filt[c] = csf_filter(ycc[c], kCsf[c], ppd, csf_radius);
  for (int c = 0; c < 3; ++c) out.lab[c] = Plane(w, h);
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 rgb = xyz_to_rgb(ycxcz_to_xyz({filt[0].v[i], filt[1].v[i], filt[2].v[i]}));
    rgb = {std::clamp(rgb.x, 0.0f, 1.0f), std::clamp(rgb.y, 0.0f, 1.0f), std::clamp(rgb.z, 0.0f, 1.0f)};
    const Vec3 lab = hunt(xyz_to_lab(rgb_to_xyz(rgb)));
    out.lab[0].v[i] = lab.x;
    out.lab[1].v[i] = lab.y;
    out.lab[2].v[i] = lab.z;
  }
  // Features on the unfiltered normalised luminance.
  Plane rows_g, rows_d1, rows_d2;
  convolve_rows(ynorm, rows_g, fk.g);
  convolve_rows(ynorm, rows_d1, fk.d1);
  convolve_rows(ynorm, rows_d2, fk.d2);
  Plane gx, gy, gxx, gyy;
  convolve_cols(rows_d1, gx, fk.g);
  convolve_cols(rows_g, gy, fk.d1);
  convolve_cols(rows_d2, gxx, fk.g);
  convolve_cols(rows_g, gyy, fk.d2);
  out.edge = Plane(w, h);
  out.point = Plane(w, h);
  for (std::size_t i = 0; i < n; ++i) {
    out.edge.v[i] = std::hypot(gx.v[i], gy.v[i]);
    out.point.v[i] = std::hypot(gxx.v[i], gyy.v[i]);
  }
  return out;
}

// Per-pixel FLIP errors, row-major.
std::vector<float> flip_errors(const Image4f& test, const Image4f& reference, double ppd) {
  if (!(ppd > 0.0) || !std::isfinite(ppd)) {
    throw std::invalid_argument("FLIP: pixels per degree must be positive and finite, got " + std::to_string(ppd));
  }
  const std::size_t n = std::size_t(test.width) * test.height;
  if (n == 0) return {};
  double bmax = 0;
  for (const CsfParams& p : kCsf) bmax = std::max({bmax, p.b1, p.a2 != 0.0 ? p.b2 : 0.0});
  const double pi = std::numbers::pi;
  const int csf_radius = int(std::ceil(3.0 * std::sqrt(bmax / (2.0 * pi * pi)) * ppd));
  const FeatureKernels fk = feature_kernels(ppd);

  const FlipPrep t = flip_prepare(test, ppd, csf_radius, fk);
  const FlipPrep r = flip_prepare(reference, ppd, csf_radius, fk);

  const Vec3 green = hunt(xyz_to_lab(rgb_to_xyz({0.0f, 1.0f, 0.0f})));
  const Vec3 blue = hunt(xyz_to_lab(rgb_to_xyz({0.0f, 0.0f, 1.0f})));
  const double cmax = std::pow(hyab(green, blue), kQc);
  const double knee = kPc * cmax;

  std::vector<float> err(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double de =
        std::pow(hyab({t.lab[0].v[i], t.lab[1].v[i], t.lab[2].v[i]}, {r.lab[0].v[i], r.lab[1].v[i], r.lab[2].v[i]}),
                 kQc);
    double ec = de < knee ? kPt / knee * de : kPt + (de - knee) / (cmax - knee) * (1.0 - kPt);
    ec = std::clamp(ec, 0.0, 1.0);
    const double fe = std::abs(double(r.edge.v[i]) - t.edge.v[i]);
    const double fp = std::abs(double(r.point.v[i]) - t.point.v[i]);
    const double ef = std::clamp(std::pow(std::max(fe, fp) / std::numbers::sqrt2, kQf), 0.0, 1.0);
    err[i] = float(std::pow(ec, 1.0 - ef));
  }
  return err;
}

}  // namespace

Image4f flip_error_map(const Image4f& test, const Image4f& reference, double ppd) {
  check_sizes(test, reference, "flip_error_map");
  const std::vector<float> err = flip_errors(test, reference, ppd);
  Image4f out(test.width, test.height);
  for (std::size_t i = 0; i < err.size(); ++i) {
    float* p = &out.rgba[i * 4];
    p[0] = p[1] = p[2] = err[i];
    p[3] = 1.0f;
  }
  return out;
}

ErrorMetrics compare_images(const Image4f& test, const Image4f& reference, const ErrorOptions& o,
                            const std::vector<uint8_t>* mask) {
  check_sizes(test, reference, "compare_images");
  const std::size_t n = std::size_t(test.width) * test.height;
  if (mask && mask->size() != n) {
    throw std::invalid_argument("compare_images: mask has " + std::to_string(mask->size()) +
                                " entries but the images are " + size_text(test) + " (" + std::to_string(n) +
                                " pixels)");
  }
  ErrorMetrics m;
  m.relmse_eps = o.relmse_eps;
  m.psnr_peak = o.psnr_peak;
  m.threshold = o.threshold;
  m.flip_ppd = o.flip_ppd;

  double sum_sq = 0, sum_rel = 0, max_abs = 0;
  uint64_t finite = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (mask && (*mask)[i] == 0) continue;
    ++m.pixels;
    const float* t = &test.rgba[i * 4];
    const float* r = &reference.rgba[i * 4];
    bool ok = true;
    for (int c = 0; c < 3; ++c) ok = ok && std::isfinite(t[c]) && std::isfinite(r[c]);
    if (!ok) {
      ++m.non_finite;
      ++m.over_threshold;
      max_abs = std::numeric_limits<double>::infinity();
      continue;
    }
    ++finite;
    double pixel_max = 0;
    for (int c = 0; c < 3; ++c) {
      const double d = double(t[c]) - double(r[c]);
      const double rr = double(r[c]);
      sum_sq += d * d;
      sum_rel += d * d / (rr * rr + o.relmse_eps);
      pixel_max = std::max(pixel_max, std::abs(d));
    }
    if (pixel_max > o.threshold) ++m.over_threshold;
    max_abs = std::max(max_abs, pixel_max);
  }
  m.max_abs = max_abs;
  if (finite == 0) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    m.mse = m.relmse = m.psnr_db = nan;
  } else {
    m.mse = sum_sq / (3.0 * double(finite));
    m.relmse = sum_rel / (3.0 * double(finite));
    m.psnr_db =
        m.mse == 0.0 ? std::numeric_limits<double>::infinity() : 10.0 * std::log10(o.psnr_peak * o.psnr_peak / m.mse);
  }

  if (o.flip) {
    if (m.pixels == 0) {
      m.flip_mean = std::numeric_limits<double>::quiet_NaN();
    } else {
      const std::vector<float> err = flip_errors(test, reference, o.flip_ppd);
      double s = 0;
      for (std::size_t i = 0; i < n; ++i) {
        if (mask && (*mask)[i] == 0) continue;
        s += err[i];
      }
      m.flip_mean = s / double(m.pixels);
    }
  }
  return m;
}

}  // namespace hp
