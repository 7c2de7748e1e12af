// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/data_dir.hpp"

#include <filesystem>

namespace toonforce {

std::string installed_data_dir() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec || exe.empty()) return {};
  // TOONFORCE_DATA_FROM_BINDIR: the install layout's path from bindir to the data ("../share/toonforce").
  const std::filesystem::path dir = (exe.parent_path() / TOONFORCE_DATA_FROM_BINDIR).lexically_normal();
  if (!std::filesystem::is_directory(dir, ec)) return {};
  return dir.string();
}

// Out of line, the one place the path is spelled: callers append to it at run time, so the
// compiler never folds it into a longer literal.
const char* build_source_dir() noexcept {
  static constexpr char kSourceDir[] = TOONFORCE_SOURCE_DIR;
  return kSourceDir;
}

}  // namespace toonforce
