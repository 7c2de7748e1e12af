#pragma once
/// What the generated image.hpp and motions.cpp (toonforce_mcu_gen) describe: motions as data
/// in the image, and the list of compile-time scenes an image carries.

#include <cstddef>

#include "toonforce/control/servo_loop.hpp"

namespace toonforce::mcu {

/// One row of a replay motion file (scenes/motions/*.csv), as the host's reader parsed it.
struct MotionRow {
  double t_s;
  Vec3<double> position_m;
};

struct Motion {
  const char* name;
  const MotionRow* rows;
  const Vec3<double>* velocity_m_per_s;  ///< nullptr: the motion gives none (it is estimated)
  std::size_t count;
};

/// The scenes of one image, each a struct with kName, Type, make() and kConfig.
template <class... Scenes>
struct SceneList {};

}  // namespace toonforce::mcu
