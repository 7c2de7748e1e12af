// SPDX-License-Identifier: Apache-2.0
// toonforce view TRACE.csv [--scene S.toml] [--port P] [--address ADDR] [--host NAME ...]
// A recorded trace (from `toonforce run --trace` or `toonforce sim --trace`) in the viewer page,
// to play, pause and scrub; served until Ctrl-C. Only in builds with TOONFORCE_VIEWER.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/viewer/trace_file.hpp"
#include "toonforce/viewer/world_view.hpp"
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
    const auto fail = [](const std::string& message) {
      fmt::print(stderr, "{}\n", message);
      set_exit_code(1);
    };
    // A world's trace (several devices: sim/world_trace.hpp) by its header; its scene is a world file.
    const bool world_trace = viewer::is_world_trace_header(viewer::read_trace_header(*trace_path));
    const bool world_scene = !scene_path->empty() && is_world_file(*scene_path);
    if (world_trace || world_scene) {
      if (!world_trace)
        return fail(fmt::format("{}: not a world's trace, but --scene {} is a world scene", *trace_path, *scene_path));
      if (!scene_path->empty() && !world_scene) {
        return fail(fmt::format("{}: a world's trace, but --scene {} is a one-device scene", *trace_path, *scene_path));
      }
      std::optional<WorldDescription> world;
      if (world_scene) {
        auto loaded = load_world_file(*scene_path);
        if (!loaded) return fail(loaded.error());
        world = std::move(loaded.value());
      }
      std::string text;
      if (std::FILE* f = std::fopen(trace_path->c_str(), "rb")) {
        char buffer[1 << 16];
        std::size_t n = 0;
        while ((n = std::fread(buffer, 1, sizeof buffer, f)) > 0) text.append(buffer, n);
        std::fclose(f);
      }
      auto recording = viewer::parse_world_trace(text, *trace_path);
      if (!recording) return fail(recording.error());
      if (!recording->note.empty()) fmt::print(stderr, "note: {}\n", recording->note);
      if (world) {
        for (const WorldDeviceEntry& d : world->devices) {
          if (std::find(recording->devices.begin(), recording->devices.end(), d.name) == recording->devices.end()) {
            return fail(fmt::format("{}: no columns of device '{}' of {}: the trace is not of this world", *trace_path,
                                    d.name, *scene_path));
          }
        }
      }
      viewer::HelloInfo hello;
      hello.source = "world trace";
      hello.title = std::filesystem::path(*trace_path).filename().string();
      hello.rate_hz = recording->rate_hz;
      hello.live = false;
      if (world) hello.scene_json = viewer::scene_json(world->scene);
      hello.world_columns = recording->columns;
      hello.world_json = viewer::world_json(recording->devices, world ? &world.value() : nullptr);
      viewer::ViewerOptions options;
      options.address_option = "--address";
      options.address = *address;
      options.hosts = *hosts;
      options.port = static_cast<std::uint16_t>(*port);
      options.has_loop = false;
      const std::string what =
          fmt::format("{}: {} frames of {} devices", *trace_path, recording->frames.size(), recording->devices.size());
      auto server = start_viewer(options, hello, std::move(recording.value().frames), "--host");
      if (!server) return fail(server.error());
      serve_until_stopped(*server.value(), what.c_str());
      set_exit_code(0);
      return;
    }
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
