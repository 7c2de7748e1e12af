// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A fixed-size histogram of durations in nanoseconds: sized at construction (start-up), then
/// record() only increments a counter (no allocation, no lock), so the real-time thread can
/// fill it every tick. Exact minimum and maximum are kept beside the bins; percentiles come from
/// the bins and are reported as the lower edge of the bin that holds them (as cyclictest
/// reports whole microseconds). Values below zero (a negative slack: an overrun) are counted
/// apart; values past the last bin fall into an overflow bin and percentiles there report the
/// exact maximum.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace toonforce {

struct LatencySummary {
  std::int64_t count = 0;
  std::int64_t min_ns = 0;
  std::int64_t median_ns = 0;
  std::int64_t p99_ns = 0;
  std::int64_t p999_ns = 0;
  std::int64_t max_ns = 0;
  std::int64_t below_zero = 0;  ///< samples < 0
  std::int64_t overflow = 0;    ///< samples past the last bin
};

class LatencyHistogram {
 public:
  /// `bins` bins of `bin_ns` each, from 0.
  LatencyHistogram(std::int64_t bin_ns, std::size_t bins) : bin_ns_(bin_ns), counts_(bins, 0) {}

  void record(std::int64_t ns) noexcept {
    ++count_;
    if (ns < min_) min_ = ns;
    if (ns > max_) max_ = ns;
    if (ns < 0) {
      ++below_zero_;
      return;
    }
    const auto bin = static_cast<std::size_t>(ns / bin_ns_);
    if (bin >= counts_.size()) {
      ++overflow_;
    } else {
      ++counts_[bin];
    }
  }

  /// The p-quantile (0 < p <= 1): the lower edge of the bin holding sample ceil(p * count).
  std::int64_t percentile_ns(double p) const noexcept {
    if (count_ == 0) return 0;
    auto rank = static_cast<std::int64_t>(p * static_cast<double>(count_));
    if (static_cast<double>(rank) < p * static_cast<double>(count_)) ++rank;
    if (rank < 1) rank = 1;
    std::int64_t seen = below_zero_;
    if (seen >= rank) return min_;
    for (std::size_t i = 0; i < counts_.size(); ++i) {
      seen += static_cast<std::int64_t>(counts_[i]);
      if (seen >= rank) return static_cast<std::int64_t>(i) * bin_ns_;
    }
    return max_;
  }

  LatencySummary summary() const noexcept {
    LatencySummary s;
    s.count = count_;
    if (count_ == 0) return s;
    s.min_ns = min_;
    s.max_ns = max_;
    s.median_ns = percentile_ns(0.5);
    s.p99_ns = percentile_ns(0.99);
    s.p999_ns = percentile_ns(0.999);
    s.below_zero = below_zero_;
    s.overflow = overflow_;
    return s;
  }

  std::int64_t bin_ns() const noexcept { return bin_ns_; }
  const std::vector<std::uint64_t>& counts() const noexcept { return counts_; }
  std::int64_t count() const noexcept { return count_; }

 private:
  std::int64_t bin_ns_;
  std::vector<std::uint64_t> counts_;
  std::int64_t count_ = 0;
  std::int64_t below_zero_ = 0;
  std::int64_t overflow_ = 0;
  std::int64_t min_ = std::numeric_limits<std::int64_t>::max();
  std::int64_t max_ = std::numeric_limits<std::int64_t>::min();
};

}  // namespace toonforce
