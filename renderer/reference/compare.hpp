// A GPU frame against its CPU reference: image error metrics (image/metrics.hpp), shadow acne and
// leaks, and the world-position reconstruction error of the depth buffer, as one JSON object that the
// scenario runner stores under a cell's "error" key and the report turns into tables.
#pragma once

#include "image/image.hpp"
#include "image/metrics.hpp"
#include "reference/reference.hpp"
#include "view.hpp"

#include <nlohmann/json.hpp>

#include <vector>

namespace hp {

/// What the GPU frame produced, read back (Frame::read_color / read_aov / read_depth).
struct FrameReadback {
  Image4f color;
  Image4f shadow;            ///< shadow AOV (r: 1 lit, 0 shadowed); empty when the pass is off
  Image4f normal;            ///< normal AOV (rgb world normal, a 0 on background)
  std::vector<float> depth;  ///< raw depth-buffer values
  View view;                 ///< the GPU frame's matrices and eye
};

/// The GPU frame's world is the reference's world scaled by `scale` about the origin, then translated
/// (a scenario's "transform"): positions are compared relative to each one's camera, in reference units.
struct WorldTransform {
  double scale = 1.0;
  glm::dvec3 translate{0.0};
};

struct CompareOptions {
  ErrorOptions image;
  uint32_t depth_bins = 12;  ///< log-spaced over the foreground's distance range
  /// A foreground pixel whose reconstructed position is this far off (relative to its distance), or whose
  /// normal differs by more than acos(min_normal_dot), saw another surface than the reference: a coverage
  /// mismatch, left out of the acne/leak and depth statistics and counted on its own.
  double mismatch_rel = 0.05;
  double min_normal_dot = 0.95;
};

/// {"image": {...metrics...}, "shadow": {compared, acne, leaks, wrong = acne + leaks, coverage_mismatch} (when `gpu.shadow` is
/// not empty), "depth": {pixels, mean_rel, max_rel, bins: [{near, far, pixels, mean_rel, max_rel}]},
/// "coverage_mismatch": n}. Throws std::invalid_argument when the sizes differ. With `flip_map` and
/// o.image.flip, the per-pixel FLIP map is returned there too (computed once: its mean is flip_mean).
nlohmann::json compare_with_reference(const FrameReadback& gpu, const ReferenceImage& ref, const WorldTransform& t,
                                      const CompareOptions& o = {}, Image4f* flip_map = nullptr);

/// The metrics as JSON (PSNR of identical images, +inf, as null).
nlohmann::json to_json(const ErrorMetrics& m);

}  // namespace hp
