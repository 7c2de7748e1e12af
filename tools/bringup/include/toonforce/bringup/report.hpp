// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What a bring-up found, step by step, as a person reads it (Markdown) and as a program or a
/// bug report carries it (JSON). Each step passes, warns, fails or is skipped, with what was
/// measured and, unless it passed, what to do next. Start-up code; allocates.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"

namespace toonforce::bringup {

enum class Outcome : std::uint8_t {
  kPass,
  kWarn,     ///< works, but something needs attention (said in `next`)
  kFail,     ///< does not work: bring-up stops here, forces off
  kSkipped,  ///< not run: asked to skip, needs a person in a non-interactive run, or an earlier step failed
};
std::string_view to_string(Outcome o) noexcept;

/// Counts of values in buckets of equal width from zero, the last one open-ended.
struct Histogram {
  std::string unit = "us";
  double bucket_width = 50.0;
  std::vector<std::uint64_t> counts;  ///< counts[i]: values in [i w, (i + 1) w); the last: above
  std::uint64_t samples = 0;
  double min = 0.0, p50 = 0.0, p99 = 0.0, max = 0.0;
};

/// Builds a Histogram (and its percentiles, from the values themselves).
class HistogramBuilder {
 public:
  HistogramBuilder(double bucket_width, std::size_t buckets, std::string unit = "us");
  void reserve(std::size_t n) { values_.reserve(n); }
  void add(double value) { values_.push_back(value); }
  Histogram build() const;

 private:
  double width_;
  std::size_t buckets_;
  std::string unit_;
  std::vector<double> values_;
};

struct Measurement {
  std::string name;   ///< "words_per_newton_metre"
  std::string value;  ///< as text, already formatted
  std::string unit;   ///< "" when none
};

struct StepReport {
  std::string id;     ///< "homing": what --only and --skip name
  std::string title;  ///< "Homing"
  Outcome outcome = Outcome::kSkipped;
  std::string finding;  ///< what was found, one or two sentences
  std::string next;     ///< what to do next (empty when it passed)
  std::vector<Measurement> measurements;
  std::optional<Histogram> histogram;
};

struct Report {
  std::string device;       ///< "Novint Falcon"
  std::string target;       ///< which one: "serial A123, usb 001/005"
  std::string started_utc;  ///< ISO 8601
  std::string toonforce_version;
  std::vector<StepReport> steps;
  /// No step failed.
  bool passed() const noexcept;
  const StepReport* step(std::string_view id) const noexcept;
};

std::string to_markdown(const Report& report);
std::string to_json(const Report& report);

/// Writes `base`.md and `base`.json; returns both paths, or an error naming the one that failed.
Result<std::vector<std::string>> write_report(const Report& report, const std::string& base);

/// Now as ISO 8601 UTC ("2026-11-23T09:41:07Z").
std::string utc_now();

}  // namespace toonforce::bringup
