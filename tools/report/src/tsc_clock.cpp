// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/tsc_clock.hpp"

#include <time.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace toonforce::report {

namespace {

double monotonic_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) * 1e9 + static_cast<double>(ts.tv_nsec);
}

bool invariant_tsc() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("flags", 0) == 0) {
      return line.find(" constant_tsc") != std::string::npos && line.find(" nonstop_tsc") != std::string::npos;
    }
  }
  return false;
}

}  // namespace

TscCalibration calibrate(double window_ms, std::uint32_t overhead_samples) {
  TscCalibration c;
  c.invariant = invariant_tsc();
  // Rate: TSC cycles over a busy-waited CLOCK_MONOTONIC window, both read back to back at
  // each end (the reads' own cost, tens of ns, is negligible against the window).
  const double t0 = monotonic_ns();
  const std::uint64_t c0 = tsc_begin();
  double t1 = t0;
  while (t1 - t0 < window_ms * 1e6) t1 = monotonic_ns();
  const std::uint64_t c1 = tsc_begin();
  c.calibration_ms = (t1 - t0) / 1e6;
  c.cycles_per_ns = static_cast<double>(c1 - c0) / (t1 - t0);

  // Overhead: an empty begin/end pair, exactly as the timing loops read the counter.
  std::vector<std::uint64_t> samples(std::max<std::uint32_t>(overhead_samples, 1));
  for (auto& s : samples) {
    const std::uint64_t start = tsc_begin();
    const std::uint64_t end = tsc_end();
    s = end - start;
  }
  // The mean leaves out what the timed ticks' means leave out too: samples of 2^17 cycles and
  // more (about 50 us: an interrupt or a preemption, not the measurement).
  double sum = 0.0;
  std::uint64_t kept = 0;
  for (const auto s : samples) {
    if (s >= (std::uint64_t{1} << 17)) continue;
    sum += static_cast<double>(s);
    ++kept;
  }
  c.overhead_mean_cycles = kept > 0 ? sum / static_cast<double>(kept) : 0.0;
  std::sort(samples.begin(), samples.end());
  c.overhead_min_cycles = samples.front();
  c.overhead_cycles = samples[samples.size() / 2];
  c.overhead_p999_cycles = samples[samples.size() * 999 / 1000];

  // Step: back-to-back reads without fences, the most frequent difference above 1 (a
  // difference of 1 shows up on some hypervisors between two reads inside one step).
  std::map<std::uint64_t, std::uint64_t> differences;
  std::uint64_t previous = tsc_begin();
  for (int i = 0; i < 100000; ++i) {
    std::uint32_t lo = 0;
    std::uint32_t hi = 0;
    asm volatile("rdtsc" : "=a"(lo), "=d"(hi));
    const std::uint64_t now = (static_cast<std::uint64_t>(hi) << 32) | lo;
    ++differences[now - previous];
    previous = now;
  }
  std::uint64_t most = 0;
  for (const auto& [difference, count] : differences) {
    if (difference > 1 && count > most) {
      most = count;
      c.step_cycles = difference;
    }
  }
  return c;
}

std::string describe(const TscCalibration& c) {
  return fmt::format(
      "time-stamp counter at {:.4f} GHz (measured against CLOCK_MONOTONIC over {:.0f} ms; invariant TSC: {}); "
      "it advances in steps of {} cycles ({:.1f} ns), so each tick's time is a multiple of that; an empty measurement "
      "(lfence; rdtsc; lfence ... rdtscp; lfence) costs {} cycles = {:.1f} ns (median of 10^6; mean {:.1f}, min {}, "
      "p99.9 {}), subtracted from every tick (the mean from mean times)",
      c.cycles_per_ns, c.calibration_ms, c.invariant ? "yes" : "NO", c.step_cycles,
      static_cast<double>(c.step_cycles) / c.cycles_per_ns, c.overhead_cycles,
      static_cast<double>(c.overhead_cycles) / c.cycles_per_ns, c.overhead_mean_cycles, c.overhead_min_cycles,
      c.overhead_p999_cycles);
}

}  // namespace toonforce::report
