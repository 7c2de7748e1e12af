// SPDX-License-Identifier: Apache-2.0
#pragma once
// The `--scene WORLD.toml` of `devices`, `doctor` and `bringup falcon`: a world scene read
// whole before any device is touched, or, on stderr, why not (file:line: key: problem).
#include <optional>
#include <string>

#include "toonforce/config/world_file.hpp"

namespace toonforce::cli {

/// The world in `path`; nullopt (said on stderr) for a missing or malformed file, or for a
/// one-device scene, which names no devices to resolve. The caller exits with status 2.
std::optional<WorldDescription> load_world_option(const std::string& path);

}  // namespace toonforce::cli
