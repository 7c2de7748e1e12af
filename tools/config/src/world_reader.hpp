// SPDX-License-Identifier: Apache-2.0
#pragma once
// Inside the config library: a world read from a TOML document already parsed (the world
// editor's candidate after a change), with the rules and messages of world files.

#include <string_view>

#include "toonforce/common/result.hpp"
#include "toonforce/config/toml_reader.hpp"
#include "toonforce/config/world_file.hpp"

namespace toonforce {

/// Reads and checks `root` as a world file named `source` would be (parse_world's checks).
Result<WorldDescription> describe_world_table(toml::table root, std::string_view source);

}  // namespace toonforce
