// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Where the reports find their inputs (scenes/, tools/*.py) and put their outputs.

#include <string>

namespace toonforce::report {

/// `given` if set; else "." if it holds scenes/; else the source tree this was built from.
std::string source_root(const std::string& given);

/// tools/plot_report.py of the source tree (TOONFORCE_PLOT_REPORT_SCRIPT overrides).
std::string plot_report_script();

}  // namespace toonforce::report
