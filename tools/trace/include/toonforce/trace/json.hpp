// SPDX-License-Identifier: Apache-2.0
#pragma once
/// JSON string literals for what toonforce writes as JSON: `run --stats-json` and the live
/// viewer's hello message. One escaper for both, so a scene name or a path reads back the same
/// in either.

#include <string>
#include <string_view>

namespace toonforce {

/// `text` as a JSON string literal, quotes included: `"` and `\` escaped, control characters as
/// \uXXXX, and `<` as \u003c so that no "</script>" survives into anything a page might inline.
std::string json_string(std::string_view text);

}  // namespace toonforce
