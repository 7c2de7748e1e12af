// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What `toonforce run` says and writes after its loop's process died (the guardian's epilogue,
/// `toonforce run-epilogue`, which the guardian program execs once it has zeroed the force;
/// control/guardian.hpp). Everything here may fail without harm: the force is already zero.

#include <string>

#include "toonforce/control/guardian.hpp"

namespace toonforce::guardian {

/// The trace's end after a death: cut back to its last whole row, then one row at the zero
/// command's time with zero force (the last frame's position and state, or zeros), as wide as
/// the trace's header whatever the frame says. An error in words ("" when written).
std::string end_trace(const std::string& path, const Verdict& verdict, const TelemetryFrame* last_frame);

/// What the guardian says on standard error after a death (several lines).
std::string describe_verdict(const Verdict& verdict, const TelemetryFrame* last_frame);

/// The statistics JSON written when the loop's process died before writing its own.
std::string verdict_json(const Verdict& verdict, const TelemetryFrame* last_frame);

}  // namespace toonforce::guardian
