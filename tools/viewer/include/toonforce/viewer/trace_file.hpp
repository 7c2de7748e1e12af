// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Reading a trace for `toonforce view`: the CSV that `toonforce run --trace` (telemetry
/// columns) or `toonforce sim --trace` (sim columns) wrote. The ten core columns
/// t,x,y,z,vx,vy,vz,fx,fy,fz are required; every other column the viewer knows by name
/// (view_frame.hpp) is taken, and so are the effects' values (columns named KEYN.VALUE, the
/// first kViewEffectValues of them); the rest is ignored, and a column or field missing is NaN.
/// Errors name the file, the line and the column.

#include <cstddef>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/viewer/view_frame.hpp"

namespace toonforce::viewer {

/// 2^20 rows: 17 minutes at 1 kHz, about 230 MB in the server and again in the page.
inline constexpr std::size_t kMaxTraceRows = std::size_t{1} << 20;

struct TraceRecording {
  std::vector<ViewFrame> frames;
  std::string source;                      ///< "run" (telemetry columns), "sim" (sim columns) or "trace"
  double rate_hz = 0.0;                    ///< from the median time step (0: fewer than two rows)
  bool has_loop = false;                   ///< the trace has the servo loop's timing columns
  std::vector<std::string> effect_values;  ///< the effects' value columns, in the frame's order
  /// Non-empty: the last row was cut (no end of line: a killed run, a full disk); it is left
  /// out and this says so, with its line.
  std::string note;
};

Result<TraceRecording> read_trace(const std::string& path, std::size_t max_rows = kMaxTraceRows);
/// The same from text; `name` stands for the file in messages.
Result<TraceRecording> parse_trace(std::string_view text, std::string_view name, std::size_t max_rows = kMaxTraceRows);

}  // namespace toonforce::viewer
