// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Motion files for `toonforce replay` (spec interfaces.md): a header row, then one row per
/// servo tick with columns t,x,y,z [s, m] and optionally all three of vx,vy,vz [m/s], in any
/// order. Lines starting with '#' are comments. `t` must be finite and strictly increasing (at
/// the nanosecond the loop resolves it to); a
/// non-finite position or velocity is a valid row (the safety stage gives zero force for it).
/// Other columns are allowed (a `sim` trace replays as it is) and reported as ignored.

#include <cstdint>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce {

struct MotionRow {
  double t_s = 0.0;
  /// t to the nearest nanosecond: the stamp the servo loop takes (effects/tick.hpp, Instant),
  /// an integer, so that a fixed-point loop times without floating point
  std::int64_t t_ns = 0;
  Vec3<double> position_m;
  Vec3<double> velocity_m_per_s;  ///< meaningful only when the motion has velocity
  std::size_t line = 0;           ///< line in the file, for messages
};

struct Motion {
  bool has_velocity = false;
  std::vector<MotionRow> rows;
  std::vector<std::string> ignored_columns;
  /// Non-empty: a warning naming the file and line, e.g. of a last row without its end of line
  /// (cut by a full disk or a killed writer), which is left out.
  std::string note;
};

/// Reads and checks a whole motion file; errors name the file, the line and the column.
Result<Motion> read_motion_csv(const std::string& path);
Result<Motion> parse_motion_csv(const std::string& text, const std::string& source_name);

}  // namespace toonforce
