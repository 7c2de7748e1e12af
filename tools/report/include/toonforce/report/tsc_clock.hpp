// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A low-overhead clock for timing single servo ticks: the x86 time-stamp counter, read with
/// fences so the timed instructions cannot start before the first read nor finish after the
/// second (Intel's "How to benchmark code execution times" white paper pattern: lfence; rdtsc;
/// lfence before, rdtscp; lfence after), calibrated against CLOCK_MONOTONIC, with the
/// cost of the two reads themselves measured and subtracted. Benchmarks only: nothing in a
/// test or in the servo loop depends on it.
///
/// Requires an invariant TSC (constant_tsc and nonstop_tsc in /proc/cpuinfo): it then ticks at
/// a fixed rate whatever the core's frequency, and `calibrate()` measures that rate.

#include <cstdint>
#include <string>

namespace toonforce::report {

/// Reads the TSC before the timed region (nothing after it starts early).
inline std::uint64_t tsc_begin() noexcept {
  std::uint32_t lo = 0;
  std::uint32_t hi = 0;
  asm volatile("lfence\n\trdtsc\n\tlfence" : "=a"(lo), "=d"(hi) : : "memory");
  return (static_cast<std::uint64_t>(hi) << 32) | lo;
}

/// Reads the TSC after the timed region (waits for everything before it to finish).
inline std::uint64_t tsc_end() noexcept {
  std::uint32_t lo = 0;
  std::uint32_t hi = 0;
  asm volatile("rdtscp\n\tlfence" : "=a"(lo), "=d"(hi) : : "rcx", "memory");
  return (static_cast<std::uint64_t>(hi) << 32) | lo;
}

/// Keeps `value` alive (and computed) without storing it anywhere the optimiser can see
/// through; the same trick as Google Benchmark's DoNotOptimize.
template <class T>
inline void keep(const T& value) noexcept {
  asm volatile("" : : "r"(&value) : "memory");
}

struct TscCalibration {
  double cycles_per_ns = 0.0;         ///< TSC rate, measured against CLOCK_MONOTONIC
  double calibration_ms = 0.0;        ///< over how long
  std::uint64_t overhead_cycles = 0;  ///< median cost of an empty begin/end pair (subtracted)
  double overhead_mean_cycles = 0.0;  ///< its mean (subtracted from mean times)
  std::uint64_t overhead_min_cycles = 0;
  std::uint64_t overhead_p999_cycles = 0;
  /// The counter's step: the most frequent non-zero difference of two back-to-back reads
  /// (1 on bare metal; a VM may advance it in coarser steps, which then quantise every time).
  std::uint64_t step_cycles = 1;
  bool invariant = false;  ///< /proc/cpuinfo says constant_tsc and nonstop_tsc
};

/// Measures the TSC rate over `window_ms` of busy waiting on CLOCK_MONOTONIC, and the
/// overhead of an empty measurement (median of `overhead_samples` empty begin/end pairs).
TscCalibration calibrate(double window_ms = 200.0, std::uint32_t overhead_samples = 1000000);

/// One line saying how the clock was calibrated, for reports.
std::string describe(const TscCalibration& c);

}  // namespace toonforce::report
