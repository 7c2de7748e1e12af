// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The OpenHaptics device frame and the scene frame (spec effects.md §0).
///
/// OpenHaptics reports positions in millimetres in a frame with x to the user's right, y up and
/// z toward the user (OMNI.md §4.1; the ROS drivers convert it with the same swap). The scene
/// frame has x right, y away from the user, z up, in metres, with its origin at the centre of
/// the device's workspace. So, with c the workspace centre in the device frame [mm]:
///
///     scene = (x, -z, y) / 1000   of   (p_device - c)
///
/// and forces go back with the inverse rotation: F_device = (Fx, Fz, -Fy) [N]. The rotation is
/// proper (determinant +1), so it maps a right-handed frame onto a right-handed one and
/// preserves force magnitudes. The centre c is that of HD_USABLE_WORKSPACE_DIMENSIONS unless
/// the user gives one: the absolute origin of OpenHaptics positions is device-specific and no
/// verified source gives it (OMNI.md §4.2-4.3), so the workspace centre is the one origin the
/// library itself defines.

#include <array>

#include "toonforce/math/vec3.hpp"

namespace toonforce::omni {

inline constexpr double kMetresPerMillimetre = 1e-3;

/// An axis-aligned box as OpenHaptics reports workspaces: {minx, miny, minz, maxx, maxy, maxz} [mm].
using DeviceBoxMm = std::array<double, 6>;

/// Converts between the OpenHaptics frame [mm] and the scene frame [m].
struct Frame {
  Vec3<double> centre_mm;  ///< workspace centre, device frame [mm]

  /// The rotation alone, device axes -> scene axes (no units, no offset).
  static constexpr Vec3<double> rotate_to_scene(const Vec3<double>& d) noexcept { return {d.x, -d.z, d.y}; }
  /// The inverse rotation, scene axes -> device axes.
  static constexpr Vec3<double> rotate_to_device(const Vec3<double>& s) noexcept { return {s.x, s.z, -s.y}; }

  /// A device position [mm] -> scene position [m].
  constexpr Vec3<double> position_m(const Vec3<double>& device_mm) const noexcept {
    return rotate_to_scene(device_mm - centre_mm) * kMetresPerMillimetre;
  }
  /// A scene position [m] -> device position [mm] (for tests and tools).
  constexpr Vec3<double> device_position_mm(const Vec3<double>& scene_m) const noexcept {
    return rotate_to_device(scene_m * (1.0 / kMetresPerMillimetre)) + centre_mm;
  }
  /// A device velocity [mm/s] -> scene velocity [m/s].
  static constexpr Vec3<double> velocity_m_per_s(const Vec3<double>& device_mm_per_s) noexcept {
    return rotate_to_scene(device_mm_per_s) * kMetresPerMillimetre;
  }
  /// A scene force [N] -> the force to command in the device frame [N].
  static constexpr Vec3<double> device_force_n(const Vec3<double>& scene_n) noexcept {
    return rotate_to_device(scene_n);
  }
  /// A device force [N] -> scene force [N].
  static constexpr Vec3<double> scene_force_n(const Vec3<double>& device_n) noexcept {
    return rotate_to_scene(device_n);
  }

  /// The centre of a device box [mm].
  static constexpr Vec3<double> centre_of(const DeviceBoxMm& box) noexcept {
    return {(box[0] + box[3]) / 2.0, (box[1] + box[4]) / 2.0, (box[2] + box[5]) / 2.0};
  }
  /// The scene-frame corners (min, max) [m] of a device box: the rotation swaps and flips axes,
  /// so each scene bound comes from the matching device bound.
  constexpr std::array<Vec3<double>, 2> scene_box_m(const DeviceBoxMm& box) const noexcept {
    const Vec3<double> a = position_m({box[0], box[1], box[2]});
    const Vec3<double> b = position_m({box[3], box[4], box[5]});
    return {Vec3<double>{min(a.x, b.x), min(a.y, b.y), min(a.z, b.z)},
            Vec3<double>{max(a.x, b.x), max(a.y, b.y), max(a.z, b.z)}};
  }

 private:
  static constexpr double min(double a, double b) noexcept { return a < b ? a : b; }
  static constexpr double max(double a, double b) noexcept { return a < b ? b : a; }
};

}  // namespace toonforce::omni
