// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Hand script files (docs/HAND_SCRIPTS.md): TOML describing where the simulated hand starts,
/// its arm impedance and the segments it performs. Checked completely at load time with the
/// same precise errors as scene files (file:line: key: problem, unknown keys with
/// did-you-mean, ranges), then planned (host_sim::HandIntent), so a segment too short for its
/// speed ramps is also reported at its line. Start-up code only.

#include <string>
#include <string_view>

#include "toonforce/common/result.hpp"
#include "toonforce/host_sim/hand_intent.hpp"

namespace toonforce {

/// A hand script as written, and the intent planned from it.
struct HandScriptFile {
  host_sim::HandScript script;
  host_sim::HandIntent intent;
};

Result<HandScriptFile> load_hand_script(const std::string& path);
/// The same from text; `source_name` stands for the file in messages.
Result<HandScriptFile> parse_hand_script(std::string_view text, std::string_view source_name);

}  // namespace toonforce
