// SPDX-License-Identifier: Apache-2.0
// `toonforce bringup falcon` against the emulated Falcon (hal/falcon/emulator) in process, with
// an emulated person who does what each request asks: a healthy Falcon passes every step, and
// each hardware fault the emulator injects is caught by the step that should catch it, with
// the message a user needs. Unpaced (as fast as the emulator answers): no timing is asserted.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <map>

#include "toonforce/config/falcon_calibration_file.hpp"
#include "toonforce/bringup/falcon_bringup.hpp"
#include "toonforce/hal/falcon/calibration.hpp"
#include "toonforce/hal/falcon/emulator/emulator_transport.hpp"
#include "toonforce/hal/falcon/emulator/falcon_emulator.hpp"

namespace toonforce::bringup {
namespace {

using falcon::emulator::EmulatorOptions;
using falcon::emulator::EmulatorTransport;
using falcon::emulator::FalconEmulator;
using ::testing::HasSubstr;
namespace fs = std::filesystem;

constexpr const char* kSerial = "FTEMU0001";

/// One emulated Falcon on "USB", opened in process.
class EmulatedAccess final : public FalconAccess {
 public:
  explicit EmulatedAccess(FalconEmulator& emu) : emu_(emu) {}
  FalconDetection detect() override {
    FalconDetection d;
    DetectedDevice dev;
    dev.kind = "Novint Falcon";
    dev.location = "emulated usb 001/005";
    dev.serial = kSerial;
    dev.can_open = can_open;
    if (!can_open) {
      dev.problem = "no permission on /dev/bus/usb/001/005";
      dev.fix = "install the udev rule";
    }
    d.devices.push_back(dev);
    return d;
  }
  Result<std::unique_ptr<falcon::FalconTransport>> open(const FalconOptions&) override {
    ++opens;
    return std::unique_ptr<falcon::FalconTransport>(std::make_unique<EmulatorTransport>(emu_));
  }
  bool can_open = true;
  int opens = 0;

 private:
  FalconEmulator& emu_;
};

/// The person at the emulated Falcon: does what each request asks, over the polls of its wait
/// (the bring-up keeps the device running meanwhile), and answers what it sees.
class EmulatedPerson final : public Operator {
 public:
  explicit EmulatedPerson(FalconEmulator& emu) : emu_(emu) {}

  void say(std::string_view line) override { said += std::string(line) + "\n"; }
  void begin(const Request& r) override {
    requests.push_back(r.id);
    polls_ = 0;
  }
  Progress poll(const Request& r) override {
    const int n = polls_++;
    if (r.id == "falcon.homing") {
      // Out to the stop, then straight in (FALCON.md §4); a person gives up after a while.
      if (n == 1) emu_.set_grip_position({0, 0, 0.178});
      if (n == 40) emu_.set_grip_position({0, 0, 0.09});
      if (n == 80) emu_.set_grip_position(kCentre);
      return n > 2000 ? Progress::kDone : Progress::kWaiting;
    }
    if (r.id == "falcon.encoders") {
      // Corners of a box inside the workspace, 30 polls each, then back to the centre.
      static const Vec3<double> kCorners[] = {{-0.045, -0.045, 0.085}, {0.045, -0.045, 0.085},  {0.045, 0.045, 0.085},
                                              {-0.045, 0.045, 0.085},  {-0.045, -0.045, 0.150}, {0.045, -0.045, 0.150},
                                              {0.045, 0.045, 0.150},   {-0.045, 0.045, 0.150}};
      const int corner = n / 30;
      if (corner < 8) {
        if (n % 30 == 0) emu_.set_grip_position(kCorners[corner]);
        return Progress::kWaiting;
      }
      emu_.set_grip_position(kCentre);
      return Progress::kDone;
    }
    if (r.id == "falcon.motors.hold") {
      emu_.set_grip_position(kCentre);
      emu_.set_hand_spring(60.0, 3.0);  // fingertips: a soft, damped hold
      return Progress::kDone;
    }
    if (r.id == "falcon.force.release") {
      emu_.set_hand_spring(0.0, 0.0);
      return n > 5 ? Progress::kDone : Progress::kWaiting;
    }
    if (r.id == "falcon.force.hang") {
      emu_.hang_weight(mass_kg);
      return n > 5 ? Progress::kDone : Progress::kWaiting;
    }
    if (r.id == "falcon.force.unhang") {
      emu_.hang_weight(0.0);
      emu_.set_hand_spring(60.0, 3.0);
      return Progress::kDone;
    }
    if (r.id.rfind("falcon.button.", 0) == 0) {
      static const std::map<std::string, std::uint8_t> kBits{{"falcon.button.plus", falcon::kButtonPlus},
                                                             {"falcon.button.forward", falcon::kButtonForward},
                                                             {"falcon.button.centre", falcon::kButtonCentre},
                                                             {"falcon.button.minus", falcon::kButtonMinus}};
      const auto it = kBits.find(r.id);
      emu_.set_buttons(it != kBits.end() ? it->second : 0);  // ".release": let go
      return Progress::kWaiting;
    }
    return Progress::kDone;
  }
  std::optional<std::string> ask(const Request& r) override {
    requests.push_back(r.id);
    if (r.id == "falcon.force.method") return std::string("weight");
    if (r.id == "falcon.force.mass_kg") return std::to_string(mass_kg);
    if (r.id.rfind("falcon.led.", 0) == 0) {
      // Looks at the LED: the colour named in the question, alone?
      const std::string colour = r.id.substr(std::string("falcon.led.").size());
      const std::uint8_t bit = colour == "red"     ? falcon::kLedRed
                               : colour == "green" ? falcon::kLedGreen
                                                   : falcon::kLedBlue;
      return std::string(emu_.led() == bit ? "y" : "n");
    }
    return std::nullopt;
  }
  bool interactive() const override { return true; }

  static constexpr Vec3<double> kCentre{0.0, 0.0, 0.110};
  double mass_kg = 0.2;
  std::string said;
  std::vector<std::string> requests;

 private:
  FalconEmulator& emu_;
  int polls_ = 0;
};

class FalconBringup : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("toonforce_bringup_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    ::setenv("XDG_CONFIG_HOME", (dir_ / "config").c_str(), 1);  // no calibration of the user's
    options.paced = false;
    options.calibration_out = (dir_ / "falcon.toml").string();
    options.homing_timeout_s = 10.0;
    options.sweep_timeout_s = 10.0;
  }
  void TearDown() override { fs::remove_all(dir_); }

  static EmulatorOptions healthy() {
    EmulatorOptions o;
    o.firmware_loaded = true;
    return o;
  }
  Report run(const EmulatorOptions& o) {
    emu = std::make_unique<FalconEmulator>(o);
    EmulatedAccess access(*emu);
    EmulatedPerson person(*emu);
    Report r = run_falcon_bringup(access, person, options);
    said = person.said;
    return r;
  }
  static Outcome outcome(const Report& r, std::string_view id) {
    const StepReport* s = r.step(id);
    EXPECT_NE(s, nullptr) << id;
    return s != nullptr ? s->outcome : Outcome::kSkipped;
  }
  static std::string finding(const Report& r, std::string_view id) {
    const StepReport* s = r.step(id);
    return s != nullptr ? s->finding + " | " + s->next : std::string();
  }
  /// Every step after `id` was not run because `id` failed.
  static void later_steps_not_run(const Report& r, std::string_view id, std::string_view title) {
    bool after = false;
    for (const StepReport& s : r.steps) {
      if (after) {
        EXPECT_EQ(s.outcome, Outcome::kSkipped) << s.id;
        EXPECT_THAT(s.finding, HasSubstr(std::string("not run: ") + std::string(title) + " failed")) << s.id;
      }
      after = after || s.id == id;
    }
  }

  fs::path dir_;
  FalconBringupOptions options;
  std::unique_ptr<FalconEmulator> emu;
  std::string said;
};

TEST_F(FalconBringup, AHealthyFalconPassesEveryStep) {
  const Report r = run(healthy());
  ASSERT_EQ(r.steps.size(), std::size(kFalconSteps));
  for (std::size_t i = 0; i < r.steps.size(); ++i) {
    EXPECT_EQ(r.steps[i].id, kFalconSteps[i]);
    EXPECT_EQ(r.steps[i].outcome, Outcome::kPass)
        << r.steps[i].id << ": " << r.steps[i].finding << " | " << r.steps[i].next;
  }
  EXPECT_TRUE(r.passed());
  EXPECT_EQ(r.target, "serial FTEMU0001, emulated usb 001/005");
  // The force step measured libnifalcon's constant back (the emulator's 1e-4 N m per word).
  auto written = falcon::read_falcon_calibration(options.calibration_out);
  ASSERT_TRUE(written) << written.error();
  EXPECT_NEAR(written.value().words_per_n_m, 10000.0, 300.0);
  EXPECT_EQ(written.value().serial, kSerial);
  EXPECT_EQ(written.value().method, "weight");
  // The timing step counted one reply per command.
  const StepReport* timing = r.step("timing");
  ASSERT_TRUE(timing->histogram);
  EXPECT_EQ(timing->histogram->samples, static_cast<std::uint64_t>(options.timing_ticks - 1));
  // Forces are off at the end.
  EXPECT_EQ(emu->last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
  if (std::getenv("TOONFORCE_PRINT_REPORT") != nullptr) std::puts(to_markdown(r).c_str());
}

TEST_F(FalconBringup, AMotorWiredBackwardsIsCaughtByTheMotorStepWhichNamesItAndCutsTheForceAtOnce) {
  EmulatorOptions o = healthy();
  o.motor_reversed = {false, true, false};
  const Report r = run(o);
  EXPECT_EQ(outcome(r, "homing"), Outcome::kPass);
  EXPECT_EQ(outcome(r, "encoders"), Outcome::kPass) << finding(r, "encoders");
  EXPECT_EQ(outcome(r, "motors"), Outcome::kFail);
  EXPECT_THAT(finding(r, "motors"), HasSubstr("arm 2 (right) turned the wrong way"));
  EXPECT_THAT(finding(r, "motors"), HasSubstr("wired backwards"));
  EXPECT_THAT(finding(r, "motors"), HasSubstr("Check the motor connector of arm 2 (right)"));
  later_steps_not_run(r, "motors", "Motor direction");
  // Zero force at once: the pulse on arm 2 ended long before its 150 ticks, and every command
  // after it is zero.
  const auto& log = emu->command_log();
  std::size_t last_torque = 0;
  std::size_t arm2_pulse = 0;
  for (std::size_t k = 0; k < log.size(); ++k) {
    if (log[k].motor != std::array<std::int16_t, 3>{0, 0, 0}) last_torque = k;
    if (log[k].motor[1] < 0 && std::abs(log[k].motor[1]) > 10 * std::abs(log[k].motor[0])) ++arm2_pulse;
  }
  EXPECT_GT(arm2_pulse, 0u);
  EXPECT_LT(arm2_pulse, 50u) << "stopped within a few ticks of turning the wrong way, not at the pulse's end";
  for (std::size_t k = last_torque + 1; k < log.size(); ++k)
    ASSERT_EQ(log[k].motor, (std::array<std::int16_t, 3>{0, 0, 0}));
  EXPECT_EQ(log.back().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
}

TEST_F(FalconBringup, ADeadEncoderIsCaughtByTheEncodersStepWhichNamesTheArm) {
  EmulatorOptions o = healthy();
  o.encoder_dead = {false, false, true};
  const Report r = run(o);
  EXPECT_EQ(outcome(r, "homing"), Outcome::kPass);
  EXPECT_EQ(outcome(r, "encoders"), Outcome::kFail);
  EXPECT_THAT(finding(r, "encoders"), HasSubstr("the encoder of arm 3 (left) does not count"));
  EXPECT_THAT(finding(r, "encoders"), HasSubstr("check the encoder cable of arm 3 (left)"));
  later_steps_not_run(r, "encoders", "Encoders and workspace");
  EXPECT_EQ(outcome(r, "motors"), Outcome::kSkipped) << "no force on a Falcon whose position is wrong";
}

TEST_F(FalconBringup, HomingThatNeverCompletesIsCaughtByTheHomingStepNamingTheAxis) {
  EmulatorOptions o = healthy();
  o.axis_never_homes = {false, true, false};
  const Report r = run(o);
  EXPECT_EQ(outcome(r, "homing"), Outcome::kFail);
  EXPECT_THAT(finding(r, "homing"), HasSubstr("homing never completed"));
  EXPECT_THAT(finding(r, "homing"), HasSubstr("arm 1 (top), arm 3 (left) reported homed, arm 2 (right) never did"));
  EXPECT_THAT(finding(r, "homing"), HasSubstr("homing sensor"));
  later_steps_not_run(r, "homing", "Homing");
}

TEST_F(FalconBringup, AFalconThatHomesNoAxisSaysSo) {
  EmulatorOptions o = healthy();
  o.axis_never_homes = {true, true, true};
  const Report r = run(o);
  EXPECT_EQ(outcome(r, "homing"), Outcome::kFail);
  EXPECT_THAT(finding(r, "homing"), HasSubstr("no axis reported homed"));
  EXPECT_THAT(finding(r, "homing"), HasSubstr("pull the grip all the way out"));
}

TEST_F(FalconBringup, AForceConstantOffByAFactorIsMeasuredSaidAndWrittenForTheDriver) {
  EmulatorOptions o = healthy();
  o.n_m_per_word = 2.5e-4;  // the motors give 2.5 times the torque libnifalcon's constant assumes
  const Report r = run(o);
  EXPECT_EQ(outcome(r, "motors"), Outcome::kPass) << finding(r, "motors");
  EXPECT_EQ(outcome(r, "force"), Outcome::kWarn) << finding(r, "force");
  EXPECT_THAT(finding(r, "force"), HasSubstr("the Falcon gives 2.5"));
  EXPECT_THAT(finding(r, "force"), HasSubstr("times the force it is asked for"));
  EXPECT_THAT(finding(r, "force"), HasSubstr("toonforce run --device falcon` reads it from now on"));
  auto written = falcon::read_falcon_calibration(options.calibration_out);
  ASSERT_TRUE(written) << written.error();
  EXPECT_NEAR(written.value().words_per_n_m, 4000.0, 4000.0 * 0.03) << "1 / (2.5e-4 N m per word)";
  if (std::getenv("TOONFORCE_PRINT_REPORT") != nullptr) std::puts(finding(r, "force").c_str());
  // The steps after it go on: a calibration is a finding, not a fault.
  EXPECT_EQ(outcome(r, "timing"), Outcome::kPass);
  EXPECT_FALSE(r.step("force")->outcome == Outcome::kFail);
}

TEST_F(FalconBringup, WithoutFirmwareItStopsAndSaysHowToLoadIt) {
  const Report r = run(EmulatorOptions{});  // a Falcon just powered up: no firmware
  EXPECT_EQ(outcome(r, "found"), Outcome::kPass);
  EXPECT_EQ(outcome(r, "firmware"), Outcome::kFail);
  EXPECT_THAT(finding(r, "firmware"), HasSubstr("no firmware runs on the Falcon"));
  EXPECT_THAT(finding(r, "firmware"), HasSubstr("--firmware FILE"));
  later_steps_not_run(r, "firmware", "Firmware");
}

TEST_F(FalconBringup, AFalconThisUserMayNotOpenFailsTheFirstStepWithTheFix) {
  emu = std::make_unique<FalconEmulator>(healthy());
  EmulatedAccess access(*emu);
  access.can_open = false;
  EmulatedPerson person(*emu);
  const Report r = run_falcon_bringup(access, person, options);
  EXPECT_EQ(outcome(r, "found"), Outcome::kFail);
  EXPECT_THAT(finding(r, "found"), HasSubstr("cannot be opened by this user: no permission"));
  EXPECT_THAT(finding(r, "found"), HasSubstr("install the udev rule"));
  EXPECT_EQ(access.opens, 0);
  later_steps_not_run(r, "found", "Found and may be opened");
}

TEST_F(FalconBringup, UnattendedItRunsWhatNeedsNoPersonAndSaysWhatItSkipped) {
  emu = std::make_unique<FalconEmulator>(healthy());
  EmulatedAccess access(*emu);
  ScriptedOperator script;
  const Report r = run_falcon_bringup(access, script, options);
  for (const char* id : {"found", "firmware", "timing"}) EXPECT_EQ(outcome(r, id), Outcome::kPass) << id;
  for (const char* id : {"homing", "encoders", "motors", "force", "buttons", "leds"}) {
    EXPECT_EQ(outcome(r, id), Outcome::kSkipped) << id;
    EXPECT_THAT(r.step(id)->finding, HasSubstr("needs a person")) << id;
  }
  EXPECT_TRUE(r.passed());
}

TEST_F(FalconBringup, OnlyAndSkipChooseTheSteps) {
  options.only = {"found", "firmware", "homing", "leds"};
  options.skip = {"leds"};
  const Report r = run(healthy());
  EXPECT_EQ(outcome(r, "homing"), Outcome::kPass);
  EXPECT_EQ(outcome(r, "leds"), Outcome::kSkipped);
  EXPECT_EQ(r.step("leds")->finding, "not asked for");
  EXPECT_EQ(outcome(r, "motors"), Outcome::kSkipped);
}

TEST_F(FalconBringup, TheReportIsMarkdownAndJsonWithEveryStep) {
  EmulatorOptions o = healthy();
  o.motor_reversed = {true, false, false};
  const Report r = run(o);
  const std::string md = to_markdown(r);
  EXPECT_THAT(md, HasSubstr("# Bring-up of the Novint Falcon"));
  EXPECT_THAT(md, HasSubstr("| Motor direction | FAIL | arm 1 (top) turned the wrong way"));
  EXPECT_THAT(md, HasSubstr("What to do: do not run forces on this Falcon"));
  const std::string json = to_json(r);
  EXPECT_THAT(json, HasSubstr("\"passed\": false"));
  EXPECT_THAT(json, HasSubstr("\"id\": \"motors\", \"title\": \"Motor direction\", \"outcome\": \"fail\""));
  // Every step once, in order, in both.
  std::size_t at_md = 0;
  std::size_t at_json = 0;
  for (const char* id : kFalconSteps) {
    at_md = md.find(std::string("(") + id + ")", at_md);
    at_json = json.find(std::string("\"id\": \"") + id + "\"", at_json);
    EXPECT_NE(at_md, std::string::npos) << id;
    EXPECT_NE(at_json, std::string::npos) << id;
  }
  auto files = write_report(r, (dir_ / "report").string());
  ASSERT_TRUE(files) << files.error();
  EXPECT_TRUE(fs::exists(dir_ / "report.md"));
  EXPECT_TRUE(fs::exists(dir_ / "report.json"));
}

}  // namespace
}  // namespace toonforce::bringup
