// Scenes that need no file: "builtin:pica", "builtin:cornell", "builtin:sphere-1m", "builtin:terrain-1m".
// All are deterministic (no clock, no std:: distributions) so images, BVHs and traces repeat exactly.
#pragma once

#include "scene/scene.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hp {

/// Names without the "builtin:" prefix, in a stable order.
std::vector<std::string> builtin_names();

/// The built-in scene called `name` (no prefix), or nullopt when there is none by that name.
std::optional<Scene> make_builtin_scene(const std::string& name);

Scene make_pica_scene();
Scene make_cornell_scene();
Scene make_sphere_1m_scene();
Scene make_terrain_1m_scene();

/// builtin:cornell, exactly. Tests compute analytic depth and normals from these numbers, so the scene is
/// built from them and nothing else.
///
///   Walls (each one quad = 2 triangles, normals pointing into the box, y up, open toward +z):
///     floor    y = 0   x in [-1,1], z in [-1,1]   normal +y   white
///     ceiling  y = 2   x in [-1,1], z in [-1,1]   normal -y   white
///     back     z = -1  x in [-1,1], y in [0,2]    normal +z   white
///     left     x = -1  y in [0,2],  z in [-1,1]   normal +x   red
///     right    x = +1  y in [0,2],  z in [-1,1]   normal -x   green
///     the side z = +1 is open (no geometry).
///   Boxes: the unit cube [-0.5,0.5]^3 instanced twice (12 triangles each), world = T * Ry * S, bottoms on
///   the floor:
///     tall  box: size 0.54 x 1.2 x 0.54, yaw +15 deg, centre (-0.45, 0.6, -0.40);
///                footprint x in [-0.781, -0.119], z in [-0.731, -0.069]
///     short box: size 0.50 x 0.6 x 0.50, yaw -17 deg, centre ( 0.42, 0.3,  0.30);
///                footprint x in [ 0.108,  0.732], z in [-0.012,  0.612]
///   Triangles: 5 walls * 2 + 2 boxes * 12 = 34.
///   Camera: position (0, 1, 3.5), target (0, 1, 0), up +y, vfov 40 deg, znear 0.1, zfar 20.
///     The image centre ray runs along -z at x=0, y=1 and hits the back wall at (0, 1, -1), depth 4.5,
///     normal +z.
///   Unobstructed regions (seen from the camera, nothing in front of them):
///     - the slab |x| <= 0.1 holds no box, so every visible point of the back wall, floor or ceiling with
///       |x| <= 0.1 is seen directly (the camera is at x = 0, so its rays to them stay inside the slab);
///     - the right wall (x = +1) for y >= 0.6 (above the short box, and the tall box is at x < 0);
///     - the left wall (x = -1) for z >= 0.1 (rays to it pass in front of the tall box).
///   Light: directional, direction (toward the light) normalize(0.3, 0.2, 1.0). It enters low through the
///     open side, because from above the ceiling would shadow everything: the whole floor and the back wall
///     below y = 1.6 (minus the boxes' shadows) are lit, the ceiling and right wall face away. The back-wall
///     centre (0, 1, -1) is lit: its shadow ray leaves through the opening at (0.6, 1.4, 1), passing above
///     the short box. The boxes cast shadows toward the back left onto the floor and the back wall.
namespace cornell {
inline constexpr float kFloorY = 0.0f;
inline constexpr float kCeilingY = 2.0f;
inline constexpr float kLeftX = -1.0f;
inline constexpr float kRightX = 1.0f;
inline constexpr float kBackZ = -1.0f;
inline constexpr float kOpenZ = 1.0f;  ///< no wall here

inline constexpr float kTallSize[3] = {0.54f, 1.2f, 0.54f};
inline constexpr float kTallYawDeg = 15.0f;
inline constexpr float kTallCenter[3] = {-0.45f, 0.6f, -0.40f};
inline constexpr float kShortSize[3] = {0.50f, 0.6f, 0.50f};
inline constexpr float kShortYawDeg = -17.0f;
inline constexpr float kShortCenter[3] = {0.42f, 0.3f, 0.30f};

inline constexpr float kCameraPosition[3] = {0.0f, 1.0f, 3.5f};
inline constexpr float kCameraTarget[3] = {0.0f, 1.0f, 0.0f};
inline constexpr float kCameraVfovDeg = 40.0f;
inline constexpr float kCameraZnear = 0.1f;
inline constexpr float kCameraZfar = 20.0f;
/// Unnormalised; the scene stores normalize(kLightDirection).
inline constexpr float kLightDirection[3] = {0.3f, 0.2f, 1.0f};
/// Half-width of the box-free slab around x = 0.
inline constexpr float kClearSlabHalfWidth = 0.1f;

inline constexpr std::size_t kTriangles = 34;
}  // namespace cornell

/// builtin:sphere-1m: one UV sphere of radius 1 at the origin, 1000 segments x 501 rings:
/// exactly 1,000,000 triangles and 500,002 vertices.
namespace sphere_1m {
inline constexpr uint32_t kSegments = 1000;
inline constexpr uint32_t kRings = 501;
inline constexpr float kRadius = 1.0f;
inline constexpr std::size_t kTriangles = 1'000'000;
}  // namespace sphere_1m

/// builtin:terrain-1m: a height field of 1000 x 500 quads of 0.2 units over x in [-100, 100],
/// z in [-50, 50]: exactly 1,000,000 triangles and 501,501 vertices. Heights are value-noise fBm plus a
/// long sine ridge from a fixed seed; |y| <= kMaxAbsHeight by construction.
namespace terrain_1m {
inline constexpr uint32_t kQuadsX = 1000;
inline constexpr uint32_t kQuadsZ = 500;
inline constexpr float kCellSize = 0.2f;
inline constexpr float kMaxAbsHeight = 14.0f;
inline constexpr uint64_t kSeed = 0x5eed'7e44a1'1ull;
inline constexpr std::size_t kTriangles = 1'000'000;
}  // namespace terrain_1m

/// builtin:pica: a reflective floor (2 triangles) and kObjects cubes and spheres.
namespace pica {
inline constexpr std::size_t kObjects = 50;
inline constexpr uint32_t kSphereSegments = 48;
inline constexpr uint32_t kSphereRings = 24;
inline constexpr float kFloorHalfSize = 20.0f;
}  // namespace pica

}  // namespace hp
