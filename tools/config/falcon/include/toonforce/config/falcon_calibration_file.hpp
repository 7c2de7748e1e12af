// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The Falcon's calibration file (the format: hal/falcon calibration.hpp), read and written here
/// with the other file formats, through toonforce::config's TableReader, so its errors name the
/// file, the line and the key as a scene file's do. open_falcon() is handed the reader
/// (FalconOptions::read_calibration); the device layer parses nothing.
///
/// Start-up code: allocates, reads files; never called from a tick.

#include <string>
#include <string_view>

#include "toonforce/common/result.hpp"
#include "toonforce/hal/falcon/calibration.hpp"

namespace toonforce::falcon {

/// Parses a calibration file's text; `source` names it in errors ("FILE:LINE: KEY: problem").
Result<FalconCalibration> parse_falcon_calibration(std::string_view text, const std::string& source);
/// Reads and parses `path`; a missing file is an error naming it (a CalibrationReader).
Result<FalconCalibration> read_falcon_calibration(const std::string& path);
/// The file text for `calibration` (what bring-up writes; parse_falcon_calibration reads it back).
std::string format_falcon_calibration(const FalconCalibration& calibration);
/// Writes `calibration` to `path`, creating its directory; an error names the path.
Result<std::string> write_falcon_calibration(const std::string& path, const FalconCalibration& calibration);

}  // namespace toonforce::falcon
