// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/check.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/control/passivity_bound.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/sim/plausibility.hpp"
#include "toonforce/sim/sim_run.hpp"
#include "toonforce/sim/world_sim.hpp"

namespace toonforce {

std::string hand_script_length_problem(const std::string& path, double length_s) {
  if (!(length_s > kMaxSimDurationS)) return {};
  return fmt::format("{}: the hand script lasts {:g} s, over the maximum of {:g} s simulated (one day)", path, length_s,
                     kMaxSimDurationS);
}

namespace {

/// The world's scene as device `d` sees it: every plane and axis carried into the device's
/// frame (a rigid frame keeps stiffness, speeds and distances: only where things are moves), so
/// the plausibility report checks it against that device's workspace and bounds.
SceneDescription in_device_frame(SceneDescription scene, const DeviceFrame& f) {
  const auto point = [&f](const Vec3<double>& w) { return f.rotate_back(w - f.offset_m); };
  const auto direction = [&f](const Vec3<double>& w) { return f.rotate_back(w); };
  for (auto& s : scene.of<RuntimeSurface>()) {
    s.plane.point_m = point(s.plane.point_m);
    s.plane.normal = direction(s.plane.normal);
  }
  for (auto& c : scene.of<CartoonCliff>()) {
    c.ground.point_m = point(c.ground.point_m);
    c.ground.normal = direction(c.ground.normal);
    c.axis = direction(c.axis);
  }
  return scene;
}

/// A world: loads as `sim` loads it; each device's loop configuration; the plausibility report
/// per device, of the scene in its frame, of each coupling and the ball at its port.
CheckReport check_world(const CheckOptions& o) {
  CheckReport out;
  out.world = true;
  if (!o.script_path.empty() || o.script_text) {
    out.errors.push_back(fmt::format("{}: a world scene takes one hand script per device: `toonforce sim --scene {} "
                                     "--script NAME=FILE ...` loads and checks them",
                                     o.scene_path, o.scene_path));
  }
  if (o.scalar != ScalarKind::kDouble) {
    out.errors.push_back(fmt::format("{}: a world runs in double (--scalar {} is for one-device scenes)", o.scene_path,
                                     scalar_kind_name(o.scalar)));
  }
  auto world = o.scene_text ? parse_world(*o.scene_text, o.scene_path) : load_world_file(o.scene_path);
  if (!world) {
    out.errors.push_back(world.error());
  } else {
    const double period_s = 1.0 / o.rate_hz;
    for (std::size_t index = 0; index < world->devices.size(); ++index) {
      const WorldDeviceEntry& d = world->devices[index];
      const SimulatedWorldDevice simulated = simulated_device(d, o.device, period_s);
      const host_sim::DeviceParams& params = simulated.params;
      const std::string who = fmt::format("{}:{}: device '{}'", o.scene_path, d.line, d.name);
      if (const std::string bad = check_servo_config(simulated.config); !bad.empty()) {
        out.errors.push_back(fmt::format("{}: the servo configuration does not work:\n{}", who, bad));
      }
      if (d.frame.scale != 1.0) {
        out.notes.push_back(fmt::format("{}: scale {:g}: its plausibility report is not made yet (it is made for "
                                        "rigid frames: offset and yaw)",
                                        who, d.frame.scale));
        continue;
      }
      SceneDescription scene = in_device_frame(world->scene_for(index), d.frame);  // what acts on it
      static_cast<SceneSettings&>(scene) = d.settings;                             // its own limits and safety
      scene.name = world->scene.name;
      PlausibilityReport plausible =
          check_plausibility(scene, fmt::format("{} ({})", o.scene_path, d.name), params, o.rate_hz);
      for (std::string& n : plausible.notes) out.notes.push_back(std::move(n));
      for (std::string& w : plausible.warnings) out.warnings.push_back(std::move(w));
      // At the device's port a coupling or the ball is at most a wall of its stiffness and
      // damping (the other end held still): the same bound.
      const auto port = [&](const std::string& what, double k, double b) {
        const double alone =
            stiffest_passive_wall_n_per_m(params.damping_n_s_per_m, period_s, params.io_delay_ticks, b);
        const double held = stiffest_passive_wall_n_per_m(params.damping_n_s_per_m + kHeldHandDampingNsPerM, period_s,
                                                          params.io_delay_ticks, b);
        const std::string text = fmt::format("{}: {} K = {:g} N/m, B = {:g} N s/m at this device's port (the other "
                                             "end held still: a wall of that law)",
                                             who, what, k, b);
        if (k > held) {
          out.warnings.push_back(fmt::format("{} is over the passive bound even when held ({:.4g} N/m with a hand of "
                                             "{:g} N s/m): it can buzz in a firm hand; soften it",
                                             text, held, kHeldHandDampingNsPerM));
        } else if (k > alone) {
          out.notes.push_back(fmt::format("{} is passive only while held (up to {:.4g} N/m; {:.4g} N/m on the device "
                                          "alone)",
                                          text, held, alone));
        } else {
          out.notes.push_back(fmt::format("{} is passive on the device alone (up to {:.4g} N/m)", text, alone));
        }
      };
      for (std::size_t j = 0; j < world->couplings.size(); ++j) {
        const WorldCouplingEntry& c = world->couplings[j];
        if (&world->devices[c.a] != &d && &world->devices[c.b] != &d) continue;
        port(fmt::format("coupling[{}]", j + 1), c.params.stiffness_n_per_m, c.params.damping_n_s_per_m);
      }
      if (world->ball && (world->ball_devices & (1U << index)) != 0)
        port("the ball", world->ball->stiffness_n_per_m, world->ball->damping_n_s_per_m);
    }
  }
  // The devices' notes that say the same (two devices of one model) are said once.
  std::vector<std::string> notes;
  for (std::string& n : out.notes) {
    if (std::find(notes.begin(), notes.end(), n) == notes.end()) notes.push_back(std::move(n));
  }
  out.notes = std::move(notes);
  out.ok = out.errors.empty() && !(o.strict && !out.warnings.empty());
  out.exit_code = out.ok ? 0 : 1;
  return out;
}

}  // namespace

CheckReport check_scene(const CheckOptions& o) {
  if (o.scene_text ? is_world_text(*o.scene_text) : is_world_file(o.scene_path)) return check_world(o);
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
  if (r.world) {
    text += r.ok ? fmt::format("ok      {}: a world of several devices; loads as sim would load it{}\n", o.scene_path,
                               r.warnings.empty() ? "" : ", with the warnings above (--strict makes them errors)")
                 : fmt::format("not ok  {}: a world of several devices; does not load as sim would load it (the "
                               "errors above)\n",
                               o.scene_path);
    return text;
  }
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
