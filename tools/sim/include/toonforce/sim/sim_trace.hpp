// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The `toonforce sim` trace (interfaces.md): the servo loop's telemetry columns, the same as
/// `toonforce run` writes (telemetry_trace.hpp: the core ten, the safety layer's state, the
/// effects' values), then what only a simulation knows:
///   true_x..true_vz             the handle's true position and velocity (not delayed, not
///                               quantised)
///   hand_x,hand_y,hand_z        the hand's reference (where it aims)
///   device_fx..device_fz        the force the device applied (saturated, quantised, held)
///   segment                     hand script segment index from 0 (= count after the script)
/// Every number reads back as the same double, so identical runs give identical bytes.

#include <string>
#include <vector>

#include "toonforce/sim/closed_loop.hpp"
#include "toonforce/trace/telemetry_trace.hpp"
#include "toonforce/trace/trace_writer.hpp"

namespace toonforce {

/// The columns after the core ten, for a scene whose effects show `value_names`.
std::vector<std::string> sim_trace_columns(const std::vector<std::string>& value_names);

/// One record's row as numbers (a scene with `values` effect values): what write_sim_record()
/// writes, and what the Python module's arrays hold. False if it does not fit a TraceRow.
bool sim_record_row(TraceRow& row, const SimRecord& record, std::size_t values);

/// Writes one record (a scene with `values` effect values); false once a write failed.
bool write_sim_record(TraceWriter& writer, const SimRecord& record, std::size_t values);

}  // namespace toonforce
