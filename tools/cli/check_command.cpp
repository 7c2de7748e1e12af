// toonforce check SCENE [HAND_SCRIPT] [--device falcon|omni] [--rate HZ] [--scalar ...] [--allow-empty]
// Everything `run` and `sim` check at load, without running: the scene's and the hand script's
// errors (file:line:key and the allowed range), the servo configuration for the device class,
// and a short plausibility report (the device's force and workspace limits, the passivity bound
// on a wall's stiffness at this rate). Exit status 0 when clean, 1 when not.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_config.hpp"
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
  };
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "check", "Check a scene (and a hand script) as run and sim would at load, without running; exit 0 when clean");
  cmd->add_option("scene", o->scene_path, "Scene file (TOML)")->required();
  cmd->add_option("hand_script", o->script_path, "Hand script (TOML, docs/HAND_SCRIPTS.md)");
  cmd->add_option("--device", o->device, "Device class the plausibility report is for (default falcon)")
      ->check(CLI::IsMember({"falcon", "omni"}, CLI::ignore_case));
  cmd->add_option("--rate", o->rate_hz, "Servo rate [Hz] (default 1000)")->check(CLI::Range(10.0, 100000.0));
  cmd->add_option("--scalar", o->scalar, "Scalar type of the controller (default double)")
      ->check(CLI::IsMember({"double", "float", "q16.16"}, CLI::ignore_case));
  cmd->add_flag("--allow-empty", o->allow_empty, "A scene without surfaces or cliffs is not an error");
  cmd->callback([o] {
    const auto lower = [](std::string text) {
      for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      return text;
    };
    int problems = 0;
    const auto report = [&problems](const std::string& text) {
      ++problems;
      std::fputs(text.c_str(), stdout);
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
        const double length = hand->intent.duration_s();
        if (length > kMaxSimDurationS) {
          report(fmt::format("{}: the hand script lasts {:g} s, over the maximum of {:g} s simulated (one day)",
                             o->script_path, length, kMaxSimDurationS));
        }
      }
    }
    if (scene) {
      const std::size_t effects = scene->of<RuntimeSurface>().size() + scene->of<CartoonCliff>().size();
      if (effects == 0 && !o->allow_empty) {
        report(fmt::format("{}: the scene has no [[surface]] or [[cliff]]: it renders zero force everywhere "
                           "(--allow-empty if that is what you want)",
                           o->scene_path));
      }
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

    // The plausibility report: what the device can do, for comparing the scene's numbers with.
    const auto& d = config.device;
    const double period_s = 1.0 / o->rate_hz;
    fmt::print("device  {} at {:g} Hz: peak force {:g} N; workspace [{:g}, {:g}] x [{:g}, {:g}] x [{:g}, {:g}] m\n",
               d.name, o->rate_hz, d.max_force_n, d.workspace_min_m.x,
               d.workspace_max_m.x, d.workspace_min_m.y, d.workspace_max_m.y, d.workspace_min_m.z,
               d.workspace_max_m.z);
    if (d.damping_n_s_per_m > 0.0) {
      fmt::print("passive a wall is passive on this device alone up to K = 2 b / T = {:g} N/m (Colgate-Brown, "
                 "b = {:g} N s/m); stiffer walls rely on the passivity controller\n",
                 2.0 * d.damping_n_s_per_m / period_s, d.damping_n_s_per_m);
    }
    if (problems == 0) {
      fmt::print("ok      {}{}{}: loads as run and sim would load it\n", o->scene_path, o->script_path.empty() ? "" : " + ",
                 o->script_path);
    } else {
      fmt::print("{} problem(s)\n", problems);
    }
    set_exit_code(problems == 0 ? 0 : 1);
  });
}

}  // namespace toonforce::cli
