#pragma once
/// Faults and limit flags of one tick, as bitmask values (no exceptions on the hot path).
/// A fault means the force could not be computed as the scene says (it is zero or suspect);
/// a limit flag means the safety stage shaped an otherwise good force.

#include <cstdint>

namespace toonforce {

enum class Fault : std::uint32_t {
  kNone = 0,
  kNonFiniteInput = 1U << 0,   ///< NaN/Inf position or velocity: zero force this tick
  kNonFiniteForce = 1U << 1,   ///< the scene's force was NaN/Inf: zero force this tick
  kFixedSaturation = 1U << 2,  ///< a Q-format operation saturated during the tick
};

/// A set of Fault bits.
class FaultSet {
 public:
  constexpr FaultSet() noexcept = default;
  constexpr explicit FaultSet(std::uint32_t bits) noexcept : bits_(bits) {}
  constexpr void set(Fault f) noexcept { bits_ |= static_cast<std::uint32_t>(f); }
  constexpr bool has(Fault f) const noexcept { return (bits_ & static_cast<std::uint32_t>(f)) != 0; }
  constexpr std::uint32_t bits() const noexcept { return bits_; }
  constexpr explicit operator bool() const noexcept { return bits_ != 0; }
  constexpr FaultSet& operator|=(FaultSet o) noexcept {
    bits_ |= o.bits_;
    return *this;
  }
  friend constexpr bool operator==(FaultSet, FaultSet) noexcept = default;

 private:
  std::uint32_t bits_ = 0;
};

enum class Limit : std::uint8_t {
  kNone = 0,
  kRateLimited = 1U << 0,  ///< the force-rate limit shortened this tick's step
  kClamped = 1U << 1,      ///< the force clamp scaled this tick's force down
};
constexpr std::uint8_t operator|(std::uint8_t bits, Limit l) noexcept {
  return static_cast<std::uint8_t>(bits | static_cast<std::uint8_t>(l));
}

}  // namespace toonforce
