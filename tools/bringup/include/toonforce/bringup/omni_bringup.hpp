// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce bringup omni`: the guided bring-up of a Phantom Omni / Touch through OpenHaptics.
/// Steps: found (libHD loads, with the install checks of install_check.hpp, and the device
/// opens), driver (version, model, the limits it reports and the cap in use), calibration (the
/// loop calibrates as the vendor does; the person is told what the device needs: the stylus in
/// the inkwell, a sweep), workspace (a sweep reaches most of the usable workspace), motors
/// (short small force pulses along each scene axis with the stylus held lightly: the stylus
/// must move the way it is pushed, else zero force at once), timing (the vendor scheduler's
/// period as a histogram, and overruns) and buttons. OpenHaptics converts to newtons itself:
/// there is no force constant to measure. The device runs on its own clock; the bring-up polls
/// the person while it does. Start-up code.

#include <string>
#include <vector>

#include "toonforce/bringup/operator.hpp"
#include "toonforce/bringup/report.hpp"
#include "toonforce/hal/omni/omni_device.hpp"

namespace toonforce::bringup {

inline constexpr const char* kOmniSteps[] = {"found",  "driver", "calibration", "workspace",
                                             "motors", "timing", "buttons"};

struct OmniBringupOptions {
  OmniOptions omni;
  std::vector<std::string> only;
  std::vector<std::string> skip;
  double calibration_timeout_s = 60.0;
  double sweep_timeout_s = 90.0;
  double person_timeout_s = 120.0;
  double button_timeout_s = 20.0;
  int timing_ticks = 2000;
  double pulse_force_n = 0.5;  ///< below the Omni's 0.88 N continuous force
  double pulse_s = 0.15;
  double min_motion_m = 0.0005;    ///< a pulse must move the stylus at least this far its way
  double poll_interval_s = 0.001;  ///< between polls of the person (0 for tests whose person steps the device)
  std::string toonforce_version;
};

Report run_omni_bringup(Operator& person, const OmniBringupOptions& options);

}  // namespace toonforce::bringup
