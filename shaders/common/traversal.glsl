// The one BVH traversal every pass uses. It mirrors renderer/bvh/traverse.cpp operation for operation
// (see the semantics there): Williams slab test with NaN-discarding comparisons and Ize's widened far
// bound, Woop-Benthin-Wald watertight triangle test with a double-precision fallback on exact zeros,
// front-to-back order by split axis, t-max pruning, a fixed stack of HP_BVH_STACK_SIZE entries.
// `precise` forbids the contraction into FMAs that the C++ side turns off with -ffp-contract=off.
#ifndef HP_TRAVERSAL_GLSL
#define HP_TRAVERSAL_GLSL

#extension GL_EXT_shader_explicit_arithmetic_types_float64 : require

#include "common/rt_bindings.glsl"

// 1 + 2 gamma(3) and 1 - 2 gamma(3), eps = 2^-24, rounded away from 1 (as the C++ constants).
const float HP_FAR_UP = 1.0000004768371582;    // 1 + 4 ulp
const float HP_FAR_DOWN = 0.99999958276748657;  // 1 - 7 ulp(below 1)

struct HpRay {
  vec3 org;
  vec3 inv;
  ivec3 neg;    // 1 where the reciprocal direction is negative (its sign bit, so -0 counts as negative)
  float tmin, tmax;
  int kx, ky, kz;
  float sx, sy, sz;
};

struct HpHit {
  int slot;     // leaf-order triangle slot, -1 = miss
  float t, u, v;
};

struct HpStats {
  uint nodes;
  uint tris;
};

bool hp_prepare(vec3 org, vec3 dir, float tmin, float tmax, out HpRay r) {
  r.org = org; r.inv = vec3(0.0); r.neg = ivec3(0); r.tmin = tmin; r.tmax = tmax;
  r.kx = 0; r.ky = 1; r.kz = 2; r.sx = 0.0; r.sy = 0.0; r.sz = 0.0;
  if (any(isnan(org)) || any(isinf(org)) || any(isnan(dir)) || any(isinf(dir)) || isnan(tmin) || isnan(tmax))
    return false;
  if (dir == vec3(0.0)) return false;
  precise vec3 inv = vec3(1.0) / dir;
  r.inv = inv;
  r.neg = ivec3(floatBitsToUint(inv.x) >> 31, floatBitsToUint(inv.y) >> 31, floatBitsToUint(inv.z) >> 31);
  vec3 ad = abs(dir);
  r.kz = ad.x >= ad.y ? (ad.x >= ad.z ? 0 : 2) : (ad.y >= ad.z ? 1 : 2);
  r.kx = (r.kz + 1) % 3;
  r.ky = (r.kx + 1) % 3;
  if (dir[r.kz] < 0.0) { int tmp = r.kx; r.kx = r.ky; r.ky = tmp; }
  precise float sx = dir[r.kx] / dir[r.kz];
  precise float sy = dir[r.ky] / dir[r.kz];
  precise float sz = 1.0 / dir[r.kz];
  r.sx = sx; r.sy = sy; r.sz = sz;
  return true;
}

float hp_widen_far(float t) { return t >= 0.0 ? t * HP_FAR_UP : t * HP_FAR_DOWN; }

bool hp_slab(HpRay r, vec3 bmin, vec3 bmax, float t_hi) {
  float tn = r.tmin;
  float tf = 1.0 / 0.0;
  for (int a = 0; a < 3; ++a) {
    float near_plane = r.neg[a] != 0 ? bmax[a] : bmin[a];
    float far_plane = r.neg[a] != 0 ? bmin[a] : bmax[a];
    precise float t0 = (near_plane - r.org[a]) * r.inv[a];
    precise float t1 = (far_plane - r.org[a]) * r.inv[a];
    // A NaN t0/t1 (0 * inf) makes the comparison false and leaves the bound as it is.
    tn = t0 > tn ? t0 : tn;
    tf = t1 < tf ? t1 : tf;
  }
  tf = t_hi < tf ? t_hi : tf;
  tf = hp_widen_far(tf);
  return tn <= tf;
}

void hp_fetch_triangle(uint slot, out vec3 p0, out vec3 p1, out vec3 p2) {
  if (HP_GEOMETRY_SOUP != 0u) {
    uint b = slot * 9u;
    p0 = vec3(soup[b + 0u], soup[b + 1u], soup[b + 2u]);
    p1 = vec3(soup[b + 3u], soup[b + 4u], soup[b + 5u]);
    p2 = vec3(soup[b + 6u], soup[b + 7u], soup[b + 8u]);
  } else {
    uint i0 = indices[slot * 3u + 0u] * 3u;
    uint i1 = indices[slot * 3u + 1u] * 3u;
    uint i2 = indices[slot * 3u + 2u] * 3u;
    p0 = vec3(positions[i0], positions[i0 + 1u], positions[i0 + 2u]);
    p1 = vec3(positions[i1], positions[i1 + 1u], positions[i1 + 2u]);
    p2 = vec3(positions[i2], positions[i2 + 1u], positions[i2 + 2u]);
  }
}

bool hp_watertight(HpRay r, vec3 p0, vec3 p1, vec3 p2, out float t, out float u, out float v) {
  t = 0.0; u = 0.0; v = 0.0;
  int kx = r.kx, ky = r.ky, kz = r.kz;
  precise float ax = p0[kx] - r.org[kx], ay = p0[ky] - r.org[ky], az = p0[kz] - r.org[kz];
  precise float bx = p1[kx] - r.org[kx], by = p1[ky] - r.org[ky], bz = p1[kz] - r.org[kz];
  precise float cx = p2[kx] - r.org[kx], cy = p2[ky] - r.org[ky], cz = p2[kz] - r.org[kz];
  precise float Ax = ax - r.sx * az, Ay = ay - r.sy * az;
  precise float Bx = bx - r.sx * bz, By = by - r.sy * bz;
  precise float Cx = cx - r.sx * cz, Cy = cy - r.sy * cz;
  precise float U = Cx * By - Cy * Bx;
  precise float V = Ax * Cy - Ay * Cx;
  precise float W = Bx * Ay - By * Ax;
  if (U == 0.0 || V == 0.0 || W == 0.0) {
    // Products of floats are exact in double, so the sign on an edge is exact.
    precise double Ud = double(Cx) * double(By) - double(Cy) * double(Bx);
    precise double Vd = double(Ax) * double(Cy) - double(Ay) * double(Cx);
    precise double Wd = double(Bx) * double(Ay) - double(By) * double(Ax);
    U = float(Ud); V = float(Vd); W = float(Wd);
  }
  if ((U < 0.0 || V < 0.0 || W < 0.0) && (U > 0.0 || V > 0.0 || W > 0.0)) return false;
  precise float det = U + V + W;
  if (det == 0.0) return false;
  precise float Az = r.sz * az, Bz = r.sz * bz, Cz = r.sz * cz;
  precise float T = U * Az + V * Bz + W * Cz;
  t = T / det;
  u = V / det;
  v = W / det;
  return true;
}

// The traversal stack lives in workgroup-shared memory, one column per invocation: a private array with a
// per-invocation index is lowered by lavapipe into code far slower than a shared-memory access. An including
// compute shader's workgroup must hold at most HP_TRAVERSAL_MAX_GROUP invocations (64 = 16 KiB).
#ifndef HP_TRAVERSAL_MAX_GROUP
#define HP_TRAVERSAL_MAX_GROUP 64u
#endif
shared uint hp_stack[HP_BVH_STACK_SIZE * HP_TRAVERSAL_MAX_GROUP];

// any_hit: stop at the first hit in [tmin, tmax]; else the closest, ties to the smallest scene index.
// Loop shape "while-while" (Aila & Laine 2009): an inner loop walks interior nodes until every SIMD lane has
// found a leaf whose box it hits (or finished), then the lanes test their leaves' triangles together. The
// order in which each ray visits nodes and triangles is the C++ reference's, node for node.
HpHit hp_trace(HpRay r, bool any_hit, inout HpStats stats) {
  HpHit best;
  best.slot = -1; best.t = 0.0; best.u = 0.0; best.v = 0.0;
  float best_t = r.tmax;
  uint best_scene = 0xFFFFFFFFu;
  uint lane = gl_LocalInvocationIndex;
  int sp = 0;
  uint node = 0u;
  bool done = false;
  while (!done) {
    uint first = 0u, last = 0u;
    for (;;) {
      BvhNode n = nodes[node];
      stats.nodes++;
      bool in_box = hp_slab(r, n.bmin, n.bmax, best_t);
      uint count = n.prim_axis >> HP_BVH_AXIS_BITS;
      if (in_box && count != 0u) {
        first = uint(n.offset);
        last = first + count;
        break;
      }
      if (in_box) {
        uint axis = n.prim_axis & HP_BVH_AXIS_MASK;
        uint near_child = node + 1u;
        uint far_child = uint(n.offset);
        if (r.neg[axis] != 0) { uint tmp = near_child; near_child = far_child; far_child = tmp; }
        // The builder bounds the depth by HP_BVH_STACK_SIZE, so this never drops a node.
        if (sp < HP_BVH_STACK_SIZE) { hp_stack[uint(sp) * HP_TRAVERSAL_MAX_GROUP + lane] = far_child; sp++; }
        node = near_child;
        continue;
      }
      if (sp == 0) { done = true; break; }
      --sp;
      node = hp_stack[uint(sp) * HP_TRAVERSAL_MAX_GROUP + lane];
    }
    if (HP_OBJECT_LEAVES != 0u && first != last) {
      first = object_first[first];
      last = object_first[last];
    }
    for (uint k = first; k < last; ++k) {
      stats.tris++;
      vec3 p0, p1, p2;
      hp_fetch_triangle(k, p0, p1, p2);
      float t, u, v;
      if (!hp_watertight(r, p0, p1, p2, t, u, v)) continue;
      if (!(t >= r.tmin)) continue;
      if (any_hit) {
        if (!(t <= r.tmax)) continue;
        best.slot = int(k); best.t = t; best.u = u; best.v = v;
        return best;
      }
      uint sc = slot_scene[k];
      if (t < best_t || (t == best_t && sc < best_scene)) {
        best_t = t;
        best_scene = sc;
        best.slot = int(k); best.t = t; best.u = u; best.v = v;
      }
    }
    if (!done) {
      if (sp == 0) break;
      --sp;
      node = hp_stack[uint(sp) * HP_TRAVERSAL_MAX_GROUP + lane];
    }
  }
  return best;
}

#endif
