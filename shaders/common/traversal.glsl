// The one BVH traversal every pass uses. It mirrors renderer/bvh/traverse.cpp operation for operation
// (see the semantics there): Williams slab test with NaN-discarding comparisons and Ize's widened far
// bound, Woop-Benthin-Wald watertight triangle test with a double-precision fallback on exact zeros,
// front-to-back order by split axis, t-max pruning, a fixed stack of HP_BVH_STACK_SIZE entries.
// `precise` forbids the contraction into FMAs that the C++ side turns off with -ffp-contract=off.
#ifndef HP_TRAVERSAL_GLSL
#define HP_TRAVERSAL_GLSL

#extension GL_EXT_shader_explicit_arithmetic_types_float64 : require
// Texel buffers are read as utextureBuffer with texelFetch, no sampler: glslang then fetches from the
// image itself. A usamplerBuffer wraps the image in an OpTypeSampledImage of Dim Buffer, which SPIR-V 1.6
// deprecates and the validation layer flags on Mesa 25 ("should not have a Dim of Buffer"). The descriptor
// type (UNIFORM_TEXEL_BUFFER) and the generated fetch are the same.
#extension GL_EXT_samplerless_texture_functions : require

#include "gpu/bindings.h"
#include "common/rt_bindings.glsl"
#include "common/trace_capture.glsl"

// The node buffer (binding 2) seen as RGBA32UI texels (binding 26), a node in two fetches: lavapipe turns
// a storage-buffer load at a per-invocation address into a loop over the SIMD lanes (mask test, bounds
// check, scalar load), and a texel fetch into a branch-free gather. Measured against four 64-bit storage
// loads on pica 1280x720: shadows 1.3-1.6x, reflections 1.2-1.4x faster, the same rays and hits; the other
// glTF scenes within noise (docs/gpu-passes.md).
layout(set = 0, binding = HP_BIND_RT_NODE_TEXELS) uniform utextureBuffer node_texels;
// The geometry buffers (bindings 3, 4, 5) seen as R32G32B32A32_UINT texels (bindings 29, 30, 31): a vertex,
// or a slot's three indices, per texel, the fourth word unused; read where HP_GEOMETRY_TEXELS is set (faster
// passes on lavapipe, docs/gpu-passes.md). UINT moves the float bits unchanged.
layout(set = 0, binding = HP_BIND_RT_POSITION_TEXELS) uniform utextureBuffer position_texels;
layout(set = 0, binding = HP_BIND_RT_INDEX_TEXELS) uniform utextureBuffer index_texels;
layout(set = 0, binding = HP_BIND_RT_SOUP_TEXELS) uniform utextureBuffer soup_texels;
layout(set = 0, binding = HP_BIND_RT_SLOT_SCENE_TEXELS) uniform utextureBuffer slot_scene_texels;
// The same four views as storage texel buffers, read instead where HP_STORAGE_TEXELS is set (the device's
// choice, RtScene::storage_texels). On lavapipe (Mesa 25.0.7) an imageLoad of these views is faster than a
// texelFetch of the same bytes: the compute traversal alone 2-23% per row (five scenes, shadows and
// reflections), the same rays and hits (docs/gpu-passes.md). GPUs keep texelFetch, the path measured there.
layout(set = 0, binding = HP_BIND_RT_NODE_IMAGE, rgba32ui) uniform readonly uimageBuffer node_images;
layout(set = 0, binding = HP_BIND_RT_POSITION_IMAGE, rgba32ui) uniform readonly uimageBuffer position_images;
layout(set = 0, binding = HP_BIND_RT_INDEX_IMAGE, rgba32ui) uniform readonly uimageBuffer index_images;
layout(set = 0, binding = HP_BIND_RT_SOUP_IMAGE, rgba32ui) uniform readonly uimageBuffer soup_images;
// Otherwise the geometry (bindings 3, 4, 5) seen as 64-bit words: a 32-bit triple at index b is one 64-bit
// word and one 32-bit load (which one depends on the parity of b), nine floats are four words and one
// float; a word is never read past the triple, so it never straddles the end of a buffer. Only bits move
// (unpackDouble2x32): no arithmetic is done on these doubles.
layout(std430, set = 0, binding = HP_BIND_RT_POSITIONS) readonly buffer PositionWords { double position_words[]; };
layout(std430, set = 0, binding = HP_BIND_RT_INDICES) readonly buffer IndexWords { double index_words[]; };
layout(std430, set = 0, binding = HP_BIND_RT_SOUP) readonly buffer SoupWords { double soup_words[]; };

// 1 + 2 gamma(3) and 1 - 2 gamma(3), eps = 2^-24, rounded away from 1 (as the C++ constants).
const float HP_FAR_UP = 1.0000004768371582;    // 1 + 4 ulp
const float HP_FAR_DOWN = 0.99999958276748657;  // 1 - 7 ulp(below 1)

struct HpRay {
  vec3 org;
  vec3 dir;     // as given (the driver traversals trace it; the compute traversal uses inv and the shear)
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

// A miss: what every traversal starts from.
HpHit hp_no_hit() {
  HpHit h;
  h.slot = -1; h.t = 0.0; h.u = 0.0; h.v = 0.0;
  return h;
}

struct HpStats {
  uint nodes;
  uint tris;
};

// A float quotient as the C++ reference's, correctly rounded. Vulkan lets a 32-bit OpFDiv be 2.5 ulp off
// (NVIDIA's is: without this, 54% of 1 M primary rays on pica came back with another t, u or v), and a shear
// factor one ulp off moves the edge functions of a nearly grazed triangle by hundreds of ulps. Where
// HP_EXACT_DIVISION is set the quotient is taken in double precision and rounded once to float: 53 >= 2 * 24 + 2
// bits, so the second rounding cannot change it when the double quotient is correctly rounded (Figueroa,
// "When is double rounding innocuous?", 1995); lavapipe's float division is IEEE's already.
float hp_div(float a, float b) { return HP_EXACT_DIVISION != 0u ? float(double(a) / double(b)) : a / b; }

bool hp_prepare(vec3 org, vec3 dir, float tmin, float tmax, out HpRay r) {
  r.org = org; r.dir = dir; r.inv = vec3(0.0); r.neg = ivec3(0); r.tmin = tmin; r.tmax = tmax;
  r.kx = 0; r.ky = 1; r.kz = 2; r.sx = 0.0; r.sy = 0.0; r.sz = 0.0;
  if (any(isnan(org)) || any(isinf(org)) || any(isnan(dir)) || any(isinf(dir)) || isnan(tmin) || isnan(tmax))
    return false;
  if (dir == vec3(0.0)) return false;
  precise vec3 inv = vec3(hp_div(1.0, dir.x), hp_div(1.0, dir.y), hp_div(1.0, dir.z));
  r.inv = inv;
  r.neg = ivec3(floatBitsToUint(inv.x) >> 31, floatBitsToUint(inv.y) >> 31, floatBitsToUint(inv.z) >> 31);
  vec3 ad = abs(dir);
  r.kz = ad.x >= ad.y ? (ad.x >= ad.z ? 0 : 2) : (ad.y >= ad.z ? 1 : 2);
  r.kx = (r.kz + 1) % 3;
  r.ky = (r.kx + 1) % 3;
  if (dir[r.kz] < 0.0) { int tmp = r.kx; r.kx = r.ky; r.ky = tmp; }
  precise float sx = hp_div(dir[r.kx], dir[r.kz]);
  precise float sy = hp_div(dir[r.ky], dir[r.kz]);
  precise float sz = hp_div(1.0, dir[r.kz]);
  r.sx = sx; r.sy = sy; r.sz = sz;
  return true;
}

float hp_widen_far(float t) { return t >= 0.0 ? t * HP_FAR_UP : t * HP_FAR_DOWN; }
vec4 hp_widen_far(vec4 t) { return mix(t * HP_FAR_DOWN, t * HP_FAR_UP, greaterThanEqual(t, vec4(0.0))); }

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

// Texel i of the node buffer, or of a geometry buffer in its texel layout, through the view HP_STORAGE_TEXELS
// picks: one function per buffer, since GLSL cannot pass a format-qualified image as a parameter (without
// shaderStorageImageReadWithoutFormat). The macro writes the four; each reads exactly one of its two views.
#define HP_TEXEL_READER(name, images, texels)                      \
  uvec4 name(uint i) {                                             \
    if (HP_STORAGE_TEXELS != 0u) return imageLoad(images, int(i)); \
    return texelFetch(texels, int(i));                             \
  }
HP_TEXEL_READER(hp_node_texel, node_images, node_texels)
HP_TEXEL_READER(hp_position_texel, position_images, position_texels)
HP_TEXEL_READER(hp_index_texel, index_images, index_texels)
HP_TEXEL_READER(hp_soup_texel, soup_images, soup_texels)
#undef HP_TEXEL_READER

uvec3 hp_triple(uvec2 w, uint single, bool odd) {
  return odd ? uvec3(single, w) : uvec3(w, single);
}

// The scene triangle of a leaf-order slot (binding 7, or its texel view).
uint hp_slot_scene(uint slot) {
  if (HP_GEOMETRY_TEXELS != 0u) return texelFetch(slot_scene_texels, int(slot)).x;
  return slot_scene[slot];
}

// A slot's three vertex indices (indexed layout).
uvec3 hp_slot_indices(uint slot) {
  if (HP_GEOMETRY_TEXELS != 0u) return hp_index_texel(slot).xyz;
  uint b = slot * 3u;
  bool odd = (b & 1u) != 0u;
  uvec2 w = unpackDouble2x32(index_words[(b + 1u) >> 1u]);
  uint single = indices[odd ? b : b + 2u];
  return hp_triple(w, single, odd);
}

vec3 hp_position(uint i) {
  if (HP_GEOMETRY_TEXELS != 0u) return uintBitsToFloat(hp_position_texel(i).xyz);
  uint b = i * 3u;
  bool odd = (b & 1u) != 0u;
  uvec2 w = unpackDouble2x32(position_words[(b + 1u) >> 1u]);
  uint single = floatBitsToUint(positions[odd ? b : b + 2u]);
  return uintBitsToFloat(hp_triple(w, single, odd));
}

void hp_fetch_triangle(uint slot, out vec3 p0, out vec3 p1, out vec3 p2) {
  // Traced as the accesses a GPU makes for one float3 each (12 bytes), whatever word size this shader
  // happens to load with: the cache model cares about the bytes touched.
  if (HP_GEOMETRY_SOUP != 0u) {
    HP_REC_LOADS(3u, HP_TBUF_SOUP, slot * 36u + uvec4(0u, 12u, 24u, 0u), 12u);
    if (HP_GEOMETRY_TEXELS != 0u) {
      p0 = uintBitsToFloat(hp_soup_texel(slot * 3u).xyz);
      p1 = uintBitsToFloat(hp_soup_texel(slot * 3u + 1u).xyz);
      p2 = uintBitsToFloat(hp_soup_texel(slot * 3u + 2u).xyz);
      return;
    }
    uint b = slot * 9u;
    bool odd = (b & 1u) != 0u;
    uint wb = (b + 1u) >> 1u;
    uvec2 w0 = unpackDouble2x32(soup_words[wb + 0u]);
    uvec2 w1 = unpackDouble2x32(soup_words[wb + 1u]);
    uvec2 w2 = unpackDouble2x32(soup_words[wb + 2u]);
    uvec2 w3 = unpackDouble2x32(soup_words[wb + 3u]);
    uint single = floatBitsToUint(soup[odd ? b : b + 8u]);
    // Even b: w0..w3 = f0..f7, single = f8. Odd b: single = f0, w0..w3 = f1..f8.
    p0 = uintBitsToFloat(odd ? uvec3(single, w0) : uvec3(w0, w1.x));
    p1 = uintBitsToFloat(odd ? uvec3(w1, w2.x) : uvec3(w1.y, w2));
    p2 = uintBitsToFloat(odd ? uvec3(w2.y, w3) : uvec3(w3, single));
  } else {
    uvec3 i = hp_slot_indices(slot);
    HP_REC_LOADS(4u, uvec4(HP_TBUF_INDICES, HP_TBUF_POSITIONS, HP_TBUF_POSITIONS, HP_TBUF_POSITIONS),
                 uvec4(slot, i) * 12u, 12u);
    p0 = hp_position(i.x);
    p1 = hp_position(i.y);
    p2 = hp_position(i.z);
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
  t = hp_div(T, det);
  u = hp_div(V, det);
  v = hp_div(W, det);
  return true;
}

#if defined(HP_RAY_QUERY) || defined(HP_RT_PIPELINE)
// The driver walks its own acceleration structure: hp_trace there (the same interface, HpStats left 0).
#include "common/driver_traversal.glsl"
#else
// The traversal stack lives in workgroup-shared memory, one column per invocation: a private array with a
// per-invocation index is lowered by lavapipe into code far slower than a shared-memory access. An including
// compute shader's workgroup must hold at most HP_TRAVERSAL_MAX_GROUP invocations (64 = 16 KiB).
#ifndef HP_TRAVERSAL_MAX_GROUP
#define HP_TRAVERSAL_MAX_GROUP 64u
#endif
shared uint hp_stack[HP_BVH_STACK_SIZE * HP_TRAVERSAL_MAX_GROUP];

// The traversal stack: its top 8 entries live in registers (s0 the top), the deeper ones in hp_stack, an
// entry at stack position i (0 the bottom) in row i. A step that pushes shifts the registers down and
// spills those that leave the window; a pop shifts them up and refills the 8th. Same LIFO order and bound
// as one array, but most pushes and pops touch no memory: shared-memory accesses at per-lane addresses are
// a loop over the lanes on a CPU driver (lavapipe), register shifts are whole-vector selects. The steps of
// hp_trace_binary and hp_trace_wide push (or, in the binary one, pop) by one shift written out in place:
// selects, where separate push and pop calls under their own `if`s would each be a masked block on llvmpipe.
struct HpStack {
  uint s0, s1, s2, s3, s4, s5, s6, s7;
  int sp;
};

HpStack hp_stack_empty() {
  HpStack st;
  st.s0 = 0u; st.s1 = 0u; st.s2 = 0u; st.s3 = 0u; st.s4 = 0u; st.s5 = 0u; st.s6 = 0u; st.s7 = 0u;
  st.sp = 0;
  return st;
}

uint hp_pop(inout HpStack st, uint lane) {
  uint x = st.s0;
  st.s0 = st.s1; st.s1 = st.s2; st.s2 = st.s3; st.s3 = st.s4;
  st.s4 = st.s5; st.s5 = st.s6; st.s6 = st.s7;
  st.sp--;
  if (st.sp >= 8) st.s7 = hp_stack[uint(st.sp - 8) * HP_TRAVERSAL_MAX_GROUP + lane];
  return x;
}

// Tests primitive slot k against the ray, keeping the closest hit in `best` (ties to the smallest scene index).
// Returns true when any_hit and k is a hit in range (`best` holds it).
bool hp_test_triangle(HpRay r, uint k, bool any_hit, inout HpHit best, inout float best_t, inout HpStats stats) {
  stats.tris++;
  vec3 p0, p1, p2;
  hp_fetch_triangle(k, p0, p1, p2);
  float t, u, v;
  if (!hp_watertight(r, p0, p1, p2, t, u, v)) return false;
  if (!(t >= r.tmin)) return false;
  if (any_hit) {
    if (!(t <= r.tmax)) return false;
    best.slot = int(k); best.t = t; best.u = u; best.v = v;
    return true;
  }
  // The reference's test is t < best_t || (t == best_t && scene(k) < best_scene), with best_scene =
  // UINT32_MAX before the first hit; the scene indices are only read on a tie (rare), which spares a
  // per-lane load per triangle.
  bool better = t < best_t;
  if (!better && t == best_t) {
    HP_REC_LOAD(HP_TBUF_SLOT_SCENE, k * 4u, 4u);
    if (best.slot >= 0) HP_REC_LOAD(HP_TBUF_SLOT_SCENE, uint(best.slot) * 4u, 4u);
    better = best.slot < 0 || hp_slot_scene(k) < hp_slot_scene(uint(best.slot));
  }
  if (better) {
    best_t = t;
    best.slot = int(k); best.t = t; best.u = u; best.v = v;
  }
  return false;
}

// The primitive slots of leaf range [first, last): object slots map to their triangles where HP_OBJECT_LEAVES.
void hp_leaf_slots(inout uint first, inout uint last) {
  if (HP_OBJECT_LEAVES != 0u && first != last) {
    HP_REC_LOADS(2u, HP_TBUF_OBJECT_FIRST, uvec4(first, last, 0u, 0u) * 4u, 4u);
    first = object_first[first];
    last = object_first[last];
  }
}

// Tests leaf primitives [first, last) against the ray (hp_test_triangle). Returns true when any_hit and a hit
// in range was found (`best` holds it). The loop tests its exit at the bottom, as hp_trace_wide's loops do.
bool hp_test_leaf(HpRay r, uint first, uint last, bool any_hit, inout HpHit best, inout float best_t,
                  inout HpStats stats) {
  hp_leaf_slots(first, last);
  uint k = first;
  if (k < last) do {
    if (hp_test_triangle(r, k, any_hit, best, best_t, stats)) return true;
  } while (++k < last);
  return false;
}

// any_hit: stop at the first hit in [tmin, tmax]; else the closest, ties to the smallest scene index.
// Loop shape "while-while" (Aila & Laine 2009): an inner loop walks interior nodes until every SIMD lane has
// found a leaf whose box it hits (or finished), then the lanes test their leaves' triangles together. The
// order in which each ray visits nodes and triangles is the C++ reference's, node for node.
HpHit hp_trace_binary(HpRay r, bool any_hit, inout HpStats stats) {
  HpHit best = hp_no_hit();
  float best_t = r.tmax;
  uint lane = gl_LocalInvocationIndex;
  HpStack st = hp_stack_empty();
  uint node = 0u;
  bool done = false;
  while (!done) {
    uint first = 0u, last = 0u;
    for (;;) {
      // A 32-byte node is two 16-byte loads on a GPU.
      HP_REC_LOADS(2u, HP_TBUF_NODES, node * 32u + uvec4(0u, 16u, 0u, 0u), 16u);
      uvec4 t0 = hp_node_texel(node * 2u);
      uvec4 t1 = hp_node_texel(node * 2u + 1u);
      BvhNode n;
      n.bmin = uintBitsToFloat(t0.xyz);
      n.offset = int(t0.w);
      n.bmax = uintBitsToFloat(t1.xyz);
      n.prim_axis = t1.w;
      stats.nodes++;
      bool in_box = hp_slab(r, n.bmin, n.bmax, best_t);
      uint count = n.prim_axis >> HP_BVH_AXIS_BITS;
      if (in_box && count != 0u) {
        first = uint(n.offset);
        last = first + count;
        break;
      }
      if (!in_box && st.sp == 0) { done = true; break; }
      // An interior node the ray enters: push the far child, visit the near one. A missed node: pop. Either
      // way one shift of the stack's register window, as selects, not two masked blocks (docs/gpu-passes.md).
      // The builder bounds the depth by HP_BVH_STACK_SIZE, so the push is never dropped.
      uint axis = n.prim_axis & HP_BVH_AXIS_MASK;
      bool swap = r.neg[axis] != 0;
      uint near_child = swap ? uint(n.offset) : node + 1u;
      uint far_child = swap ? node + 1u : uint(n.offset);
      bool push = in_box && st.sp < HP_BVH_STACK_SIZE;
      bool pop = !in_box;
      if (push && st.sp >= 8) hp_stack[uint(st.sp - 8) * HP_TRAVERSAL_MAX_GROUP + lane] = st.s7;
      uint o0 = st.s0, o1 = st.s1, o2 = st.s2, o3 = st.s3, o4 = st.s4, o5 = st.s5, o6 = st.s6, o7 = st.s7;
      st.s0 = push ? far_child : (pop ? o1 : o0);
      st.s1 = push ? o0 : (pop ? o2 : o1);
      st.s2 = push ? o1 : (pop ? o3 : o2);
      st.s3 = push ? o2 : (pop ? o4 : o3);
      st.s4 = push ? o3 : (pop ? o5 : o4);
      st.s5 = push ? o4 : (pop ? o6 : o5);
      st.s6 = push ? o5 : (pop ? o7 : o6);
      st.s7 = push ? o6 : o7;
      st.sp += push ? 1 : (pop ? -1 : 0);
      if (pop && st.sp >= 8) st.s7 = hp_stack[uint(st.sp - 8) * HP_TRAVERSAL_MAX_GROUP + lane];
      node = in_box ? near_child : o0;
    }
    if (hp_test_leaf(r, first, last, any_hit, best, best_t, stats)) return best;
    if (!done) {
      if (st.sp == 0) break;
      node = hp_pop(st, lane);
    }
  }
  return best;
}

// The four slots of a wide node slab-tested together against [tmin, t_hi], axis by axis as the C++ twin's
// slab4 (bvh/wide.cpp): each slot's planes decoded as origin + q * step, rounded once (`precise` keeps the
// products out of FMAs, as -ffp-contract=off does there). Per slot and axis the operations are those of
// hp_slab, in the same order, so the bits are too. Axis by axis, only one axis's node data and ray data are
// live at a time beside the four slots' running bounds: llvmpipe spilled the slot-by-slot form, which needs
// every axis at once (docs/gpu-passes.md).
bvec4 hp_wide_boxes(HpRay r, uvec4 t0, uvec4 t1, uvec4 t2, float t_hi) {
  const uvec4 shifts = uvec4(0u, 8u, 16u, 24u);
  uvec3 lo_words = uvec3(t1.x, t1.z, t2.x), hi_words = uvec3(t1.y, t1.w, t2.y);
  vec4 tn = vec4(r.tmin);
  vec4 tf = vec4(1.0 / 0.0);
  for (int a = 0; a < 3; ++a) {
    float origin = uintBitsToFloat(t0[a]);
    float step = uintBitsToFloat(((t0.w >> (8u * uint(a))) & 255u) << 23u);
    // The near and far planes picked as quantized words, before decoding: two selects, not eight.
    bool negative = r.neg[a] != 0;
    uint near_word = negative ? hi_words[a] : lo_words[a];
    uint far_word = negative ? lo_words[a] : hi_words[a];
    precise vec4 near_planes = origin + vec4((uvec4(near_word) >> shifts) & 255u) * step;
    precise vec4 far_planes = origin + vec4((uvec4(far_word) >> shifts) & 255u) * step;
    precise vec4 t_near = (near_planes - r.org[a]) * r.inv[a];
    precise vec4 t_far = (far_planes - r.org[a]) * r.inv[a];
    // A NaN bound (0 * inf) makes the comparison false and leaves the running bound as it is.
    tn = mix(tn, t_near, greaterThan(t_near, tn));
    tf = mix(tf, t_far, lessThan(t_far, tf));
  }
  tf = mix(tf, vec4(t_hi), lessThan(vec4(t_hi), tf));
  return lessThanEqual(tn, hp_widen_far(tf));
}

// A wide leaf's child word as its primitive range [first, last).
void hp_wide_leaf_range(uint word, out uint first, out uint last) {
  first = word & HP_WIDE_FIRST_MASK;
  last = first + ((word >> HP_WIDE_COUNT_SHIFT) & HP_WIDE_COUNT_MASK);
}

// The same traversal over the wide4 layout (gpu::WideNode), operation for operation the C++ twin in
// renderer/bvh/wide.cpp: a visited node tests its four child boxes with the closest t so far, the first hit
// child in the binary order (the node's visiting order for the ray's octant, gpu::WideNode w[2].zw) is
// visited next and the other hit children are pushed, the last first. Stack entries are child words: a
// leaf's word carries its primitive range, so a popped leaf is tested without another fetch.
HpHit hp_trace_wide(HpRay r, bool any_hit, inout HpStats stats) {
  HpHit best = hp_no_hit();
  float best_t = r.tmax;
  uint lane = gl_LocalInvocationIndex;
  HpStack st = hp_stack_empty();
  uint entry = 0u;  // the root, an interior node
  uint octant = uint(r.neg.x) | uint(r.neg.y) << 1u | uint(r.neg.z) << 2u;
  bool done = false;
  while (!done) {
    uint first = 0u, last = 0u;
    // The node loop and the leaf loop below test their exit at the bottom (do-while, entered under an if).
    // llvmpipe runs a loop until no lane is left in it, and a lane that leaves at a top test leaves the rest
    // of that last trip to run masked: a whole node step (four texel fetches) or triangle test for nothing,
    // once per loop. Exiting where the next entry is known saves it: 3-10% faster on lavapipe
    // (docs/gpu-passes.md), the same steps per ray.
    if ((entry & HP_WIDE_LEAF) == 0u) do {
      // A 64-byte node is four 16-byte loads on a GPU.
      HP_REC_LOADS(4u, HP_TBUF_NODES, entry * 64u + uvec4(0u, 16u, 32u, 48u), 16u);
      uvec4 t0 = hp_node_texel(entry * 4u);
      uvec4 t1 = hp_node_texel(entry * 4u + 1u);
      uvec4 t2 = hp_node_texel(entry * 4u + 2u);
      uvec4 t3 = hp_node_texel(entry * 4u + 3u);
      stats.nodes++;
      bvec4 in_box = hp_wide_boxes(r, t0, t1, t2, best_t);
      // The hit children's words (0 where missed or empty: a child word is never 0), and the visiting order
      // for the ray's octant (the binary order, make_wide): slot o_i is visited i-th.
      uvec4 hit_words = mix(uvec4(0u), t3, in_box);
      uint ord = ((octant & 4u) != 0u ? t2.w : t2.z) >> ((octant & 3u) * 8u);
      uint c0 = hit_words[ord & 3u], c1 = hit_words[(ord >> 2u) & 3u];
      uint c2 = hit_words[(ord >> 4u) & 3u], c3 = hit_words[(ord >> 6u) & 3u];
      bool y0 = c0 != 0u, y1 = c1 != 0u, y2 = c2 != 0u, y3 = c3 != 0u;
      // The hit children in visiting order, compacted: l0 is visited next, l1..lm are pushed in one step with
      // l1 on top (the stack the C++ twin's pushes of lm, ..., l1 leave). One step with selects rather than
      // up to three pushes under their own branches, each a masked block for llvmpipe: 3-14% faster traversal
      // on lavapipe (docs/gpu-passes.md). bvh::make_wide bounds the pushes by HP_BVH_STACK_SIZE, so the clamp
      // never drops an entry.
      // Shifted in from the last: a hit child moves the ones after it down by one (a missed one is 0).
      uint l0 = c3, l1 = 0u, l2 = 0u, l3 = 0u;
      if (y2) { l1 = l0; l0 = c2; }
      if (y1) { l2 = l1; l1 = l0; l0 = c1; }
      if (y0) { l3 = l2; l2 = l1; l1 = l0; l0 = c0; }
      uint k = (y0 ? 1u : 0u) + (y1 ? 1u : 0u) + (y2 ? 1u : 0u) + (y3 ? 1u : 0u);
      bool have = k != 0u;
      uint next = l0;
      int m = min(k > 1u ? int(k) - 1 : 0, HP_BVH_STACK_SIZE - st.sp);
      if (m > 0) {
        // Registers s(8-m)..s7 leave the window: to memory at their stack positions (sp-1-j), where they exist.
        if (st.sp + m > 8) {
          if (m >= 3 && st.sp >= 6) hp_stack[uint(st.sp - 6) * HP_TRAVERSAL_MAX_GROUP + lane] = st.s5;
          if (m >= 2 && st.sp >= 7) hp_stack[uint(st.sp - 7) * HP_TRAVERSAL_MAX_GROUP + lane] = st.s6;
          if (st.sp >= 8) hp_stack[uint(st.sp - 8) * HP_TRAVERSAL_MAX_GROUP + lane] = st.s7;
        }
        bool m1 = m == 1, m2 = m == 2;
        st.s7 = m1 ? st.s6 : (m2 ? st.s5 : st.s4);
        st.s6 = m1 ? st.s5 : (m2 ? st.s4 : st.s3);
        st.s5 = m1 ? st.s4 : (m2 ? st.s3 : st.s2);
        st.s4 = m1 ? st.s3 : (m2 ? st.s2 : st.s1);
        st.s3 = m1 ? st.s2 : (m2 ? st.s1 : st.s0);
        st.s2 = m1 ? st.s1 : (m2 ? st.s0 : l3);
        st.s1 = m1 ? st.s0 : l2;
        st.s0 = l1;
        st.sp += m;
      }
      if (have) {
        entry = next;
      } else if (st.sp == 0) {
        done = true;
        break;
      } else {
        entry = hp_pop(st, lane);
      }
    } while ((entry & HP_WIDE_LEAF) == 0u);
    if (!done) hp_wide_leaf_range(entry, first, last);
    // The leaf's triangles, then those of each leaf popped right after it, in one loop: a popped leaf is
    // tested without another box test either way, so the order, the hits and the counters are those of a
    // leaf at a time, but the lanes of a vector wait for the longest run of triangles, not for the longest
    // leaf of each run in turn (docs/gpu-passes.md).
    hp_leaf_slots(first, last);
    uint k = first;
    if (k < last) do {
      if (hp_test_triangle(r, k, any_hit, best, best_t, stats)) return best;
      ++k;
      if (k == last && st.sp > 0 && (st.s0 & HP_WIDE_LEAF) != 0u) {
        hp_wide_leaf_range(hp_pop(st, lane), k, last);
        hp_leaf_slots(k, last);
      }
    } while (k < last);
    if (!done) {
      if (st.sp == 0) break;
      entry = hp_pop(st, lane);
    }
  }
  return best;
}

// The compute traversal of the scene's node layout (a specialization constant: the other one is not run).
HpHit hp_trace(HpRay r, bool any_hit, inout HpStats stats) {
  if (HP_WIDE_NODES != 0u) return hp_trace_wide(r, any_hit, stats);
  return hp_trace_binary(r, any_hit, stats);
}
#endif  // compute traversal

#endif
