// SPDX-License-Identifier: Apache-2.0
// The effects plus the safety stage of an image's scenes, alone, on Q16.16 inputs (no
// servo loop, no double DeviceReading): the part of the tick that is already free of floating point
// on an FPU-less core, which the no-float test checks. The inputs are read through volatile
// so the compiler cannot fold the scene away; the forces are printed so nothing is discarded.
#include <cstdint>

#include "board.hpp"
#include "image.hpp"

namespace toonforce::mcu {
namespace {

using S = Q16_16;

// Raw Q16.16 inputs: above, at and 3 mm inside the ground, across the cliff's gap, still and
// moving (positions in m, velocities in m/s, times 2^16).
volatile std::int32_t g_positions[][3] = {{-1311, 0, 131}, {0, 0, 0}, {655, 0, -197}, {1966, 0, -65}};
volatile std::int32_t g_velocities[][3] = {{0, 0, 0}, {6554, 0, -13107}, {3277, 655, 0}, {0, 0, 6554}};

template <class SceneDef>
std::int32_t probe() noexcept {
  using SceneT = typename SceneDef::Type;
  static constexpr SceneT kScene = SceneDef::make();
  typename SceneT::State state{};
  static constexpr ForceSafety<S> kSafety{SceneDef::config(0.001, false).limits};  // converted at compile time
  ForceSafety<S> safety = kSafety;
  ActiveForce<S> active[SceneT::kActiveCapacity > 0 ? SceneT::kActiveCapacity : 1]{};
  std::int32_t checksum = 0;
  for (std::int64_t k = 0; k < 4; ++k) {
    TickInput<S> in{};
    const auto i = static_cast<std::size_t>(k);
    in.position_m = {S::from_raw(g_positions[i][0]), S::from_raw(g_positions[i][1]), S::from_raw(g_positions[i][2])};
    in.velocity_m_per_s = {S::from_raw(g_velocities[i][0]), S::from_raw(g_velocities[i][1]),
                           S::from_raw(g_velocities[i][2])};
    in.rate_hz = S::from_raw(1000 << 16);
    in.now = Instant{k, 0};
    const Vec3<S> f = safety.limit(kScene.force(in, state, active), in.rate_hz).force_n;
    checksum ^= f.x.raw() ^ f.y.raw() ^ f.z.raw();
  }
  return checksum;
}

template <class... Scenes>
std::int32_t probe_all(SceneList<Scenes...>) noexcept {
  return (probe<Scenes>() ^ ...);
}

}  // namespace
}  // namespace toonforce::mcu

volatile std::int32_t g_checksum = 0;  // the forces' checksum, so no force is discarded

int run_image() {
  g_checksum = toonforce::mcu::probe_all(toonforce::mcu::image::Scenes{});
  toonforce::mcu::board::write0("probe ok\n");
  return 0;
}
