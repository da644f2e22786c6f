#include "reference/reference.hpp"

#include "error.hpp"
#include "reference/shading.hpp"
#include "rt_geometry.hpp"
#include "stable_id.hpp"
#include "view.hpp"

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <limits>
#include <thread>
#include <vector>

namespace hp {

namespace {

constexpr float kFltMax = 3.402823466e+38f;
// Bump when the reference's shading model changes, so cached images are re-rendered.
constexpr int kReferenceVersion = 1;

glm::vec2 halton23(uint32_t i) {
  double f = 0.5, r2 = 0.0;
  for (uint32_t k = i; k > 0; k >>= 1, f *= 0.5) r2 += f * double(k & 1u);
  double g = 1.0 / 3.0, r3 = 0.0;
  for (uint32_t k = i; k > 0; k /= 3, g /= 3.0) r3 += g * double(k % 3u);
  return {float(r2), float(r3)};
}

struct SurfacePoint {
  glm::vec3 pos;     // exact hit, rounded once to float
  glm::dvec3 pos_d;  // exact hit in double
  glm::vec3 ng;      // geometric normal (unit, unoriented)
  glm::vec3 ns;      // interpolated shading normal (unit, unoriented; ng where it degenerates)
  uint32_t material;
};

class Tracer {
 public:
  Tracer(const Scene& scene, const RtGeometry& g, const ReferenceSettings& s, const glm::vec3& camera_pos)
      : scene_(scene), g_(g), s_(s), cam_(camera_pos) {
    l_ = glm::normalize(scene.light.direction);
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (const glm::vec3& p : g.world.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    extent_ = g.world.positions.empty() ? 1.0 : double(std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}));
    light_ = scene.light.color * scene.light.intensity;
    sky_ = scene.sky_color;
  }

  SurfacePoint surface(const bvh::Hit& h) const {
    const auto& w = g_.world;
    const uint32_t i0 = w.indices[3 * size_t(h.prim)], i1 = w.indices[3 * size_t(h.prim) + 1],
                   i2 = w.indices[3 * size_t(h.prim) + 2];
    const double u = h.u, v = h.v, b0 = 1.0 - u - v;
    const glm::dvec3 p0(w.positions[i0]), p1(w.positions[i1]), p2(w.positions[i2]);
    SurfacePoint sp;
    sp.pos_d = b0 * p0 + u * p1 + v * p2;
    sp.pos = glm::vec3(sp.pos_d);
    const glm::dvec3 ng = glm::cross(p1 - p0, p2 - p0);
    const double ngl = glm::length(ng);
    sp.ng = ngl > 0.0 ? glm::vec3(ng / ngl) : glm::vec3(0.0f, 1.0f, 0.0f);
    const glm::dvec3 ns =
        b0 * glm::dvec3(w.normals[i0]) + u * glm::dvec3(w.normals[i1]) + v * glm::dvec3(w.normals[i2]);
    const double nsl = glm::length(ns);
    sp.ns = nsl > 1e-10 ? glm::vec3(ns / nsl) : sp.ng;
    sp.material = w.material[size_t(h.prim)];
    return sp;
  }

  // A ray origin off the surface on the side of `n`: a distance proportional to the scene's extent (so the
  // answer does not change when the world is scaled; Wächter & Binder's absolute 2^-16 near the origin
  // does) plus 128 ULPs of the largest coordinate (so it survives a translation far from the origin).
  glm::vec3 offset(const glm::vec3& p, const glm::vec3& n) const {
    const double big = std::max({std::abs(double(p.x)), std::abs(double(p.y)), std::abs(double(p.z))});
    const double eps = extent_ * 0x1p-20 + big * 0x1p-16;
    return glm::vec3(glm::dvec3(p) + glm::dvec3(n) * eps);
  }

  // 1 when nothing lies between p (on a surface with geometric normal ng) and the light.
  float visibility(const glm::vec3& p, const glm::vec3& ng) {
    const glm::vec3 side = glm::dot(ng, l_) >= 0.0f ? ng : -ng;
    bvh::Ray r;
    r.origin = offset(p, side);
    r.dir = l_;
    r.tmin = 0.0f;
    r.tmax = kFltMax;
    ++rays_;
    return bvh::intersect_any(g_.bvh, g_.leaf, r).hit() ? 0.0f : 1.0f;
  }

  // The GPU's reflection estimator for one direction (hp_shade_reflection), with exact offsets.
  glm::vec3 shade_reflection(const glm::vec3& o, const glm::vec3& d) {
    bvh::Ray r;
    r.origin = o;
    r.dir = d;
    r.tmin = 0.0f;
    r.tmax = kFltMax;
    ++rays_;
    const bvh::Hit h = bvh::intersect_closest(g_.bvh, g_.leaf, r);
    if (!h.hit()) return sky_;
    const SurfacePoint sp = surface(h);
    const Material& m = scene_.materials[sp.material];
    glm::vec3 hn = sp.ns;
    if (glm::dot(hn, d) > 0.0f) hn = -hn;
    float vis = 1.0f;
    if (s_.reflection_shadows && glm::dot(hn, l_) > 0.0f) vis = visibility(sp.pos, sp.ng);
    const float hit_rough = std::max(m.roughness, 0.25f);
    return vis * ref::shade_direct(hn, -d, l_, m.base_color, m.metallic, hit_rough, light_) +
           ref::shade_ambient(hn, -d, m.base_color, m.metallic, sky_);
  }

  // One pixel: returns colour; fills the shading and position layers.
  void pixel(const bvh::Ray& primary, uint32_t pixel_index, float* color, float* shading, float* position) {
    ++rays_;
    const bvh::Hit h = bvh::intersect_closest(g_.bvh, g_.leaf, primary);
    if (!h.hit()) {
      color[0] = sky_.r, color[1] = sky_.g, color[2] = sky_.b, color[3] = 1.0f;
      shading[0] = -1.0f, shading[1] = shading[2] = shading[3] = 0.0f;
      position[0] = position[1] = position[2] = position[3] = 0.0f;
      return;
    }
    const SurfacePoint sp = surface(h);
    const Material& m = scene_.materials[sp.material];
    // Orientation as the G-buffer pass: geometric normal toward the camera, shading normal on its side.
    glm::vec3 ng = sp.ng;
    if (glm::dot(ng, cam_ - sp.pos) < 0.0f) ng = -ng;
    glm::vec3 n = sp.ns;
    if (glm::dot(n, ng) < 0.0f) n = -n;
    const glm::vec3 v = glm::normalize(cam_ - sp.pos);

    float lit = 1.0f;
    if (s_.shadows) lit = glm::dot(n, l_) > 0.0f ? visibility(sp.pos, sp.ng) : 0.0f;
    glm::vec3 c = lit * ref::shade_direct(n, v, l_, m.base_color, m.metallic, m.roughness, light_);

    const bool reflective = s_.reflections && m.roughness < s_.roughness_threshold;
    if (reflective) {
      const glm::vec3 mirror = ref::reflect(-v, n);
      const uint32_t rot_bits = ref::hash32(pixel_index * 0x9E3779B9u + 0x85EBCA6Bu);
      const glm::vec2 rot(float(rot_bits & 0xFFFFu) / 65536.0f, float(rot_bits >> 16) / 65536.0f);
      // A perfect mirror has one direction: one sample is the converged value.
      const uint32_t n_samples = m.roughness > 0.0f ? s_.samples : 1u;
      glm::dvec3 sum(0.0);
      for (uint32_t k = 0; k < n_samples; ++k) {
        glm::vec3 d = mirror;
        if (m.roughness > 0.0f) {
          const glm::vec2 xi = glm::fract(halton23(k + 1) + rot);
          const glm::vec3 dj = ref::reflect(-v, ref::sample_ggx(n, m.roughness, xi));
          if (glm::dot(dj, n) > 0.0f) d = dj;
        }
        const glm::vec3 side = glm::dot(sp.ng, d) >= 0.0f ? sp.ng : -sp.ng;
        sum += glm::dvec3(shade_reflection(offset(sp.pos, side), d));
      }
      const glm::vec3 refl(sum / double(n_samples));
      const glm::vec3 f0 = glm::mix(glm::vec3(0.04f), m.base_color, m.metallic);
      const glm::vec3 F = ref::fresnel_schlick(f0, std::max(glm::dot(n, v), 0.0f));
      c += ref::shade_ambient_diffuse(n, v, m.base_color, m.metallic, sky_) + F * refl;
    } else {
      c += ref::shade_ambient(n, v, m.base_color, m.metallic, sky_);
    }
    color[0] = c.r, color[1] = c.g, color[2] = c.b, color[3] = 1.0f;
    shading[0] = s_.shadows ? lit : 1.0f, shading[1] = n.x, shading[2] = n.y, shading[3] = n.z;
    const glm::dvec3 rel = sp.pos_d - glm::dvec3(cam_);
    position[0] = float(rel.x), position[1] = float(rel.y), position[2] = float(rel.z), position[3] = 1.0f;
  }

  uint64_t rays() const { return rays_; }

 private:
  const Scene& scene_;
  const RtGeometry& g_;
  const ReferenceSettings& s_;
  glm::vec3 cam_, l_, light_, sky_;
  double extent_ = 1.0;
  uint64_t rays_ = 0;
};

}  // namespace

ReferenceImage render_reference(const Scene& scene, const Camera& camera, const ReferenceSettings& s) {
  if (s.width == 0 || s.height == 0 || s.width > 16384 || s.height > 16384) {
    throw InputError("reference: " + std::to_string(s.width) + "x" + std::to_string(s.height) +
                     " is outside 1..16384 per side");
  }
  if (s.samples == 0) throw InputError("reference: samples must be at least 1");
  const auto t0 = std::chrono::steady_clock::now();
  bvh::BuildOptions bo;
  bo.threads = s.threads;
  const RtGeometry g = build_rt_geometry(scene, bo);

  // The primary rays in double: direction through the pixel centre in camera space, then to world. The
  // direction's forward component is 1, so t is the view depth and [znear, zfar] is the raster's clip range.
  const glm::dvec3 eye(camera.position), target(camera.target), up = view_up(camera);
  const glm::dvec3 fwd = glm::normalize(target - eye);
  const glm::dvec3 right = glm::normalize(glm::cross(fwd, up));
  const glm::dvec3 cam_up = glm::cross(right, fwd);
  const double f = 1.0 / std::tan(glm::radians(double(camera.vfov_deg)) * 0.5);
  const double aspect = double(s.width) / double(s.height);

  ReferenceImage out;
  out.color = Image4f(s.width, s.height);
  out.shading = Image4f(s.width, s.height);
  out.position = Image4f(s.width, s.height);
  std::atomic<uint32_t> next_row{0};
  std::atomic<uint64_t> rays{0};
  const auto work = [&] {
    Tracer tracer(scene, g, s, camera.position);
    for (uint32_t y = next_row++; y < s.height; y = next_row++) {
      for (uint32_t x = 0; x < s.width; ++x) {
        const double ndc_x = (double(x) + 0.5) / double(s.width) * 2.0 - 1.0;
        const double ndc_y = (double(y) + 0.5) / double(s.height) * 2.0 - 1.0;
        const glm::dvec3 d = right * (ndc_x * aspect / f) + cam_up * (-ndc_y / f) + fwd;
        bvh::Ray r;
        r.origin = camera.position;
        r.dir = glm::vec3(d);
        r.tmin = camera.znear;
        r.tmax = camera.zfar;
        tracer.pixel(r, y * s.width + x, out.color.at(x, y), out.shading.at(x, y), out.position.at(x, y));
      }
    }
    rays += tracer.rays();
  };
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  const unsigned n = s.threads > 0 ? unsigned(s.threads) : hw;
  std::vector<std::thread> pool;
  for (unsigned i = 1; i < n; ++i) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  out.rays = rays;
  out.render_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

std::string reference_id(const std::string& scene_spec, const Scene& scene, const Camera& c,
                         const ReferenceSettings& s) {
  using json = nlohmann::json;
  const auto v3 = [](const glm::vec3& v) { return json::array({v.x, v.y, v.z}); };
  json j;
  j["version"] = kReferenceVersion;
  j["scene"] = scene_spec;
  j["camera"] = {{"position", v3(c.position)}, {"target", v3(c.target)}, {"up", v3(c.up)},
                 {"fov", c.vfov_deg},          {"near", c.znear},        {"far", c.zfar}};
  j["light"] = {{"direction", v3(scene.light.direction)},
                {"color", v3(scene.light.color)},
                {"intensity", scene.light.intensity}};
  j["sky"] = v3(scene.sky_color);
  j["size"] = {s.width, s.height};
  j["passes"] = {{"shadows", s.shadows}, {"reflections", s.reflections}, {"reflection_shadows", s.reflection_shadows}};
  j["roughness_threshold"] = s.roughness_threshold;
  j["samples"] = s.samples;
  return stable_id(j.dump());
}

namespace {
std::string layer_path(const std::string& dir, const std::string& id, const char* layer) {
  return (std::filesystem::path(dir) / (id + "." + layer + ".exr")).string();
}
}  // namespace

void save_reference(const std::string& dir, const std::string& id, const ReferenceImage& ref) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(dir + ": cannot create the reference cache folder: " + ec.message());
  // The color layer last: load_reference treats a missing layer as "not cached", so an interrupted save
  // is re-rendered.
  write_image(layer_path(dir, id, "shading"), ref.shading);
  write_image(layer_path(dir, id, "position"), ref.position);
  write_image(layer_path(dir, id, "color"), ref.color);
}

bool load_reference(const std::string& dir, const std::string& id, uint32_t width, uint32_t height,
                    ReferenceImage& out) {
  for (const char* layer : {"color", "shading", "position"}) {
    if (!std::filesystem::exists(layer_path(dir, id, layer))) return false;
  }
  ReferenceImage r;
  r.color = read_image(layer_path(dir, id, "color"));
  r.shading = read_image(layer_path(dir, id, "shading"));
  r.position = read_image(layer_path(dir, id, "position"));
  for (const Image4f* im : {&r.color, &r.shading, &r.position}) {
    if (im->width != width || im->height != height) return false;
  }
  out = std::move(r);
  return true;
}

}  // namespace hp
