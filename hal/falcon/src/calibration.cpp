// SPDX-License-Identifier: Apache-2.0
// Where the Falcon's calibration file lives (calibration.hpp). Its format is read and written in
// tools/config (falcon_calibration_file.hpp): this layer parses nothing.
#include "toonforce/hal/falcon/calibration.hpp"

#include <cstdlib>

namespace toonforce::falcon {

std::string default_falcon_calibration_path(std::string_view serial) {
  std::string base;
  if (const char* xdg = std::getenv("XDG_CONFIG_HOME"); xdg != nullptr && xdg[0] == '/') {
    base = xdg;
  } else if (const char* home = std::getenv("HOME"); home != nullptr && home[0] != '\0') {
    base = std::string(home) + "/.config";
  } else {
    return {};
  }
  // A serial number is an FTDI string: keep it to characters safe in a file name.
  std::string name;
  for (const char ch : serial) {
    const bool safe =
        (ch >= 'A' && ch <= 'Z') || (ch >= 'a' && ch <= 'z') || (ch >= '0' && ch <= '9') || ch == '-' || ch == '_';
    name += safe ? ch : '_';
  }
  return base + "/toonforce/" + (name.empty() ? std::string("falcon.toml") : "falcon-" + name + ".toml");
}

}  // namespace toonforce::falcon
