// SPDX-License-Identifier: Apache-2.0
// toonforce run --device sim|falcon|omni --scene S.toml [--rate HZ] [--duration S] [--trace out.csv]
//               [--stats-json FILE] [--cpu N] [--priority P] [--allow-non-rt] [--no-mlock] [--scalar ...]
//               [--view [PORT]] [--view-address ADDR] [--server-user NAME]
//               [--control [--control-token T] [--control-wait]]
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/gpio_cli/gpio_options.hpp"
#include "toonforce/hal/gpio/output_line.hpp"
#include "toonforce/run/command_stop.hpp"
#include "toonforce/control/guardian.hpp"
#include "toonforce/control/process_split.hpp"
#include "toonforce/run/guardian_report.hpp"
#include "toonforce/run/run.hpp"
#include "toonforce/run/world_run.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/sim/world_sim.hpp"
#if TOONFORCE_VIEWER
#include <pwd.h>

#include <fstream>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/config/toml_reader.hpp"
#include "server_process.hpp"
#include "toonforce/viewer/world_view.hpp"
#include "viewer_support.hpp"
#endif

namespace toonforce::cli {

namespace {

/// Forks the loop's process (process_split.hpp). This process execs the guardian program and
/// never comes back here; in the loop's process, it returns nothing (it goes on as `run`), or
/// the command's exit status if the split could not be made.
std::optional<int> become_guardian(RunOptions& options, double stall_limit_ms) {
  GuardianStart start;
  auto program = guardian_program_path();
  if (!program) {
    fmt::print(stderr, "{}\n", program.error());
    return 2;
  }
  start.program = program.value();
  start.stall_limit_ms = stall_limit_ms;
  // Above the loop's priority when it may (a wedged loop thread must not starve it).
  start.priority = std::min(options.priority + 1, 99);
  // The amplifier-enable line is the guardian's alone: checked here (a problem with it stops
  // the start, said with the line's name), then released and requested again by the guardian
  // itself, which drives it only while the loop ticks.
  if (!options.gpio.amp_enable_pin.empty()) {
    auto spec = gpio::parse_line_spec(options.gpio.amp_enable_pin);
    auto line = spec ? gpio::OutputLine::open(spec.value(), "toonforce-guardian")
                     : Result<std::unique_ptr<gpio::OutputLine>>(Error{spec.error()});
    if (!line) {
      fmt::print(stderr, "--amp-enable-pin {}\n", line.error());
      return 2;
    }
    start.enable_chip = line.value()->chip_node();
    start.enable_offset = line.value()->offset();
    start.enable_active_low = line.value()->active_low();
  }
  // After a death, the guardian hands over to this program's epilogue (`run-epilogue`), which
  // ends the trace and writes the statistics: what may fail, apart from what must not.
  char self[4096] = {};
  const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
  if (n > 0) {
    start.epilogue = {std::string(self, static_cast<std::size_t>(n)), "run-epilogue"};
    if (!options.trace_path.empty() && options.trace_path != "-") {
      start.epilogue.insert(start.epilogue.end(), {"--trace", options.trace_path});
    }
    if (!options.stats_json_path.empty())
      start.epilogue.insert(start.epilogue.end(), {"--stats-json", options.stats_json_path});
  }
  auto page = split_off_guardian(start);  // returns in the loop's process only
  if (!page) {
    fmt::print(stderr, "{}\n", page.error());
    return 2;
  }
  options.guardian = page.value();
  return std::nullopt;
}

/// Two outputs that are the same file would write over each other: refused before either opens.
std::string same_output_problem(const RunOptions& options) {
  const std::string& a = options.trace_path;
  const std::string& b = options.stats_json_path;
  if (a.empty() || b.empty() || a == "-") return {};
  std::error_code ec;
  const bool same = a == b || (std::filesystem::equivalent(a, b, ec) && !ec);
  if (!same) return {};
  return fmt::format("--trace {} and --stats-json {} are the same file: one would overwrite the other; choose two", a,
                     b);
}

#if TOONFORCE_VIEWER
/// The scene file's text, read once for the whole run: the viewer's hello, the control
/// protocol's editor (in the server process, which reads no file) and the loop all take this
/// text, so an edit of the file while the run waits for its control client is not half taken.
/// nullopt when it is not a regular file that can be read (load_scene_file then says why).
std::optional<std::string> read_scene_text(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::string text;
  std::array<char, 1U << 16> chunk{};
  // No further than just past the scene files' limit: the parser refuses the rest anyway.
  while (text.size() <= kMaxTomlBytes && (in.read(chunk.data(), chunk.size()) || in.gcount() > 0)) {
    text.append(chunk.data(), static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) return std::nullopt;
  return text;
}
#endif

#if TOONFORCE_VIEWER
/// `run --view` of a world: each trace row (from the writer thread) as the page's row
/// (world_view.hpp), carried to the server process in a frame's values (server_process.cpp
/// hands them on as they are). No allocation.
class WorldViewRows final : public WorldRowSink {
 public:
  WorldViewRows(TelemetrySink& sink, viewer::WorldViewMap map) : sink_(sink), map_(std::move(map)) {}
  void begin(const std::vector<std::string>& /*columns*/, std::int64_t /*ticks*/) override {}
  void row(const std::vector<double>& values) override {
    const viewer::ViewFrame v = map_.frame(values, static_cast<double>(tick_));
    frame_.t_s = v[viewer::kT];
    frame_.tick = tick_++;
    frame_.value_count = static_cast<std::uint16_t>(v.size());
    std::copy(v.begin(), v.end(), frame_.values.begin());
    sink_.publish(frame_);
  }

 private:
  TelemetrySink& sink_;
  viewer::WorldViewMap map_;
  std::int64_t tick_ = 0;
  TelemetryFrame frame_{};
};

/// The control protocol's token: `given` (--control-token), else $TOONFORCE_CONTROL_TOKEN, else
/// 128 random bits, which the "control: ..." line then says.
void choose_control_token(ServerSetup& setup, const std::string& given) {
  const char* env = std::getenv("TOONFORCE_CONTROL_TOKEN");
  const bool from_env = env != nullptr && *env != '\0';
  setup.viewer.control_options.token = !given.empty() ? given : from_env ? std::string(env) : viewer::random_token();
  if (given.empty() && !from_env) setup.token_note = " (random; set one with --control-token)";
}

/// --control-wait, before the devices open (a session that never gets its client commands no
/// force at all): true once a control client's hello passed; false, said why, when a stop
/// signal came or the server process ended first.
bool wait_for_control_client(const ServerProcess& server) {
  fmt::print(stderr, "control: waiting for a control client's hello before the loop starts (Ctrl-C to give up)\n");
  std::fflush(stderr);
  if (command_stop().load() == 0 && server.wait_for_control(command_stop())) return true;
  const int signo = command_stop().load();
  const std::string gone = server.ended_early();
  fmt::print(stderr, "control: no control client came{}; the loop did not start\n",
             signo != 0      ? " (stopped by " + signal_name(signo) + ")"
             : !gone.empty() ? " (the server process " + gone + ")"
                             : std::string());
  return false;
}

/// What `run --view` of a world needs from the command line.
struct WorldViewRequest {
  const ViewFlags* view = nullptr;  ///< null or not wanted: no viewer
  std::string server_user;
  bool server_user_given = false;
  bool control = false;       ///< --control: /control changes the world's effects
  bool control_wait = false;  ///< --control-wait
  std::string control_token;  ///< --control-token (empty: the environment's, else a random one)
};
#endif

/// `run` of a world scene (run/world_run.hpp): the options one device's run takes that a world
/// does not are refused, not ignored; the rest as for one device. The command's exit status.
int run_world_command(RunOptions& options, const CLI::App& cmd, const std::vector<std::string>& scripts,
                      const std::string& fail, bool quiet
#if TOONFORCE_VIEWER
                      ,
                      const WorldViewRequest& view_request
#endif
) {
  for (const char* name : {
#if !TOONFORCE_VIEWER
         "--view",
#endif
             "--serial", "--falcon-index", "--falcon-calibration", "--omni-device", "--tick-pin", "--estop-pin",
             "--enable-pin", "--amp-enable-pin", "--led-pin"
       }) {
    const CLI::Option* option = cmd.get_option_no_throw(name);
    if (option != nullptr && option->count() > 0) {
      fmt::print(stderr, "{}: a world scene ({}) does not take it yet{}\n", name, options.scene_path,
                 std::string_view(name).starts_with("--serial") || std::string_view(name).starts_with("--falcon") ||
                         std::string_view(name) == "--omni-device"
                     ? " (each [[device]] table names its device with `select`)"
                     : "");
      return 2;
    }
  }
  for (const std::string& text : scripts) {
    auto named = parse_named_script(text);
    if (!named) {
      fmt::print(stderr, "{}\n", named.error());
      return 2;
    }
    options.world_scripts.push_back(std::move(named.value()));
  }
  if (!fail.empty()) {
    const std::size_t at = fail.rfind('@');
    char* end = nullptr;
    const double seconds = at == std::string::npos ? -1.0 : std::strtod(fail.c_str() + at + 1, &end);
    if (at == std::string::npos || at == 0 || end == fail.c_str() + at + 1 || *end != '\0' ||
        !(seconds >= 0.0 && std::isfinite(seconds))) {
      fmt::print(stderr, "--fail {}: give NAME@SECONDS (a device of the scene, a time >= 0)\n", fail);
      return 2;
    }
    options.world_fail = std::pair{fail.substr(0, at), seconds};
  }
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> stats_file(nullptr, &std::fclose);
  if (!options.stats_json_path.empty()) {
    std::vector<std::string> inputs{options.scene_path};
    for (const auto& [name, path] : options.world_scripts) inputs.push_back(path);
    for (const std::string& input : inputs) {
      std::error_code ec;
      if (std::filesystem::equivalent(options.stats_json_path, input, ec) && !ec) {
        fmt::print(stderr,
                   "--stats-json {} is an input of the run ({}): it would be overwritten; choose another file\n",
                   options.stats_json_path, input);
        return 2;
      }
    }
    stats_file.reset(std::fopen(options.stats_json_path.c_str(), "wb"));
    if (!stats_file) {
      fmt::print(stderr, "--stats-json {}: cannot be created: {}\n", options.stats_json_path, std::strerror(errno));
      return 2;
    }
  }
#if TOONFORCE_VIEWER
  // As for one device: the server runs in a process of its own, forked here before any thread.
  std::unique_ptr<ServerProcess> server;
  std::optional<WorldViewRows> rows;
  if (view_request.view != nullptr && view_request.view->wanted()) {
    const ViewFlags& view = *view_request.view;
    auto world = load_world_file(options.scene_path);
    if (!world) {
      fmt::print(stderr, "{}\n", world.error());
      return 2;
    }
    auto map = viewer::WorldViewMap::make(world_columns(world.value()));
    if (!map) {
      fmt::print(stderr, "{}: {}\n", options.scene_path, map.error());
      return 2;
    }
    ServerSetup setup;
    if (geteuid() == 0 || view_request.server_user_given) {
      const passwd* user = getpwnam(view_request.server_user.c_str());
      if (user == nullptr) {
        fmt::print(stderr,
                   "--server-user {}: no such user (the viewer's server process runs as this user when "
                   "`run` is started as root)\n",
                   view_request.server_user);
        return 2;
      }
      if (geteuid() == 0) setup.user = ServerUser{view_request.server_user, user->pw_uid, user->pw_gid};
    }
    if (options.guardian != nullptr) setup.dropped_mappings.push_back({options.guardian, sizeof(guardian::SharedPage)});
    if (view_request.control) {
      // The world's text, read once: the server's editor and the loop start from the same.
      options.scene_text = read_scene_text(options.scene_path);
      if (!options.scene_text) {
        fmt::print(stderr, "{}: cannot be read: {}\n", options.scene_path, std::strerror(errno));
        return 2;
      }
      auto same = parse_world(*options.scene_text, options.scene_path);
      if (!same) {
        fmt::print(stderr, "{}\n", same.error());
        return 2;
      }
      setup.control = true;
      setup.world = true;
      setup.scene_text = *options.scene_text;
      setup.scene_name = options.scene_path;
      choose_control_token(setup, view_request.control_token);
    }
    viewer::HelloInfo& hello = setup.hello;
    hello.source = "run";
    hello.title = fmt::format("{} on {}", world->scene.name, options.device);
    hello.rate_hz = options.rate_hz;
    hello.scene_json = viewer::scene_json(world->scene);
    hello.world_columns = map->columns();
    hello.world_json = viewer::world_json(map->devices(), &world.value());
    setup.viewer.address = view.address;
    setup.viewer.hosts = view.hosts;
    setup.viewer.port = static_cast<std::uint16_t>(view.port);
    auto started = ServerProcess::start(setup);
    if (!started) {
      if (!started.error().empty()) fmt::print(stderr, "{}\n", started.error());
      return 2;
    }
    server = std::move(started.value());
    rows.emplace(server->sink(), std::move(map.value()));
    options.world_rows = &rows.value();
    if (view_request.control) options.live = &server->live();
    if (view_request.control_wait && !wait_for_control_client(*server)) return 2;  // could not start
  }
  if (command_stop().load() != 0) {  // stopped while the viewer started
    fmt::print(stderr, "stopped by {} before the loop started\n", signal_name(command_stop().load()));
    return 2;
  }
#endif
  const auto summary = run_world_servo(options);
  if (!summary) {
    std::fputs(summary.error().c_str(), stderr);
    if (summary.error().empty() || summary.error().back() != '\n') std::fputc('\n', stderr);
    if (stats_file) {
      stats_file.reset();
      std::filesystem::remove(options.stats_json_path);  // created above, for nothing
    }
    return 2;
  }
  if (!quiet) {
    std::fputs(format_world_run_summary(summary.value(), options).c_str(), options.trace_path == "-" ? stderr : stdout);
  }
  int status = 0;
  if (stats_file) {
    const std::string json = world_stats_json(summary.value(), options);
    std::FILE* f = stats_file.release();
    if (std::fwrite(json.data(), 1, json.size(), f) != json.size() || std::fclose(f) != 0) {
      fmt::print(stderr, "{}: cannot write the statistics: {}\n", options.stats_json_path, std::strerror(errno));
      status = 1;
    }
  }
  if (!summary->trace_error.empty()) {
    fmt::print(stderr, "{}: the trace is incomplete: {}\n", options.trace_path, summary->trace_error);
    status = 1;
  }
  std::fflush(stdout);
#if TOONFORCE_VIEWER
  if (server) {
    // As for one device: stopped from outside, the page closes with the run; else it keeps the
    // recording until Ctrl-C.
    const int stopped_by = summary->report.stop_signal;
    const bool keep = status == 0 && (stopped_by == 0 || stopped_by == SIGINT || stopped_by == kStopByUser);
    if (!keep && status == 0) {
      fmt::print(stderr, "viewer: the run was stopped by {}; the page closes with it\n", signal_name(stopped_by));
    }
    server->finish(keep);
  }
#endif
  return status;
}

}  // namespace

/// `toonforce run-epilogue`: what the guardian program execs after the loop's process died and
/// it zeroed the force (guardian_main.cpp). Hidden: `run` names it, never a person.
void add_run_epilogue(CLI::App& app) {
  auto trace = std::make_shared<std::string>();
  auto stats = std::make_shared<std::string>();
  auto page_fd = std::make_shared<int>(-1);
  CLI::App* cmd = app.add_subcommand("run-epilogue", "")->group("");
  cmd->add_option("--trace", *trace);
  cmd->add_option("--stats-json", *stats);
  cmd->add_option("--page-fd", *page_fd)->required();
  cmd->callback([=] {
    guardian::SharedPage* page = guardian::attach_shared_page(*page_fd);
    if (page == nullptr) {
      fmt::print(stderr,
                 "guardian: the loop's process died and the guardian zeroed what it could; its page is gone, so "
                 "nothing more can be said\n");
      set_exit_code(guardian::kExitLoopDied);
      return;
    }
    const guardian::Verdict verdict = page->verdict;
    TelemetryFrame frame{};
    const bool have_frame = guardian::read_frame(*page, frame);
    const TelemetryFrame* last = have_frame ? &frame : nullptr;
    std::fputs(guardian::describe_verdict(verdict, last).c_str(), stderr);
    int status = verdict.exit_status;
    if (!trace->empty()) {
      const std::string bad = guardian::end_trace(*trace, verdict, last);
      if (!bad.empty()) {
        fmt::print(stderr, "guardian: {}\n", bad);
      } else {
        fmt::print(stderr, "guardian: {} ends with the zero-force row at t = {:.4f} s\n", *trace, verdict.t_end_s);
      }
    }
    if (!stats->empty()) {
      const std::string json = guardian::verdict_json(verdict, last);
      std::FILE* f = std::fopen(stats->c_str(), "wb");
      const bool written = f != nullptr && std::fwrite(json.data(), 1, json.size(), f) == json.size();
      const int error = errno;
      const bool closed = f != nullptr && std::fclose(f) == 0;
      if (!written || !closed) {
        fmt::print(stderr, "guardian: {}: the statistics could not be written: {}\n", *stats,
                   std::strerror(errno != 0 ? errno : (error != 0 ? error : EIO)));
      }
    }
    std::fflush(stderr);
    set_exit_code(status);
  });
}

void add_run(CLI::App& app) {
  add_run_epilogue(app);
  auto options = std::make_shared<RunOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto no_mlock = std::make_shared<bool>(false);
  CLI::App* cmd =
      app.add_subcommand("run", "The servo loop on a device in real time, with a timing summary at the end");
  cmd->add_option("--device", options->device,
                  "sim (the host simulation's device and hand), falcon (Novint Falcon over USB) or omni "
                  "(Phantom Omni / Touch through OpenHaptics); a world scene ([[device]] tables): sim (every device "
                  "simulated) or scene (each device as its table says)")
      ->required()
      ->check(CLI::IsMember({"sim", "falcon", "omni", "scene"}));
  cmd->add_option("--scene", options->scene_path, "Scene file (TOML)")->required();
  cmd->add_flag("--allow-empty", options->allow_empty, "A scene without surfaces or cliffs is not an error");
  cmd->add_flag("--strict", options->strict,
                "Do not start on a plausibility warning (the scene outside the device's limits: `toonforce check`)");
  CLI::Option_group* sim = cmd->add_option_group("Simulated device (--device sim)");
  auto scripts = std::make_shared<std::vector<std::string>>();
  sim->add_option("--script", *scripts,
                  "Hand script the simulated hand follows (docs/HAND_SCRIPTS.md); default: it holds still 1 cm "
                  "above the workspace centre. A world scene takes one per device, as NAME=FILE");
  auto fail = std::make_shared<std::string>();
  sim->add_option("--fail", *fail,
                  "World scenes: pull simulated device NAME's cable at SECONDS (NAME@SECONDS): its reads and writes "
                  "fail from then on");
  sim->add_option("--sim-device", options->sim_device, "Device model of the simulation")
      ->check(CLI::IsMember({"falcon", "omni"}))
      ->capture_default_str();
  sim->add_option("--seed", options->seed, "Seed of the simulated sensor noise")->capture_default_str();
  CLI::Option_group* falcon = cmd->add_option_group("Novint Falcon (--device falcon)");
  falcon->add_option("--serial", options->falcon.serial, "Serial number of the Falcon to open (toonforce devices)");
  falcon->add_option("--falcon-index", options->falcon.index, "The index-th Falcon when no --serial is given")
      ->capture_default_str();
  falcon
      ->add_option("--firmware", options->falcon.firmware_path,
                   "Firmware file to load if the Falcon has none yet (after power-up; docs/FALCON.md)")
      ->check(CLI::ExistingFile);
  falcon
      ->add_option("--falcon-calibration", options->falcon.calibration_path,
                   "Calibration file with the Falcon's words per N m (default: the one `toonforce bringup "
                   "falcon` wrote for this serial number, if any; docs/FALCON.md)")
      ->check(CLI::ExistingFile);
  CLI::Option_group* omni = cmd->add_option_group("Phantom Omni / Touch (--device omni)");
  omni->add_option("--omni-device", options->omni.device_name,
                   "OpenHaptics device name as set in Touch_Setup (default: the default device)");
  omni->add_option("--omni-library", options->omni.library_path,
                   "The OpenHaptics HD library to load (default: $TOONFORCE_LIBHD, else libHD.so)");
  omni->add_option("--omni-max-force", options->omni.max_force_n,
                   "Force cap [N]; default (0): the device's nominal continuous force. Raise it for short "
                   "bursts, up to the nominal peak (the library's thermal model then guards the motors)")
      ->check(non_negative_number());
  auto disable_on_close = std::make_shared<std::string>("auto");
  omni->add_option("--omni-disable-on-close", *disable_on_close,
                   "Call hdDisableDevice when closing: auto (yes, except on OpenHaptics' FireWire stack, "
                   "where it crashes FireWire Omnis), yes or no")
      ->check(CLI::IsMember({"auto", "yes", "no"}))
      ->capture_default_str();
  add_gpio_options(*cmd, options->gpio);
  cmd->add_option("--rate", options->rate_hz, "Servo rate [Hz], 500..10000")
      ->check(number_in(500.0, 10000.0))
      ->capture_default_str();
  cmd->add_option("--duration", options->duration_s, "Seconds to run; 0 runs until Ctrl-C (SIGINT) or SIGTERM")
      ->check(non_negative_number())
      ->capture_default_str();
  cmd->add_option("--trace", options->trace_path, "Trace CSV to write (t,x,y,z,vx,vy,vz,fx,fy,fz, then the rest)");
  cmd->add_option("--max-output", options->max_output_bytes,
                  "Largest trace to write, e.g. 500M or 4G (0: no limit; default 1G); past it the trace stops "
                  "with a warning, the run goes on; at most 4E")
      ->transform(CLI::AsSizeValue(false))
      ->check(max_output_range());
  cmd->add_option("--stats-json", options->stats_json_path, "Timing statistics and counts as JSON");
  cmd->add_option("--cpu", options->cpu, "Pin the servo thread to this CPU")->check(non_negative_number());
  cmd->add_option("--priority", options->priority, "SCHED_FIFO priority of the servo thread (1..98)")
      ->check(number_in(1, 98))
      ->capture_default_str();
  cmd->add_flag("--allow-non-rt", options->allow_non_realtime,
                "Run at normal priority if SCHED_FIFO is refused (timing will be poor)");
  cmd->add_flag("--no-mlock", *no_mlock, "Do not lock memory (mlockall)");
  const std::map<std::string, ScalarKind> scalars{
      {"double", ScalarKind::kDouble}, {"float", ScalarKind::kFloat}, {"q16.16", ScalarKind::kQ16_16}};
  cmd->add_option("--scalar", options->scalar, "Scalar type of the servo loop (a firmware build has q16.16 only)")
      ->transform(CLI::CheckedTransformer(scalars, CLI::ignore_case));
  cmd->add_flag("--quiet,-q", *quiet, "Print nothing but errors and fault messages");
  auto no_guardian = std::make_shared<bool>(false);
  auto stall_limit_ms = std::make_shared<double>(500.0);
  cmd->add_flag("--no-guardian", *no_guardian,
                "One process, without the guardian that zeroes the force when the loop's process dies (to debug "
                "the loop in gdb; docs/DEPLOY.md \"Processes\")");
  cmd->add_option("--stall-limit", *stall_limit_ms,
                  "Milliseconds without a tick after which the guardian kills the loop's process and zeroes the "
                  "force, 50..10000 (the in-process heartbeat watchdog zeroes first, after the scene's "
                  "watchdog_periods)")
      ->check(number_in(50.0, 10000.0))
      ->capture_default_str();
#if TOONFORCE_VIEWER
  auto view = std::make_shared<ViewFlags>();
  add_view_flags(cmd, *view);
  // Live scenes (docs/spec/control-protocol.md): the control protocol at /control of
  // the viewer's server. Its state lives as long as the command's callback.
  auto control = std::make_shared<bool>(false);
  auto control_token = std::make_shared<std::string>();
  CLI::Option* control_flag =
      cmd->add_flag("--control", *control,
                    "Take scene changes while running: the control protocol at ws://HOST:PORT/control of the viewer's "
                    "server (docs/spec/control-protocol.md); changes keep the scene's list of effects")
          ->needs(view->view);
  cmd->add_option("--control-token", *control_token,
                  "The token a control client sends in its hello (default: $TOONFORCE_CONTROL_TOKEN, else a random "
                  "one, printed)")
      ->needs(control_flag);
  auto server_user = std::make_shared<std::string>("nobody");
  CLI::Option* server_user_option =
      cmd->add_option("--server-user", *server_user,
                      "Started as root: the user the viewer's server process becomes once its socket is bound "
                      "(docs/DEPLOY.md \"Processes\")")
          ->capture_default_str()
          ->needs(view->view);
  auto control_wait = std::make_shared<bool>(false);
  cmd->add_flag("--control-wait", *control_wait,
                "Start the loop only once a control client's hello has passed (a game or story page sets the scene up "
                "first: its changes then meet the loop's first tick)")
      ->needs(control_flag);
#endif
  cmd->callback([=] {
    options->lock_memory = !*no_mlock;
    // The guardian first: before any thread, device or server exists, `run` forks;
    // this process becomes the guardian and the child does all the rest.
    if (*no_guardian && !options->gpio.amp_enable_pin.empty()) {
      std::fputs("--amp-enable-pin: the guardian process holds the amplifier-enable line; --no-guardian has none\n",
                 stderr);
      set_exit_code(2);
      return;
    }
    if (const std::string same = same_output_problem(*options); !same.empty()) {
      fmt::print(stderr, "{}\n", same);
      set_exit_code(2);
      return;
    }
    if (!*no_guardian) {
      const std::optional<int> guardian_status = become_guardian(*options, *stall_limit_ms);
      if (guardian_status) {
        set_exit_code(*guardian_status);
        return;
      }
    }
    // From here to the end, every stop signal takes one path: the command's flag before and
    // after the loop (the scene loading, the device opening, the viewer), the loop's own
    // handlers (which put these back) while it runs; one that came before them stops the loop at
    // its first tick. main() installed the handlers before it read the command line, and the
    // split blocked them across the fork: let them through now.
    install_command_stop_signals();
    unblock_stop_signals();
    options->early_stop = &command_stop();
    if (*disable_on_close != "auto") options->omni.disable_device_on_close = *disable_on_close == "yes";
    if (is_world_file(options->scene_path)) {
#if TOONFORCE_VIEWER
      WorldViewRequest request;
      request.view = view.get();
      request.server_user = *server_user;
      request.server_user_given = server_user_option->count() > 0;
      request.control = *control;
      request.control_wait = *control_wait;
      request.control_token = *control_token;
      set_exit_code(run_world_command(*options, *cmd, *scripts, *fail, *quiet, request));
#else
      set_exit_code(run_world_command(*options, *cmd, *scripts, *fail, *quiet));
#endif
      return;
    }
    if (!fail->empty()) {
      fmt::print(stderr, "--fail: only a world scene ([[device]] tables) takes it\n");
      set_exit_code(2);
      return;
    }
    if (scripts->size() > 1) {
      fmt::print(stderr, "--script: {} is a one-device scene: it takes one hand script\n", options->scene_path);
      set_exit_code(2);
      return;
    }
    if (!scripts->empty()) options->hand_script_path = scripts->front();
    if (options->device == "scene") {
      fmt::print(stderr, "--device scene: {} is a one-device scene: give sim, falcon or omni\n", options->scene_path);
      set_exit_code(2);
      return;
    }
#if TOONFORCE_VIEWER
    // The viewer and the control protocol's server run in a process of their own
    // (server_process.hpp), forked here, before this process has any thread: the writer thread
    // (never the servo thread) hands it frames, and its checked scene updates come back through
    // the live-scene mailbox in the memory they share.
    std::unique_ptr<ServerProcess> server;
    if (view->wanted()) {
      ServerSetup setup;
      // Started as root, the server process runs as another user; otherwise it cannot change
      // its user and keeps this one. A name given that is no user is an error either way.
      if (geteuid() == 0 || server_user_option->count() > 0) {
        const passwd* user = getpwnam(server_user->c_str());
        if (user == nullptr) {
          fmt::print(stderr,
                     "--server-user {}: no such user (the viewer's server process runs as this user when "
                     "`run` is started as root)\n",
                     *server_user);
          set_exit_code(2);
          return;
        }
        if (geteuid() == 0) setup.user = ServerUser{*server_user, user->pw_uid, user->pw_gid};
      }
      if (options->guardian != nullptr) {  // the server must not forge the loop's heartbeat
        setup.dropped_mappings.push_back({options->guardian, sizeof(guardian::SharedPage)});
      }
      options->scene_text = read_scene_text(options->scene_path);
      auto scene = options->scene_text
                       ? parse_scene(*options->scene_text, options->scene_path, options->scalar)
                       : load_scene_file(options->scene_path, options->scalar);  // errors: run_servo reports them
      viewer::HelloInfo& hello = setup.hello;
      hello.source = "run";
      hello.title = fmt::format("{} on {}", scene ? scene->name : options->scene_path, options->device);
      hello.rate_hz = options->rate_hz;
      if (scene) {
        hello.scene_json = viewer::scene_json(scene.value());
        hello.effect_values = effect_value_names(make_runtime_scene<double>(scene.value()));
      }
      if (scene && scene->safety.has_workspace) {
        hello.workspace_min_m = scene->safety.workspace_min_m;
        hello.workspace_max_m = scene->safety.workspace_max_m;
      }
      setup.viewer.address = view->address;
      setup.viewer.hosts = view->hosts;
      setup.viewer.port = static_cast<std::uint16_t>(view->port);
      if (*control) {
        if (!scene) {  // the run would refuse it too; say it once, before the server starts
          std::fputs(scene.error().c_str(), stderr);
          set_exit_code(2);
          return;
        }
        setup.control = true;
        setup.scene_text = *options->scene_text;  // a scene that parsed was read
        setup.scene_name = options->scene_path;
        setup.scalar = options->scalar;
        choose_control_token(setup, *control_token);
      }
      auto started = ServerProcess::start(setup);
      if (!started) {
        if (!started.error().empty()) fmt::print(stderr, "{}\n", started.error());
        set_exit_code(2);
        return;
      }
      server = std::move(started.value());
      options->sink = &server->sink();
      if (*control) options->live = &server->live();
      if (*control_wait && !wait_for_control_client(*server)) {
        set_exit_code(2);  // could not start (interfaces.md: exit status)
        return;
      }
    }
#endif
    if (command_stop().load() != 0) {  // stopped while the scene loaded or the viewer started
      fmt::print(stderr, "stopped by {} before the loop started\n", signal_name(command_stop().load()));
      set_exit_code(2);  // could not start (exits.md)
      return;
    }
    // The hand script's length by check's rule (one shared check: check refused what run took).
    if (options->device == "sim" && !options->hand_script_path.empty()) {
      if (auto script = load_hand_script(options->hand_script_path)) {
        if (std::string bad = hand_script_length_problem(options->hand_script_path, script->intent.duration_s());
            !bad.empty()) {
          fmt::print(stderr, "{}\n", bad);
          set_exit_code(2);
          return;
        }
      }  // a script that does not load: run_servo says why
    }
    // The statistics file is opened (created) before the loop starts: a path that cannot be
    // written is a reason not to start, not a surprise after the session.
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> stats_file(nullptr, &std::fclose);
    if (!options->stats_json_path.empty()) {
      for (const std::string& input : {options->scene_path, options->hand_script_path}) {
        std::error_code ec;
        if (!input.empty() && std::filesystem::equivalent(options->stats_json_path, input, ec) && !ec) {
          fmt::print(stderr,
                     "--stats-json {} is an input of the run ({}): it would be overwritten; choose another file\n",
                     options->stats_json_path, input);
          set_exit_code(2);
          return;
        }
      }
      stats_file.reset(std::fopen(options->stats_json_path.c_str(), "wb"));
      if (!stats_file) {
        fmt::print(stderr, "--stats-json {}: cannot be created: {}\n", options->stats_json_path, std::strerror(errno));
        set_exit_code(2);
        return;
      }
    }
    const auto summary = run_servo(*options);
    if (!summary) {
      std::fputs(summary.error().c_str(), stderr);
      if (summary.error().empty() || summary.error().back() != '\n') std::fputc('\n', stderr);
      set_exit_code(2);
      if (stats_file) {
        stats_file.reset();
        std::filesystem::remove(options->stats_json_path);  // created above, for nothing
      }
      return;
    }
    if (!*quiet) {  // beside a trace on standard output, on standard error
      std::fputs(format_run_summary(summary.value(), *options).c_str(), options->trace_path == "-" ? stderr : stdout);
    }
    int status = 0;
    if (stats_file) {
      const std::string json = stats_json(summary.value(), *options);
      std::FILE* f = stats_file.release();
      if (std::fwrite(json.data(), 1, json.size(), f) != json.size() || std::fclose(f) != 0) {
        fmt::print(stderr, "{}: cannot write the statistics: {}\n", options->stats_json_path, std::strerror(errno));
        status = 1;
      }
    }
    if (!summary->trace_error.empty()) {
      fmt::print(stderr, "{}: the trace is incomplete: {}\n", options->trace_path, summary->trace_error);
      status = 1;
    }
    std::fflush(stdout);
    set_exit_code(status);
    if (status != 0) return;
#if TOONFORCE_VIEWER
    if (server) {
      std::fflush(stdout);
      // A run stopped from outside (SIGTERM, SIGHUP, ...: a service manager, a script, `kill`)
      // ends the command with it: one signal, not two. After its --duration, or after Ctrl-C or
      // 'q' at a terminal, the page keeps the recording to scrub until the next Ctrl-C.
      const int stopped_by = summary->report.stop_signal;
      if (stopped_by != 0 && stopped_by != SIGINT && stopped_by != kStopByUser) {
        fmt::print(stderr, "viewer: the run was stopped by {}; the page closes with it\n", signal_name(stopped_by));
        server->finish(false);
        return;
      }
      server->finish(true);  // the server process says "the run is over" and serves until Ctrl-C
    }
#endif
  });
}

}  // namespace toonforce::cli
