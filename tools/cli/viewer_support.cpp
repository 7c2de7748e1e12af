#include "viewer_support.hpp"

#include "commands.hpp"

#include <signal.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include <fmt/format.h>

namespace toonforce::cli {

namespace {
std::atomic<int> g_view_stop{0};
struct sigaction g_old_int {};
struct sigaction g_old_term {};
bool g_installed = false;

extern "C" void on_view_signal(int signal) { g_view_stop.store(signal); }
}  // namespace

void add_view_flags(CLI::App* cmd, ViewFlags& flags) {
  flags.view = cmd->add_option("--view", flags.port,
                               fmt::format("Serve the live viewer page on 127.0.0.1:PORT (default {}; 0: any free "
                                           "port) and keep serving the recording after the run until Ctrl-C",
                                           viewer::kDefaultPort))
                   ->expected(0, 1)
                   ->default_str(std::to_string(viewer::kDefaultPort))
                   ->check(number_in(0, 65535));
  cmd->add_option("--view-address", flags.address,
                  "Listen on this address instead of 127.0.0.1 (e.g. 0.0.0.0: other hosts can watch; read-only)")
      ->needs(flags.view);
  cmd->add_option("--view-host", flags.hosts, kViewHostHelp)->type_name("NAME")->allow_extra_args(false)->take_all()->needs(flags.view);
}

Result<std::unique_ptr<viewer::ViewerServer>> start_viewer(const viewer::ViewerOptions& options,
                                                           const viewer::HelloInfo& hello,
                                                           std::optional<std::vector<viewer::ViewFrame>> recording,
                                                           std::string_view host_option) {
  auto server = recording ? viewer::ViewerServer::start_recording(options, viewer::make_hello(hello), std::move(recording))
                          : viewer::ViewerServer::start(options, viewer::make_hello(hello));
  if (!server) return server;
  const bool other_hosts = options.address != "127.0.0.1" && options.address != "::1";
  fmt::print(stderr, "viewer: {} (open it in a browser){}\n", server.value()->url(),
             other_hosts ? "; read-only, but visible to other hosts" : "");
  if (other_hosts) {
    // The names a request may give, the loopback ones aside: say them, since any other is refused.
    const std::string port = std::to_string(server.value()->port());
    std::string urls;
    for (const std::string& host : server.value()->host_names()) {
      if (host == "127.0.0.1:" + port || host == "localhost:" + port || host == "[::1]:" + port) continue;
      if (host.find(':') == std::string::npos || host.back() == ']') continue;  // port 80's bare form
      urls += fmt::format("{}http://{}/", urls.empty() ? "" : ", ", host);
    }
    fmt::print(stderr, "viewer: other hosts open {}; requests naming another host are refused (add names with {} NAME)\n",
               urls.empty() ? "nothing yet" : urls, host_option);
  }
  std::fflush(stderr);
  return server;
}

std::atomic<int>& view_stop() { return g_view_stop; }

void install_view_signals() {
  g_view_stop.store(0);
  struct sigaction action {};
  action.sa_handler = on_view_signal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, &g_old_int);
  sigaction(SIGTERM, &action, &g_old_term);
  g_installed = true;
}

void restore_view_signals() {
  if (!g_installed) return;
  sigaction(SIGINT, &g_old_int, nullptr);
  sigaction(SIGTERM, &g_old_term, nullptr);
  g_installed = false;
}

void serve_until_stopped(const viewer::ViewerServer& server, const char* what) {
  if (g_installed && g_view_stop.load() != 0) {  // stopped already, while the run went on
    restore_view_signals();
    return;
  }
  if (!g_installed) install_view_signals();
  fmt::print(stderr, "viewer: {}; the page keeps it at {} until Ctrl-C\n", what, server.url());
  std::fflush(stderr);
  while (g_view_stop.load() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  restore_view_signals();
}

}  // namespace toonforce::cli
