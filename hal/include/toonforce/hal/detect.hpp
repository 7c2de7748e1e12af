// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What `toonforce devices` reports about each device a backend finds on this host: whether
/// this user may open it and, if not, what to do. Backends provide the detection; the command
/// prints the list (spec interfaces.md "toonforce devices").

#include <string>
#include <vector>

namespace toonforce {

struct DetectedDevice {
  std::string kind;       ///< "Novint Falcon", "3D Systems Touch", ...
  std::string location;   ///< where it is: "usb 001/005 (/dev/bus/usb/001/005)"
  std::string serial;     ///< empty when unknown
  bool can_open = false;  ///< this user may open it now
  std::string problem;    ///< why not (empty when can_open)
  std::string fix;        ///< what to do about it (a command, a file to install)
};

/// A software prerequisite a backend needs (OpenHaptics, firmware), checked by `devices`.
struct Prerequisite {
  std::string name;  ///< "OpenHaptics HD library"
  bool ok = false;
  std::string detail;  ///< what was found, or what is missing
  std::string fix;     ///< what to install or change (empty when ok)
};

}  // namespace toonforce
