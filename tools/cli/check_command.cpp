// SPDX-License-Identifier: Apache-2.0
// toonforce check SCENE [HAND_SCRIPT] [--device falcon|omni] [--rate HZ] [--scalar ...] [--allow-empty]
// Everything `run` and `sim` check at load, without running: the scene's and the hand script's
// errors (file:line:key and the allowed range), the servo configuration for the device class,
// and the plausibility report (sim/plausibility.hpp: each effect against the device's stability
// bound, force and workspace). Exit status 0 when clean (warnings allowed, unless --strict), 1
// when not.
#include <cctype>
#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/report/staged_outputs.hpp"
#include "toonforce/sim/check.hpp"

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
  cmd->preparse_callback(
      [](std::size_t) { report::install_report_stop_handlers("toonforce check", "it writes nothing"); });
  cmd->callback([o] {
    const auto lower = [](std::string text) {
      for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      return text;
    };
    CheckOptions check;
    check.scene_path = o->scene_path;
    check.script_path = o->script_path;
    check.rate_hz = o->rate_hz;
    check.scalar = parse_scalar_kind(lower(o->scalar)).value_or(ScalarKind::kDouble);
    check.device = host_sim::parse_device_preset(lower(o->device)).value_or(host_sim::DevicePreset::kFalcon);
    check.allow_empty = o->allow_empty;
    check.strict = o->strict;
    const CheckReport report = check_scene(check);
    if (!report.rate_error.empty()) {
      fmt::print(stderr, "{}\n", report.rate_error);
      set_exit_code(report.exit_code);
      return;
    }
    const std::string text = format_check_report(report, check);
    std::fwrite(text.data(), 1, text.size(), stdout);  // whole, whatever it holds
    set_exit_code(report.exit_code);
  });
}

}  // namespace toonforce::cli
