// SPDX-License-Identifier: Apache-2.0
#pragma once
/// One tick of a world (world.hpp) as a record, in double and SI units: every device's HIP in
/// the world frame, the force its loop commanded (its own frame), the forces between HIPs on it
/// (world frame, before its safety chain), its faults and state; each coupling's force on its
/// first device; the ball; whether one stop holds every device. Fixed size and trivially
/// copyable: the servo thread fills one a tick and hands it through an SpscRing to the writer
/// thread (`toonforce run`), and the simulation (`toonforce sim`) writes its trace from the same
/// record, so both traces have one meaning.

#include <array>
#include <cstddef>
#include <cstdint>

#include "toonforce/control/telemetry.hpp"
#include "toonforce/control/world.hpp"

namespace toonforce {

/// The most devices a world record carries (a world file lists at most this many).
inline constexpr std::size_t kWorldFrameDevices = 4;

struct WorldDeviceFrame {
  Vec3<double> hip_m;       ///< world frame
  Vec3<double> force_n;     ///< what the device's loop commanded, in the device's own frame
  Vec3<double> coupling_n;  ///< the couplings' sum on this HIP, world frame
  Vec3<double> ball_n;      ///< the ball's force on this HIP, world frame
  std::uint32_t faults = 0;
  std::uint32_t latched = 0;
  std::uint8_t state = 0;   ///< LoopState
  std::uint8_t limits = 0;  ///< Limit bits (faults.hpp): which limits acted on its force
};

struct WorldFrame {
  std::int64_t tick = 0;
  double t_s = 0.0;
  std::uint8_t devices = 0;
  std::uint8_t couplings = 0;
  bool has_ball = false;
  bool held = false;            ///< one stop holds every device at zero force
  std::uint8_t held_by = 0xFF;  ///< the device whose fault started the hold (0xFF: none)
  std::array<WorldDeviceFrame, kWorldFrameDevices> device{};
  std::array<Vec3<double>, kMaxCouplings> coupling_n{};  ///< each coupling's force on its first device
  Vec3<double> ball_m;
  TickTiming timing{};  ///< the real-time runner's (zero in simulated time)
};

/// Fills `out` from `world` after a tick at integer time k whose outcome was `status`.
template <class WorldT, std::size_t N>
void fill_world_frame(const WorldT& world, const WorldStatus<N>& status, std::int64_t k, double period_s,
                      WorldFrame& out) noexcept {
  static_assert(N <= kWorldFrameDevices, "a world record carries at most kWorldFrameDevices devices");
  out.tick = k;
  out.t_s = static_cast<double>(k) * period_s;
  out.devices = static_cast<std::uint8_t>(N);
  for (std::size_t i = 0; i < N; ++i) {
    WorldDeviceFrame& d = out.device[i];
    const auto& loop = world.loop(i);
    d.hip_m = to_double(world.hip_m(i));
    d.force_n = to_double(loop.force());
    d.coupling_n = to_double(world.coupling_sum_n(i));
    d.ball_n = to_double(world.ball_force_n(i));
    d.faults = status.devices[i].faults.bits();
    d.latched = loop.latched().bits();
    d.state = static_cast<std::uint8_t>(status.devices[i].state);
    d.limits = status.devices[i].limits;
  }
  const std::size_t couplings = world.config().coupling_count;
  out.couplings = static_cast<std::uint8_t>(couplings);
  for (std::size_t j = 0; j < couplings; ++j) out.coupling_n[j] = to_double(world.coupling_force_n(j));
  out.has_ball = world.config().has_ball;
  out.ball_m = world.ball().position_m;
  out.held = status.held;
  out.held_by = status.held_by < N ? static_cast<std::uint8_t>(status.held_by) : std::uint8_t{0xFF};
}

/// The status of the shut-down tick (each loop's last), for its record.
template <class WorldT>
auto shutdown_status(const WorldT& world) noexcept {
  WorldStatus<WorldT::size()> status;
  for (std::size_t i = 0; i < WorldT::size(); ++i) status.devices[i] = world.loop(i).last_status();
  status.held = world.held();
  status.held_by = world.held_by();
  return status;
}

}  // namespace toonforce
