// SPDX-License-Identifier: Apache-2.0
// `toonforce bringup gpio` against emulated /dev/gpiochip0 (umockdev, hal/gpio/emulator), with
// an emulated person who presses the switches and reads the tick pin on an emulated scope: the
// e-stop gives zero force in the tick the servo loop sees it, and an e-stop wired with the
// wrong polarity, or a scope on the wrong line, is caught with what to do. CTest runs this
// under umockdev-wrapper; run by hand without it, the tests skip.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>

#include "toonforce/bringup/gpio_bringup.hpp"
#include "toonforce/hal/gpio/emulated_gpio.hpp"

namespace toonforce::bringup {
namespace {

using gpio::emulation::ChipSpec;
using gpio::emulation::EmulatedGpio;
using ::testing::HasSubstr;

constexpr unsigned kTick = 1;
constexpr unsigned kEstop = 4;
constexpr unsigned kEnable = 5;
constexpr unsigned kOther = 7;

/// Presses and releases switches (active-high wiring: pressed drives the line high), and reads
/// the tick pin's frequency on an emulated scope: level changes over the ticks it watched.
class GpioPerson final : public Operator {
 public:
  GpioPerson(EmulatedGpio& emu, double rate_hz) : emu_(emu), rate_hz_(rate_hz) {}
  void say(std::string_view line) override { said += std::string(line) + "\n"; }
  void begin(const Request& r) override {
    polls_ = 0;
    if (r.id == "gpio.tick") changes_at_start_ = emu_.line(0, scope_line).changes;
  }
  Progress poll(const Request& r) override {
    const int n = polls_++;
    if (r.id == "gpio.tick") {
      if (n + 1 < 400) return Progress::kWaiting;
      // Each poll follows one tick: 400 ticks watched.
      const auto changes = emu_.line(0, scope_line).changes - changes_at_start_;
      read_hz_ = static_cast<double>(changes) / 2.0 / (400.0 / rate_hz_);
      return Progress::kDone;
    }
    if (r.id == "gpio.estop.press" && n == 20) emu_.drive(0, kEstop, 1);
    if (r.id == "gpio.estop.release" && n == 20) emu_.drive(0, kEstop, 0);
    if ((r.id == "gpio.enable.press" || r.id == "gpio.enable.press.again") && n == 5) emu_.drive(0, kEnable, 1);
    if (r.id == "gpio.enable.release" && n == 20) emu_.drive(0, kEnable, 0);
    return Progress::kWaiting;
  }
  std::optional<std::string> ask(const Request& r) override {
    if (r.id == "gpio.tick.frequency_hz") return std::to_string(read_hz_);
    return std::nullopt;
  }
  bool interactive() const override { return true; }

  unsigned scope_line = kTick;
  std::string said;

 private:
  EmulatedGpio& emu_;
  double rate_hz_;
  int polls_ = 0;
  std::uint64_t changes_at_start_ = 0;
  double read_hz_ = 0.0;
};

class GpioBringup : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!EmulatedGpio::available()) {
      if (std::getenv("TOONFORCE_REQUIRE_UMOCKDEV") != nullptr) FAIL() << "the umockdev preload is not active";
      GTEST_SKIP() << "needs umockdev: run under umockdev-wrapper (CTest does)";
    }
    emu = std::make_unique<EmulatedGpio>(std::vector<ChipSpec>{ChipSpec{"bring-up", 8, {}}});
    options.paced = false;
    options.pins.tick_pin = "gpiochip0:1";
    options.pins.estop_pin = "gpiochip0:4:pull-down";
    options.pins.enable_pin = "gpiochip0:5:pull-down";
  }
  static std::string finding(const Report& r, std::string_view id) {
    const StepReport* s = r.step(id);
    return s != nullptr ? s->finding + " | " + s->next : std::string();
  }
  std::unique_ptr<EmulatedGpio> emu;
  GpioBringupOptions options;
};

TEST_F(GpioBringup, WellWiredLinesPassAndTheEstopCutsTheForceInTheTickItIsSeen) {
  GpioPerson person(*emu, options.rate_hz);
  const Report r = run_gpio_bringup(person, options);
  for (const char* id : kGpioSteps) {
    EXPECT_EQ(r.step(id)->outcome, Outcome::kPass) << id << ": " << finding(r, id);
  }
  EXPECT_THAT(finding(r, "tick"), HasSubstr("500.0 Hz, half the loop's 1000 Hz"));
  EXPECT_THAT(finding(r, "estop"), HasSubstr("zero force in the tick the loop saw the e-stop"));
  const StepReport* estop = r.step("estop");
  const auto value_of = [&](std::string_view name) {
    for (const auto& m : estop->measurements) {
      if (m.name == name) return m.value;
    }
    return std::string("?");
  };
  EXPECT_EQ(value_of("force in the tick the e-stop was seen"), "0.000");
  EXPECT_EQ(value_of("force before"), "1.000") << "the loop pushed 1 N out of the bench's floor before";
}

TEST_F(GpioBringup, AnEstopThatReadsEngagedUnpressedIsCaughtWithThePolarityFix) {
  emu->drive(0, kEstop, 1);  // a normally-closed switch read active-high: engaged at rest
  GpioPerson person(*emu, options.rate_hz);
  options.only = {"lines", "estop"};
  const Report r = run_gpio_bringup(person, options);
  EXPECT_EQ(r.step("estop")->outcome, Outcome::kFail);
  EXPECT_THAT(finding(r, "estop"), HasSubstr("reads engaged although nobody pressed it"));
  EXPECT_THAT(finding(r, "estop"), HasSubstr(":active-low"));
}

TEST_F(GpioBringup, AScopeOnAnotherLineReadsNothingAndIsToldWhichLineToProbe) {
  GpioPerson person(*emu, options.rate_hz);
  person.scope_line = kOther;
  options.only = {"lines", "tick"};
  const Report r = run_gpio_bringup(person, options);
  EXPECT_EQ(r.step("tick")->outcome, Outcome::kFail);
  EXPECT_THAT(finding(r, "tick"), HasSubstr("shows 0.0 Hz, not 500.0 Hz"));
  EXPECT_THAT(finding(r, "tick"), HasSubstr("not the header pin number"));
}

TEST_F(GpioBringup, ALineThatDoesNotExistStopsAtTheFirstStep) {
  options.pins.estop_pin = "gpiochip0:60";
  GpioPerson person(*emu, options.rate_hz);
  const Report r = run_gpio_bringup(person, options);
  EXPECT_EQ(r.step("lines")->outcome, Outcome::kFail);
  EXPECT_THAT(finding(r, "lines"), HasSubstr("there is no line 60"));
  EXPECT_THAT(r.step("estop")->finding, HasSubstr("not run"));
}

}  // namespace
}  // namespace toonforce::bringup
