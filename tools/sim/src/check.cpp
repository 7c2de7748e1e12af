// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/check.hpp"

#include <fmt/format.h>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/sim/plausibility.hpp"
#include "toonforce/sim/sim_run.hpp"

namespace toonforce {

std::string hand_script_length_problem(const std::string& path, double length_s) {
  if (!(length_s > kMaxSimDurationS)) return {};
  return fmt::format("{}: the hand script lasts {:g} s, over the maximum of {:g} s simulated (one day)", path, length_s,
                     kMaxSimDurationS);
}

CheckReport check_scene(const CheckOptions& o) {
  CheckReport out;
  SimOptions sim;
  sim.scene_path = o.scene_path;
  sim.script_path = o.script_path;
  sim.rate_hz = o.rate_hz;
  sim.scalar = o.scalar;
  sim.device = o.device;
  const SimConfig config = sim_config(sim);

  auto scene =
      o.scene_text ? parse_scene(*o.scene_text, o.scene_path, o.scalar) : load_scene_file(o.scene_path, o.scalar);
  if (!scene) out.errors.push_back(scene.error());
  // As run and sim refuse it: a rate Q16.16 cannot hold is a bad command-line value.
  if (scene) {
    if (std::string bad = fixed_point::check_rate(o.rate_hz, o.scalar, scene.value()); !bad.empty()) {
      out.rate_error = fmt::format("--rate {}", bad);
      out.exit_code = 2;
      return out;
    }
  }
  std::optional<HandScriptFile> hand;
  if (!o.script_path.empty() || o.script_text) {
    auto loaded = o.script_text ? parse_hand_script(*o.script_text, o.script_path) : load_hand_script(o.script_path);
    if (!loaded) {
      out.errors.push_back(loaded.error());
    } else {
      hand = std::move(loaded.value());
      if (std::string long_script = hand_script_length_problem(o.script_path, hand->intent.duration_s());
          !long_script.empty()) {
        out.errors.push_back(std::move(long_script));
      }
    }
  }
  if (scene && !o.allow_empty) {
    if (std::string empty = empty_scene_problem(scene.value(), o.scene_path); !empty.empty()) {
      out.errors.push_back(std::move(empty));
    }
  }
  if (scene) {
    DeviceInfo info;
    info.name = std::string(config.device.name);
    info.max_force_n = config.device.max_force_n;
    info.workspace_min_m = config.device.workspace_min_m;
    info.workspace_max_m = config.device.workspace_max_m;
    const ServoConfig servo = with_device(servo_config(scene.value(), 1.0 / o.rate_hz), info);
    if (const std::string bad = check_servo_config(servo); !bad.empty()) {
      out.errors.push_back(fmt::format("{}: the servo configuration does not work:\n{}", o.scene_path, bad));
    }
    if (hand) {
      auto session = SimSession::create(scene.value(), *hand, config);
      if (!session) out.errors.push_back(session.error());
    }
    // The plausibility report: the scene's numbers against the device's.
    PlausibilityReport plausible = check_plausibility(scene.value(), o.scene_path, config.device, o.rate_hz);
    out.notes = std::move(plausible.notes);
    out.warnings = std::move(plausible.warnings);
  }
  out.ok = out.errors.empty() && !(o.strict && !out.warnings.empty());
  out.exit_code = out.ok ? 0 : 1;
  return out;
}

std::string format_check_report(const CheckReport& r, const CheckOptions& o) {
  std::string text;
  for (const std::string& e : r.errors) {
    text += e;  // whole, whatever it holds
    if (e.empty() || e.back() != '\n') text += '\n';
  }
  for (const std::string& note : r.notes) text += fmt::format("note    {}\n", note);
  for (const std::string& warning : r.warnings) text += fmt::format("warning {}\n", warning);
  // No count here: one file's errors are many lines, capped (ErrorList::kShown), and a count
  // of reports would say "1 problem" above twenty of them.
  const bool with_script = !o.script_path.empty();
  if (r.ok) {
    text +=
        fmt::format("ok      {}{}{}: loads as run and sim would load it{}\n", o.scene_path, with_script ? " + " : "",
                    o.script_path, r.warnings.empty() ? "" : ", with the warnings above (--strict makes them errors)");
  } else {
    text += fmt::format("not ok  {}{}{}: does not load as run and sim would load it (the errors above)\n", o.scene_path,
                        with_script ? " + " : "", o.script_path);
  }
  return text;
}

}  // namespace toonforce
