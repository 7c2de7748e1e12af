// SPDX-License-Identifier: Apache-2.0
#include "toonforce/viewer/assets.hpp"

namespace toonforce::viewer {

const Asset* find_asset(std::string_view target) noexcept {
  if (const std::size_t query = target.find_first_of("?#"); query != std::string_view::npos) {
    target = target.substr(0, query);
  }
  if (target == "/") target = "/index.html";
  for (const Asset& asset : assets()) {
    if (asset.path == target) return &asset;
  }
  return nullptr;
}

}  // namespace toonforce::viewer
