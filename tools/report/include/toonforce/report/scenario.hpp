// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Scripted HIP motions for the reports: for each of the five bundled paper scenes, one
/// periodic path that drives every branch of its laws (in and out of contact; Coulomb below
/// and above v_reg; the slippery cap reached and not; an impact triggered, re-triggered while
/// running, and a slow entry that does not trigger; every cliff state and both ledge faces),
/// so a latency or precision figure measured on it covers the expensive ticks too.
///
/// A path is C1: cubic Hermite segments between keyframes (time, position, velocity), so its
/// velocity is exact and continuous, and it repeats with its period (the last keyframe equals
/// the first, one period later). Frame: the scene frame (effects.md §0); every bundled scene
/// has its ground at z = 0 with normal +z, the cliff's gap across x in [0, 0.02] m.

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/math/vec3.hpp"

namespace toonforce::report {

/// The five bundled scenes of the paper's figures (scenes/NAME.toml).
inline constexpr std::array<std::string_view, 5> kPaperScenes{"wall", "realistic_friction", "slippery", "cartoon_wall",
                                                              "cliff"};

struct PathPoint {
  Vec3<double> position_m;
  Vec3<double> velocity_m_per_s;
};

struct Keyframe {
  double t_s = 0.0;
  Vec3<double> position_m;
  Vec3<double> velocity_m_per_s;
};

class KeyframePath {
 public:
  /// `keys` start at t = 0 and increase; the last one closes the period (same position and
  /// velocity as the first). Start-up code.
  explicit KeyframePath(std::vector<Keyframe> keys);

  /// The point at `phase_s` in [0, period) (the caller reduces time exactly, from integer ticks).
  PathPoint at(double phase_s) const noexcept;
  double period_s() const noexcept { return keys_.back().t_s; }
  const std::vector<Keyframe>& keys() const noexcept { return keys_; }

 private:
  std::vector<Keyframe> keys_;
  mutable std::size_t cursor_ = 0;  // last segment found (evaluation mostly moves forward)
};

/// The scenario of a paper scene (one of kPaperScenes); an empty path for any other name.
KeyframePath paper_scenario(std::string_view scene);

/// The bundled scene file of a paper scene: <root>/scenes/<name>.toml.
std::string paper_scene_path(const std::string& root, std::string_view scene);

}  // namespace toonforce::report
