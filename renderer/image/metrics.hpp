// Image error metrics between a test image and a reference image (host side, no Vulkan, no files).
//
// All metrics compare the RGB channels of two Image4f of the same size (alpha is ignored); values are
// linear floats as stored. A pixel is "compared" when the optional mask (width*height bytes, row-major,
// top row first, nonzero = compare) selects it, or always when there is no mask. With N the number of
// compared pixels whose six RGB values (test and reference) are all finite, and c over R, G, B:
//
//   mse      = 1/(3N) * sum_{p,c} (t - r)^2
//   relmse   = 1/(3N) * sum_{p,c} (t - r)^2 / (r^2 + eps)          eps = ErrorOptions::relmse_eps (0.01)
//              (relative MSE in the style of Rousselle et al.: the squared error is divided by the squared
//              reference value per channel, eps keeps dark pixels from dominating)
//   psnr_db  = 10 * log10(peak^2 / mse)                              peak = ErrorOptions::psnr_peak (1.0)
//              exactly the stated peak, NOT OpenImageIO's max(1, image peak); +infinity when mse == 0.
//              JSON cannot hold infinity: callers store a non-finite psnr_db as null.
//   max_abs  = max over compared pixels and channels of |t - r|      (+infinity if any compared pixel is
//              non-finite)
//   over_threshold = number of compared pixels whose max_c |t - r| > threshold (0.1), plus every
//              non-finite compared pixel
//   non_finite = number of compared pixels with a NaN or +-inf in any RGB channel of the test OR the
//              reference image. Such pixels are left out of mse / relmse / psnr (N counts finite pixels
//              only) but counted in over_threshold and make max_abs infinite.
//   When N == 0 (empty image, mask selects nothing, or every compared pixel is non-finite) mse, relmse
//   and psnr_db are NaN (stored as null by callers): there is nothing to average.
//   flip_mean = mean of the LDR-FLIP error map over the compared pixels (all of them, non-finite ones
//              included after the sanitising described below); -1 when not computed, NaN when no pixel
//              is compared.
//
// LDR-FLIP, implemented from the paper's description: P. Andersson, J. Nilsson, T. Akenine-Möller,
// M. Oskarsson, K. Åström, M. D. Fairchild, "FLIP: A Difference Evaluator for Alternating Images",
// Proc. ACM Comput. Graph. Interact. Tech. 3(2), 2020. Per image:
//   1. Inputs are linear RGB: NaN -> 0, then clamp to [0, 1] (LDR; +inf -> 1, -inf -> 0).
//   2. Linear sRGB (D65) -> XYZ -> YCxCz, with the white point = XYZ of RGB (1,1,1):
//        Y' = 116 Y/Yn - 16,  Cx = 500 (X/Xn - Y/Yn),  Cz = 200 (Y/Yn - Z/Zn).
//   3. Each channel is convolved with the spatial contrast sensitivity filter of the paper,
//        S(x) = a1 sqrt(pi/b1) exp(-pi^2 |x|^2 / b1) + a2 sqrt(pi/b2) exp(-pi^2 |x|^2 / b2),
//      |x| in degrees of visual angle (pixel offset / ppd), with (a1, b1, a2, b2) =
//        achromatic (1, 0.0047, 0, 1e-5), red-green (1, 0.0053, 0, 1e-5),
//        blue-yellow (34.1, 0.04, 13.5, 0.025);
//      the 2D kernel has radius r = ceil(3 sqrt(b_max / (2 pi^2)) ppd) pixels (b_max = 0.04, the widest
//      Gaussian, same radius for all channels) and is normalised to sum to 1.
//   4. Filtered YCxCz -> XYZ -> linear RGB, clamp to [0, 1], -> CIELAB (D65 white = XYZ of RGB (1,1,1)).
//   5. Hunt adjustment: a' = 0.01 L a, b' = 0.01 L b.  HyAB distance:
//        dE = |L1 - L2| + sqrt((a1' - a2')^2 + (b1' - b2')^2).
//   6. Colour error remap with qc = 0.7, pc = 0.4, pt = 0.95 and cmax = HyAB(Hunt(Lab(green)),
//      Hunt(Lab(blue)))^qc (green = linear (0,1,0), blue = (0,0,1)):
//        e = dE^qc;  Ec = pt / (pc cmax) * e                               if e < pc cmax
//                    Ec = pt + (e - pc cmax) / (cmax - pc cmax) * (1 - pt)  otherwise.
//   7. Features on the achromatic channel of the unfiltered (clamped) images, normalised to [0,1] as
//      (Y' + 16) / 116 = Y/Yn: edges = |(I * Gx, I * Gy)| with first derivatives of a Gaussian,
//      points = |(I * Gxx, I * Gyy)| with second derivatives, sigma = 0.5 * w * ppd pixels, w = 0.082 deg,
//      radius ceil(3 sigma); each derivative kernel is normalised so its positive weights sum to 1 and
//      its negative weights to -1 (the Gaussian factor along the other axis sums to 1).
//        Ef = ( max(| |edge_r| - |edge_t| |, | |point_r| - |point_t| |) / sqrt(2) )^qf,  qf = 0.5.
//   8. E = Ec^(1 - Ef).
// Simplifications / choices not fixed by the paper, stated honestly:
//   - Borders: convolutions replicate the edge pixels (clamp-to-edge addressing).
//   - Ec is additionally clamped to [0, 1] and Ef to [0, 1] (safety clamps; for in-gamut LDR input the
//     green-blue cmax already bounds the colour term in practice).
//   - Kernels are evaluated at pixel centres (no supersampling) and applied separably (exact for sums
//     of Gaussians, done as one separable pass per Gaussian term).
//   - Only LDR-FLIP; no HDR-FLIP exposure bracketing; no alpha handling; NaN/inf sanitised as in step 1.
//   - Computed in single precision floats.
#pragma once

#include "image/image.hpp"

#include <cstdint>
#include <limits>
#include <vector>

namespace hp {

struct ErrorOptions {
  double relmse_eps = 0.01;  ///< relative MSE epsilon in the denominator
  double psnr_peak = 1.0;    ///< PSNR peak (linear values); used as stated, NOT OpenImageIO's max(1, peak)
  double threshold = 0.1;    ///< a pixel is "over threshold" when its max abs channel error > threshold
  bool flip = true;          ///< compute FLIP (LDR-FLIP) too
  double flip_ppd = 67.0;    ///< pixels per degree of the FLIP observer (0.7 m from a 0.7 m-wide 4K monitor)
};

struct ErrorMetrics {
  uint64_t pixels = 0;          ///< pixels compared (the mask may exclude some), non-finite ones included
  uint64_t non_finite = 0;      ///< compared pixels with NaN/inf in an RGB channel of test or reference
  double mse = 0;               ///< over finite compared pixels; NaN when there are none
  double relmse = 0;            ///< over finite compared pixels; NaN when there are none
  double psnr_db = 0;           ///< +infinity when mse == 0; NaN when there are no finite pixels
  double max_abs = 0;           ///< +infinity when non_finite > 0
  uint64_t over_threshold = 0;  ///< includes every non-finite compared pixel
  double flip_mean = -1;        ///< mean LDR-FLIP error over compared pixels; -1 when not computed,
                                ///< NaN when FLIP was asked for but no pixel is compared
  // Echo of the options used, so a report can state them.
  double relmse_eps = 0.01;
  double psnr_peak = 1.0;
  double threshold = 0.1;
  double flip_ppd = 67.0;
};

/// Compares RGB (alpha ignored) of `test` against `reference`. Throws std::invalid_argument naming both
/// sizes when they differ, or when `mask` is given and its size is not width*height.
/// `mask` (optional, width*height bytes, nonzero = compare) restricts the pixels.
ErrorMetrics compare_images(const Image4f& test, const Image4f& reference, const ErrorOptions& o = {},
                            const std::vector<uint8_t>* mask = nullptr);

/// The per-pixel LDR-FLIP error map (r = g = b = error in [0, 1], a = 1). Same size check as above.
Image4f flip_error_map(const Image4f& test, const Image4f& reference, double ppd = 67.0);

}  // namespace hp
