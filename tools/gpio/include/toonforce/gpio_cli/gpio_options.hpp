// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The GPIO options of `toonforce run` (docs/GPIO.md), registered on any CLI11 (sub)command:
///   --tick-pin CHIP:OFFSET            toggled every tick (scope / logic analyser)
///   --estop-pin LINE[:active-low]     emergency stop input
///   --enable-pin LINE[:active-low]    enable (deadman) input
///   --amp-enable-pin LINE[:active-low] amplifier-enable output, held by run's guardian process
///   --led-pin ROLE=LINE               status light, ROLE idle|homing|armed|fault; repeatable,
///                                     or comma-separated (armed=gpiochip0:5,fault=gpiochip0:6)
/// LINE is CHIP:OFFSET or a line name, with optional :active-low, :pull-up, :pull-down.
/// Syntax errors are CLI11 parse errors; opening the lines (missing chip, line in use, no
/// permission) is gpio::open_gpio / with_gpio_pins, before the loop starts.

#include <CLI/CLI.hpp>

#include "toonforce/hal/gpio/line_spec.hpp"

namespace toonforce::cli {

/// Adds the five options to `command` (in an option group "GPIO"), filling `options`.
void add_gpio_options(CLI::App& command, gpio::GpioOptions& options);

}  // namespace toonforce::cli
