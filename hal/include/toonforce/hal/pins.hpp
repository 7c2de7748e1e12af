// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Digital I/O the servo loop may use on a bring-up host: a tick pin toggled every tick (a
/// scope shows the true period and jitter), an emergency-stop input, an enable (deadman)
/// input, and status lights. The loop is a template over a `Pins` bundle; with `NullPins` every
/// call is an empty inline function, so a build without GPIO runs no GPIO code and `control/`
/// needs no #ifdef (after modm's GpioUnused). Real pins live in hal/gpio.

#include <concepts>
#include <cstdint>

namespace toonforce {

/// The level of an input, already mapped through its configured active level.
enum class PinLevel : std::uint8_t {
  kInactive = 0,
  kActive,
  kError,  ///< the read failed: treat as the safe state (e-stop engaged, enable released)
};

/// What the status lights show.
enum class LightState : std::uint8_t { kIdle, kHoming, kArmed, kFault };

// clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
// clang-format off
template <class P>
concept TickPin = requires(P& p) {
  { p.toggle() } noexcept;
};
template <class P>
concept InputPin = requires(P& p) {
  { p.read() } noexcept -> std::same_as<PinLevel>;
};
template <class L>
concept StatusLights = requires(L& l, LightState s) {
  { l.show(s) } noexcept;
};
// clang-format on

struct NullTickPin {
  constexpr void toggle() noexcept {}
};
/// An input that is never active: the e-stop of a host without one.
struct NeverActive {
  constexpr PinLevel read() noexcept { return PinLevel::kInactive; }
};
/// An input that is always active: the enable switch of a host without one.
struct AlwaysActive {
  constexpr PinLevel read() noexcept { return PinLevel::kActive; }
};
struct NullLights {
  constexpr void show(LightState) noexcept {}
};

/// The pins of one servo loop.
template <TickPin Tick = NullTickPin, InputPin Estop = NeverActive, InputPin Enable = AlwaysActive,
          StatusLights Lights = NullLights>
struct Pins {
  [[no_unique_address]] Tick tick{};
  [[no_unique_address]] Estop estop{};
  [[no_unique_address]] Enable enable{};
  [[no_unique_address]] Lights lights{};
};
using NullPins = Pins<>;

}  // namespace toonforce
