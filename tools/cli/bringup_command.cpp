// SPDX-License-Identifier: Apache-2.0
// toonforce bringup falcon|omni|gpio [--only STEPS] [--skip STEPS] [--non-interactive]
//                                   [--answer ID=VALUE]... [--report BASE] [device options]
//        toonforce bringup falcon --scene WORLD.toml [--device NAME] [...]: the world's Falcons
// The guided hardware-in-the-loop bring-up of one device (tools/bringup): each step passes or
// fails with what to do next; the report is written as BASE.md and BASE.json. Exit status 0
// when no step failed, 1 when one did, 2 when the command line or the report is wrong.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <initializer_list>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/bringup/falcon_bringup.hpp"
#include "toonforce/bringup/gpio_bringup.hpp"
#include "toonforce/bringup/omni_bringup.hpp"
#include "toonforce/gpio_cli/gpio_options.hpp"
#include "world_option.hpp"

namespace toonforce::cli {
namespace {

/// What every device's bring-up takes.
struct Common {
  std::vector<std::string> only;
  std::vector<std::string> skip;
  bool non_interactive = false;
  std::vector<std::string> answers;  // ID=VALUE
  std::string report;                // BASE of BASE.md and BASE.json
};

void add_common(CLI::App* cmd, Common& c, const std::string& steps) {
  cmd->add_option("--only", c.only, "Run only these steps (comma-separated): " + steps)->delimiter(',');
  cmd->add_option("--skip", c.skip, "Do not run these steps (comma-separated)")->delimiter(',');
  cmd->add_flag("--non-interactive", c.non_interactive,
                "No person at the device: run the steps that need none (and those named with --only), taking "
                "answers only from --answer");
  cmd->add_option("--answer", c.answers,
                  "Answer a request by its id, e.g. falcon.force.method=weight, falcon.led.red=y, "
                  "falcon.motors.hold=done (repeatable; docs/BRINGUP.md lists the ids)");
  cmd->add_option("--report", c.report, "Write the report to BASE.md and BASE.json (default: bringup-DEVICE-TIME)");
}

/// Parses --answer ID=VALUE; false (with a message) on a malformed one.
bool answers_of(const Common& c, std::map<std::string, std::string>& out) {
  for (const auto& a : c.answers) {
    const auto eq = a.find('=');
    if (eq == std::string::npos || eq == 0) {
      fmt::print(stderr, "--answer {}: expected ID=VALUE (e.g. falcon.force.method=weight)\n", a);
      return false;
    }
    out[a.substr(0, eq)] = a.substr(eq + 1);
  }
  return true;
}

std::unique_ptr<bringup::Operator> person_for(const Common& c) {
  std::map<std::string, std::string> answers;
  if (!answers_of(c, answers)) return nullptr;
  if (c.non_interactive) return std::make_unique<bringup::ScriptedOperator>(std::move(answers), stdout);
  return std::make_unique<bringup::ConsoleOperator>(stdin, stdout, std::move(answers));
}

/// Unknown step names are a usage error naming the known ones.
bool steps_known(const Common& c, const std::vector<std::string>& known) {
  for (const auto* list : {&c.only, &c.skip}) {
    for (const auto& s : *list) {
      if (std::find(known.begin(), known.end(), s) == known.end()) {
        std::string all;
        for (const auto& k : known) all += (all.empty() ? "" : ", ") + k;
        fmt::print(stderr, "no bring-up step '{}' (the steps are: {})\n", s, all);
        return false;
      }
    }
  }
  return true;
}

/// Refuses a --report BASE whose files (BASE.md, BASE.json) would overwrite an input, or that
/// names a directory (BASE/ wrote the hidden files BASE/.md and BASE/.json); false (said).
bool report_base_ok(const Common& c, std::initializer_list<std::string> inputs) {
  if (c.report.empty()) return true;
  std::error_code ec;
  if (c.report.back() == '/' || std::filesystem::is_directory(c.report, ec)) {
    fmt::print(stderr,
               "--report {}: is a directory; give a base name (e.g. {}/bringup): the report is written to "
               "BASE.md and BASE.json\n",
               c.report, c.report.back() == '/' ? c.report.substr(0, c.report.size() - 1) : c.report);
    return false;
  }
  for (const char* ext : {".md", ".json"}) {
    const std::string output = c.report + ext;
    if (const std::string input = input_overwritten_by(output, inputs); !input.empty()) {
      fmt::print(stderr, "--report {}: its {} would overwrite the input {}; choose another base name\n", c.report,
                 output, input);
      return false;
    }
  }
  return true;
}

/// Writes the report to `base` (empty: bringup-DEVICE-TIME) and says so; the exit status.
int write_and_say(const bringup::Report& report, std::string base, const std::string& device) {
  if (base.empty()) {
    std::string stamp = report.started_utc;
    for (char& ch : stamp) {
      if (ch == ':') ch = '-';
    }
    base = fmt::format("bringup-{}-{}", device, stamp);
  }
  auto written = bringup::write_report(report, base);
  if (!written) {
    fmt::print(stderr, "{}\n", written.error());
    return 2;
  }
  std::size_t failed = 0;
  for (const auto& s : report.steps) failed += s.outcome == bringup::Outcome::kFail ? 1 : 0;
  fmt::print("\n{}: report written to {} and {}\n", report.passed() ? "no step failed" : "a step FAILED",
             written.value()[0], written.value()[1]);
  return failed == 0 ? 0 : 1;
}

void finish(const bringup::Report& report, const Common& c, const char* device) {
  set_exit_code(write_and_say(report, c.report, device));
}

/// A device's name as part of a file name: a name is any one line (world_file.hpp), but a '/'
/// in BASE-NAME would be a directory, so what is not a letter, a digit, '.', '_' or '-' is '_'.
std::string file_part(const std::string& name) {
  std::string out = name;
  for (char& ch : out) {
    const bool plain = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '.' ||
                       ch == '_' || ch == '-';
    if (!plain) ch = '_';
  }
  return out;
}

/// `bringup falcon --scene WORLD.toml [--device NAME]`: the world's Falcons one after another,
/// each chosen by its `select` serial, each report BASE-NAME.md and .json. Devices of other
/// backends are named with what brings them up instead; the world's couplings and ball are not
/// a bring-up's (they need every device at once: `toonforce run` of the world exercises them).
int falcon_world_bringup(const bringup::FalconBringupOptions& options, const Common& c, const std::string& scene,
                         const std::string& only_device) {
  const auto world = load_world_option(scene);
  if (!world) return 2;
  std::vector<const WorldDeviceEntry*> devices;
  std::string names;
  for (const WorldDeviceEntry& d : world->devices) {
    names += (names.empty() ? "" : ", ") + d.name;
    if (only_device.empty() || d.name == only_device) devices.push_back(&d);
  }
  if (devices.empty()) {
    fmt::print(stderr, "--device {}: the scene {} has no such device (its devices: {})\n", only_device, scene, names);
    return 2;
  }
  std::size_t falcons = 0;
  for (const WorldDeviceEntry& d : world->devices) falcons += d.backend == "falcon";
  if (std::none_of(devices.begin(), devices.end(), [](const auto* d) { return d->backend == "falcon"; })) {
    fmt::print(stderr, "{}: no device with backend \"falcon\" to bring up{}\n", scene,
               only_device.empty() ? "" : " (--device " + only_device + ")");
    return 2;
  }
  // Every report's name is checked before the first device is touched; the base itself first
  // (a directory would give the files out/-left.md).
  if (!report_base_ok(c, {options.falcon.firmware_path, scene})) return 2;
  for (const WorldDeviceEntry* d : devices) {
    Common named = c;
    if (!named.report.empty()) named.report += "-" + file_part(d->name);
    if (!report_base_ok(named, {options.falcon.firmware_path, scene})) return 2;
  }
  auto person = person_for(c);
  if (!person) return 2;
  auto access = bringup::usb_falcon_access();
  int status = 0;
  std::string summary;
  for (const WorldDeviceEntry* d : devices) {
    const std::string who = fmt::format("{}:{}: device '{}'", scene, d->line, d->name);
    if (d->backend != "falcon") {
      const std::string why = d->backend == "omni"
                                  ? fmt::format("not a Falcon: bring it up with `toonforce bringup omni{}`",
                                                d->select.empty() ? "" : " --omni-device \"" + d->select + "\"")
                                  : std::string("simulated: nothing to bring up");
      fmt::print("\n{} ({}): {}\n", who, d->backend, why);
      summary += fmt::format("  {}: {}\n", d->name, why);
      continue;
    }
    if (d->select.empty() && falcons > 1) {
      fmt::print("\n{}: NOT brought up: the world has {} Falcons, so each needs `select`: add select = \"<serial>\" "
                 "(`toonforce devices --scene {}` lists the attached serials)\n",
                 who, falcons, scene);
      summary += fmt::format("  {}: NOT brought up (no select)\n", d->name);
      status = std::max(status, 1);
      continue;
    }
    fmt::print("\n=== {}: Novint Falcon{} ===\n", who, d->select.empty() ? "" : ", serial " + d->select);
    bringup::FalconBringupOptions o = options;
    o.falcon.serial = d->select;  // empty: the world's only Falcon is --falcon-index's (0), as `run` opens it
    bringup::Report report = bringup::run_falcon_bringup(*access, *person, o);
    report.target = fmt::format("'{}' of {}{}", d->name, scene, report.target.empty() ? "" : ": " + report.target);
    const int one =
        write_and_say(report, c.report.empty() ? "" : c.report + "-" + file_part(d->name), file_part(d->name));
    summary += fmt::format("  {}: {}\n", d->name,
                           one == 0   ? "no step failed"
                           : one == 1 ? "a step FAILED"
                                      : "report not written");
    status = std::max(status, one);
  }
  fmt::print("\nthe world's devices, one after another (its couplings and ball need them all at once: `toonforce run` "
             "of the world):\n{}",
             summary);
  return status;
}

template <std::size_t N>
std::vector<std::string> names(const char* const (&steps)[N]) {
  return {std::begin(steps), std::end(steps)};
}
std::string joined(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += (out.empty() ? "" : ",") + s;
  return out;
}

}  // namespace

void add_bringup(CLI::App& app) {
  CLI::App* bringup = app.add_subcommand(
      "bringup", "Guided hardware-in-the-loop bring-up of a device, step by step, with a report (docs/BRINGUP.md)");
  bringup->require_subcommand(1);

  // ---- falcon ----
  auto falcon = std::make_shared<bringup::FalconBringupOptions>();
  auto falcon_common = std::make_shared<Common>();
  falcon->toonforce_version = TOONFORCE_VERSION;
  const auto falcon_steps = names(bringup::kFalconSteps);
  CLI::App* f = bringup->add_subcommand("falcon", "Novint Falcon: found, firmware, homing, encoders, motors, force "
                                                  "constant, USB timing, buttons, LED");
  add_common(f, *falcon_common, joined(falcon_steps));
  auto scene = std::make_shared<std::string>();
  auto scene_device = std::make_shared<std::string>();
  CLI::Option* serial =
      f->add_option("--serial", falcon->falcon.serial, "Serial number of the Falcon (toonforce devices)");
  CLI::Option* index =
      f->add_option("--falcon-index", falcon->falcon.index, "The index-th Falcon when no --serial is given")
          ->capture_default_str();
  f->add_option("--scene", *scene,
                "A world scene: bring up its Falcons one after another, each by its `select` serial, each report "
                "BASE-NAME.md and .json");
  f->add_option("--device", *scene_device, "With --scene: only the device of this name");
  f->add_option("--firmware", falcon->falcon.firmware_path, "Firmware file to load if the Falcon has none")
      ->check(CLI::ExistingFile);
  CLI::Option* calibration = f->add_option("--calibration", falcon->falcon.calibration_path,
                                           "The calibration in use (default: the one for this serial number, if any)")
                                 ->check(CLI::ExistingFile);
  CLI::Option* calibration_out =
      f->add_option("--calibration-out", falcon->calibration_out,
                    "Where the force step writes the calibration (default: ~/.config/toonforce/falcon-SERIAL.toml, "
                    "which `toonforce run` reads)");
  f->add_option("--homing-timeout", falcon->homing_timeout_s, "Seconds to wait for homing, 0.1..3600")
      ->check(number_in(0.1, 3600.0))  // nan, inf, negatives reached lround out of its range
      ->capture_default_str();
  f->add_option("--timing-ticks", falcon->timing_ticks, "Exchanges timed at 1 kHz")
      ->check(number_in(10, 100000))
      ->capture_default_str();
  f->callback([falcon, falcon_common, falcon_steps, scene, scene_device, serial, index, calibration, calibration_out] {
    if (!steps_known(*falcon_common, falcon_steps)) return set_exit_code(2);
    if (!scene_device->empty() && scene->empty()) {
      fmt::print(stderr, "--device {}: names a device of a world scene: give the scene with --scene\n", *scene_device);
      return set_exit_code(2);
    }
    if (!scene->empty()) {
      // One Falcon's choice or file would be wrong for the others: each is chosen by its table's
      // `select` and uses (and writes) the calibration file of its own serial number.
      for (const CLI::Option* o : {serial, index, calibration, calibration_out}) {
        if (o->count() > 0) {
          fmt::print(stderr,
                     "{}: not with --scene: each Falcon of a world is chosen by its `select` serial and "
                     "uses the calibration file of that serial\n",
                     o->get_name());
          return set_exit_code(2);
        }
      }
      return set_exit_code(falcon_world_bringup(*falcon, *falcon_common, *scene, *scene_device));
    }
    if (!report_base_ok(*falcon_common,
                        {falcon->falcon.firmware_path, falcon->falcon.calibration_path, falcon->calibration_out})) {
      return set_exit_code(2);
    }
    auto person = person_for(*falcon_common);
    if (!person) return set_exit_code(2);
    falcon->only = falcon_common->only;
    falcon->skip = falcon_common->skip;
    auto access = bringup::usb_falcon_access();
    finish(bringup::run_falcon_bringup(*access, *person, *falcon), *falcon_common, "falcon");
  });

  // ---- omni ----
  auto omni = std::make_shared<bringup::OmniBringupOptions>();
  auto omni_common = std::make_shared<Common>();
  omni->toonforce_version = TOONFORCE_VERSION;
  const auto omni_steps = names(bringup::kOmniSteps);
  CLI::App* o = bringup->add_subcommand("omni", "Phantom Omni / Touch: found, driver, calibration, workspace, motors, "
                                                "scheduler rate, buttons");
  add_common(o, *omni_common, joined(omni_steps));
  o->add_option("--omni-device", omni->omni.device_name, "OpenHaptics device name as set in Touch_Setup");
  o->add_option("--omni-library", omni->omni.library_path, "The OpenHaptics HD library to load");
  o->add_option("--omni-max-force", omni->omni.max_force_n, "Force cap [N] (default: the continuous force)")
      ->check(non_negative_number());
  o->add_option("--timing-ticks", omni->timing_ticks, "Scheduler ticks timed")
      ->check(number_in(10, 20000))
      ->capture_default_str();
  o->callback([omni, omni_common, omni_steps] {
    if (!steps_known(*omni_common, omni_steps)) return set_exit_code(2);
    if (!report_base_ok(*omni_common, {omni->omni.library_path})) return set_exit_code(2);
    auto person = person_for(*omni_common);
    if (!person) return set_exit_code(2);
    omni->only = omni_common->only;
    omni->skip = omni_common->skip;
    finish(bringup::run_omni_bringup(*person, *omni), *omni_common, "omni");
  });

  // ---- gpio ----
  auto gpio = std::make_shared<bringup::GpioBringupOptions>();
  auto gpio_common = std::make_shared<Common>();
  gpio->toonforce_version = TOONFORCE_VERSION;
  const auto gpio_steps = names(bringup::kGpioSteps);
  CLI::App* g = bringup->add_subcommand("gpio", "GPIO lines: they open, the tick pin's frequency, the e-stop and the "
                                                "enable switch cut the force in their tick");
  add_common(g, *gpio_common, joined(gpio_steps));
  add_gpio_options(*g, gpio->pins);
  g->add_option("--rate", gpio->rate_hz, "Servo rate [Hz]")->check(number_in(100.0, 10000.0))->capture_default_str();
  g->callback([gpio, gpio_common, gpio_steps] {
    if (!steps_known(*gpio_common, gpio_steps)) return set_exit_code(2);
    if (!report_base_ok(*gpio_common, {})) return set_exit_code(2);
    auto person = person_for(*gpio_common);
    if (!person) return set_exit_code(2);
    gpio->only = gpio_common->only;
    gpio->skip = gpio_common->skip;
    finish(bringup::run_gpio_bringup(*person, *gpio), *gpio_common, "gpio");
  });
}

}  // namespace toonforce::cli
