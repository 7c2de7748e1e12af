// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The page's files (tools/viewer/dist, the Vite build of tools/viewer/web), compiled into the
/// binary by cmake/embed_assets.cmake: running needs no npm and no files beside the binary, and
/// the server can serve nothing but these (there is no file system path to traverse).

#include <span>
#include <string_view>

namespace toonforce::viewer {

struct Asset {
  std::string_view path;  ///< URL path, "/index.html", "/assets/index-1a2b.js"
  std::string_view content_type;
  std::string_view body;
};

/// Every embedded file.
std::span<const Asset> assets() noexcept;

/// The file a request target names, or nullptr: exact match of the path ("/" is /index.html;
/// a query string is ignored). Nothing is decoded or normalised, so "/../x", "/%2e%2e/x" and
/// "//etc/passwd" name no file.
const Asset* find_asset(std::string_view target) noexcept;

}  // namespace toonforce::viewer
