// SPDX-License-Identifier: Apache-2.0
#pragma once
/// How a person names a GPIO line on the command line, parsed into a value (start-up code; no
/// libgpiod here). Grammar (docs/GPIO.md):
///   LINE    = CHIP ":" OFFSET [":" FLAG]...  |  NAME [":" FLAG]...
///   CHIP    = "gpiochipN" | "/dev/gpiochipN" | "N"
///   FLAG    = "active-low" | "pull-up" | "pull-down"
///   LED     = ROLE "=" LINE, ROLE = "idle" | "homing" | "armed" | "fault"
/// A NAME is the line's name in the kernel (gpioinfo shows it), looked up on every chip.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/hal/pins.hpp"

namespace toonforce::gpio {

/// The pull resistor to ask the kernel for (GPIO uAPI v1 bias flags, Linux 5.5+).
enum class Bias : std::uint8_t { kAsIs, kPullUp, kPullDown };

/// One line, as written.
struct LineSpec {
  std::string chip;         ///< "gpiochip0", "/dev/gpiochip0" or "0"; empty when by name
  unsigned offset = 0;      ///< line offset on `chip` (only when `chip` is set)
  std::string name;         ///< line name to look up on every chip; empty when by chip
  bool active_low = false;  ///< the line is active (asserted) when its level is low
  Bias bias = Bias::kAsIs;
  std::string text;  ///< as written, for messages

  bool by_name() const noexcept { return chip.empty(); }
};

/// Parses `CHIP:OFFSET[:FLAG...]` or `NAME[:FLAG...]`; the error says what is wrong and shows
/// the expected form.
Result<LineSpec> parse_line_spec(std::string_view text);

/// One status light: lit while the loop shows `state`.
struct LedSpec {
  LightState state = LightState::kIdle;
  LineSpec line;
};

/// Parses `ROLE=LINE`, e.g. `armed=gpiochip0:5`, `fault=LED_RED:active-low`.
Result<LedSpec> parse_led_spec(std::string_view text);

/// "idle", "homing", "armed", "fault".
std::string_view light_state_name(LightState state) noexcept;
std::optional<LightState> parse_light_state(std::string_view name) noexcept;

/// `/dev/gpiochipN` for "gpiochipN", "N" or a path (returned as is).
std::string chip_path(std::string_view chip);

/// The GPIO part of a run's command line, as given (tools/gpio registers the options).
struct GpioOptions {
  std::string tick_pin;               ///< --tick-pin: toggled every tick
  std::string estop_pin;              ///< --estop-pin: emergency stop input
  std::string enable_pin;             ///< --enable-pin: enable (deadman) input
  std::vector<std::string> led_pins;  ///< --led-pin ROLE=LINE, repeatable
  /// --amp-enable-pin: the amplifier-enable output. The guardian process holds it, never the
  /// loop's (tools/run/guardian.hpp), so it is not one of the loop's pins (empty() leaves it out).
  std::string amp_enable_pin;

  /// No pin of the loop's configured: the run uses NullPins and no GPIO code.
  bool empty() const noexcept {
    return tick_pin.empty() && estop_pin.empty() && enable_pin.empty() && led_pins.empty();
  }
};

}  // namespace toonforce::gpio
