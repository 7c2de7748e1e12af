// SPDX-License-Identifier: Apache-2.0
// toonforce bringup falcon|omni|gpio [--only STEPS] [--skip STEPS] [--non-interactive]
//                                   [--answer ID=VALUE]... [--report BASE] [device options]
// The guided hardware-in-the-loop bring-up of one device (tools/bringup): each step passes or
// fails with what to do next; the report is written as BASE.md and BASE.json. Exit status 0
// when no step failed, 1 when one did, 2 when the command line or the report is wrong.
#include <unistd.h>

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

void finish(const bringup::Report& report, const Common& c, const char* device) {
  std::string base = c.report;
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
    set_exit_code(2);
    return;
  }
  std::size_t failed = 0;
  for (const auto& s : report.steps) failed += s.outcome == bringup::Outcome::kFail ? 1 : 0;
  fmt::print("\n{}: report written to {} and {}\n", report.passed() ? "no step failed" : "a step FAILED",
             written.value()[0], written.value()[1]);
  set_exit_code(failed == 0 ? 0 : 1);
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
  f->add_option("--serial", falcon->falcon.serial, "Serial number of the Falcon (toonforce devices)");
  f->add_option("--falcon-index", falcon->falcon.index, "The index-th Falcon when no --serial is given")
      ->capture_default_str();
  f->add_option("--firmware", falcon->falcon.firmware_path, "Firmware file to load if the Falcon has none")
      ->check(CLI::ExistingFile);
  f->add_option("--calibration", falcon->falcon.calibration_path,
                "The calibration in use (default: the one for this serial number, if any)")
      ->check(CLI::ExistingFile);
  f->add_option("--calibration-out", falcon->calibration_out,
                "Where the force step writes the calibration (default: ~/.config/toonforce/falcon-SERIAL.toml, "
                "which `toonforce run` reads)");
  f->add_option("--homing-timeout", falcon->homing_timeout_s, "Seconds to wait for homing, 0.1..3600")
      ->check(number_in(0.1, 3600.0))  // nan, inf, negatives reached lround out of its range
      ->capture_default_str();
  f->add_option("--timing-ticks", falcon->timing_ticks, "Exchanges timed at 1 kHz")
      ->check(number_in(10, 100000))
      ->capture_default_str();
  f->callback([falcon, falcon_common, falcon_steps] {
    if (!steps_known(*falcon_common, falcon_steps)) return set_exit_code(2);
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
