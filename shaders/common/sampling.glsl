// Random numbers and GGX sampling for the reflection jitter.
#ifndef HP_SAMPLING_GLSL
#define HP_SAMPLING_GLSL

const float HP_PI_S = 3.14159265358979;

// Radical inverse in base 2 and 3: the first two dimensions of the Halton sequence.
float hp_halton2(uint i) { return float(bitfieldReverse(i)) * 2.3283064365386963e-10; }
float hp_halton3(uint i) {
  float f = 1.0, r = 0.0;
  while (i > 0u) {
    f /= 3.0;
    r += f * float(i % 3u);
    i /= 3u;
  }
  return r;
}

// A 32-bit integer hash (lowbias32, Chris Wellons' published constants) for per-pixel decorrelation.
uint hp_hash(uint x) {
  x ^= x >> 16; x *= 0x7feb352du;
  x ^= x >> 15; x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

// Visible-normal-free GGX half-vector sampling around n (Walter et al. 2007): h has the GGX normal
// distribution with alpha = roughness^2.
vec3 hp_sample_ggx(vec3 n, float roughness, vec2 xi) {
  float a = max(roughness * roughness, 1e-4);
  float phi = 2.0 * HP_PI_S * xi.x;
  float cos_t = sqrt((1.0 - xi.y) / (1.0 + (a * a - 1.0) * xi.y));
  float sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
  vec3 up = abs(n.z) < 0.999 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0);
  vec3 tx = normalize(cross(up, n));
  vec3 ty = cross(n, tx);
  precise vec3 h = normalize(tx * (sin_t * cos(phi)) + ty * (sin_t * sin(phi)) + n * cos_t);
  return h;
}

#endif
