// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What the generated image.hpp and motions.cpp (toonforce_mcu_gen) describe: motions as data
/// in the image, and the list of compile-time scenes an image carries.

#include <cstddef>
#include <cstdint>

#include "toonforce/control/servo_loop.hpp"

namespace toonforce::mcu {

/// One row of a replay motion file (scenes/motions/*.csv) as the image's device reads it: the
/// stamp in whole nanoseconds and the position in the image's scalar, converted by the host
/// generator exactly as replay's loop converts a double reading.
template <class S>
struct MotionRowOf {
  std::int64_t t_ns;
  Vec3<S> position_m;
};

template <class S>
struct MotionOf {
  const char* name;
  const MotionRowOf<S>* rows;
  const Vec3<S>* velocity_m_per_s;  ///< nullptr: the motion gives none (it is estimated)
  std::size_t count;
};

/// The scenes of one image, each a struct with kName, Type, make() and kConfig.
template <class... Scenes>
struct SceneList {};

}  // namespace toonforce::mcu
