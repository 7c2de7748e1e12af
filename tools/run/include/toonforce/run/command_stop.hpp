// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A command's stop path outside its servo loop: before the loop (the scene loading,
/// the device opening, the viewer starting, `--control-wait`) and after it (the viewer serving
/// the recording), every stop signal (stop_signals(): SIGHUP, SIGINT, SIGTERM, ...) sets
/// command_stop() instead of taking its default action. While the loop runs, the loop's own
/// handlers (realtime_runner.hpp) take over and put these back at its end; a stop that came
/// before them is handed to the loop (SessionOptions::pending_stop), which stops at its first tick
/// with zero force.
#include <atomic>

namespace toonforce {

/// The stop signal's number once one came (0: none).
std::atomic<int>& command_stop();
/// Installs the handlers (once; command_stop() cleared).
void install_command_stop_signals();
/// Puts back what each signal did before.
void restore_command_stop_signals();
bool command_stop_signals_installed();

}  // namespace toonforce
