// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The Falcon's calibration file: the motor words per newton-metre of joint torque measured on
/// one device, which the driver uses instead of libnifalcon's uncalibrated 10000 (FALCON.md §5
/// "Forces": "rather random"; §3's captures of Novint's own driver used 2-4 times fewer words
/// per newton). `toonforce bringup falcon` measures it and writes the file; open_falcon() uses
/// what a reader it is given parsed (the file format lives with the other file formats, in
/// tools/config: falcon_calibration_file.hpp; this layer parses nothing). Format (TOML; errors
/// name the file, the line and the key, as scene files do):
///
///   # toonforce Falcon calibration (docs/FALCON.md, "Calibration")
///   serial = "A1234567"                 # optional: the Falcon it was measured on
///   words_per_newton_metre = 10400.0    # required, 1000..100000
///
///   [measurement]                       # optional: how it was measured (kept for reports)
///   method = "weight"                   # "weight", "spring-scale" or "manual"
///   reference_force_n = 4.905           # the known force [N] (> 0)
///   measured_force_n = 4.72             # what the scale read, or the weight's equivalent [N]
///   date = "2026-11-23T10:00:00Z"
///   note = "500 g on the grip, z axis"
///
/// Start-up code: allocates, reads files; never called from a tick.

#include <optional>
#include <string>
#include <string_view>

#include "toonforce/common/result.hpp"

namespace toonforce::falcon {

/// libnifalcon's constant (FALCON.md §5), used when no calibration file exists.
inline constexpr double kUncalibratedWordsPerNewtonMetre = 10000.0;
/// The range a file may give: outside it a units slip is likelier than a Falcon.
inline constexpr double kMinWordsPerNewtonMetre = 1000.0;
inline constexpr double kMaxWordsPerNewtonMetre = 100000.0;

struct FalconCalibration {
  double words_per_n_m = kUncalibratedWordsPerNewtonMetre;
  std::string serial;  ///< the Falcon it was measured on; empty: any
  // [measurement]: informational.
  std::string method;
  std::optional<double> reference_force_n;
  std::optional<double> measured_force_n;
  std::string date;
  std::string note;
};

/// Reads and checks the calibration file at `path` (tools/config's read_falcon_calibration); a
/// missing or bad file is an error naming it.
using CalibrationReader = Result<FalconCalibration> (*)(const std::string& path);

/// Where the calibration of the Falcon with this serial number lives by default:
/// $XDG_CONFIG_HOME/toonforce/falcon-SERIAL.toml, else $HOME/.config/toonforce/... ("falcon.toml"
/// without a serial number). Empty when neither variable is set.
std::string default_falcon_calibration_path(std::string_view serial);

}  // namespace toonforce::falcon
