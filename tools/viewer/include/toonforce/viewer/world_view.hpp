// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A world (several devices in one scene: config/world_file.hpp) as the viewer page sees it. The
/// frame is the one-device frame's row of kViewStride doubles, its columns named by the hello
/// as for one device: here a world trace's own column names ("left.x", "ball.x", "held"; the
/// trace's header, sim/world_trace.hpp), so the page finds every value by the device it belongs
/// to. A world trace has 15 columns a device; the row holds the ones the page needs first (time,
/// each HIP, commanded force, faults and state; the ball; the hold), then each coupling's force,
/// then every device's coupling and ball forces, each group only if it fits whole.
/// The hello's "world" member names the devices (in order), the couplings (pairs of device
/// indices) and the ball's radius, for the page to draw them.

#include <cstddef>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/viewer/view_frame.hpp"

namespace toonforce::viewer {

/// From a world trace's columns to the page's row: which trace column fills each view column.
class WorldViewMap {
 public:
  /// `trace_columns`: a world trace's header (world_columns() of sim/world_trace.hpp); the
  /// devices are those with a NAME.x column, in order. An error if there is none, or no "t".
  static Result<WorldViewMap> make(const std::vector<std::string>& trace_columns);

  /// The page's column names (kViewStride of them; "" where unused).
  const std::vector<std::string>& columns() const noexcept { return columns_; }
  /// The devices' names, in the trace's order.
  const std::vector<std::string>& devices() const noexcept { return devices_; }
  /// A trace row (in trace_columns' order) as the page's frame: no allocation. `tick` fills the
  /// "tick" column (a world trace has none).
  ViewFrame frame(std::span<const double> row, double tick) const noexcept;

 private:
  std::vector<std::string> columns_;
  std::vector<std::size_t> from_;  ///< per view column: its trace column (npos: none)
  std::vector<std::string> devices_;
};

/// The hello's "world" member: {"devices":[names],"couplings":[[a,b],...],"ball_radius":R|null,
/// "rotations":[[row,row,row],...]|null}: coupling and rotation by the order of `devices`; a
/// device's rotation takes its own frame's vectors (its commanded force) to the world's. Without
/// the world file (`world` null: a trace alone) no couplings, ball radius or rotations.
std::string world_json(const std::vector<std::string>& devices, const WorldDescription* world);

/// A world trace file read for `toonforce view`: its rows as the page's frames.
struct WorldRecording {
  std::vector<ViewFrame> frames;
  std::vector<std::string> columns;  ///< the page's columns (WorldViewMap::columns)
  std::vector<std::string> devices;
  double rate_hz = 0.0;
  std::string note;  ///< non-empty: the last row was cut and left out (as TraceRecording::note)
};

/// Whether a trace header (its first line) is a world trace's: "t" first, a "held" column and
/// no "x" (a one-device trace's HIP).
bool is_world_trace_header(const std::vector<std::string>& header);
Result<WorldRecording> parse_world_trace(std::string_view text, std::string_view name,
                                         std::size_t max_rows = std::size_t{1} << 20);
/// The header of the trace file at `path` (empty if it cannot be read).
std::vector<std::string> read_trace_header(const std::string& path);

}  // namespace toonforce::viewer
