// SPDX-License-Identifier: Apache-2.0
// Links the Falcon, GPIO and Omni backends as installed and calls into each (libusb, nettle,
// libgpiod, hidapi, libdl), so an export that forgot a dependency fails to link or to run. Argument: the installed udev
// rule, which must be the rule built into the backend (`toonforce falcon udev-rule`).
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/gpio/gpio_session.hpp"
#include "toonforce/hal/gpio/line_spec.hpp"
#include "toonforce/hal/omni/touch_detect.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: backends INSTALLED_UDEV_RULE\n");
    return 2;
  }
  std::ifstream in(argv[1]);
  std::stringstream installed;
  installed << in.rdbuf();
  if (!in || installed.str() != toonforce::falcon_udev_rule()) {
    std::fprintf(stderr, "%s is not the rule built into the Falcon backend\n", argv[1]);
    return 1;
  }
  // libusb: enumerate (no probing); this machine may have no USB at all, which is fine.
  toonforce::FalconDetectOptions detect;
  detect.probe_firmware = false;
  const auto falcons = toonforce::detect_falcons(detect);
  std::printf("Falcons: %zu\n", falcons.devices.size());

  const auto line = toonforce::gpio::parse_line_spec("gpiochip0:17:active-low");
  if (!line || line.value().offset != 17 || !line.value().active_low) {
    std::fprintf(stderr, "parse_line_spec: %s\n", line ? "wrong value" : line.error().c_str());
    return 1;
  }
  // libgpiod: list the chips (none on a machine without GPIO).
  std::printf("GPIO chips: %zu\n", toonforce::gpio::list_chips().size());

  // libusb and hidapi: list Touches (none here); libdl: OpenHaptics from a path that does not
  // exist must be reported missing, with a fix.
  std::printf("Touches: %zu\n", toonforce::detect_touch_devices().size());
  const auto openhaptics = toonforce::openhaptics_prerequisite("/nonexistent/libHD.so");
  if (openhaptics.ok || openhaptics.fix.empty()) {
    std::fprintf(stderr, "OpenHaptics from a missing file: ok=%d, fix '%s'\n", openhaptics.ok, openhaptics.fix.c_str());
    return 1;
  }
  return 0;
}
