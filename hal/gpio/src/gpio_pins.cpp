// SPDX-License-Identifier: Apache-2.0
// The tick-path GPIO calls: the libgpiod C API only (see gpio_pins.hpp for why not gpiod.hpp).
// gpiod_line_set_value/get_value (libgpiod 1.6 lib/core.c) put a one-line bulk on the stack and
// make a single GPIOHANDLE_{SET,GET}_LINE_VALUES ioctl on the line-handle fd: no allocation,
// no lock, and failure is -1 with errno.
#include "toonforce/hal/gpio/gpio_pins.hpp"

#include <gpiod.h>

namespace toonforce::gpio {

namespace detail {

bool write_line(gpiod_line* line, int value) noexcept { return gpiod_line_set_value(line, value) == 0; }

PinLevel read_line(gpiod_line* line) noexcept {
  // The line was requested with GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW when the user asked for
  // it, so the kernel already returns the logical (active = 1) value.
  const int value = gpiod_line_get_value(line);
  if (value < 0) return PinLevel::kError;
  return value != 0 ? PinLevel::kActive : PinLevel::kInactive;
}

}  // namespace detail

void GpioTickPin::write_next() noexcept {
  const int next = value_ ^ 1;
  if (detail::write_line(line_, next)) {
    value_ = next;
  } else {
    ++write_errors_;  // the pin kept its level; the next tick tries again
  }
}

void GpioLights::write(LightState state) noexcept {
  // Every LED is written on a change (state changes are rare), so a write that failed earlier
  // cannot leave a stale LED lit; the others go off before the new one goes on, so two are
  // never lit together.
  const auto lit = static_cast<std::size_t>(state);
  bool ok = true;
  for (std::size_t i = 0; i < kStates; ++i) {
    if (lines_[i] != nullptr && i != lit) ok = detail::write_line(lines_[i], 0) && ok;
  }
  if (lit < kStates && lines_[lit] != nullptr) ok = detail::write_line(lines_[lit], 1) && ok;
  if (ok) {
    shown_ = state;
  } else {
    ++write_errors_;  // shown_ unchanged: the next show() writes again
  }
}

void GpioLights::all_off() noexcept {
  bool ok = true;
  for (auto* line : lines_) {
    if (line != nullptr) ok = detail::write_line(line, 0) && ok;
  }
  if (!ok) ++write_errors_;
  shown_ = static_cast<LightState>(0xFF);
}

}  // namespace toonforce::gpio
