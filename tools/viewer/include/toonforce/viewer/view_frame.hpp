// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What the viewer page gets for one servo tick: a fixed row of doubles (kViewColumns, in this
/// order), so a batch of frames travels as one Float64Array and the page finds each value by
/// the column name the hello message lists. Filled from the servo loop's TelemetryFrame (run,
/// sim) or from a trace row (view); a value the source does not have is NaN.

#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/control/telemetry.hpp"

namespace toonforce::viewer {

inline constexpr std::array<std::string_view, 25> kViewColumns{"t",          "tick",
                                                               "x",          "y",
                                                               "z",          "vx",
                                                               "vy",         "vz",
                                                               "fx",         "fy",
                                                               "fz",         "scene_fx",
                                                               "scene_fy",   "scene_fz",
                                                               "faults",     "latched",
                                                               "limits",     "state",
                                                               "contact",    "max_force",
                                                               "gain",       "wake_latency_us",
                                                               "compute_us", "slack_us",
                                                               "missed"};
inline constexpr std::size_t kViewFixed = kViewColumns.size();
/// After the fixed columns, the first of the scene's effect values ("surface1.impact_t", named
/// by the hello message; NaN where the scene has fewer).
inline constexpr std::size_t kViewEffectValues = 24;
inline constexpr std::size_t kViewStride = kViewFixed + kViewEffectValues;

/// Column indices (kViewColumns[kT] == "t", ...).
enum ViewColumn : std::size_t {
  kT,
  kTick,
  kX,
  kY,
  kZ,
  kVx,
  kVy,
  kVz,
  kFx,
  kFy,
  kFz,
  kSceneFx,
  kSceneFy,
  kSceneFz,
  kFaults,
  kLatched,
  kLimits,
  kState,
  kContact,
  kMaxForce,
  kGain,
  kWakeLatencyUs,
  kComputeUs,
  kSlackUs,
  kMissed,
  kFirstEffectValue
};
static_assert(kFirstEffectValue == kViewFixed);

using ViewFrame = std::array<double, kViewStride>;

/// Index of a fixed column by name, or kViewStride if there is none.
constexpr std::size_t view_column(std::string_view name) noexcept {
  for (std::size_t i = 0; i < kViewFixed; ++i) {
    if (kViewColumns[i] == name) return i;
  }
  return kViewStride;
}

/// Every column's name as the page gets it: the fixed ones, then `effect_values` (the first
/// kViewEffectValues of them), "" for effect columns the scene does not use.
std::vector<std::string> view_columns(const std::vector<std::string>& effect_values);

/// A telemetry frame as the page sees it. `has_timing` false (the host simulation, which has no
/// real-time runner) leaves the timing columns NaN.
ViewFrame view_frame(const TelemetryFrame& frame, bool has_timing) noexcept;

}  // namespace toonforce::viewer
