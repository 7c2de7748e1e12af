// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Plots of sim traces: runs tools/plot_trace.py (matplotlib, from Debian's python3-matplotlib)
/// through /usr/bin/python3 as a child process, without a shell. The script is found through
/// the environment variable TOONFORCE_PLOT_SCRIPT, else beside an installed binary's data
/// (<prefix>/share/toonforce/plot_trace.py, data_dir.hpp), else in the source tree this binary
/// was built from. Start-up/after-run code only.

#include <string>
#include <vector>

#include "toonforce/common/result.hpp"

namespace toonforce {

struct PlotRequest {
  std::string trace_path;     ///< a sim trace (sim_trace.hpp columns)
  std::string out_path;       ///< .png or .svg
  std::string kind = "auto";  ///< auto, stroke, wall, cliff or overview (see the script)
  std::string title;
  std::vector<std::string> extra_args;  ///< e.g. --gap XMIN XMAX --threshold V
};

/// Where the plotting script is (for messages and checks).
std::string plot_script_path();

/// Runs the script; an error with what to do if python3, matplotlib or the script is missing.
Result<bool> plot_trace(const PlotRequest& request);

}  // namespace toonforce
