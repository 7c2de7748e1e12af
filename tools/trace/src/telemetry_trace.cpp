// SPDX-License-Identifier: Apache-2.0
#include "toonforce/trace/telemetry_trace.hpp"

#include <array>

namespace toonforce {

namespace {
constexpr std::array<const char*, 18> kLoopColumns{
    "scene_fx",    "scene_fy",        "scene_fz",       "damping_fx", "damping_fy", "damping_fz",
    "faults",      "latched",         "limits",         "state",      "contact",    "max_force",
    "temperature", "observed_energy", "episode_energy", "gain",       "tick",       nullptr};
constexpr std::size_t kLoopCount = kLoopColumns.size() - 1;
constexpr std::array<const char*, 4> kTimingColumns{"wake_latency_us", "compute_us", "slack_us", "missed"};
static_assert(kMaxTraceRowValues == kLoopCount + kMaxEffectValues + kTimingColumns.size() + 64,
              "kMaxTraceRowValues counts the loop's, the effects', the timing's and 64 of a producer's own");
}  // namespace

std::vector<std::string> telemetry_columns(const std::vector<std::string>& effect_values, bool with_timing) {
  std::vector<std::string> columns;
  for (std::size_t i = 0; i < kLoopCount; ++i) columns.emplace_back(kLoopColumns[i]);
  const std::size_t n = std::min(effect_values.size(), kMaxEffectValues);
  columns.insert(columns.end(), effect_values.begin(), effect_values.begin() + static_cast<std::ptrdiff_t>(n));
  if (with_timing) columns.insert(columns.end(), kTimingColumns.begin(), kTimingColumns.end());
  return columns;
}

std::size_t telemetry_extra_count(std::size_t effect_values, bool with_timing) {
  return kLoopCount + std::min(effect_values, kMaxEffectValues) + (with_timing ? kTimingColumns.size() : 0);
}

bool frame_row(TraceRow& out, const TelemetryFrame& f, std::size_t effect_values, bool with_timing,
               std::span<const double> more) {
  std::array<double, kMaxTraceRowValues>& row = out.values;
  std::size_t n = 0;
  for (const double v :
       {f.scene_force_n.x, f.scene_force_n.y, f.scene_force_n.z, f.damping_n.x, f.damping_n.y, f.damping_n.z,
        static_cast<double>(f.faults), static_cast<double>(f.latched), static_cast<double>(f.limits),
        static_cast<double>(f.state), f.in_contact ? 1.0 : 0.0, f.max_force_n, f.temperature, f.observed_energy_j,
        f.episode_energy_j, f.gain, static_cast<double>(f.tick)}) {
    row[n++] = v;
  }
  // A frame carries at most kMaxEffectValues; the header was made for `effect_values`.
  const std::size_t values = std::min(effect_values, kMaxEffectValues);
  for (std::size_t i = 0; i < values; ++i) {
    row[n++] = i < f.value_count ? f.values[i] : std::numeric_limits<double>::quiet_NaN();
  }
  if (with_timing) {
    for (const double v :
         {static_cast<double>(f.timing.wake_latency_ns) / 1000.0, static_cast<double>(f.timing.compute_ns) / 1000.0,
          static_cast<double>(f.timing.slack_ns) / 1000.0, static_cast<double>(f.timing.missed_total)}) {
      row[n++] = v;
    }
  }
  if (more.size() > row.size() - n) return false;
  for (const double v : more) row[n++] = v;
  out.count = n;
  out.core = {f.t_s, f.position_m, f.velocity_m_per_s, f.force_n};
  return true;
}

bool write_frame(TraceWriter& writer, const TelemetryFrame& f, std::size_t effect_values, bool with_timing,
                 std::span<const double> more) {
  TraceRow row;
  return frame_row(row, f, effect_values, with_timing, more) && writer.write(row.core, row.extras());
}

SummaryColumns SummaryColumns::of(const std::vector<std::string>& names) {
  SummaryColumns c;
  const auto ends_with = [](std::string_view s, std::string_view tail) {
    return s.size() >= tail.size() && s.substr(s.size() - tail.size()) == tail;
  };
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (ends_with(names[i], ".impact_t")) c.impact_times.push_back(i);
    if (names[i].starts_with("cliff") && ends_with(names[i], ".state")) c.cliff_states.push_back(i);
  }
  return c;
}

}  // namespace toonforce
