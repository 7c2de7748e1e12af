// SPDX-License-Identifier: Apache-2.0
#include "world_option.hpp"

#include <cstdio>

#include <fmt/format.h>

#include "toonforce/config/scene_file.hpp"

namespace toonforce::cli {

std::optional<WorldDescription> load_world_option(const std::string& path) {
  if (!is_world_file(path)) {
    // A missing or malformed file: the scene reader's message (file:line: key: problem).
    auto one = load_scene_file(path);
    if (!one) {
      std::fputs(one.error().c_str(), stderr);
    } else {
      fmt::print(stderr,
                 "{}:1: device: a one-device scene (no [[device]] tables), but --scene here takes a world scene "
                 "(docs/spec/interfaces.md, \"World scenes\"); a one-device scene's device is chosen by the options "
                 "of `run --device falcon|omni` (--serial, --falcon-index, --omni-device)\n",
                 path);
    }
    return std::nullopt;
  }
  auto loaded = load_world_file(path);
  if (!loaded) {
    std::fputs(loaded.error().c_str(), stderr);
    return std::nullopt;
  }
  return std::move(loaded).value();
}

}  // namespace toonforce::cli
