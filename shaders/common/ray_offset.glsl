// Ray origins that do not re-hit the surface they leave (mirrored in C++ by hp::offset_ray_origin).
#ifndef HP_RAY_OFFSET_GLSL
#define HP_RAY_OFFSET_GLSL

// Wächter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6:
// move the point a fixed number of ULPs along the normal (scale-independent), and by a tiny float offset
// where the coordinates are so close to 0 that ULPs are denormal-small.
vec3 hp_offset_robust(vec3 p, vec3 n) {
  const float origin = 1.0 / 32.0;
  const float float_scale = 1.0 / 65536.0;
  const float int_scale = 256.0;
  ivec3 of_i = ivec3(int_scale * n);
  vec3 p_i = vec3(intBitsToFloat(floatBitsToInt(p.x) + (p.x < 0.0 ? -of_i.x : of_i.x)),
                  intBitsToFloat(floatBitsToInt(p.y) + (p.y < 0.0 ? -of_i.y : of_i.y)),
                  intBitsToFloat(floatBitsToInt(p.z) + (p.z < 0.0 ? -of_i.z : of_i.z)));
  precise vec3 p_f = p + float_scale * n;
  return vec3(abs(p.x) < origin ? p_f.x : p_i.x, abs(p.y) < origin ? p_f.y : p_i.y,
              abs(p.z) < origin ? p_f.z : p_i.z);
}

// The study's offset: a fixed world-space distance along the normal (0.1 by default there).
vec3 hp_offset_bias(vec3 p, vec3 n, float bias) {
  precise vec3 q = p + bias * n;
  return q;
}

#endif
