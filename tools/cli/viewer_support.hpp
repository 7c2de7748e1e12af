#pragma once
// The viewer's command-line flags and the life of its server around a run (only in builds with
// TOONFORCE_VIEWER): `--view [PORT]` and `--view-address ADDR` on run and sim, the URL on
// standard error, and serving the recording after the run until Ctrl-C (SIGINT) or SIGTERM.
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "toonforce/trace/telemetry_trace.hpp"
#include "toonforce/viewer/hello.hpp"
#include "toonforce/viewer/scene_json.hpp"
#include "toonforce/viewer/viewer_server.hpp"

namespace toonforce::cli {

struct ViewFlags {
  int port = viewer::kDefaultPort;
  std::string address = "127.0.0.1";
  CLI::Option* view = nullptr;  ///< given?
  bool wanted() const { return view != nullptr && view->count() > 0; }
};

/// Adds --view [PORT] and --view-address ADDR to a subcommand.
void add_view_flags(CLI::App* cmd, ViewFlags& flags);

/// Starts the server and prints where to open it; an error message on failure.
Result<std::unique_ptr<viewer::ViewerServer>> start_viewer(const viewer::ViewerOptions& options, const viewer::HelloInfo& hello,
                                                           std::optional<std::vector<viewer::ViewFrame>> recording = std::nullopt);

/// Set by SIGINT/SIGTERM once install_view_signals() ran.
std::atomic<int>& view_stop();
void install_view_signals();
void restore_view_signals();

/// Keeps serving (the page has the whole recording) until Ctrl-C or SIGTERM.
void serve_until_stopped(const viewer::ViewerServer& server, const char* what);

}  // namespace toonforce::cli
