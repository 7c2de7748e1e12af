// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce bringup falcon`: a guided hardware-in-the-loop bring-up of one Novint Falcon, run
/// once per device and after any change. Steps, in order, each passing or failing with what to
/// do next; the first failure stops the bring-up with forces off:
///   found     the Falcon is on USB and this user may open it
///   firmware  its firmware answers (loaded from --firmware FILE if it has none)
///   homing    all three axes report homed after the person pulls the grip out and pushes it in
///   encoders  the person sweeps the grip to its workspace limits: every encoder counts, over
///             the range the kinematics expect, and the pose estimate converges
///   motors    short small torque pulses, one motor at a time, with the grip held lightly: each
///             arm must turn the way its torque pushes, else zero force at once, naming the motor
///   force     the words-per-torque constant, with a known weight (held by a PI loop) or a
///             spring scale, written to the calibration file open_falcon() reads
///   timing    the USB round trip at 1 kHz as a histogram, and lost replies
///   buttons   each of the four grip buttons, in turn
///   leds      red, green and blue, confirmed by the person
/// Steps that need a person are skipped in a non-interactive run unless named with `only`.
/// Start-up code: allocates, blocks, paces itself at 1 kHz (unless `paced` is off, for tests).

#include <memory>
#include <string>
#include <vector>

#include "toonforce/bringup/operator.hpp"
#include "toonforce/bringup/report.hpp"
#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/falcon/transport.hpp"

namespace toonforce::bringup {

inline constexpr const char* kFalconSteps[] = {"found", "firmware", "homing",  "encoders", "motors",
                                               "force", "timing",   "buttons", "leds"};

struct FalconBringupOptions {
  FalconOptions falcon;           ///< which Falcon, a firmware file, the calibration file in use
  std::vector<std::string> only;  ///< steps to run (empty: all); named steps run unattended too
  std::vector<std::string> skip;  ///< steps not to run
  bool paced = true;              ///< 1 kHz in real time; false: as fast as the device answers
  std::string calibration_out;    ///< where the force step writes; empty: the default for the serial
  double homing_timeout_s = 60.0;
  double sweep_timeout_s = 90.0;
  double person_timeout_s = 120.0;  ///< waits for a person's Enter
  double button_timeout_s = 20.0;
  int timing_ticks = 2000;
  double pulse_torque_n_m = 0.04;  ///< one motor's torque in a pulse (about 1 N at the grip)
  double pulse_s = 0.15;
  int min_motion_counts = 3;  ///< a pulse must turn its arm at least this far
  double hold_s = 2.0;        ///< how long the force step holds before averaging
  std::string toonforce_version;
};

/// Where the Falcon comes from: libusb (usb_falcon_access) or a test's emulator.
class FalconAccess {
 public:
  virtual ~FalconAccess() = default;
  virtual FalconDetection detect() = 0;
  /// The transport of the Falcon `options` select (serial, else index), claimed.
  virtual Result<std::unique_ptr<falcon::FalconTransport>> open(const FalconOptions& options) = 0;
};

/// The Falcons on this host's USB (detect_falcons, open_falcon_transport).
std::unique_ptr<FalconAccess> usb_falcon_access();

Report run_falcon_bringup(FalconAccess& access, Operator& person, const FalconBringupOptions& options);

/// Whether `step` runs under these options, for a given operator (shared by all devices).
bool step_selected(std::string_view step, const std::vector<std::string>& only, const std::vector<std::string>& skip);

}  // namespace toonforce::bringup
