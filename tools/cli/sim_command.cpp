// SPDX-License-Identifier: Apache-2.0
// toonforce sim --scene S.toml --script hand.toml --duration SECONDS --trace out.csv [--plot out.svg|out.png]
//   [--device falcon|omni] [--integrator ...] [--substeps N] [--rate HZ] [--seed N]
//   [--sensor-noise M] [--scalar ...] [--sine ...] [--view [PORT]] [--view-address ADDR] [--view-pace X]
// toonforce sim --scene WORLD.toml --script NAME=hand.toml ... [--fail NAME@SECONDS] --trace out.csv
//   a world scene ([[device]] tables): one hand script per device (sim/world_sim.hpp)
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/sim/sim_run.hpp"
#include "toonforce/sim/world_sim.hpp"
#if TOONFORCE_VIEWER
#include "toonforce/viewer/world_sink.hpp"
#include "toonforce/viewer/world_view.hpp"
#include "viewer_support.hpp"
#endif

namespace toonforce::cli {

#if TOONFORCE_VIEWER
namespace {

/// The hello's words for the page's clock at --view-pace `pace`.
std::string pacing(double pace) {
  return pace > 0.0 ? fmt::format("simulated time at {:g}x wall-clock time", pace)
                    : "simulated time, as fast as it runs";
}

/// The page's server for a simulation (one device or a world), once a page has connected:
/// simulated time costs nothing, so nothing is lost by waiting for it. Null when it could not
/// start or Ctrl-C gave up (said, and the exit status set).
std::unique_ptr<viewer::ViewerServer> serve_simulation(const ViewFlags& view, const viewer::HelloInfo& hello) {
  viewer::ViewerOptions vo;
  vo.address = view.address;
  vo.hosts = view.hosts;
  vo.port = static_cast<std::uint16_t>(view.port);
  vo.has_loop = false;
  auto started = start_viewer(vo, hello);
  if (!started) {
    fmt::print(stderr, "{}\n", started.error());
    set_exit_code(1);
    return nullptr;
  }
  std::unique_ptr<viewer::ViewerServer> server = std::move(started.value());
  install_command_stop_signals();
  fmt::print(stderr, "viewer: waiting for a page to connect before the simulation starts (Ctrl-C to give up)\n");
  std::fflush(stderr);
  const bool connected = server->wait_for_page(command_stop());
  restore_command_stop_signals();
  if (!connected) {
    set_exit_code(1);
    return nullptr;
  }
  return server;
}

}  // namespace
#endif

void add_sim(CLI::App& app) {
  auto options = std::make_shared<SimOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto duration = std::make_shared<double>(0.0);
  auto noise = std::make_shared<double>(0.0);
  CLI::App* cmd = app.add_subcommand(
      "sim",
      "Closed loop on the simulated device and hand, in simulated time (deterministic: same inputs, same bytes)");
  cmd->add_option("--scene", options->scene_path, "Scene file (TOML)")->required();
  cmd->add_flag("--allow-empty", options->allow_empty, "A scene without surfaces or cliffs is not an error");
  cmd->add_flag("--strict", options->strict,
                "Do not start on a plausibility warning (the scene outside the device's limits: `toonforce check`)");
  auto scripts = std::make_shared<std::vector<std::string>>();
  cmd->add_option("--script", *scripts,
                  "Hand script (TOML, docs/HAND_SCRIPTS.md); a world scene takes one per device, as NAME=FILE")
      ->required();
  auto fail = std::make_shared<std::string>();
  cmd->add_option("--fail", *fail,
                  "World scenes: pull device NAME's cable at SECONDS (NAME@SECONDS): its reads and writes fail from "
                  "then on, as an unplugged device's would");
  CLI::Option* duration_option =
      cmd->add_option("--duration", *duration, "Simulated seconds (default: the hand script's length)")
          ->check(positive_number());
  cmd->add_option("--trace", options->trace_path, "Trace CSV to write ('-' for standard output)")->required();
  cmd->add_option("--max-output", options->max_output_bytes,
                  "Largest trace to write, e.g. 500M or 4G (0: no limit; default 1G); past it the trace stops "
                  "with a warning, the run goes on; at most 4E")
      ->transform(CLI::AsSizeValue(false))
      ->check(max_output_range());
  cmd->add_option("--plot", options->plot_path, "Also plot the trace (.png or .svg; python3-matplotlib)");
  cmd->add_option("--plot-kind", options->plot_kind, "Plot layout: auto, stroke, wall, cliff or overview")
      ->check(CLI::IsMember({"auto", "stroke", "wall", "cliff", "overview"}));
  // Enumerations as words (CheckedTransformer would print their uint8_t values as characters).
  auto device = std::make_shared<std::string>("falcon");
  auto integrator = std::make_shared<std::string>("rk4");
  auto scalar = std::make_shared<std::string>("double");
  auto sine = std::make_shared<std::string>();
  cmd->add_option("--device", *device, "Simulated device class (default falcon)")
      ->check(CLI::IsMember({"falcon", "omni"}, CLI::ignore_case));
  cmd->add_option("--integrator", *integrator, "Integrator of the device and hand (default rk4)")
      ->check(CLI::IsMember({"semi-implicit-euler", "velocity-verlet", "rk4", "exact"}, CLI::ignore_case));
  cmd->add_option("--substeps", options->substeps, "Integrator sub-steps per servo tick (default 4)")
      ->check(number_in(1, 1000));
  cmd->add_option("--rate", options->rate_hz, "Servo rate [Hz] (default 1000)")->check(number_in(10.0, 100000.0));
  cmd->add_option("--seed", options->seed, "Seed of the sensor noise generator (default 1)");
  CLI::Option* noise_option =
      cmd->add_option("--sensor-noise", *noise, "Standard deviation of position noise [m] (default 0)")
          ->check(non_negative_number());
  cmd->add_option("--scalar", *scalar, "Scalar type of the controller (default double)")
      ->check(CLI::IsMember({"double", "float", "q16.16"}, CLI::ignore_case));
  cmd->add_option("--sine", *sine, "Sine method of impact transients (overrides the scene)")
      ->check(CLI::IsMember({"library", "polynomial", "table"}, CLI::ignore_case));
  cmd->add_flag("--quiet,-q", *quiet, "Print nothing but errors");
#if TOONFORCE_VIEWER
  auto view = std::make_shared<ViewFlags>();
  add_view_flags(cmd, *view);
  cmd->add_option("--view-pace", options->pace,
                  "With --view: simulated seconds per wall-clock second (default 1, real time; 0.25 slow motion; "
                  "0 as fast as possible). The trace is the same at any pace")
      ->check(number_in(0.0, 1000.0))
      ->needs(view->view);
#endif
  cmd->callback([=] {
    // The checks above admit only known words (in any case): these parse.
    const auto lower = [](std::string text) {
      for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      return text;
    };
    if (is_world_file(options->scene_path)) {
      // Options of the one-device simulation that a world does not take are refused, not ignored.
      for (const char* name : {"--plot", "--plot-kind", "--scalar", "--sine", "--sensor-noise", "--strict",
                               "--allow-empty", "--max-output"}) {
        if (cmd->get_option(name)->count() > 0) {
          fmt::print(stderr, "{}: a world scene ({}) does not take it yet\n", name, options->scene_path);
          set_exit_code(2);
          return;
        }
      }
      WorldSimOptions w;
      w.scene_path = options->scene_path;
      for (const std::string& text : *scripts) {
        auto named = parse_named_script(text);
        if (!named) {
          fmt::print(stderr, "{}\n", named.error());
          set_exit_code(2);
          return;
        }
        w.scripts.push_back(std::move(named).value());
      }
      if (!fail->empty()) {
        const std::size_t at = fail->rfind('@');
        char* end = nullptr;
        const double seconds = at == std::string::npos ? -1.0 : std::strtod(fail->c_str() + at + 1, &end);
        if (at == std::string::npos || at == 0 || end == fail->c_str() + at + 1 || *end != '\0' ||
            !(seconds >= 0.0 && std::isfinite(seconds))) {
          fmt::print(stderr, "--fail {}: give NAME@SECONDS (a device of the scene, a time >= 0)\n", *fail);
          set_exit_code(2);
          return;
        }
        w.fail = std::pair{fail->substr(0, at), seconds};
      }
      if (duration_option->count() > 0) w.duration_s = *duration;
      w.trace_path = options->trace_path;
      w.device = host_sim::parse_device_preset(lower(*device)).value_or(host_sim::DevicePreset::kFalcon);
      w.integrator = host_sim::parse_integrator(lower(*integrator)).value_or(host_sim::Integrator::kRk4);
      w.substeps = options->substeps;
      w.rate_hz = options->rate_hz;
      w.seed = options->seed;
      static std::atomic<int> world_stop{0};
      world_stop.store(0);
#if TOONFORCE_VIEWER
      // As for one device: wait for a page, then pace the simulation to the wall clock; the
      // page gets every row the trace gets, each value named by its device.
      std::unique_ptr<viewer::ViewerServer> server;
      std::optional<viewer::WorldViewSink> sink;
      if (view->wanted()) {
        auto world = load_world_file(w.scene_path);
        if (!world) {
          fmt::print(stderr, "{}\n", world.error());
          set_exit_code(1);
          return;
        }
        auto map = viewer::WorldViewMap::make(world_columns(world.value()));
        if (!map) {
          fmt::print(stderr, "{}: {}\n", w.scene_path, map.error());
          set_exit_code(1);
          return;
        }
        viewer::HelloInfo hello;
        hello.source = "sim";
        std::string scripts_text;
        for (const auto& [name, file] : w.scripts)
          scripts_text += fmt::format("{}{}={}", scripts_text.empty() ? "" : ", ", name, file);
        hello.title = fmt::format("{} / {}", world->scene.name, scripts_text);
        hello.rate_hz = w.rate_hz;
        hello.scene_json = viewer::scene_json(world->scene);
        hello.world_columns = map->columns();
        hello.world_json = viewer::world_json(map->devices(), &world.value());
        hello.pacing = pacing(options->pace);
        server = serve_simulation(*view, hello);
        if (!server) return;
        sink.emplace(*server, std::move(map.value()), options->pace, &world_stop);
        w.rows = &sink.value();
      }
#endif
      install_signal_handlers(world_stop, EmergencyZero{});
      w.stop = &world_stop;
      const auto summary = run_world_sim(w);
      restore_signals();
#if TOONFORCE_VIEWER
      if (server) server->finish();
#endif
      if (!summary) {
        std::fputs(summary.error().c_str(), stderr);
        if (summary.error().empty() || summary.error().back() != '\n') std::fputc('\n', stderr);
        set_exit_code(1);
        return;
      }
      if (!*quiet) {
        std::fputs(format_world_sim_summary(summary.value(), w).c_str(), w.trace_path == "-" ? stderr : stdout);
      }
      set_exit_code(0);
#if TOONFORCE_VIEWER
      if (server && summary->stop_signal == 0) {
        std::fflush(stdout);
        serve_until_stopped(*server, "the simulation is over");
      }
#endif
      return;
    }
    if (scripts->size() != 1) {
      fmt::print(stderr, "--script given {} times: a one-device scene takes one hand script\n", scripts->size());
      set_exit_code(2);
      return;
    }
    if (!fail->empty()) {
      fmt::print(stderr, "--fail: only a world scene ([[device]] tables) takes it\n");
      set_exit_code(2);
      return;
    }
    options->script_path = scripts->front();
    if (duration_option->count() > 0) options->duration_s = *duration;
    if (noise_option->count() > 0) options->sensor_noise_m = *noise;
    options->device = host_sim::parse_device_preset(lower(*device)).value_or(host_sim::DevicePreset::kFalcon);
    options->integrator = host_sim::parse_integrator(lower(*integrator)).value_or(host_sim::Integrator::kRk4);
    options->scalar = parse_scalar_kind(lower(*scalar)).value_or(ScalarKind::kDouble);
    if (!sine->empty()) options->sine = parse_sine_method(lower(*sine));
    // A servo rate Q16.16 cannot hold is a bad command-line value: exit 2 before anything runs
    // (run_sim checks it too, for other callers). An unloadable scene is run_sim's to report.
    if (auto scene = load_scene_file(options->scene_path, options->scalar)) {
      if (const std::string bad = fixed_point::check_rate(options->rate_hz, options->scalar, scene.value());
          !bad.empty()) {
        fmt::print(stderr, "--rate {}\n", bad);
        set_exit_code(2);
        return;
      }
    }
#if TOONFORCE_VIEWER
    // Live, for a simulation, means paced to the wall clock (--view-pace) from the moment a
    // page connects: simulated time costs nothing, so nothing is lost by waiting for the page.
    std::unique_ptr<viewer::ViewerServer> server;
    if (view->wanted()) {
      auto scene = load_scene_file(options->scene_path, options->scalar);  // errors: run_sim reports them
      const SimConfig config = sim_config(*options);
      viewer::HelloInfo hello;
      hello.source = "sim";
      hello.title = fmt::format("{} / {}", scene ? scene->name : options->scene_path, options->script_path);
      hello.rate_hz = options->rate_hz;
      if (scene) {
        hello.scene_json = viewer::scene_json(scene.value());
        hello.effect_values = effect_value_names(make_runtime_scene<double>(scene.value()));
      }
      hello.pacing = pacing(options->pace);
      hello.workspace_min_m = config.device.workspace_min_m;
      hello.workspace_max_m = config.device.workspace_max_m;
      server = serve_simulation(*view, hello);
      if (!server) return;
      options->sink = server.get();
    }
#endif
    // Every terminating signal (SIGINT, SIGTERM, SIGHUP, ...) stops the run after the tick under
    // way, with the shut-down tick as the trace's last row and the summary; SIGPIPE is ignored
    // (a closed `--trace -` is a write error).
    static std::atomic<int> stop{0};
    stop.store(0);
    install_signal_handlers(stop, EmergencyZero{});
    options->stop = &stop;
    const auto summary = run_sim(*options);
    restore_signals();
    options->stop = nullptr;
    if (!summary) {
      std::fputs(summary.error().c_str(), stderr);
      if (summary.error().empty() || summary.error().back() != '\n') std::fputc('\n', stderr);
      set_exit_code(1);
      return;
    }
    if (!*quiet) {
      std::fputs(format_sim_summary(summary.value(), *options).c_str(), options->trace_path == "-" ? stderr : stdout);
    }
    if (!summary->trace_error.empty()) {
      fmt::print(stderr, "{}: the trace is incomplete: {}\n", options->trace_path, summary->trace_error);
      set_exit_code(1);
      return;
    }
    set_exit_code(0);
#if TOONFORCE_VIEWER
    if (server && summary->stop_signal == 0) {
      std::fflush(stdout);
      serve_until_stopped(*server, "the simulation is over");
    }
#endif
  });
}

}  // namespace toonforce::cli
