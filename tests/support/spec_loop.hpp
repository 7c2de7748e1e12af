// SPDX-License-Identifier: Apache-2.0
#pragma once
// The servo loop as `toonforce replay` runs it (effects.md §6 stages only), fed one device
// sample per tick by the test: what the foundation's tests, the scalar agreement and the
// tick fuzzer drive. Nothing here allocates in a tick.
#include <cstdint>

#include "toonforce/control/servo_loop.hpp"

namespace toonforce::test {

/// What the device reports on the next tick (a test sets it before each tick).
struct Sample {
  Vec3<double> position_m;
  Vec3<double> velocity_m_per_s;
  bool has_velocity = false;
  std::int64_t k = 0;
};

inline Sample sample(std::int64_t k, Vec3<double> x) {
  Sample s;
  s.position_m = x;
  s.k = k;
  return s;
}

struct Player {
  const Sample* current;
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = current->position_m;
    r.velocity_m_per_s = current->velocity_m_per_s;
    r.has_velocity = current->has_velocity;
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>&) noexcept { return DeviceStatus::kOk; }
};

/// What a tick gave: the force written, the scene's force, faults and limits.
template <Scalar S>
struct Result {
  Vec3<S> force_n;
  Vec3<S> scene_force_n;
  FaultSet faults;
  std::uint8_t limits = 0;
};

/// Replay's loop over a scene, fed one sample per tick.
template <class SceneT>
class SpecLoop {
 public:
  using S = typename SceneT::Scalar;
  SpecLoop(const SceneT& scene, const ServoConfig& c) : loop_(Player{&current_}, scene, c) {}
  Result<S> tick(const Sample& s, std::int64_t stamp_ns = 0) {
    current_ = s;
    const TickStatus status = loop_.tick(Instant{s.k, stamp_ns});
    const bool counted = !status.faults.has(Fault::kNonFiniteInput) && !status.faults.has(Fault::kNonFiniteForce);
    return {loop_.force(), counted ? loop_.scene_force() : Vec3<S>{}, status.faults, status.limits};
  }

 private:
  Sample current_{};
  ServoLoop<Player, SceneT, NullPins, kSpecStages> loop_;
};

}  // namespace toonforce::test
