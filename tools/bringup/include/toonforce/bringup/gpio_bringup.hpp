// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce bringup gpio`: the guided bring-up of a real-time host's GPIO lines (docs/GPIO.md).
/// Steps: lines (every configured line opens, as `toonforce run` opens them), tick (the tick
/// pin toggles once per tick: the person reads half the loop's rate on a scope or counter),
/// estop (the e-stop reads released, and pressing it gives zero force in the very tick the
/// servo loop sees it, latched until released and re-armed) and enable (releasing the enable
/// switch gives zero force in that tick; pressing it brings the force back). The e-stop and
/// enable steps run the servo loop itself (control/servo_loop.hpp) with the pins, on a recording
/// device held in a floor, so what is checked is what `run` does. Start-up code.

#include <string>
#include <vector>

#include "toonforce/bringup/operator.hpp"
#include "toonforce/bringup/report.hpp"
#include "toonforce/hal/gpio/line_spec.hpp"

namespace toonforce::bringup {

inline constexpr const char* kGpioSteps[] = {"lines", "tick", "estop", "enable"};

struct GpioBringupOptions {
  gpio::GpioOptions pins;
  std::vector<std::string> only;
  std::vector<std::string> skip;
  double rate_hz = 1000.0;
  bool paced = true;  ///< the loop's rate in real time; false: as fast as it runs (tests)
  double person_timeout_s = 120.0;
  double frequency_tolerance = 0.02;  ///< the tick pin's measured frequency, relative
  std::string toonforce_version;
};

Report run_gpio_bringup(Operator& person, const GpioBringupOptions& options);

}  // namespace toonforce::bringup
