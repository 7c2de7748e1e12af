#include "viewer_support.hpp"

#include "commands.hpp"

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <concepts>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include <fmt/format.h>

namespace toonforce::cli {

namespace {
std::atomic<int> g_view_stop{0};
// Every stop signal, not SIGINT and SIGTERM alone (issue 27: SIGHUP, SIGQUIT, SIGUSR1, ...
// ended a `run --control-wait` by their default action): the same stop path as the loop's.
std::vector<struct sigaction> g_old_actions;
bool g_installed = false;

extern "C" void on_view_signal(int signal, siginfo_t* info, void* /*context*/) {
  // The kernel's SIGXFSZ (a file-size limit) is a write error the writer reports, not a stop;
  // one sent with kill() is a stop like the loop's (realtime_runner.cpp).
  // (The kernel sends it as if the process had: SI_USER with the process's own pid.)
  if (signal == SIGXFSZ && info != nullptr &&
      ((info->si_code != SI_USER && info->si_code != SI_QUEUE) || info->si_pid == getpid())) {
    return;
  }
  g_view_stop.store(signal);
}
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

namespace {

/// The control protocol's SceneControl with the mailbox it pushes into.
template <Scalar S>
class LiveControl final : public viewer::SceneControl {
 public:
  LiveControl(std::unique_ptr<SceneMailbox<RuntimeScene<S>>> mailbox, SceneEditor<S> editor)
      : mailbox_(std::move(mailbox)), control_(std::move(editor)) {}
  Result<std::uint64_t> set(std::string_view effect, std::string_view keys) override { return control_.set(effect, keys); }
  Result<std::uint64_t> add(std::string_view kind, std::string_view keys) override { return control_.add(kind, keys); }
  Result<std::uint64_t> remove(std::string_view effect) override { return control_.remove(effect); }
  Result<std::uint64_t> load(std::string_view text, std::string name) override {
    return control_.load(text, std::move(name));
  }
  Result<std::uint64_t> fire(std::string_view effect, std::string_view event, double value) override {
    return control_.fire(effect, event, value);
  }
  std::uint64_t applied() const override { return control_.applied(); }
  std::string scene_json() const override { return control_.scene_json(); }

 private:
  std::unique_ptr<SceneMailbox<RuntimeScene<S>>> mailbox_;  // before the editor that points to it
  viewer::EditorControl<S> control_;
};

}  // namespace

Result<std::unique_ptr<viewer::SceneControl>> open_live_control(const std::string& path, ScalarKind scalar,
                                                                LiveMailboxes& live) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in) return Error{fmt::format("{}: cannot be read", path)};
  return with_scalar(
      scalar,
      [&]<Scalar S>() -> Result<std::unique_ptr<viewer::SceneControl>> {
        auto mailbox = std::make_unique<SceneMailbox<RuntimeScene<S>>>();
        auto editor = SceneEditor<S>::open(text.str(), path, *mailbox);
        if (!editor) return Error{editor.error()};
        editor->keep_layout("this run's trace and viewer show the starting scene's effects by column "
                            "(docs/spec/control-protocol.md): move or retune effects instead");
        if constexpr (std::same_as<S, double>) {
          live.of_double = mailbox.get();
        } else if constexpr (std::same_as<S, float>) {
          live.of_float = mailbox.get();
        } else {
          live.of_q16 = mailbox.get();
        }
        return std::unique_ptr<viewer::SceneControl>(
            std::make_unique<LiveControl<S>>(std::move(mailbox), std::move(editor.value())));
      },
      [](ScalarKind kind) -> Result<std::unique_ptr<viewer::SceneControl>> {
        return Error{fmt::format("--scalar {} is not built here", scalar_kind_name(kind))};
      });
}

std::atomic<int>& view_stop() { return g_view_stop; }

void install_view_signals() {
  if (g_installed) return;
  g_view_stop.store(0);
  struct sigaction action {};
  action.sa_sigaction = on_view_signal;
  // Restarted: a message or a statistics file being written when the signal comes completes.
  action.sa_flags = SA_SIGINFO | SA_RESTART;
  sigemptyset(&action.sa_mask);
  const auto signals = stop_signals();
  g_old_actions.resize(signals.size());
  for (std::size_t i = 0; i < signals.size(); ++i) sigaction(signals[i], &action, &g_old_actions[i]);
  g_installed = true;
}

void restore_view_signals() {
  if (!g_installed) return;
  const auto signals = stop_signals();
  for (std::size_t i = 0; i < signals.size(); ++i) sigaction(signals[i], &g_old_actions[i], nullptr);
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
