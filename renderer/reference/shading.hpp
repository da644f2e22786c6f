// C++ twins of the GLSL shading the hybrid frame uses (shaders/common/brdf.glsl, sampling.glsl,
// ray_offset.glsl), so the CPU reference shades exactly the same model: any difference between a GPU
// frame and the reference is then the error of a shortcut (fewer rays, a bias, a reduced grid), not of
// a different BRDF.
#pragma once

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace hp::ref {

constexpr float kPi = 3.14159265358979f;

inline glm::vec3 fresnel_schlick(const glm::vec3& f0, float cos_theta) {
  const float m = std::clamp(1.0f - cos_theta, 0.0f, 1.0f);
  const float m2 = m * m;
  return f0 + (glm::vec3(1.0f) - f0) * (m2 * m2 * m);
}

/// Lambert diffuse + GGX specular (Smith height-correlated), radiance toward v from a directional light.
inline glm::vec3 shade_direct(const glm::vec3& n, const glm::vec3& v, const glm::vec3& l, const glm::vec3& albedo,
                              float metallic, float roughness, const glm::vec3& light) {
  const float ndl = glm::dot(n, l);
  if (ndl <= 0.0f) return glm::vec3(0.0f);
  const float ndv = std::max(glm::dot(n, v), 1e-4f);
  const glm::vec3 h = glm::normalize(l + v);
  const float ndh = std::max(glm::dot(n, h), 0.0f);
  const float vdh = std::max(glm::dot(v, h), 0.0f);
  const float a = std::max(roughness * roughness, 1e-3f);
  const float a2 = a * a;
  const float d = ndh * ndh * (a2 - 1.0f) + 1.0f;
  const float D = a2 / (kPi * d * d);
  const float gv = ndl * std::sqrt(ndv * ndv * (1.0f - a2) + a2);
  const float gl = ndv * std::sqrt(ndl * ndl * (1.0f - a2) + a2);
  const float V = 0.5f / std::max(gv + gl, 1e-6f);
  const glm::vec3 f0 = glm::mix(glm::vec3(0.04f), albedo, metallic);
  const glm::vec3 F = fresnel_schlick(f0, vdh);
  const glm::vec3 diffuse = (glm::vec3(1.0f) - F) * (1.0f - metallic) * albedo / kPi;
  return (diffuse + D * V * F) * light * ndl;
}

inline glm::vec3 shade_ambient_diffuse(const glm::vec3& n, const glm::vec3& v, const glm::vec3& albedo, float metallic,
                                       const glm::vec3& sky) {
  const glm::vec3 f0 = glm::mix(glm::vec3(0.04f), albedo, metallic);
  const glm::vec3 F = fresnel_schlick(f0, std::max(glm::dot(n, v), 0.0f));
  const float up = 0.5f + 0.5f * n.y;
  return sky * (0.25f + 0.25f * up) * (1.0f - metallic) * albedo * (glm::vec3(1.0f) - F);
}

inline glm::vec3 shade_ambient(const glm::vec3& n, const glm::vec3& v, const glm::vec3& albedo, float metallic,
                               const glm::vec3& sky) {
  const glm::vec3 f0 = glm::mix(glm::vec3(0.04f), albedo, metallic);
  const glm::vec3 F = fresnel_schlick(f0, std::max(glm::dot(n, v), 0.0f));
  const float up = 0.5f + 0.5f * n.y;
  return sky * (0.25f + 0.25f * up) * ((1.0f - metallic) * albedo * (glm::vec3(1.0f) - F) + 0.2f * F);
}

/// GGX half vector around n for alpha = roughness^2 (Walter et al. 2007), as hp_sample_ggx.
inline glm::vec3 sample_ggx(const glm::vec3& n, float roughness, glm::vec2 xi) {
  const float a = std::max(roughness * roughness, 1e-4f);
  const float phi = 2.0f * kPi * xi.x;
  const float cos_t = std::sqrt((1.0f - xi.y) / (1.0f + (a * a - 1.0f) * xi.y));
  const float sin_t = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
  const glm::vec3 up = std::abs(n.z) < 0.999f ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(1.0f, 0.0f, 0.0f);
  const glm::vec3 tx = glm::normalize(glm::cross(up, n));
  const glm::vec3 ty = glm::cross(n, tx);
  return glm::normalize(tx * (sin_t * std::cos(phi)) + ty * (sin_t * std::sin(phi)) + n * cos_t);
}

/// GLSL reflect(): i - 2 dot(n, i) n.
inline glm::vec3 reflect(const glm::vec3& i, const glm::vec3& n) { return i - 2.0f * glm::dot(n, i) * n; }

/// lowbias32 integer hash (as hp_hash).
inline uint32_t hash32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

/// Wächter & Binder's robust origin offset (Ray Tracing Gems ch. 6), as hp_offset_robust.
inline glm::vec3 offset_robust(const glm::vec3& p, const glm::vec3& n) {
  constexpr float kOrigin = 1.0f / 32.0f, kFloatScale = 1.0f / 65536.0f, kIntScale = 256.0f;
  glm::vec3 out;
  for (int i = 0; i < 3; ++i) {
    const int32_t of = int32_t(kIntScale * n[i]);
    int32_t bits;
    std::memcpy(&bits, &p[i], 4);
    bits += p[i] < 0.0f ? -of : of;
    float pi;
    std::memcpy(&pi, &bits, 4);
    const float pf = p[i] + kFloatScale * n[i];
    out[i] = std::abs(p[i]) < kOrigin ? pf : pi;
  }
  return out;
}

}  // namespace hp::ref
