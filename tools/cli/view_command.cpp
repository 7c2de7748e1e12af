// SPDX-License-Identifier: Apache-2.0
// toonforce view TRACE.csv [--scene S.toml] [--port P] [--address ADDR] [--host NAME ...]
// A recorded trace (from `toonforce run --trace` or `toonforce sim --trace`) in the viewer page,
// to play, pause and scrub; served until Ctrl-C. Only in builds with TOONFORCE_VIEWER.
#include <cstdio>
#include <filesystem>
#include <memory>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/viewer/trace_file.hpp"
#include "viewer_support.hpp"

namespace toonforce::cli {

void add_view(CLI::App& app) {
  auto trace_path = std::make_shared<std::string>();
  auto scene_path = std::make_shared<std::string>();
  auto port = std::make_shared<int>(viewer::kDefaultPort);
  auto address = std::make_shared<std::string>("127.0.0.1");
  auto hosts = std::make_shared<std::vector<std::string>>();
  CLI::App* cmd = app.add_subcommand("view", "A recorded trace in the viewer page (play, pause, scrub) until Ctrl-C");
  cmd->add_option("trace", *trace_path, "Trace CSV written by toonforce run --trace or toonforce sim --trace")
      ->required();
  cmd->add_option("--scene", *scene_path, "The scene file the trace was recorded with, to draw its surfaces and gap");
  cmd->add_option("--port", *port, "Port to serve on (0: any free port)")
      ->check(number_in(0, 65535))
      ->capture_default_str();
  cmd->add_option("--address", *address, "Listen on this address instead of 127.0.0.1 (other hosts can then watch)");
  cmd->add_option("--host", *hosts, kViewHostHelp)->type_name("NAME")->allow_extra_args(false)->take_all();
  cmd->callback([=] {
    auto recording = viewer::read_trace(*trace_path);
    if (!recording) {
      fmt::print(stderr, "{}\n", recording.error());
      set_exit_code(1);
      return;
    }
    if (!recording->note.empty()) fmt::print(stderr, "note: {}\n", recording->note);
    std::optional<SceneDescription> scene;
    if (!scene_path->empty()) {
      auto loaded = load_scene_file(*scene_path);
      if (!loaded) {
        fmt::print(stderr, "{}\n", loaded.error());
        set_exit_code(1);
        return;
      }
      scene = std::move(loaded.value());
    }
    viewer::HelloInfo hello;
    hello.source = recording->source == "trace" ? "trace" : fmt::format("{} trace", recording->source);
    hello.title = std::filesystem::path(*trace_path).filename().string();
    hello.rate_hz = recording->rate_hz;
    hello.live = false;
    if (scene) hello.scene_json = viewer::scene_json(*scene);
    hello.effect_values = recording->effect_values;
    viewer::ViewerOptions options;
    options.address_option = "--address";
    options.address = *address;
    options.hosts = *hosts;
    options.port = static_cast<std::uint16_t>(*port);
    options.has_loop = recording->has_loop;
    const std::size_t frames = recording->frames.size();
    auto server = start_viewer(options, hello, std::move(recording.value().frames), "--host");
    if (!server) {
      fmt::print(stderr, "{}\n", server.error());
      set_exit_code(1);
      return;
    }
    serve_until_stopped(*server.value(), fmt::format("{}: {} frames", *trace_path, frames).c_str());
    set_exit_code(0);
  });
}

}  // namespace toonforce::cli
