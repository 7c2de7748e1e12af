// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The Novint Falcon backend's public entry points: open_falcon() is the one factory the rest
/// of toonforce uses (`toonforce run --device falcon` wires to it); detect_falcons() feeds
/// `toonforce devices`; falcon_udev_rule() is the udev rule `toonforce falcon udev-rule`
/// prints. Start-up code: these allocate and block; the returned driver's read()/write() are
/// the tick's (no allocation, bounded, noexcept).

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/hal/detect.hpp"
#include "toonforce/hal/device.hpp"
#include "toonforce/hal/falcon/calibration.hpp"
#include "toonforce/hal/falcon/firmware.hpp"
#include "toonforce/hal/falcon/kinematics.hpp"

namespace toonforce {

/// How to open a Falcon and run its 1 kHz exchange. Defaults suit a real device.
struct FalconOptions {
  // User-provided, so `open_falcon({})` value-initialises through it: g++ 12 otherwise reports
  // a false -Wmaybe-uninitialized on the std::function inside `firmware` at such call sites.
  FalconOptions() noexcept {}  // NOLINT(modernize-use-equals-default)
  std::string serial;          ///< the FTDI serial number of the Falcon to open; empty: use `index`
  unsigned index = 0;          ///< the index-th Falcon in USB enumeration order when `serial` is empty
  /// A firmware file to load if the Falcon has none yet (power-up). Empty: firmware must
  /// already be loaded (`toonforce falcon firmware FILE`). Checked before the device is touched.
  std::string firmware_path;
  falcon::FirmwareLoadOptions firmware{};
  /// The workspace centre in the Falcon frame [m]: the scene-frame origin (effects.md §0).
  /// z = 0.110 is libnifalcon's examples' centre (FALCON.md §5 "Frame").
  Vec3<double> workspace_centre_falcon_m{0.0, 0.0, 0.110};
  /// The calibration file (hal/falcon calibration.hpp) whose words per N m open_falcon() puts
  /// in `motor`. Empty: the default path for the opened Falcon's serial number
  /// (default_falcon_calibration_path) when that file exists, else libnifalcon's uncalibrated
  /// constant. A given path must exist; a file naming another serial number is refused.
  std::string calibration_path;
  /// What reads a calibration file (tools/config's read_falcon_calibration). Null: no file is
  /// read, and a calibration file that should be (a given path, or the default one that exists)
  /// is an error saying so.
  falcon::CalibrationReader read_calibration = nullptr;
  falcon::MotorScale motor{};  ///< words per N m (from the calibration) and the command range
  /// Where motor.words_per_n_m came from, for messages and reports (open_falcon() fills it).
  std::string calibration_source = "libnifalcon's uncalibrated 10000 words per N m (no calibration file)";
  falcon::FkOptions fk{};
  double fk_accept_residual_rad = 1e-6;  ///< a pose estimate worse than this is not used
  std::uint32_t io_timeout_ms = 4;       ///< per USB transfer in a tick (the FTDI answers every 1 ms)
  int max_reads_per_tick = 4;            ///< bulk-IN transfers one read() may make
};

/// Opens a Falcon over libusb-1.0: finds it (VID 0403, PID cb48), claims interface 0, puts the
/// FTDI in normal mode, checks the firmware answers (loading options.firmware_path if it does
/// not), and returns a DeviceDriver in the scene frame. Errors name the device and say what to
/// do (permissions, udev rule, firmware, another program holding it).
Result<std::unique_ptr<DeviceDriver>> open_falcon(const FalconOptions& options = {});

/// Loads a firmware file into a Falcon (`toonforce falcon firmware FILE`): validates the file
/// first, then opens the device, skips the load if firmware already answers (unless `reload`),
/// and loads with retries. Returns a one-line summary of what happened.
Result<std::string> load_falcon_firmware(const std::string& path, const FalconOptions& options, bool reload);

struct FalconDetectOptions {
  bool probe_firmware = true;  ///< open each Falcon this user may open and ask whether firmware runs
};

struct FalconDetection {
  std::vector<DetectedDevice> devices;
  std::vector<Prerequisite> prerequisites;
};

/// The calibration open_falcon() uses for the Falcon with serial number `serial`: the file at
/// `explicit_path` (which must exist), else the default path for `serial` if that file exists,
/// else libnifalcon's uncalibrated constant. `source` says which, for messages.
struct ResolvedFalconCalibration {
  falcon::FalconCalibration calibration;
  std::string source;
  bool from_file = false;
};
Result<ResolvedFalconCalibration> resolve_falcon_calibration(const std::string& explicit_path, std::string_view serial,
                                                             falcon::CalibrationReader read);

/// Every Falcon on the USB bus, whether this user may open it (and if not, why and how to fix
/// it), plus the udev rule, group membership and (per device) firmware prerequisites.
FalconDetection detect_falcons(const FalconDetectOptions& options = {});

/// The udev rule for the Falcon (hal/falcon/udev/60-novint-falcon.rules, built in).
std::string_view falcon_udev_rule() noexcept;
inline constexpr std::string_view kFalconUdevRuleName = "60-novint-falcon.rules";

}  // namespace toonforce
