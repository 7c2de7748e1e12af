// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce-lab report latency`: the cost of one servo tick of each effect (by branch), of the
/// safety stage, of each paper scene (effects plus ForceSafety) as Scene<...> and as the
/// RuntimeScene its file gives, of the spec's loop (the servo loop with the spec's stages) and of
/// the whole servo loop tick (every safety stage on), for double, float and Q16.16:
///   - ns per tick: every tick timed alone with the TSC (tsc_clock.hpp), the empty
///     measurement's median cost subtracted; median, p99.9 and maximum over `ticks` ticks;
///   - instructions per tick: callgrind (callgrind.hpp), the empty tick's count subtracted;
///     mean, and for the scenarios the most expensive tick.
/// Timings vary with the machine and its load; instruction counts do not.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/report/machine.hpp"
#include "toonforce/report/tsc_clock.hpp"
#include "toonforce/report/workloads.hpp"

namespace toonforce::report {

/// The targets for a paper scene's tick (effects plus safety stage, double).
inline constexpr double kTargetInstructionsPerTick = 400.0;
/// The whole servo loop tick (read to write, every safety stage on), mean instructions, double.
inline constexpr double kTargetLoopInstructionsPerTick = 600.0;
inline constexpr double kTargetMedianNsPerTick = 100.0;

struct LatencyOptions {
  std::string root;                  ///< source tree with scenes/
  std::uint64_t ticks = 10'000'000;  ///< timed ticks per case
  std::string filter;                ///< workloads.hpp selected()
  bool callgrind = true;
  std::string valgrind = "valgrind";
  std::string tick_count;  ///< empty: beside this executable
  int cpu = -1;            ///< pin the timing thread to this CPU (-1: no)
  /// Scene and loop rows: ticks timed with the data caches cold (0: none). Before each, a
  /// buffer larger than the last-level cache is written, outside the timed region.
  std::uint64_t cold_ticks = 1000;
};

struct LatencyRow {
  CaseInfo info;
  std::uint64_t ticks = 0;
  double mean_ns = 0.0;  ///< of the ticks under 50 us (averages out the counter's steps)
  double median_ns = 0.0;
  double p999_ns = 0.0;
  double max_ns = 0.0;
  std::optional<double> instructions_mean;  ///< harness subtracted
  std::optional<double> instructions_max;   ///< scenarios: the most expensive tick of the pass
  std::optional<double> cold_median_ns;     ///< data caches cold (LatencyOptions::cold_ticks)
  std::optional<double> cold_p99_ns;
  /// Search rows: the index of the most expensive tick in the pass.
  std::optional<std::size_t> instructions_argmax;
  /// Loop search rows: what the loop did on each tick (workloads.hpp search_loop_ticks) and
  /// each tick's instructions (harness subtracted), in pass order.
  std::vector<SearchTick> search_ticks;
  std::vector<double> search_instructions;
};

struct LatencyReport {
  MachineInfo machine;
  std::string load_before;
  std::string load_after;
  TscCalibration clock;
  std::uint64_t ticks = 0;
  std::uint64_t cold_ticks = 0;
  std::string command;            ///< how to reproduce
  std::string callgrind_command;  ///< empty if not counted
  double harness_instructions = 0.0;
  std::vector<LatencyRow> rows;
};

using Progress = std::function<void(const std::string&)>;

Result<LatencyReport> run_latency(const LatencyOptions& options, const Progress& progress = {});

/// The report as Markdown sections (tables of paper scenes, effects, controller).
std::string latency_markdown(const LatencyReport& report);

/// Pins the calling thread to `cpu`; false if it could not.
bool pin_to_cpu(int cpu);

}  // namespace toonforce::report
