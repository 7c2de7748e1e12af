// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Faults and limit flags of one tick, as bitmask values (no exceptions on the hot path).
/// A fault means the force could not be computed as the scene says (it is zero or suspect);
/// a limit flag means the safety stage shaped an otherwise good force.
///
/// Latched faults (kLatchedFaults) keep the force at zero until the servo loop is explicitly
/// re-armed (ServoLoop::request_rearm) and their cause is gone; the others last one tick, after
/// which the force comes back through the soft-start ramp.

#include <cstdint>
#include <string_view>

namespace toonforce {

enum class Fault : std::uint32_t {
  kNone = 0,
  kNonFiniteInput = 1U << 0,   ///< NaN/Inf position or velocity: zero force this tick
  kNonFiniteForce = 1U << 1,   ///< the scene's force was NaN/Inf: zero force this tick
  kFixedSaturation = 1U << 2,  ///< a Q-format operation saturated during the tick
  // The servo loop's safety layer (control/servo_loop.hpp):
  kEstop = 1U << 3,             ///< emergency stop engaged (latched until released + re-armed)
  kWatchdog = 1U << 4,          ///< ticks missed beyond the watchdog's periods (latched)
  kDeviceSilent = 1U << 5,      ///< the device failed for too many ticks in a row (latched)
  kDeviceError = 1U << 6,       ///< this tick's device read or write did not succeed
  kOverspeed = 1U << 7,         ///< HIP faster than max_velocity: force off this tick
  kOutsideWorkspace = 1U << 8,  ///< HIP outside the workspace bounds: force off this tick
};

/// The faults that stay until re-armed.
inline constexpr std::uint32_t kLatchedFaults = static_cast<std::uint32_t>(Fault::kEstop) |
                                                static_cast<std::uint32_t>(Fault::kWatchdog) |
                                                static_cast<std::uint32_t>(Fault::kDeviceSilent);

/// Every fault bit, lowest first (for messages).
inline constexpr Fault kAllFaults[] = {Fault::kNonFiniteInput, Fault::kNonFiniteForce, Fault::kFixedSaturation,
                                       Fault::kEstop,          Fault::kWatchdog,       Fault::kDeviceSilent,
                                       Fault::kDeviceError,    Fault::kOverspeed,      Fault::kOutsideWorkspace};

constexpr std::string_view fault_name(Fault f) noexcept {
  switch (f) {
    case Fault::kNone: return "none";
    case Fault::kNonFiniteInput: return "non-finite input";
    case Fault::kNonFiniteForce: return "non-finite scene force";
    case Fault::kFixedSaturation: return "fixed-point saturation";
    case Fault::kEstop: return "emergency stop";
    case Fault::kWatchdog: return "missed ticks (the loop's own watchdog)";
    case Fault::kDeviceSilent: return "device silent";
    case Fault::kDeviceError: return "device error";
    case Fault::kOverspeed: return "over speed";
    case Fault::kOutsideWorkspace: return "outside workspace";
  }
  return "?";
}

/// A set of Fault bits.
class FaultSet {
 public:
  constexpr FaultSet() noexcept = default;
  constexpr explicit FaultSet(std::uint32_t bits) noexcept : bits_(bits) {}
  constexpr void set(Fault f) noexcept { bits_ |= static_cast<std::uint32_t>(f); }
  constexpr void clear(Fault f) noexcept { bits_ &= ~static_cast<std::uint32_t>(f); }
  constexpr bool has(Fault f) const noexcept { return (bits_ & static_cast<std::uint32_t>(f)) != 0; }
  constexpr std::uint32_t bits() const noexcept { return bits_; }
  constexpr FaultSet latched() const noexcept { return FaultSet(bits_ & kLatchedFaults); }
  constexpr explicit operator bool() const noexcept { return bits_ != 0; }
  constexpr FaultSet& operator|=(FaultSet o) noexcept {
    bits_ |= o.bits_;
    return *this;
  }
  friend constexpr FaultSet operator|(FaultSet a, FaultSet b) noexcept { return FaultSet(a.bits_ | b.bits_); }
  friend constexpr bool operator==(FaultSet, FaultSet) noexcept = default;

 private:
  std::uint32_t bits_ = 0;
};

enum class Limit : std::uint8_t {
  kNone = 0,
  kRateLimited = 1U << 0,  ///< the force-rate limit shortened this tick's step
  kClamped = 1U << 1,      ///< the force clamp scaled this tick's force down
  // The servo loop's safety layer:
  kThermal = 1U << 2,    ///< the clamp is derated below max_force by the thermal model
  kPassivity = 1U << 3,  ///< the passivity controller added damping this tick
  kSoftStart = 1U << 4,  ///< the soft-start ramp scaled the force down
  kEngaging = 1U << 5,   ///< waiting for the scene force to drop below engage_force
  // The device: its reading says the force written the tick before was more than it could
  // give (DeviceReading::force_limited; the Falcon's motor-word cap, docs/FALCON.md).
  kDeviceLimited = 1U << 6,
};
constexpr std::uint8_t operator|(std::uint8_t bits, Limit l) noexcept {
  return static_cast<std::uint8_t>(bits | static_cast<std::uint8_t>(l));
}
constexpr bool has(std::uint8_t bits, Limit l) noexcept { return (bits & static_cast<std::uint8_t>(l)) != 0; }

}  // namespace toonforce
