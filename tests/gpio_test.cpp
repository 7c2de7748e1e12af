// SPDX-License-Identifier: Apache-2.0
// GPIO: line specs and the CLI options; then the real backend (libgpiod 1.6 C API)
// against emulated /dev/gpiochip0 and /dev/gpiochip1 (umockdev, hal/gpio/emulator): pins that
// toggle once per tick, inputs read in the same call with their active level, lights, the
// start-up errors, and no allocation on the tick path. The emulation tests need
// umockdev-wrapper: CTest provides it; run by hand without it, they skip.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <stdexcept>
#include <thread>
#include <type_traits>

#include "alloc_counter.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/hal/pins.hpp"
#include "toonforce/effects/scene.hpp"
#include "toonforce/gpio_cli/gpio_options.hpp"
#include "toonforce/hal/gpio/emulated_gpio.hpp"
#include "toonforce/hal/gpio/gpio_session.hpp"
#include "toonforce/hal/gpio/output_line.hpp"
#include "guardian_stand_in.hpp"

namespace toonforce {
namespace {

using gpio::Bias;
using gpio::GpioOptions;
using gpio::emulation::ChipSpec;
using gpio::emulation::EmulatedGpio;
using ::testing::HasSubstr;

// ---- line specs (no emulation) ----------------------------------------------------------------

TEST(GpioLineSpec, ParsesChipAndOffset) {
  const auto spec = gpio::parse_line_spec("gpiochip0:17");
  ASSERT_TRUE(spec) << spec.error();
  EXPECT_EQ(spec->chip, "gpiochip0");
  EXPECT_EQ(spec->offset, 17u);
  EXPECT_FALSE(spec->by_name());
  EXPECT_FALSE(spec->active_low);
  EXPECT_EQ(spec->bias, Bias::kAsIs);
}

TEST(GpioLineSpec, ParsesFlagsInAnyOrder) {
  const auto spec = gpio::parse_line_spec("gpiochip1:4:pull-down:active-low");
  ASSERT_TRUE(spec) << spec.error();
  EXPECT_EQ(spec->chip, "gpiochip1");
  EXPECT_EQ(spec->offset, 4u);
  EXPECT_TRUE(spec->active_low);
  EXPECT_EQ(spec->bias, Bias::kPullDown);
}

TEST(GpioLineSpec, ParsesALineNameWithFlags) {
  const auto spec = gpio::parse_line_spec("ESTOP:active-low:pull-up");
  ASSERT_TRUE(spec) << spec.error();
  EXPECT_TRUE(spec->by_name());
  EXPECT_EQ(spec->name, "ESTOP");
  EXPECT_TRUE(spec->active_low);
  EXPECT_EQ(spec->bias, Bias::kPullUp);
}

TEST(GpioLineSpec, AcceptsChipNumberAndDevicePath) {
  const auto by_number = gpio::parse_line_spec("2:3");
  const auto by_path = gpio::parse_line_spec("/dev/gpiochip2:3");
  ASSERT_TRUE(by_number && by_path);
  EXPECT_EQ(gpio::chip_path(by_number->chip), "/dev/gpiochip2");
  EXPECT_EQ(gpio::chip_path(by_path->chip), "/dev/gpiochip2");
  EXPECT_EQ(gpio::chip_path("gpiochip2"), "/dev/gpiochip2");
}

TEST(GpioLineSpec, RejectsMalformedSpecsSayingWhy) {
  const auto expect_error = [](std::string_view text, std::string_view why) {
    const auto spec = gpio::parse_line_spec(text);
    ASSERT_FALSE(spec) << text;
    EXPECT_THAT(spec.error(), HasSubstr(why)) << text;
  };
  expect_error("", "empty");
  expect_error("gpiochip0", "no line offset");
  expect_error("gpiochip0:x", "line offset 'x' is not a number");
  expect_error("gpiochip0:17:activelow", "unknown flag 'activelow'");
  expect_error("ESTOP:pull-up:pull-down", "at most one of pull-up, pull-down");
  expect_error("ESTOP:active-low:active-low", "active-low given twice");
  expect_error(":active-low", "no line name");
  expect_error("gpiochip0:99999999999", "too large");
}

TEST(GpioLedSpec, ParsesRoleAndLine) {
  const auto led = gpio::parse_led_spec("fault=gpiochip0:6:active-low");
  ASSERT_TRUE(led) << led.error();
  EXPECT_EQ(led->state, LightState::kFault);
  EXPECT_EQ(led->line.offset, 6u);
  EXPECT_TRUE(led->line.active_low);
  for (const auto s : {LightState::kIdle, LightState::kHoming, LightState::kArmed, LightState::kFault}) {
    EXPECT_EQ(gpio::parse_light_state(gpio::light_state_name(s)), s);
  }
}

TEST(GpioLedSpec, RejectsUnknownRolesAndMissingRole) {
  EXPECT_THAT(gpio::parse_led_spec("armd=gpiochip0:5").error(), HasSubstr("unknown light 'armd'"));
  EXPECT_THAT(gpio::parse_led_spec("gpiochip0:5").error(), HasSubstr("expected ROLE=LINE"));
  EXPECT_THAT(gpio::parse_led_spec("armed=gpiochip0").error(), HasSubstr("armed light"));
}

// ---- CLI options -------------------------------------------------------------------------------

TEST(GpioCli, FillsOptionsFromTheCommandLine) {
  CLI::App app;
  GpioOptions options;
  cli::add_gpio_options(app, options);
  const char* argv[] = {"run",         "--tick-pin",       "gpiochip0:17",
                        "--estop-pin", "ESTOP:active-low", "--enable-pin",
                        "gpiochip0:5", "--led-pin",        "armed=gpiochip0:6,fault=gpiochip0:7",
                        "--led-pin",   "homing=LED_H"};
  app.parse(static_cast<int>(std::size(argv)), const_cast<char**>(argv));  // NOLINT
  EXPECT_EQ(options.tick_pin, "gpiochip0:17");
  EXPECT_EQ(options.estop_pin, "ESTOP:active-low");
  EXPECT_EQ(options.enable_pin, "gpiochip0:5");
  EXPECT_EQ(options.led_pins, (std::vector<std::string>{"armed=gpiochip0:6", "fault=gpiochip0:7", "homing=LED_H"}));
  EXPECT_FALSE(options.empty());
}

TEST(GpioCli, NoOptionsMeansNoGpio) {
  CLI::App app;
  GpioOptions options;
  cli::add_gpio_options(app, options);
  const char* argv[] = {"run"};
  app.parse(1, const_cast<char**>(argv));  // NOLINT
  EXPECT_TRUE(options.empty());
}

TEST(GpioCli, RejectsABadSpecAtParseTime) {
  const auto parse_error = [](std::vector<const char*> argv) -> std::string {
    CLI::App app;
    GpioOptions options;
    cli::add_gpio_options(app, options);
    try {
      app.parse(static_cast<int>(argv.size()), const_cast<char**>(argv.data()));  // NOLINT
    } catch (const CLI::ParseError& e) {
      return e.what();
    }
    return {};
  };
  EXPECT_THAT(parse_error({"run", "--estop-pin", "gpiochip0:4:activelow"}), HasSubstr("unknown flag 'activelow'"));
  EXPECT_THAT(parse_error({"run", "--led-pin", "armed=gpiochip0:5,blink=gpiochip0:6"}),
              HasSubstr("unknown light 'blink'"));
}

// ---- against emulated chips --------------------------------------------------------------------

// gpiochip0: 8 lines, some named as a bring-up board's device tree would name them;
// gpiochip1: 4 lines. "DUP" names a line on each chip.
const std::vector<ChipSpec> kChips = {
    {"toonforce-test-0", 8, {"", "", "", "DUP", "ESTOP", "ENABLE", "LED_ARMED", "LED_FAULT"}},
    {"toonforce-test-1", 4, {"TICK", "", "", "DUP"}},
};

class GpioEmulation : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!EmulatedGpio::available()) {
      if (std::getenv("TOONFORCE_REQUIRE_UMOCKDEV") != nullptr) {
        FAIL() << "CTest runs this binary under umockdev-wrapper, but the preload is not active";
      }
      GTEST_SKIP() << "needs umockdev: run as `umockdev-wrapper "
                   << "toonforce_gpio_tests`";
    }
    emu_ = std::make_unique<EmulatedGpio>(kChips);
  }
  void TearDown() override { emu_.reset(); }

  EmulatedGpio& emu() { return *emu_; }

  /// Opens, or ends the test (gtest reports the exception with the error text).
  gpio::GpioSession open(const GpioOptions& options) {
    auto session = gpio::open_gpio(options);
    if (!session) throw std::runtime_error("open_gpio failed: " + session.error());
    return std::move(session).value();
  }
  /// The error text of a failed open (and a test failure if it opened).
  std::string open_error(const GpioOptions& options) {
    auto session = gpio::open_gpio(options);
    EXPECT_FALSE(session) << "opened although it should not";
    return session ? std::string() : session.error();
  }

 private:
  std::unique_ptr<EmulatedGpio> emu_;
};

GpioOptions all_pins() {
  GpioOptions o;
  o.tick_pin = "gpiochip1:0";
  o.estop_pin = "ESTOP:active-low";  // gpiochip0:4
  o.enable_pin = "gpiochip0:5";
  o.led_pins = {"armed=LED_ARMED", "fault=gpiochip0:7"};
  return o;
}

TEST_F(GpioEmulation, RequestsEachLineOnceWithOurLabelAndDirection) {
  const auto session = open(all_pins());
  const auto tick = emu().line(1, 0);
  EXPECT_TRUE(tick.requested);
  EXPECT_TRUE(tick.output);
  EXPECT_EQ(tick.consumer, "toonforce");
  EXPECT_EQ(tick.physical, 0);  // starts low
  const auto estop = emu().line(0, 4);
  EXPECT_TRUE(estop.requested);
  EXPECT_FALSE(estop.output);
  EXPECT_TRUE(estop.active_low);  // the kernel inverts: gpioinfo shows it as active-low
  EXPECT_EQ(estop.consumer, "toonforce");
  const auto enable = emu().line(0, 5);
  EXPECT_TRUE(enable.requested);
  EXPECT_FALSE(enable.output);
  EXPECT_FALSE(enable.active_low);
  for (const unsigned led : {6u, 7u}) {
    EXPECT_TRUE(emu().line(0, led).requested);
    EXPECT_TRUE(emu().line(0, led).output);
    EXPECT_EQ(emu().line(0, led).physical, 0);  // LEDs start off
  }
  EXPECT_FALSE(emu().line(0, 0).requested);  // nothing else
  ASSERT_EQ(session.summary().size(), 5u);
  EXPECT_THAT(session.summary()[1], HasSubstr("gpiochip0:4 'ESTOP' input, active-low"));
}

TEST_F(GpioEmulation, AcceptsChipNumbersAndDevicePaths) {
  GpioOptions o;
  o.tick_pin = "/dev/gpiochip1:2";
  o.enable_pin = "0:1";
  const auto session = open(o);
  EXPECT_TRUE(emu().line(1, 2).requested);
  EXPECT_TRUE(emu().line(0, 1).requested);
}

TEST_F(GpioEmulation, PassesThePullResistorToTheKernel) {
  GpioOptions o;
  o.estop_pin = "gpiochip0:4:active-low:pull-down";
  o.enable_pin = "gpiochip0:5:pull-up";
  const auto session = open(o);
  EXPECT_EQ(emu().line(0, 4).bias, Bias::kPullDown);
  EXPECT_EQ(emu().line(0, 5).bias, Bias::kPullUp);
}

// ---- the servo loop on these pins ------------------------------------------------------------

// The servo loop itself with the pins under test, on a device that holds the handle where the
// test puts it: every tick reads the e-stop and the enable, zeroes the force while the e-stop
// is latched (engaged or unreadable, until released AND re-armed) or the enable is not active,
// shows the lights and toggles the tick pin. Engage and soft start are off (engage_force above
// any force here, no ramp) so the wall's force shows the gate alone.
using Wall = Surface<SpringWall<double>>;
using WallScene = Scene<Wall>;
constexpr double kPeriodS = 1e-3;

struct HeldDevice {
  const Vec3<double>* position_m;
  Vec3<double>* written_n;
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = *position_m;
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>& f) noexcept {
    *written_n = f;
    return DeviceStatus::kOk;
  }
};

inline ServoConfig pins_config() {
  ServoConfig c;
  c.period_s = kPeriodS;
  c.safety.engage_force_n = 1e3;
  c.safety.soft_start_s = 0.0;
  return c;
}

template <class PinsT>
class PinnedLoop {
 public:
  explicit PinnedLoop(PinsT pins)
      : loop_(HeldDevice{&position_m_, &written_n_},
              WallScene{Wall::Params{Plane<double>{{0, 0, 0}, {0, 0, 1}}, {1000.0, 0.0}}}, pins_config(), pins) {}

  /// One tick with the handle at `position_m`; the force commanded.
  Vec3<double> tick(const Vec3<double>& position_m) noexcept {
    position_m_ = position_m;
    last_ = loop_.tick(k_++);
    return written_n_;
  }
  /// The operator's re-arm (taken at the next tick, which runs here): false while the e-stop
  /// still reads engaged.
  bool rearm() noexcept {
    loop_.request_rearm();
    static_cast<void>(tick(position_m_));
    return !last_.rearm_refused && !loop_.latched();
  }
  PinsT& pins() noexcept { return loop_.pins(); }

 private:
  Vec3<double> position_m_{};
  Vec3<double> written_n_{};
  TickStatus last_{};
  std::int64_t k_ = 0;
  ServoLoop<HeldDevice, WallScene, PinsT> loop_;
};

const Vec3<double> kInWall{0.0, 0.0, -0.002};  // 2 mm deep: 2 N up
constexpr double kWallForceN = 2.0;

TEST_F(GpioEmulation, TickPinTogglesOncePerTick) {
  GpioOptions o;
  o.tick_pin = "gpiochip1:0";
  const auto session = open(o);
  PinnedLoop loop(session.pins());
  for (int k = 1; k <= 25; ++k) {
    loop.tick(kInWall);
    const auto line = emu().line(1, 0);
    ASSERT_EQ(line.writes, static_cast<std::uint64_t>(k)) << "one write per tick";
    ASSERT_EQ(line.changes, static_cast<std::uint64_t>(k)) << "every write changes the level";
    ASSERT_EQ(line.physical, k % 2) << "the level alternates, starting high on tick 1";
  }
  EXPECT_EQ(loop.pins().tick.write_errors(), 0u);
}

TEST_F(GpioEmulation, EstopReadsActiveInTheSameCallItIsPressed) {
  GpioOptions o;
  o.estop_pin = "gpiochip0:4";  // active-high
  const auto session = open(o);
  auto pins = session.pins();
  emu().drive(0, 4, 0);
  EXPECT_EQ(pins.estop.read(), PinLevel::kInactive);
  emu().drive(0, 4, 1);
  EXPECT_EQ(pins.estop.read(), PinLevel::kActive);  // no debounce, no delay: this very read
  emu().drive(0, 4, 0);
  EXPECT_EQ(pins.estop.read(), PinLevel::kInactive);
}

TEST_F(GpioEmulation, ActiveLowInputIsActiveWhenTheLineIsLow) {
  GpioOptions o;
  o.estop_pin = "ESTOP:active-low";
  o.enable_pin = "ENABLE:active-low";
  const auto session = open(o);
  auto pins = session.pins();
  emu().drive(0, 4, 1);
  emu().drive(0, 5, 0);
  EXPECT_EQ(pins.estop.read(), PinLevel::kInactive);
  EXPECT_EQ(pins.enable.read(), PinLevel::kActive);
  emu().drive(0, 4, 0);
  emu().drive(0, 5, 1);
  EXPECT_EQ(pins.estop.read(), PinLevel::kActive);
  EXPECT_EQ(pins.enable.read(), PinLevel::kInactive);
}

// The wiring docs/GPIO.md recommends: a normally-closed contact from 3V3 to the input, a pull-
// down, `:active-low`. Pressing the button, a broken wire or an unplugged connector all leave
// the line undriven, the pull-down takes it low, and the e-stop reads engaged.
TEST_F(GpioEmulation, BrokenEstopWireReadsEngagedWithTheRecommendedWiring) {
  GpioOptions o;
  o.estop_pin = "ESTOP:active-low:pull-down";
  const auto session = open(o);
  auto pins = session.pins();
  emu().drive(0, 4, 1);  // contact closed: the line is held at 3V3
  EXPECT_EQ(pins.estop.read(), PinLevel::kInactive);
  emu().disconnect(0, 4);  // contact open or wire cut
  EXPECT_EQ(pins.estop.read(), PinLevel::kActive);
}

TEST_F(GpioEmulation, EstopZeroesForceInTheTickItEngagesAndStaysLatchedUntilRearmed) {
  GpioOptions o;
  o.estop_pin = "ESTOP:active-low";
  const auto session = open(o);
  PinnedLoop loop(session.pins());
  emu().drive(0, 4, 1);  // released
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(loop.tick(kInWall).z, kWallForceN, 1e-9);

  emu().drive(0, 4, 0);  // pressed between two ticks
  EXPECT_EQ(loop.tick(kInWall).z, 0.0) << "zero in the very tick that reads it";
  emu().drive(0, 4, 1);  // released again
  for (int k = 0; k < 5; ++k) EXPECT_EQ(loop.tick(kInWall).z, 0.0) << "latched after release";

  emu().drive(0, 4, 0);
  EXPECT_FALSE(loop.rearm()) << "no re-arm while still pressed";
  emu().drive(0, 4, 1);
  EXPECT_TRUE(loop.rearm());
  EXPECT_NEAR(loop.tick(kInWall).z, kWallForceN, 1e-9);
}

TEST_F(GpioEmulation, EnableGatesForceLikeADeadman) {
  GpioOptions o;
  o.enable_pin = "ENABLE";
  const auto session = open(o);
  PinnedLoop loop(session.pins());
  emu().drive(0, 5, 0);
  EXPECT_EQ(loop.tick(kInWall).z, 0.0) << "not held: no force";
  emu().drive(0, 5, 1);
  EXPECT_NEAR(loop.tick(kInWall).z, kWallForceN, 1e-9) << "held: force";
  emu().drive(0, 5, 0);
  EXPECT_EQ(loop.tick(kInWall).z, 0.0) << "let go: no force in that tick";
}

TEST_F(GpioEmulation, ReadErrorIsTheSafeState) {
  GpioOptions o;
  o.estop_pin = "ESTOP:active-low";
  o.enable_pin = "ENABLE";
  const auto session = open(o);
  PinnedLoop loop(session.pins());
  emu().drive(0, 4, 1);
  emu().drive(0, 5, 1);
  EXPECT_NEAR(loop.tick(kInWall).z, kWallForceN, 1e-9);

  emu().fail_values(0, 5, EIO);
  EXPECT_EQ(loop.pins().enable.read(), PinLevel::kError);
  EXPECT_EQ(loop.tick(kInWall).z, 0.0) << "an unreadable enable is a released enable";
  emu().fail_values(0, 5, 0);

  emu().fail_values(0, 4, EIO);
  EXPECT_EQ(loop.pins().estop.read(), PinLevel::kError);
  EXPECT_EQ(loop.tick(kInWall).z, 0.0) << "an unreadable e-stop is an engaged e-stop";
  EXPECT_EQ(loop.pins().estop.read_errors(), 2u);   // likewise
  EXPECT_EQ(loop.pins().enable.read_errors(), 2u);  // the read above and the tick's
}

TEST_F(GpioEmulation, FailedTickWriteIsCountedNotThrown) {
  GpioOptions o;
  o.tick_pin = "gpiochip1:0";
  const auto session = open(o);
  auto pins = session.pins();
  pins.tick.toggle();
  emu().fail_values(1, 0, EIO);
  pins.tick.toggle();
  pins.tick.toggle();
  EXPECT_EQ(pins.tick.write_errors(), 2u);
  EXPECT_EQ(pins.tick.value(), 1);  // still what the pin shows
  EXPECT_EQ(emu().line(1, 0).physical, 1);
  emu().fail_values(1, 0, 0);
  pins.tick.toggle();
  EXPECT_EQ(emu().line(1, 0).physical, 0);
  EXPECT_THAT(gpio::pin_error_summary(pins), HasSubstr("tick pin: 2 failed writes"));
}

TEST_F(GpioEmulation, LightsShowOneLedAndWriteOnlyWhenTheStateChanges) {
  GpioOptions o;
  o.led_pins = {"armed=LED_ARMED", "fault=LED_FAULT:active-low"};
  const auto session = open(o);
  auto pins = session.pins();
  EXPECT_EQ(emu().line(0, 7).physical, 1) << "an active-low LED starts off, i.e. high";

  pins.lights.show(LightState::kArmed);
  EXPECT_EQ(emu().line(0, 6).physical, 1);
  EXPECT_EQ(emu().line(0, 7).physical, 1);  // off
  const auto writes = emu().line(0, 6).writes + emu().line(0, 7).writes;
  for (int k = 0; k < 100; ++k) pins.lights.show(LightState::kArmed);
  EXPECT_EQ(emu().line(0, 6).writes + emu().line(0, 7).writes, writes) << "no ioctl without a change";

  pins.lights.show(LightState::kFault);
  EXPECT_EQ(emu().line(0, 6).physical, 0);
  EXPECT_EQ(emu().line(0, 7).physical, 0);  // on (active-low)
  pins.lights.show(LightState::kHoming);    // no homing LED: all off
  EXPECT_EQ(emu().line(0, 6).physical, 0);
  EXPECT_EQ(emu().line(0, 7).physical, 1);
}

TEST_F(GpioEmulation, ClosingTheSessionSwitchesTheLightsOff) {
  GpioOptions o;
  o.led_pins = {"armed=LED_ARMED", "fault=LED_FAULT:active-low"};
  {
    std::optional<gpio::GpioSession> first(open(o));
    const gpio::GpioSession session = std::move(*first);
    auto pins = session.pins();
    pins.lights.show(LightState::kArmed);
    first.reset();
    EXPECT_EQ(emu().line(0, 6).physical, 1) << "a moved-from session touches nothing";
  }
  EXPECT_EQ(emu().line(0, 6).physical, 0) << "no 'armed' light after the run";
  EXPECT_EQ(emu().line(0, 7).physical, 1) << "active-low fault light off";
}

TEST_F(GpioEmulation, AbsentPinsBehaveLikeTheNullPinsAndTouchNoDevice) {
  gpio::GpioPins pins;  // nothing configured
  const auto before = emu().ioctl_count();
  pins.tick.toggle();
  EXPECT_EQ(pins.estop.read(), PinLevel::kInactive);
  EXPECT_EQ(pins.enable.read(), PinLevel::kActive);
  pins.lights.show(LightState::kFault);
  EXPECT_EQ(emu().ioctl_count(), before);
  EXPECT_FALSE(pins.tick.present() || pins.estop.present() || pins.enable.present() || pins.lights.present());

  GpioOptions o;
  o.estop_pin = "ESTOP";  // only the e-stop: the rest stays absent
  const auto session = open(o);
  EXPECT_TRUE(session.pins().estop.present());
  EXPECT_FALSE(session.pins().tick.present());
  EXPECT_EQ(gpio::GpioEnablePin{}.read(), AlwaysActive{}.read());
  EXPECT_EQ(gpio::GpioEstopPin{}.read(), NeverActive{}.read());
}

TEST_F(GpioEmulation, TickPathAllocatesNothing) {
  const auto session = open(all_pins());
  PinnedLoop loop(session.pins());
  emu().drive(0, 4, 1);
  emu().drive(0, 5, 1);
  loop.tick(kInWall);  // first-call effects out of the way
  const test::AllocationScope scope;
  for (int k = 0; k < 50; ++k) {
    loop.tick(kInWall);
    if (k == 20) emu().drive(0, 4, 0);  // lights change too
  }
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_EQ(emu().line(1, 0).writes, 51u);
}

// ---- choosing the pin type at run time ---------------------------------------------------------

template <class P>
constexpr int kind_of() {
  return std::is_same_v<P, NullPins> ? 0 : std::is_same_v<P, gpio::GpioPins> ? 1 : -1;
}

TEST_F(GpioEmulation, WithGpioPinsRunsNullPinsWhenNothingIsConfigured) {
  int runs = 0;
  const auto run = [&](auto& pins) {
    ++runs;
    return kind_of<std::remove_cvref_t<decltype(pins)>>();
  };
  const auto none = gpio::with_gpio_pins(GpioOptions{}, run);
  ASSERT_TRUE(none);
  EXPECT_EQ(none.value(), 0);
  EXPECT_EQ(emu().ioctl_count(), 0u);

  GpioOptions o;
  o.tick_pin = "gpiochip1:0";
  const auto some = gpio::with_gpio_pins(o, run);
  ASSERT_TRUE(some) << some.error();
  EXPECT_EQ(some.value(), 1);

  o.estop_pin = "gpiochip9:1";
  const auto bad = gpio::with_gpio_pins(o, run);
  ASSERT_FALSE(bad);
  EXPECT_THAT(bad.error(), HasSubstr("no GPIO chip /dev/gpiochip9"));
  EXPECT_EQ(runs, 2) << "not run when opening fails";
}

// ---- start-up errors ---------------------------------------------------------------------------

TEST_F(GpioEmulation, MissingChipListsTheChipsThatExist) {
  GpioOptions o;
  o.tick_pin = "gpiochip7:1";
  EXPECT_THAT(open_error(o), HasSubstr("--tick-pin gpiochip7:1: no GPIO chip /dev/gpiochip7; the chips "
                                       "here are gpiochip0 [toonforce-test-0, 8 lines], gpiochip1 "
                                       "[toonforce-test-1, 4 lines]"));
}

TEST_F(GpioEmulation, LineOutOfRangeGivesTheChipsRange) {
  GpioOptions o;
  o.estop_pin = "gpiochip0:17";
  EXPECT_THAT(open_error(o),
              HasSubstr("--estop-pin gpiochip0:17: gpiochip0 has 8 lines (offsets 0 to 7); there is no line 17"));
}

TEST_F(GpioEmulation, LineInUseNamesItsUser) {
  emu().claim(0, 4, "other-app");
  GpioOptions o;
  o.estop_pin = "ESTOP:active-low";
  const auto error = open_error(o);
  EXPECT_THAT(error, HasSubstr("--estop-pin ESTOP:active-low: gpiochip0:4 is in use by 'other-app'"));
  EXPECT_THAT(error, HasSubstr("gpioinfo gpiochip0"));
}

TEST_F(GpioEmulation, LineTakenBetweenCheckAndRequestIsInUseToo) {
  emu().fail_request(0, 5, EBUSY);
  GpioOptions o;
  o.enable_pin = "gpiochip0:5";
  EXPECT_THAT(open_error(o), HasSubstr("--enable-pin gpiochip0:5: gpiochip0:5 is in use by"));
}

TEST_F(GpioEmulation, PermissionDeniedNamesTheNodeAndTheFix) {
  emu().deny_open(0, EACCES);
  GpioOptions o;
  o.tick_pin = "gpiochip0:2";
  const auto error = open_error(o);
  EXPECT_THAT(error, HasSubstr("--tick-pin gpiochip0:2: no permission to open /dev/gpiochip0"));
  // The emulated node belongs to root's group, so the fix is a udev rule for a gpio group.
  EXPECT_THAT(error, HasSubstr("KERNEL==\"gpiochip*\", GROUP=\"gpio\", MODE=\"0660\""));
  EXPECT_THAT(error, HasSubstr("usermod -aG gpio"));
}

TEST_F(GpioEmulation, UnknownLineNameSaysWhereItLooked) {
  GpioOptions o;
  o.estop_pin = "E_STOP";
  EXPECT_THAT(open_error(o), HasSubstr("--estop-pin E_STOP: no line named 'E_STOP' on any GPIO chip "
                                       "(searched gpiochip0, gpiochip1"));
}

TEST_F(GpioEmulation, NameSearchReportsChipsItCouldNotOpen) {
  emu().deny_open(1, EACCES);
  GpioOptions o;
  o.tick_pin = "TICK";  // on gpiochip1, which we may not open
  const auto error = open_error(o);
  EXPECT_THAT(error, HasSubstr("no line named 'TICK'"));
  EXPECT_THAT(error, HasSubstr("could not search gpiochip1 (no permission to open /dev/gpiochip1"));
}

TEST_F(GpioEmulation, AmbiguousNameAsksForChipAndOffset) {
  GpioOptions o;
  o.tick_pin = "DUP";
  EXPECT_THAT(open_error(o), HasSubstr("the name 'DUP' belongs to several lines (gpiochip0:3, gpiochip1:3); "
                                       "name the line as CHIP:OFFSET"));
}

TEST_F(GpioEmulation, OneLineForTwoPinsIsRefused) {
  GpioOptions o;
  o.tick_pin = "gpiochip0:6";
  o.led_pins = {"armed=LED_ARMED"};  // gpiochip0:6 too
  EXPECT_THAT(open_error(o), HasSubstr("--led-pin armed=LED_ARMED: gpiochip0:6 is already the line of "
                                       "--tick-pin gpiochip0:6"));
}

TEST_F(GpioEmulation, ReportsEveryProblemAtOnce) {
  emu().claim(0, 5, "other-app");
  GpioOptions o;
  o.tick_pin = "gpiochip7:0";
  o.enable_pin = "gpiochip0:5";
  o.led_pins = {"fault=gpiochip0:40"};
  const auto error = open_error(o);
  EXPECT_THAT(error, HasSubstr("--tick-pin gpiochip7:0: no GPIO chip"));
  EXPECT_THAT(error, HasSubstr("\n--enable-pin gpiochip0:5: gpiochip0:5 is in use by 'other-app'"));
  EXPECT_THAT(error, HasSubstr("\n--led-pin fault=gpiochip0:40: gpiochip0 has 8 lines"));
}

TEST_F(GpioEmulation, UnsupportedPullResistorIsExplained) {
  emu().fail_request(0, 4, EINVAL);
  GpioOptions o;
  o.estop_pin = "ESTOP:pull-down";
  EXPECT_THAT(open_error(o), HasSubstr("the kernel refused the pull resistor"));
}

TEST_F(GpioEmulation, UnreadableInputStopsTheStart) {
  emu().fail_values(0, 4, EIO);
  GpioOptions o;
  o.estop_pin = "ESTOP";
  EXPECT_THAT(open_error(o), HasSubstr("--estop-pin ESTOP: cannot read gpiochip0:4: Input/output error"));
}

TEST_F(GpioEmulation, FailedStartReleasesTheLinesItHadRequested) {
  GpioOptions o;
  o.tick_pin = "gpiochip1:0";    // fine
  o.estop_pin = "gpiochip0:17";  // out of range
  EXPECT_FALSE(gpio::open_gpio(o));
  // umockdev notices the closed line-handle fd on its worker thread: wait for it (bounded).
  for (int i = 0; i < 500 && emu().line(1, 0).requested; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_FALSE(emu().line(1, 0).requested);
}

TEST_F(GpioEmulation, ListsTheChips) {
  const auto chips = gpio::list_chips();
  ASSERT_EQ(chips.size(), 2u);
  EXPECT_EQ(chips[0].path, "/dev/gpiochip0");
  EXPECT_EQ(chips[0].label, "toonforce-test-0");
  EXPECT_EQ(chips[1].num_lines, 4u);
  EXPECT_TRUE(chips[1].problem.empty());
}

// ---- the amplifier-enable line, held by `toonforce run`'s guardian -----------------

TEST_F(GpioEmulation, TheGuardianHoldsTheAmplifierEnableActiveWhileTheLoopTicksAndDropsItWhenItsProcessIsKilled) {
  auto spec = gpio::parse_line_spec("gpiochip0:2:active-low");
  ASSERT_TRUE(spec) << spec.error();
  auto line = gpio::OutputLine::open(spec.value(), "toonforce-guardian");
  ASSERT_TRUE(line) << line.error();
  EXPECT_EQ(emu().line(0, 2).physical, 1) << "requested at its inactive level (active-low: high)";
  EXPECT_EQ(emu().line(0, 2).consumer, "toonforce-guardian");
  struct Enable final : guardian::EnableLine {
    gpio::OutputLine& line;
    explicit Enable(gpio::OutputLine& l) : line(l) {}
    bool set(bool active) noexcept override { return line.set(active); }
    std::string describe() const override { return "the amplifier-enable line " + line.describe(); }
  } enable(*line.value());
  const toonforce::test::GuardedStandIn run =
      toonforce::test::guard_a_stand_in(ExternalZero{}, &enable, [&] { return emu().line(0, 2).physical == 0; });
  EXPECT_TRUE(run.active_while_ticking) << "the line is active (low) while the loop ticks";
  EXPECT_TRUE(run.outcome.loop_died);
  EXPECT_TRUE(run.outcome.zero_sent) << run.outcome.zero_detail;
  EXPECT_NE(run.outcome.zero_detail.find("the amplifier-enable line /dev/gpiochip0 line 2 was dropped"),
            std::string::npos)
      << run.outcome.zero_detail;
  EXPECT_GE(run.outcome.zero_ns, run.killed_ns);
  EXPECT_EQ(emu().line(0, 2).physical, 1) << "dropped: inactive (high) once the loop's process is gone";
}

TEST_F(GpioEmulation, AnAmplifierEnableLineThatCannotBeTakenSaysWhoHoldsIt) {
  emu().claim(0, 2, "someone-else");
  auto spec = gpio::parse_line_spec("gpiochip0:2");
  ASSERT_TRUE(spec);
  auto line = gpio::OutputLine::open(spec.value(), "toonforce-guardian");
  ASSERT_FALSE(line);
  EXPECT_NE(line.error().find("held by 'someone-else'"), std::string::npos) << line.error();
}

TEST_F(GpioEmulation, TheGuardianRequestsTheEnableLineItselfAndDrivesItThroughItsOwnHandle) {
  // `toonforce-guardian` takes the line it is given by chip and offset, at its inactive level,
  // as the guardian's; the guard then drives it (the stand-in: active while it ticks, dropped at
  // its death).
  guardian::GpioEnableLine line;
  ASSERT_EQ(line.open("/dev/gpiochip0", 2, /*active_low=*/true), "");
  EXPECT_EQ(emu().line(0, 2).consumer, "toonforce-guardian");
  EXPECT_EQ(emu().line(0, 2).physical, 1) << "requested inactive (active-low: high)";
  EXPECT_EQ(line.describe(), "the amplifier-enable line /dev/gpiochip0 line 2");
  const toonforce::test::GuardedStandIn run =
      toonforce::test::guard_a_stand_in(ExternalZero{}, &line, [&] { return emu().line(0, 2).physical == 0; });
  EXPECT_TRUE(run.active_while_ticking);
  EXPECT_TRUE(run.outcome.zero_sent) << run.outcome.zero_detail;
  EXPECT_GE(run.outcome.zero_ns, run.killed_ns);
  // For tools/bench/guardian-kill (a time, never asserted): the line as the guardian program
  // holds it.
  std::printf("guardian kill to zero (gpio): %.3f ms\n",
              static_cast<double>(run.outcome.zero_ns - run.killed_ns) * 1e-6);
  EXPECT_EQ(emu().line(0, 2).physical, 1) << "dropped once the loop's process is gone";
}

TEST_F(GpioEmulation, TheGuardianRefusesAnEnableChipThatIsNotAGpioChip) {
  for (const std::string& chip :
       {std::string("/etc/passwd"), std::string("/dev/gpiochip0/../null"), std::string("/dev/gpiochip9")}) {
    guardian::GpioEnableLine line;
    EXPECT_NE(line.open(chip, 0, false), "") << chip;
    EXPECT_FALSE(line.set(true)) << chip;
  }
  guardian::GpioEnableLine past_the_end;
  EXPECT_NE(past_the_end.open("/dev/gpiochip0", 4096, false).find("no line 4096"), std::string::npos);
}

}  // namespace
}  // namespace toonforce
