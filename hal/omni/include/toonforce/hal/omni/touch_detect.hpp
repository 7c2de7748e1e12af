// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Detection and diagnostics for `toonforce devices` (spec interfaces.md): which 3D Systems
/// Touch devices are plugged in, whether this user may open the node the vendor driver uses,
/// and whether OpenHaptics is installed and loadable, each with what to do otherwise.
///
/// A Touch is found by its USB vendor id 0x2988 (OMNI.md §1.2; product ids 0x0302 and 0x0304
/// are in public sources). libusb enumerates and tries to open the USB node, which the vendor
/// I/O library claims for the HID model; hidapi lists the hidraw node of the HID model; the
/// serial number and the ttyACM node of the older USB-serial model come from sysfs. Nothing is
/// sent to a device: no Touch wire protocol is public (§1.2, recommendation 4), so detection is
/// all we do with it outside OpenHaptics. Start-up code; allocates.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/hal/detect.hpp"

namespace toonforce {

inline constexpr std::uint16_t kTouchUsbVendorId = 0x2988;
/// Product ids of Touch models seen in public sources (OMNI.md §1.2).
inline constexpr std::uint16_t kTouchUsbProductIds[] = {0x0302, 0x0304};

/// Every device with the 3D Systems vendor id, one entry each.
std::vector<DetectedDevice> detect_touch_devices();

/// Whether the OpenHaptics HD library loads (the same search as open_omni: `library_path`,
/// else $TOONFORCE_LIBHD, else libHD.so, libHD.so.3.4, libHD.so.3.0), and what to install or
/// fix when it does not. Loading is harmless and the library stays loaded (hd_library.hpp).
Prerequisite openhaptics_prerequisite(std::string_view library_path = {});

/// Why a device node could not be opened (an errno value) and what to do, for the node the
/// vendor driver uses: "usb" (/dev/bus/usb/...), "tty" (/dev/ttyACM*) or "hidraw".
struct OpenProblem {
  std::string problem;
  std::string fix;
};
OpenProblem describe_open_failure(std::string_view node, std::string_view kind, int error_number);

}  // namespace toonforce
