// Direct lighting shared by the composite and the reflection hit shading: Lambert diffuse + GGX
// specular (Smith height-correlated visibility, Schlick Fresnel), metallic-roughness parametrisation.
#ifndef HP_BRDF_GLSL
#define HP_BRDF_GLSL

const float HP_PI = 3.14159265358979;

vec3 fresnel_schlick(vec3 f0, float cos_theta) {
  float m = clamp(1.0 - cos_theta, 0.0, 1.0);
  float m2 = m * m;
  return f0 + (1.0 - f0) * (m2 * m2 * m);
}

// Radiance reflected toward `v` from a directional light of radiance `light` arriving from `l`.
vec3 shade_direct(vec3 n, vec3 v, vec3 l, vec3 albedo, float metallic, float roughness, vec3 light) {
  float ndl = dot(n, l);
  if (ndl <= 0.0) return vec3(0.0);
  float ndv = max(dot(n, v), 1e-4);
  vec3 h = normalize(l + v);
  float ndh = max(dot(n, h), 0.0);
  float vdh = max(dot(v, h), 0.0);
  float a = max(roughness * roughness, 1e-3);
  float a2 = a * a;
  float d = ndh * ndh * (a2 - 1.0) + 1.0;
  float D = a2 / (HP_PI * d * d);
  float gv = ndl * sqrt(ndv * ndv * (1.0 - a2) + a2);
  float gl = ndv * sqrt(ndl * ndl * (1.0 - a2) + a2);
  float V = 0.5 / max(gv + gl, 1e-6);
  vec3 f0 = mix(vec3(0.04), albedo, metallic);
  vec3 F = fresnel_schlick(f0, vdh);
  vec3 diffuse = (1.0 - F) * (1.0 - metallic) * albedo / HP_PI;
  return (diffuse + D * V * F) * light * ndl;
}

// The diffuse half of the ambient term (where a traced reflection provides the specular half).
vec3 shade_ambient_diffuse(vec3 n, vec3 v, vec3 albedo, float metallic, vec3 sky) {
  vec3 f0 = mix(vec3(0.04), albedo, metallic);
  vec3 F = fresnel_schlick(f0, max(dot(n, v), 0.0));
  float up = 0.5 + 0.5 * n.y;
  return sky * (0.25 + 0.25 * up) * (1.0 - metallic) * albedo * (1.0 - F);
}

// A crude constant-sky ambient term so that unlit sides are not black (no GI in this renderer).
vec3 shade_ambient(vec3 n, vec3 v, vec3 albedo, float metallic, vec3 sky) {
  vec3 f0 = mix(vec3(0.04), albedo, metallic);
  vec3 F = fresnel_schlick(f0, max(dot(n, v), 0.0));
  float up = 0.5 + 0.5 * n.y;
  return sky * (0.25 + 0.25 * up) * ((1.0 - metallic) * albedo * (1.0 - F) + 0.2 * F);
}

#endif
