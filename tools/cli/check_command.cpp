// toonforce check SCENE [HAND_SCRIPT] [--device falcon|omni] [--rate HZ] [--scalar ...] [--allow-empty]
// Everything `run` and `sim` check at load, without running: the scene's and the hand script's
// errors (file:line:key and the allowed range), the servo configuration for the device class,
// and the plausibility report (sim/plausibility.hpp: each effect against the device's stability
// bound, force and workspace). Exit status 0 when clean (warnings allowed, unless --strict), 1
// when not.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/report/staged_outputs.hpp"
#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/sim/plausibility.hpp"
#include "toonforce/sim/sim_run.hpp"

namespace toonforce::cli {

void add_check(CLI::App& app) {
  struct Options {
    std::string scene_path;
    std::string script_path;
    std::string device = "falcon";
    std::string scalar = "double";
    double rate_hz = 1000.0;
    bool allow_empty = false;
    bool strict = false;
  };
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "check", "Check a scene (and a hand script) as run and sim would at load, without running; exit 0 when clean");
  cmd->add_option("scene", o->scene_path, "Scene file (TOML)")->required();
  cmd->add_option("hand_script", o->script_path, "Hand script (TOML, docs/HAND_SCRIPTS.md)");
  cmd->add_option("--device", o->device, "Device class the plausibility report is for (default falcon)")
      ->check(CLI::IsMember({"falcon", "omni"}, CLI::ignore_case));
  cmd->add_option("--rate", o->rate_hz, "Servo rate [Hz] (default 1000)")->check(number_in(10.0, 100000.0));
  cmd->add_option("--scalar", o->scalar, "Scalar type of the controller (default double)")
      ->check(CLI::IsMember({"double", "float", "q16.16"}, CLI::ignore_case));
  cmd->add_flag("--allow-empty", o->allow_empty, "A scene without surfaces or cliffs is not an error");
  cmd->add_flag("--strict", o->strict, "A plausibility warning (outside the device's limits) is an error");
  // check writes nothing; a stop signal says so and exits 1 rather than ending it silently.
  cmd->preparse_callback([](std::size_t) { report::install_report_stop_handlers("check", "it writes nothing"); });
  cmd->callback([o] {
    const auto lower = [](std::string text) {
      for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      return text;
    };
    bool problems = false;
    const auto report = [&problems](const std::string& text) {
      problems = true;
      std::fwrite(text.data(), 1, text.size(), stdout);  // whole, whatever it holds
      if (text.empty() || text.back() != '\n') std::fputc('\n', stdout);
    };
    SimOptions sim;
    sim.scene_path = o->scene_path;
    sim.script_path = o->script_path;
    sim.rate_hz = o->rate_hz;
    sim.scalar = parse_scalar_kind(lower(o->scalar)).value_or(ScalarKind::kDouble);
    sim.device = host_sim::parse_device_preset(lower(o->device)).value_or(host_sim::DevicePreset::kFalcon);
    const SimConfig config = sim_config(sim);

    auto scene = load_scene_file(o->scene_path, sim.scalar);
    if (!scene) report(scene.error());
    // As run and sim refuse it: a rate Q16.16 cannot hold is a bad command-line value (exit 2).
    if (const std::string bad = scene ? fixed_point::check_rate(o->rate_hz, sim.scalar, scene.value()) : ""; !bad.empty()) {
      fmt::print(stderr, "--rate {}\n", bad);
      set_exit_code(2);
      return;
    }
    std::optional<HandScriptFile> hand;
    if (!o->script_path.empty()) {
      auto loaded = load_hand_script(o->script_path);
      if (!loaded) {
        report(loaded.error());
      } else {
        hand = std::move(loaded.value());
        if (std::string long_script = hand_script_length_problem(o->script_path, hand->intent.duration_s());
            !long_script.empty()) {
          report(long_script);
        }
      }
    }
    if (scene && !o->allow_empty) {
      if (std::string empty = empty_scene_problem(scene.value(), o->scene_path); !empty.empty()) report(empty);
    }
    if (scene) {
      DeviceInfo info;
      info.name = std::string(config.device.name);
      info.max_force_n = config.device.max_force_n;
      info.workspace_min_m = config.device.workspace_min_m;
      info.workspace_max_m = config.device.workspace_max_m;
      const ServoConfig servo = with_device(servo_config(scene.value(), 1.0 / o->rate_hz), info);
      if (const std::string bad = check_servo_config(servo); !bad.empty()) {
        report(fmt::format("{}: the servo configuration does not work:\n{}", o->scene_path, bad));
      }
      if (hand) {
        auto session = SimSession::create(scene.value(), *hand, config);
        if (!session) report(session.error());
      }
    }

    // The plausibility report (issue 15 item 8): the scene's numbers against the device's.
    bool warned = false;
    if (scene) {
      const PlausibilityReport plausible = check_plausibility(scene.value(), o->scene_path, config.device, o->rate_hz);
      for (const std::string& note : plausible.notes) fmt::print("note    {}\n", note);
      for (const std::string& warning : plausible.warnings) fmt::print("warning {}\n", warning);
      warned = !plausible.warnings.empty();
      if (warned && o->strict) problems = true;
    }
    // No count here: one file's errors are many lines, capped (ErrorList::kShown), and a count
    // of reports would say "1 problem" above twenty of them.
    if (!problems) {
      fmt::print("ok      {}{}{}: loads as run and sim would load it{}\n", o->scene_path,
                 o->script_path.empty() ? "" : " + ", o->script_path,
                 warned ? ", with the warnings above (--strict makes them errors)" : "");
    } else {
      fmt::print("not ok  {}{}{}: does not load as run and sim would load it (the errors above)\n", o->scene_path,
                 o->script_path.empty() ? "" : " + ", o->script_path);
    }
    set_exit_code(problems ? 1 : 0);
  });
}

}  // namespace toonforce::cli
