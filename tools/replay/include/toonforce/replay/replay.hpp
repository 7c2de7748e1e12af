// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce replay`: forces for a given motion, open loop (spec interfaces.md). Each input row
/// is one tick of the servo loop (ServoLoop with the spec's stages, kSpecStages: velocity
/// estimate unless given, scene forces, safety stage) on the recorded motion, in the chosen
/// scalar type.

#include <atomic>
#include <cstdio>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/scene_file.hpp"

namespace toonforce {

/// Where run_replay hands every output row as numbers, besides the output file or (with an
/// empty output_path) instead of it: the Python module keeps them as arrays. A field the file
/// leaves empty (a tick whose input was not finite: its effects did not advance) is NaN.
class ReplayRowSink {
 public:
  virtual ~ReplayRowSink() = default;
  /// Before the first row: the output's columns (its header) and the rows to come.
  virtual void begin(const std::vector<std::string>& columns, std::size_t rows) = 0;
  virtual void row(std::span<const double> values) = 0;
};

struct ReplayOptions {
  std::string scene_path;
  /// Set: the scene is this TOML text, not the file's; scene_path names it in messages.
  std::optional<std::string> scene_text;
  bool allow_empty = false;  ///< a scene without effects is not an error (--allow-empty)
  std::string input_path;
  std::optional<std::string> input_text;  ///< set: the motion is this CSV text (as scene_text)
  std::string output_path;                ///< "-" writes to standard output; empty: no file (with `rows`)
  ReplayRowSink* rows = nullptr;          ///< also (or, without output_path, only) every row as numbers
  ScalarKind scalar = ScalarKind::kDouble;
  std::optional<SineMethod> sine;  ///< overrides the scene's sine method
  /// Non-null and set (to a signal's number): stop after the row under way; the output ends on
  /// that whole row (a stop signal: replay once left a cut 80 MB CSV).
  const std::atomic<int>* stop = nullptr;
};

/// What a replay did, for the summary printed at the end.
struct ReplaySummary {
  std::string scene_name;
  std::size_t surfaces = 0;
  std::size_t cliffs = 0;
  std::size_t rows = 0;
  double duration_s = 0.0;
  double median_rate_hz = 0.0;
  bool given_velocity = false;
  std::vector<std::string> ignored_columns;
  double peak_force_n = 0.0;
  double peak_force_t_s = 0.0;
  double peak_scene_force_n = 0.0;
  std::size_t ticks_in_contact = 0;
  std::size_t impacts = 0;       ///< transients triggered
  std::size_t cliff_falls = 0;   ///< SUPPORTED -> FALLEN transitions
  std::size_t rate_limited = 0;  ///< ticks
  std::size_t clamped = 0;       ///< ticks
  std::size_t fault_ticks = 0;
  std::uint32_t fault_bits = 0;  ///< union over the run
  /// Non-empty: writing the output failed (the message, said at once on standard error); the
  /// output stops there (nothing more is written) and the exit status is 1.
  std::string output_error;
  std::string input_note;     ///< the motion reader's warning (a cut last row left out), if any
  int stop_signal = 0;        ///< non-zero: `stop` ended the replay early
  std::size_t rows_done = 0;  ///< rows replayed (and written, unless the output failed)
};

Result<ReplaySummary> run_replay(const ReplayOptions& options);

/// The summary as a few lines for a person.
std::string format_summary(const ReplaySummary& summary, const ReplayOptions& options);

}  // namespace toonforce
