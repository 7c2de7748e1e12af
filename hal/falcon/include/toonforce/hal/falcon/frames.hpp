// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Falcon frame <-> scene frame. Falcon (FALCON.md §5 "Frame"): x to the user's right, y up,
/// z toward the user (out of the device), origin inside the device body. Scene (effects.md
/// §0): x right, y away from the user, z up, origin at the workspace centre. So
/// scene = (x, -z, y) of (falcon - centre): a proper rotation (det +1), so forces map the same
/// way without the offset.

#include "toonforce/math/vec3.hpp"

namespace toonforce::falcon {

constexpr Vec3<double> falcon_to_scene(const Vec3<double>& p_falcon, const Vec3<double>& centre) noexcept {
  const Vec3<double> d = p_falcon - centre;
  return {d.x, -d.z, d.y};
}
constexpr Vec3<double> scene_to_falcon(const Vec3<double>& p_scene, const Vec3<double>& centre) noexcept {
  return Vec3<double>{p_scene.x, p_scene.z, -p_scene.y} + centre;
}
constexpr Vec3<double> scene_force_to_falcon(const Vec3<double>& f_scene) noexcept {
  return {f_scene.x, f_scene.z, -f_scene.y};
}
constexpr Vec3<double> falcon_force_to_scene(const Vec3<double>& f_falcon) noexcept {
  return {f_falcon.x, -f_falcon.z, f_falcon.y};
}

}  // namespace toonforce::falcon
