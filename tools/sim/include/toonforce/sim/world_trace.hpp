// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A world's trace (docs/spec/interfaces.md "World scenes"): a CSV with a header and one row a
/// tick, made from a WorldFrame (control/world_frame.hpp), the same for `sim` and `run`. Per
/// device NAME: NAME.x/y/z (its HIP, world frame), NAME.fx/fy/fz (the force its loop commanded,
/// its own frame), NAME.coupling_f*, NAME.ball_f* (the forces between HIPs on it, world frame),
/// NAME.faults, NAME.latched, NAME.state; then couplingJ.f* (coupling J's force on its first
/// device; the second gets its negation), ball.x/y/z, held.

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/control/world_frame.hpp"

namespace toonforce {

/// The trace's columns, in order.
std::vector<std::string> world_columns(const WorldDescription& world);
/// The SI unit of a world trace's column ("" for flags, bit sets and states).
std::string world_column_unit(const std::string& column);
/// The row of `frame`, in world_columns' order (`row` is cleared first).
void world_row(const WorldFrame& frame, std::vector<double>& row);
/// |the couplings' forces summed over every device| [N]: zero by Newton's third law.
double coupling_imbalance_n(const WorldFrame& frame) noexcept;

/// The trace file: the header, then one line of shortest round-trip numbers a row.
class WorldTrace {
 public:
  /// `path` "-": standard output. `flag` names the option in messages ("--trace").
  static Result<std::unique_ptr<WorldTrace>> open(const std::string& path, const std::vector<std::string>& columns,
                                                  const std::string& flag);
  ~WorldTrace();
  WorldTrace(const WorldTrace&) = delete;
  WorldTrace& operator=(const WorldTrace&) = delete;
  /// False once a write failed or the size limit was reached: nothing more is written.
  bool write(const std::vector<double>& row);
  /// Past `bytes` (0: none) no row is written and write() says false.
  void limit_size(std::uint64_t bytes) noexcept { limit_bytes_ = bytes; }
  bool size_limit_reached() const noexcept { return limit_reached_; }
  bool flush();
  bool close();

 private:
  WorldTrace(std::FILE* file, bool owned) : file_(file), owned_(owned) {}
  std::FILE* file_;
  bool owned_;
  bool ok_ = true;
  bool limit_reached_ = false;
  std::uint64_t limit_bytes_ = 0;
  std::uint64_t written_bytes_ = 0;
  std::string line_;
};

}  // namespace toonforce
