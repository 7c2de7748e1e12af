// SPDX-License-Identifier: Apache-2.0
#pragma once
// The viewer's command-line flags and the life of its server around a run (only in builds with
// TOONFORCE_VIEWER): `--view [PORT]`, `--view-address ADDR` and `--view-host NAME` on run and
// sim, the URL on standard error, and serving the recording after the run until Ctrl-C (SIGINT)
// or SIGTERM.
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <CLI/CLI.hpp>

#include "toonforce/run/command_stop.hpp"
#include "toonforce/run/run.hpp"
#include "toonforce/trace/telemetry_trace.hpp"
#include "toonforce/viewer/hello.hpp"
#include "toonforce/viewer/scene_json.hpp"
#include "toonforce/viewer/viewer_server.hpp"

namespace toonforce::cli {

struct ViewFlags {
  int port = viewer::kDefaultPort;
  std::string address = "127.0.0.1";
  std::vector<std::string> hosts;  ///< --view-host: more names the page may be opened by
  CLI::Option* view = nullptr;     ///< given?
  bool wanted() const { return view != nullptr && view->count() > 0; }
};

/// Adds --view [PORT], --view-address ADDR and --view-host NAME to a subcommand.
void add_view_flags(CLI::App* cmd, ViewFlags& flags);

/// The help text of the host-name option (`--view-host` on run and sim, `--host` on view).
inline constexpr const char* kViewHostHelp =
    "A name other hosts open the page by (the Host header they send), e.g. this host's DNS name, besides the "
    "listen address (and on 0.0.0.0 this host's addresses); repeatable. Requests naming anything else are refused";

/// Starts the server and prints where to open it; an error message on failure. `host_option`
/// is the option that adds names (for the message when other hosts can connect).
Result<std::unique_ptr<viewer::ViewerServer>> start_viewer(
    const viewer::ViewerOptions& options, const viewer::HelloInfo& hello,
    std::optional<std::vector<viewer::ViewFrame>> recording = std::nullopt,
    std::string_view host_option = "--view-host");

/// Live scenes (`run --control`): the editor of the scene `text` (the file `name`'s, as the run
/// read it: named in its messages) for the run's scalar, with its mailbox (set in `live`), for
/// the viewer server's /control. Changes keep the scene's list of effects (the trace's and the
/// viewer's columns). Owns the mailbox: keep it until the run and the server are over. `place`:
/// construct the mailbox there instead (memory shared with the loop's process, room for any
/// scalar's mailbox; server_process.hpp), not owned.
Result<std::unique_ptr<viewer::SceneControl>> open_live_control(const std::string& text, const std::string& name,
                                                                ScalarKind scalar, LiveMailboxes& live,
                                                                void* place = nullptr);

/// The same for a world (`run --scene WORLD --control`): changes go to every device an effect
/// acts on at once (config/world_editor.hpp); `place` as above.
Result<std::unique_ptr<viewer::SceneControl>> open_world_control(const std::string& text, const std::string& name,
                                                                 LiveMailboxes& live, void* place = nullptr);

/// Keeps serving (the page has the whole recording) until Ctrl-C or another stop signal.
void serve_until_stopped(const viewer::ViewerServer& server, const char* what);

}  // namespace toonforce::cli
