// The ray payload of the ray-tracing pipeline (driver_traversal.glsl, rt/hit.rchit, rt/miss.rmiss).
#ifndef HP_RT_PAYLOAD_GLSL
#define HP_RT_PAYLOAD_GLSL
struct HpPayload {
  int primitive;  // the committed triangle's instance custom index + primitive index, -1 = miss
  float t, u, v;
};
#endif
