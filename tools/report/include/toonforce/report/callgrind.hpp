// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Instructions per tick, counted by valgrind's callgrind (deterministic: the same binary on
/// the same inputs counts the same, whatever the load). Runs toonforce_tick_count under
///   valgrind --tool=callgrind --collect-atstart=no --toggle-collect=*measured_tick*
/// so only the ticks are counted (workloads.hpp), and reads back the dumps it makes after each
/// tick (scenarios) or each case (branches). The harness's own cost (the empty tick: the call
/// into measured_tick and its return) is reported apart and subtracted by the callers.

#include <cstdint>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"

namespace toonforce::report {

struct CountedCase {
  std::size_t index = 0;  ///< in make_cases() order
  std::string id;
  bool per_tick = false;  ///< a scenario: one count per tick of one pass
  std::uint64_t ticks = 0;
  std::vector<std::uint64_t> per_tick_counts;  ///< per_tick: instructions of each tick
  std::uint64_t total = 0;                     ///< instructions over all `ticks`

  double mean() const noexcept { return ticks == 0 ? 0.0 : static_cast<double>(total) / static_cast<double>(ticks); }
  /// The most expensive tick (per_tick), else the mean rounded up.
  std::uint64_t max() const noexcept;
};

struct CallgrindOptions {
  std::string valgrind = "valgrind";
  std::string tick_count;  ///< path of toonforce_tick_count
  std::string root;        ///< source tree with scenes/
  std::string filter;      ///< workloads.hpp selected()
  std::uint64_t branch_ticks = 1024;
};

struct CallgrindResult {
  std::vector<CountedCase> cases;
  std::string command;  ///< the command that was run, for reports
};

Result<CallgrindResult> count_instructions(const CallgrindOptions& options);

/// Where toonforce_tick_count is: beside the running executable (build/<preset>/bin).
std::string default_tick_count_path();

}  // namespace toonforce::report
