#pragma once
/// What the viewer page gets for one servo tick: a fixed row of doubles (kViewColumns, in this
/// order), so a batch of frames travels as one Float64Array and the page finds each value by
/// the column name the hello message lists. Filled from the servo loop's TelemetryFrame (run,
/// sim) or from a trace row (view); a value the source does not have is NaN.

#include <array>
#include <cstddef>
#include <string_view>

#include "toonforce/control/telemetry.hpp"

namespace toonforce::viewer {

inline constexpr std::array<std::string_view, 27> kViewColumns{
    "t",       "tick",     "x",      "y",           "z",           "vx",        "vy",
    "vz",      "fx",       "fy",     "fz",          "scene_fx",    "scene_fy",  "scene_fz",
    "faults",  "latched",  "limits", "state",       "contact",     "impact_t",  "cliff_state",
    "max_force", "gain",   "wake_latency_us", "compute_us", "slack_us", "missed"};
inline constexpr std::size_t kViewStride = kViewColumns.size();

/// Column indices (kViewColumns[kT] == "t", ...).
enum ViewColumn : std::size_t {
  kT, kTick, kX, kY, kZ, kVx, kVy, kVz, kFx, kFy, kFz, kSceneFx, kSceneFy, kSceneFz,
  kFaults, kLatched, kLimits, kState, kContact, kImpactT, kCliffState, kMaxForce, kGain,
  kWakeLatencyUs, kComputeUs, kSlackUs, kMissed
};
static_assert(kMissed + 1 == kViewStride);

using ViewFrame = std::array<double, kViewStride>;

/// Index of a column by name, or kViewStride if there is none.
constexpr std::size_t view_column(std::string_view name) noexcept {
  for (std::size_t i = 0; i < kViewStride; ++i) {
    if (kViewColumns[i] == name) return i;
  }
  return kViewStride;
}

/// A telemetry frame as the page sees it. `has_loop` false (the host simulation, which runs
/// the controller without the servo loop and its runner) leaves the loop's state and timing NaN.
ViewFrame view_frame(const TelemetryFrame& frame, bool has_loop) noexcept;

}  // namespace toonforce::viewer
