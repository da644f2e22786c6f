#include "reference/compare.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hp {

using json = nlohmann::json;

json to_json(const ErrorMetrics& m) {
  json j;
  j["pixels"] = m.pixels;
  j["mse"] = m.mse;
  j["relmse"] = m.relmse;
  j["relmse_eps"] = m.relmse_eps;
  j["psnr_db"] = std::isfinite(m.psnr_db) ? json(m.psnr_db) : json(nullptr);
  j["psnr_peak"] = m.psnr_peak;
  j["max_abs"] = std::isfinite(m.max_abs) ? json(m.max_abs) : json(nullptr);
  j["over_threshold"] = m.over_threshold;
  j["threshold"] = m.threshold;
  j["non_finite"] = m.non_finite;
  if (m.flip_mean >= 0.0) j["flip_mean"] = m.flip_mean;
  return j;
}

json compare_with_reference(const FrameReadback& gpu, const ReferenceImage& ref, const WorldTransform& t,
                            const CompareOptions& o, Image4f* flip_map) {
  const uint32_t w = ref.color.width, h = ref.color.height;
  const auto same = [&](const Image4f& im) { return im.width == w && im.height == h; };
  if (!same(gpu.color) || !same(gpu.normal) || gpu.depth.size() != size_t(w) * h ||
      (!gpu.shadow.rgba.empty() && !same(gpu.shadow))) {
    throw std::invalid_argument("compare_with_reference: the frame is " + std::to_string(gpu.color.width) + "x" +
                                std::to_string(gpu.color.height) + ", the reference " + std::to_string(w) + "x" +
                                std::to_string(h));
  }
  json out;
  if (flip_map && o.image.flip) {
    *flip_map = flip_error_map(gpu.color, ref.color, o.image.flip_ppd);
    ErrorOptions without = o.image;
    without.flip = false;
    ErrorMetrics m = compare_images(gpu.color, ref.color, without);
    double sum = 0.0;
    for (size_t i = 0; i < flip_map->rgba.size(); i += 4) sum += flip_map->rgba[i];
    m.flip_mean = flip_map->rgba.empty() ? 0.0 : sum / double(flip_map->rgba.size() / 4);
    out["image"] = to_json(m);
  } else {
    out["image"] = to_json(compare_images(gpu.color, ref.color, o.image));
  }

  const float far_depth = gpu.view.far_depth();
  const glm::dvec3 cam(gpu.view.eye);
  struct Sample {
    double dist, rel;
  };
  std::vector<Sample> samples;
  samples.reserve(size_t(w) * h);
  uint64_t mismatch = 0, compared = 0, acne = 0, leaks = 0;
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      const float depth = gpu.depth[size_t(y) * w + x];
      const bool gpu_fg = depth != far_depth;
      const bool ref_fg = ref.position.at(x, y)[3] > 0.5f;
      if (!gpu_fg && !ref_fg) continue;
      if (gpu_fg != ref_fg) {
        ++mismatch;
        continue;
      }
      // The GPU's reconstruction (hp_world_position, float), relative to its camera, in reference units.
      const glm::vec3 p = unproject(gpu.view, float(x), float(y), w, h, depth);
      const glm::dvec3 rel_gpu = (glm::dvec3(p) - cam) / t.scale;
      const float* rp = ref.position.at(x, y);
      const glm::dvec3 rel_ref(rp[0], rp[1], rp[2]);
      const double dist = glm::length(rel_ref);
      const double rel = dist > 0.0 ? glm::length(rel_gpu - rel_ref) / dist : 0.0;
      const float* gn = gpu.normal.at(x, y);
      const float* rn = ref.shading.at(x, y);
      const double ndot = double(gn[0]) * rn[1] + double(gn[1]) * rn[2] + double(gn[2]) * rn[3];
      if (!(rel <= o.mismatch_rel) || !(ndot >= o.min_normal_dot)) {
        ++mismatch;
        continue;
      }
      samples.push_back({dist, rel});
      if (!gpu.shadow.rgba.empty()) {
        ++compared;
        const bool gpu_lit = gpu.shadow.at(x, y)[0] > 0.5f;
        const bool ref_lit = rn[0] > 0.5f;
        if (!gpu_lit && ref_lit) ++acne;
        if (gpu_lit && !ref_lit) ++leaks;
      }
    }
  }
  out["coverage_mismatch"] = mismatch;
  if (!gpu.shadow.rgba.empty()) {
    out["shadow"] = {{"compared", compared},
                     {"acne", acne},
                     {"leaks", leaks},
                     {"wrong", acne + leaks},
                     {"coverage_mismatch", mismatch}};
  }

  json depth;
  depth["pixels"] = samples.size();
  if (!samples.empty()) {
    double lo = samples[0].dist, hi = lo, sum = 0.0, mx = 0.0;
    for (const Sample& s : samples) {
      lo = std::min(lo, s.dist);
      hi = std::max(hi, s.dist);
      sum += s.rel;
      mx = std::max(mx, s.rel);
    }
    depth["mean_rel"] = sum / double(samples.size());
    depth["max_rel"] = mx;
    const uint32_t nb = std::max(1u, o.depth_bins);
    const double llo = std::log(lo), lhi = std::log(hi) + 1e-12;
    std::vector<double> bsum(nb, 0.0), bmax(nb, 0.0);
    std::vector<uint64_t> bn(nb, 0);
    for (const Sample& s : samples) {
      const uint32_t b = std::min(nb - 1, uint32_t((std::log(s.dist) - llo) / (lhi - llo) * nb));
      bsum[b] += s.rel;
      bmax[b] = std::max(bmax[b], s.rel);
      ++bn[b];
    }
    json bins = json::array();
    for (uint32_t b = 0; b < nb; ++b) {
      if (bn[b] == 0) continue;
      bins.push_back({{"near", std::exp(llo + (lhi - llo) * b / nb)},
                      {"far", std::exp(llo + (lhi - llo) * (b + 1) / nb)},
                      {"pixels", bn[b]},
                      {"mean_rel", bsum[b] / double(bn[b])},
                      {"max_rel", bmax[b]}});
    }
    depth["bins"] = bins;
  }
  out["depth"] = depth;
  return out;
}

}  // namespace hp
