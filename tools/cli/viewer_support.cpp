// SPDX-License-Identifier: Apache-2.0
#include "viewer_support.hpp"

#include "commands.hpp"

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <concepts>
#include <cstdio>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "toonforce/config/world_editor.hpp"
#include "toonforce/trace/json.hpp"

namespace toonforce::cli {

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
  cmd->add_option("--view-host", flags.hosts, kViewHostHelp)
      ->type_name("NAME")
      ->allow_extra_args(false)
      ->take_all()
      ->needs(flags.view);
}

Result<std::unique_ptr<viewer::ViewerServer>> start_viewer(const viewer::ViewerOptions& options,
                                                           const viewer::HelloInfo& hello,
                                                           std::optional<std::vector<viewer::ViewFrame>> recording,
                                                           std::string_view host_option) {
  auto server = recording
                    ? viewer::ViewerServer::start_recording(options, viewer::make_hello(hello), std::move(recording))
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
    fmt::print(stderr,
               "viewer: other hosts open {}; requests naming another host are refused (add names with {} NAME)\n",
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
  LiveControl(std::unique_ptr<SceneMailbox<RuntimeScene<S>>> owned, SceneEditor<S> editor)
      : owned_(std::move(owned)), control_(std::move(editor)) {}
  Result<std::uint64_t> set(std::string_view effect, std::string_view keys) override {
    return control_.set(effect, keys);
  }
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
  std::unique_ptr<SceneMailbox<RuntimeScene<S>>>
      owned_;  // before the editor that points to it (null: in shared memory)
  viewer::EditorControl<S> control_;
};

/// The effect kinds' keys ("surface", "cliff") by kind index.
std::string kind_key(std::size_t kind) {
  std::string key;
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    ((I == kind ? (key = RuntimeScene<double>::Kind<I>::kKey, 0) : 0), ...);
  }
  (std::make_index_sequence<RuntimeScene<double>::kind_count()>{});
  return key;
}

/// The control protocol's SceneControl of a world: its WorldEditor and mailbox. Its scene is
/// the viewer's scene JSON of every effect, with `devices`: each device's name and the effects
/// that act on it.
class WorldControl final : public viewer::SceneControl {
 public:
  WorldControl(std::unique_ptr<WorldEditor::Mailbox> owned, WorldEditor editor)
      : owned_(std::move(owned)), editor_(std::move(editor)) {}
  Result<std::uint64_t> set(std::string_view effect, std::string_view keys) override {
    return editor_.set(effect, keys);
  }
  Result<std::uint64_t> add(std::string_view kind, std::string_view) override { return editor_.add(kind); }
  Result<std::uint64_t> remove(std::string_view effect) override { return editor_.remove(effect); }
  Result<std::uint64_t> load(std::string_view, std::string name) override { return editor_.load(name); }
  Result<std::uint64_t> fire(std::string_view effect, std::string_view event, double value) override {
    return editor_.fire(effect, event, value);
  }
  std::uint64_t applied() const override { return editor_.applied(); }
  std::string scene_json() const override {
    const WorldDescription& world = editor_.world();
    std::string out = viewer::scene_json(world.scene);
    if (out.empty() || out.back() != '}') return out;
    out.pop_back();
    out += R"(,"devices":[)";
    for (std::size_t i = 0; i < world.devices.size(); ++i) {
      std::string effects;
      for (const SceneEntry& e : world.scene.order) {
        const auto& masks = world.effect_devices[e.kind];
        if (e.index < masks.size() && (masks[e.index] & (1U << i)) == 0) continue;
        effects += fmt::format(R"({}{{"key":{},"number":{}}})", effects.empty() ? "" : ",",
                               json_string(kind_key(e.kind)), e.index + 1);
      }
      out += fmt::format(R"({}{{"name":{},"backend":{},"effects":[{}]}})", i == 0 ? "" : ",",
                         json_string(world.devices[i].name), json_string(world.devices[i].backend), effects);
    }
    out += "]}";
    return out;
  }

 private:
  std::unique_ptr<WorldEditor::Mailbox> owned_;  // before the editor that points to it (null: in shared memory)
  WorldEditor editor_;
};

}  // namespace

Result<std::unique_ptr<viewer::SceneControl>> open_world_control(const std::string& text, const std::string& name,
                                                                 LiveMailboxes& live, void* place) {
  std::unique_ptr<WorldEditor::Mailbox> owned;
  WorldEditor::Mailbox* mailbox = nullptr;
  if (place != nullptr) {
    mailbox = new (place) WorldEditor::Mailbox();
  } else {
    owned = std::make_unique<WorldEditor::Mailbox>();
    mailbox = owned.get();
  }
  auto editor = WorldEditor::open(text, name, *mailbox);
  if (!editor) return Error{editor.error()};
  live.of_world = mailbox;
  return std::unique_ptr<viewer::SceneControl>(
      std::make_unique<WorldControl>(std::move(owned), std::move(editor.value())));
}

Result<std::unique_ptr<viewer::SceneControl>> open_live_control(const std::string& text, const std::string& name,
                                                                ScalarKind scalar, LiveMailboxes& live, void* place) {
  return with_scalar(
      scalar,
      [&]<Scalar S>() -> Result<std::unique_ptr<viewer::SceneControl>> {
        // In `place` (the memory the server process shares with the loop's) or owned here.
        std::unique_ptr<SceneMailbox<RuntimeScene<S>>> owned;
        SceneMailbox<RuntimeScene<S>>* mailbox = nullptr;
        if (place != nullptr) {
          mailbox = new (place) SceneMailbox<RuntimeScene<S>>();
        } else {
          owned = std::make_unique<SceneMailbox<RuntimeScene<S>>>();
          mailbox = owned.get();
        }
        auto editor = SceneEditor<S>::open(text, name, *mailbox);
        if (!editor) return Error{editor.error()};
        editor->keep_layout("this run's trace and viewer show the starting scene's effects by column "
                            "(docs/spec/control-protocol.md): move or retune effects instead");
        if constexpr (std::same_as<S, double>) {
          live.of_double = mailbox;
        } else if constexpr (std::same_as<S, float>) {
          live.of_float = mailbox;
        } else {
          live.of_q16 = mailbox;
        }
        return std::unique_ptr<viewer::SceneControl>(
            std::make_unique<LiveControl<S>>(std::move(owned), std::move(editor.value())));
      },
      [](ScalarKind kind) -> Result<std::unique_ptr<viewer::SceneControl>> {
        return Error{fmt::format("--scalar {} is not built here", scalar_kind_name(kind))};
      });
}

void serve_until_stopped(const viewer::ViewerServer& server, const char* what) {
  if (command_stop_signals_installed() && command_stop().load() != 0) {  // stopped already, while the run went on
    restore_command_stop_signals();
    return;
  }
  if (!command_stop_signals_installed()) install_command_stop_signals();
  fmt::print(stderr, "viewer: {}; the page keeps it at {} until Ctrl-C\n", what, server.url());
  std::fflush(stderr);
  while (command_stop().load() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  restore_command_stop_signals();
}

}  // namespace toonforce::cli
