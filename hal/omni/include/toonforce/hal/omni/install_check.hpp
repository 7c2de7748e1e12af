// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Checks of an OpenHaptics install that the library loader alone cannot explain, for
/// `toonforce devices` and `toonforce doctor`, each with a fix that works on Debian/Ubuntu:
///  - OpenHaptics 3.0 (and the PHANTOM Device Drivers) install into /usr/lib64, which the
///    Debian/Ubuntu dynamic loader does not search: an /etc/ld.so.conf.d entry is needed
///    (`sudo ldconfig` alone changes nothing);
///  - the FireWire Omni's driver (PDD 4.3, libPHANToMIO) wants libraw1394.so.8, where Debian 12
///    ships libraw1394.so.11 (OMNI.md §5: users link one to the other);
///  - the Touch driver (libPhantomIOLib42) keeps its configuration under $GTDD_HOME; its
///    installer sets GTDD_HOME=/usr/share/3DSystems in /etc/environment and Touch_Setup writes
///    $GTDD_HOME/config (OMNI.md §1.2; public install notes create /usr/share/3DSystems/config).
/// Everything is read under a root directory so tests point it at a faked tree. A check is
/// reported only when it applies (the files it is about are installed, or the device it
/// matters for is plugged in). Start-up code; allocates.

#include <optional>
#include <string>
#include <vector>

#include "toonforce/hal/detect.hpp"

namespace toonforce {

struct OpenHapticsHost {
  std::string root = "/";                ///< where etc/, usr/ and sys/ are
  std::optional<std::string> gtdd_home;  ///< $GTDD_HOME of the process that will open the device
  /// This process's view: root "/", $GTDD_HOME from the environment.
  static OpenHapticsHost this_process();
};

/// One check's outcome, with whether a device it matters for is connected (then a problem
/// keeps that device from working; otherwise it is only a warning).
struct OpenHapticsInstallFinding {
  Prerequisite prerequisite;
  bool device_present = false;
};

std::vector<OpenHapticsInstallFinding> check_openhaptics_install(const OpenHapticsHost& host);

/// The fix for a libHD that the loader cannot find although it is installed in /usr/lib64.
inline constexpr const char* kLib64LoaderFix =
    "echo /usr/lib64 | sudo tee /etc/ld.so.conf.d/openhaptics.conf && sudo ldconfig "
    "(Debian and Ubuntu do not search /usr/lib64; `sudo ldconfig` alone does not add it)";

}  // namespace toonforce
