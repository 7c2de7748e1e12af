// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/paths.hpp"

#include <cstdlib>
#include <filesystem>

namespace toonforce::report {

std::string source_root(const std::string& given) {
  if (!given.empty()) return given;
  std::error_code ec;
  if (std::filesystem::is_regular_file("scenes/cartoon_wall.toml", ec)) return ".";
  return TOONFORCE_SOURCE_DIR;
}

std::string plot_report_script() {
  if (const char* env = std::getenv("TOONFORCE_PLOT_REPORT_SCRIPT"); env != nullptr && *env != '\0') return env;
  return std::string(TOONFORCE_SOURCE_DIR) + "/tools/plot_report.py";
}

}  // namespace toonforce::report
