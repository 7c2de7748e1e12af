// SPDX-License-Identifier: Apache-2.0
#include "toonforce/gpio_cli/gpio_options.hpp"

namespace toonforce::cli {
namespace {

// CLI11 validators return "" when the value is fine, else the message it prints.
const CLI::Validator kLineSpec(
    [](std::string& text) {
      auto spec = gpio::parse_line_spec(text);
      return spec ? std::string() : spec.error();
    },
    "LINE");
const CLI::Validator kLedSpec(
    [](std::string& text) {
      auto spec = gpio::parse_led_spec(text);
      return spec ? std::string() : spec.error();
    },
    "ROLE=LINE");

}  // namespace

void add_gpio_options(CLI::App& command, gpio::GpioOptions& options) {
  auto* group =
      command.add_option_group("GPIO", "Bring-up pins (libgpiod). LINE is CHIP:OFFSET (gpiochip0:17) or a line name, "
                                       "optionally followed by :active-low, :pull-up or :pull-down");
  group->add_option("--tick-pin", options.tick_pin, "Output toggled every tick (scope it: period, jitter)")
      ->type_name("LINE")
      ->check(kLineSpec);
  group
      ->add_option("--estop-pin", options.estop_pin,
                   "Emergency-stop input: force is zero in the tick it reads active, latched until "
                   "released and re-armed (wire normally-closed, use :active-low)")
      ->type_name("LINE")
      ->check(kLineSpec);
  group->add_option("--enable-pin", options.enable_pin, "Enable (deadman) input: force only while it reads active")
      ->type_name("LINE")
      ->check(kLineSpec);
  group
      ->add_option("--amp-enable-pin", options.amp_enable_pin,
                   "Amplifier-enable output, held by the guardian process (not the loop's): active while the "
                   "loop ticks, dropped at once when the loop's process ends, dies or stalls (docs/DEPLOY.md)")
      ->type_name("LINE")
      ->check(kLineSpec);
  group
      ->add_option("--led-pin", options.led_pins,
                   "Status light ROLE=LINE, ROLE one of idle, homing, armed, fault; repeat or "
                   "separate with commas")
      ->type_name("ROLE=LINE")
      ->delimiter(',')
      ->check(kLedSpec);
}

}  // namespace toonforce::cli
