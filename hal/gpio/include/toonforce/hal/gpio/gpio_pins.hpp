// SPDX-License-Identifier: Apache-2.0
#pragma once
/// GPIO pins for the servo loop's `Pins` bundle (control/pins.hpp), over libgpiod 1.6 lines
/// that a `GpioSession` requested at start-up. Tick-path calls (toggle, read, show) are
/// noexcept, allocate nothing and make at most one GPIO ioctl per line; a failed ioctl is
/// counted, never thrown, and a failed read is PinLevel::kError (the safe state).
///
/// A default-constructed pin is *absent*: toggle() and show() do nothing, an absent e-stop
/// reads kInactive and an absent enable kActive, exactly like the null types, at the cost of
/// one predictable branch. So one `GpioPins` type serves any subset of configured pins.
///
/// Why the libgpiod C API underneath, not gpiod.hpp: in libgpiod 1.6 the C++ `line::set_value`
/// and `line::get_value` build a `line_bulk` (a std::vector) and a std::vector of values on
/// every call, and throw std::system_error on failure (bindings/cxx/line.cpp: "Creating a
/// line_bulk object involves a memory allocation every time"); the v1 C++ line also does not
/// expose its `gpiod_line*`. The C `gpiod_line_set_value`/`get_value` build their bulk on the
/// stack and return -1 with errno (lib/core.c). Pins are cheap to copy and do not own their
/// line: the session that opened them must outlive every copy.

#include <array>
#include <cstdint>

#include "toonforce/hal/pins.hpp"

struct gpiod_line;  // libgpiod's opaque line (gpiod.h), owned by its chip in the session

namespace toonforce::gpio {

namespace detail {
/// One GPIOHANDLE_SET_LINE_VALUES ioctl; false if it failed.
bool write_line(gpiod_line* line, int value) noexcept;
/// One GPIOHANDLE_GET_LINE_VALUES ioctl, mapped through the requested active level.
PinLevel read_line(gpiod_line* line) noexcept;
}  // namespace detail

/// An output toggled once per tick: a scope on it shows the true period and jitter.
class GpioTickPin {
 public:
  GpioTickPin() = default;  ///< absent
  /// `line` requested as an output at `initial_value` (start-up, by the session).
  GpioTickPin(gpiod_line* line, int initial_value) noexcept : line_(line), value_(initial_value) {}

  void toggle() noexcept {
    if (line_ != nullptr) write_next();
  }
  bool present() const noexcept { return line_ != nullptr; }
  /// The value last written (logical, i.e. before any active-low inversion).
  int value() const noexcept { return value_; }
  std::uint32_t write_errors() const noexcept { return write_errors_; }

 private:
  void write_next() noexcept;

  gpiod_line* line_ = nullptr;
  int value_ = 0;
  std::uint32_t write_errors_ = 0;
};

/// An input read once per tick; `kWhenAbsent` is what it reads when no line is configured.
template <PinLevel kWhenAbsent>
class GpioInput {
 public:
  GpioInput() = default;  ///< absent
  /// `line` requested as an input (with the active-low flag when the user gave it).
  explicit GpioInput(gpiod_line* line) noexcept : line_(line) {}

  PinLevel read() noexcept {
    if (line_ == nullptr) return kWhenAbsent;
    const PinLevel level = detail::read_line(line_);
    if (level == PinLevel::kError) ++read_errors_;
    return level;
  }
  bool present() const noexcept { return line_ != nullptr; }
  std::uint32_t read_errors() const noexcept { return read_errors_; }

 private:
  gpiod_line* line_ = nullptr;
  std::uint32_t read_errors_ = 0;
};

/// Emergency stop: absent means never engaged (as NeverActive).
using GpioEstopPin = GpioInput<PinLevel::kInactive>;
/// Enable (deadman) switch: absent means always enabled (as AlwaysActive).
using GpioEnablePin = GpioInput<PinLevel::kActive>;

/// One LED per LightState (any subset); the LED of the shown state is lit, the others off.
/// show() writes only when the state changes (then one ioctl per LED), so calling it every
/// tick costs nothing in the steady state.
class GpioLights {
 public:
  static constexpr std::size_t kStates = 4;

  GpioLights() = default;  ///< absent: no LED
  /// Start-up: the LED for `state`, requested as an output at 0 (off).
  void attach(LightState state, gpiod_line* line) noexcept { lines_[static_cast<std::size_t>(state)] = line; }

  void show(LightState state) noexcept {
    if (state == shown_) return;
    if (present()) write(state);
  }
  /// Every LED off (end of a run); afterwards the next show() writes again.
  void all_off() noexcept;

  bool present() const noexcept {
    for (const auto* l : lines_) {
      if (l != nullptr) return true;
    }
    return false;
  }
  std::uint32_t write_errors() const noexcept { return write_errors_; }

 private:
  void write(LightState state) noexcept;

  std::array<gpiod_line*, kStates> lines_{};
  // Nothing shown yet (all LEDs start off), so the first show() writes.
  LightState shown_ = static_cast<LightState>(0xFF);
  std::uint32_t write_errors_ = 0;
};

/// The pins of a run with GPIO (any of them may be absent).
using GpioPins = Pins<GpioTickPin, GpioEstopPin, GpioEnablePin, GpioLights>;

static_assert(TickPin<GpioTickPin> && InputPin<GpioEstopPin> && InputPin<GpioEnablePin> && StatusLights<GpioLights>);

}  // namespace toonforce::gpio
