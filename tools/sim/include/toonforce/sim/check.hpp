// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce check` as a library: everything `run` and `sim` check at load, without running,
/// and the plausibility report, as data. The command prints it (tools/cli/check_command.cpp);
/// the Python module returns it (tools/python), so both say the same from the same code.

#include <optional>
#include <string>
#include <vector>

#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/math/scalar_kind.hpp"

namespace toonforce {

struct CheckOptions {
  std::string scene_path;
  std::optional<std::string> scene_text;   ///< set: the scene is this text; scene_path names it in messages
  std::string script_path;                 ///< empty: no hand script
  std::optional<std::string> script_text;  ///< set: the hand script is this text (as scene_text)
  host_sim::DevicePreset device = host_sim::DevicePreset::kFalcon;
  double rate_hz = 1000.0;  ///< servo rate [Hz]
  ScalarKind scalar = ScalarKind::kDouble;
  bool allow_empty = false;  ///< a scene without effects is not an error
  bool strict = false;       ///< a plausibility warning is an error
};

struct CheckReport {
  /// Non-empty: the rate is one Q16.16 cannot hold for this scene, a bad command-line value
  /// (`check` exits 2 and says nothing else).
  std::string rate_error;
  /// The scene's and hand script's errors, each as printed (one file's errors are one entry of
  /// several lines), in the order found: scene, hand script, its length, an empty scene, the
  /// servo configuration, the simulation's set-up.
  std::vector<std::string> errors;
  std::vector<std::string> notes;     ///< the plausibility report's notes
  std::vector<std::string> warnings;  ///< the plausibility report's warnings
  bool ok = false;                    ///< no error (and, with strict, no warning)
  bool world = false;                 ///< the scene is a world (`sim` and `run` run it)
  int exit_code = 1;                  ///< what `toonforce check` exits with: 0 ok, 1 not, 2 rate_error
};

/// "" or why `check` and `run --script` refuse a hand script lasting `length_s` (one shared
/// rule: over one day; `sim` takes such a script only with a shorter --duration).
std::string hand_script_length_problem(const std::string& path, double length_s);

CheckReport check_scene(const CheckOptions& options);

/// What `toonforce check` prints on standard output for `report` (not the rate error, which goes
/// to standard error): the errors, "note    ..." and "warning ..." lines, the verdict line.
std::string format_check_report(const CheckReport& report, const CheckOptions& options);

}  // namespace toonforce
