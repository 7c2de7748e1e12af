// SPDX-License-Identifier: Apache-2.0
// `toonforce bringup omni` against the fake libHD (our own simulated Omni behind the documented
// HD API), with an emulated person who steps the fake's scheduler while acting: a healthy
// device passes, and a device whose calibration needs the inkwell is caught by the calibration
// step with the instruction a user needs. Proves the bring-up against the documented API
// behaviour, not against the real driver.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "omni_test_support.hpp"
#include "toonforce/bringup/omni_bringup.hpp"

namespace toonforce::bringup {
namespace {

using ::testing::HasSubstr;

/// The person at the fake Omni. The fake's scheduler runs a tick only when stepped (manual
/// mode), so every poll steps it: the device runs while the bring-up waits.
class OmniPerson final : public Operator {
 public:
  explicit OmniPerson(test::FakeHd& fake) : fake_(fake) {}
  void say(std::string_view line) override { said += std::string(line) + "\n"; }
  void begin(const Request& r) override {
    requests.push_back(r.id);
    polls_ = 0;
  }
  Progress poll(const Request& r) override {
    const int n = polls_++;
    Progress answer = Progress::kWaiting;
    if (r.id == "omni.calibration") {
      if (docks_stylus && n == 5) fake_.set_inkwell(1);
      if (!docks_stylus && n > 300) answer = Progress::kDone;  // says it is done; it is not
    } else if (r.id == "omni.workspace") {
      // A slow sweep through the fake's usable workspace (device frame, mm), 0.4 mm per tick.
      static constexpr std::array<std::array<double, 3>, 9> kPath{{{0, 0, 0},
                                                                   {-75, -60, -35},
                                                                   {75, -60, -35},
                                                                   {75, 50, -35},
                                                                   {-75, 50, -35},
                                                                   {-75, 50, 25},
                                                                   {75, 50, 25},
                                                                   {75, -60, 25},
                                                                   {0, 0, 0}}};
      if (leg_ + 1 < kPath.size()) {
        const auto& a = kPath[leg_];
        const auto& b = kPath[leg_ + 1];
        const double length =
            std::sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
        const double t = std::min(1.0, 0.4 * (along_ += 1.0) / length);
        fake_.pin_hand(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2]));
        if (t >= 1.0) {
          ++leg_;
          along_ = 0.0;
        }
      } else {
        answer = Progress::kDone;
      }
    } else if (r.id == "omni.motors.hold") {
      fake_.spring_hand(0.0, -5.0, -5.0, 100.0, 3.0);  // fingertips at the workspace centre
      answer = Progress::kDone;
    } else if (r.id == "omni.button.1") {
      fake_.set_buttons(1);
    } else if (r.id == "omni.button.2") {
      fake_.set_buttons(2);
    } else if (r.id.rfind("omni.button.", 0) == 0) {
      fake_.set_buttons(0);  // ".release"
    }
    fake_.step(1);
    return answer;
  }
  std::optional<std::string> ask(const Request& r) override {
    requests.push_back(r.id);
    return std::nullopt;
  }
  bool interactive() const override { return true; }

  bool docks_stylus = true;
  std::string said;
  std::vector<std::string> requests;

 private:
  test::FakeHd& fake_;
  int polls_ = 0;
  std::size_t leg_ = 0;
  double along_ = 0.0;
};

class OmniBringup : public ::testing::Test {
 protected:
  void SetUp() override {
    RecordProperty("proves", test::kProves);
    fake.reset();
    fake.set_manual(1);
    options.omni.library_path = test::kFakeHd;
    options.poll_interval_s = 0.0;  // the person steps the scheduler
    options.timing_ticks = 500;
  }
  void TearDown() override {
    EXPECT_EQ(fake.stats().protocol_violations, 0U) << fake.stats().last_violation_call;
    fake.reset();
  }
  static std::string finding(const Report& r, std::string_view id) {
    const StepReport* s = r.step(id);
    return s != nullptr ? s->finding + " | " + s->next : std::string("no step ") + std::string(id);
  }

  test::FakeHd fake;
  OmniBringupOptions options;
};

TEST_F(OmniBringup, AHealthyTouchPassesEveryStep) {
  OmniPerson person(fake);
  const Report r = run_omni_bringup(person, options);
  ASSERT_EQ(r.steps.size(), std::size(kOmniSteps));
  for (std::size_t i = 0; i < r.steps.size(); ++i) {
    EXPECT_EQ(r.steps[i].id, kOmniSteps[i]);
    EXPECT_EQ(r.steps[i].outcome, Outcome::kPass)
        << r.steps[i].id << ": " << r.steps[i].finding << " | " << r.steps[i].next;
  }
  EXPECT_THAT(finding(r, "driver"), HasSubstr("capped at 0.88 N"));
  const StepReport* timing = r.step("timing");
  ASSERT_TRUE(timing->histogram);
  EXPECT_EQ(timing->histogram->samples, 499U);
  EXPECT_EQ(fake.stats().scheduler_running, 0) << "stopped at the end";
  EXPECT_EQ(fake.stats().force_output_enabled, 0);
}

TEST_F(OmniBringup, ADeviceThatNeedsTheInkwellIsCalibratedOnceThePersonDocksTheStylus) {
  fake.set_calibration(hd::kCalibrationNeedsManualInput, hd::kCalibrationInkwell);
  OmniPerson person(fake);
  options.only = {"found", "driver", "calibration"};
  const Report r = run_omni_bringup(person, options);
  EXPECT_EQ(r.step("calibration")->outcome, Outcome::kPass) << finding(r, "calibration");
  EXPECT_NE(std::find(person.requests.begin(), person.requests.end(), "omni.calibration"), person.requests.end());
  EXPECT_EQ(fake.stats().calibration_update_errors, 0U) << "no update while manual input was needed";
}

TEST_F(OmniBringup, ADeviceThatNeedsTheInkwellIsCaughtByTheCalibrationStepWithWhatToDo) {
  fake.set_calibration(hd::kCalibrationNeedsManualInput, hd::kCalibrationInkwell);
  OmniPerson person(fake);
  person.docks_stylus = false;
  const Report r = run_omni_bringup(person, options);
  EXPECT_EQ(r.step("calibration")->outcome, Outcome::kFail);
  EXPECT_THAT(finding(r, "calibration"), HasSubstr("still not calibrated"));
  EXPECT_THAT(finding(r, "calibration"), HasSubstr("put the stylus in the inkwell"));
  EXPECT_EQ(r.step("motors")->outcome, Outcome::kSkipped);
  EXPECT_THAT(r.step("motors")->finding, HasSubstr("not run: Calibration failed"));
  EXPECT_EQ(fake.stats().max_force_norm_n, 0.0) << "no force on an uncalibrated device";
}

TEST_F(OmniBringup, WithoutOpenHapticsTheFirstStepSaysWhatToInstall) {
  options.omni.library_path = "/nonexistent/libHD.so";
  OmniPerson person(fake);
  const Report r = run_omni_bringup(person, options);
  EXPECT_EQ(r.step("found")->outcome, Outcome::kFail);
  EXPECT_THAT(finding(r, "found"), HasSubstr("/nonexistent/libHD.so does not exist"));
  EXPECT_EQ(r.step("calibration")->outcome, Outcome::kSkipped);
}

TEST(OmniBringupCommand, RunsUnattendedAgainstTheFakeLibHdThroughTheCommandLine) {
  // The child process loads the fake, whose scheduler then runs in real time (no test steps it).
  const std::string base = ::testing::TempDir() + "omni_bringup_report";
  const std::string cmd = std::string(TOONFORCE_BINARY) + " bringup omni --non-interactive --omni-library " +
                          test::kFakeHd + " --only found,driver,calibration,timing --timing-ticks 200 --report " +
                          base + " 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string output;
  char buf[4096];
  for (std::size_t n = 0; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) output.append(buf, n);
  const int status = ::pclose(p);
  ASSERT_TRUE(WIFEXITED(status)) << output;
  EXPECT_EQ(WEXITSTATUS(status), 0) << output;
  EXPECT_THAT(output, HasSubstr("[pass] Driver and limits: Touch (toonforce fake libHD)"));
  EXPECT_THAT(output, HasSubstr("[pass] Calibration"));
  // The scheduler runs in real time here: whether more than 1 % of its periods overran (a warning)
  // depends on this machine's load, which a test must not judge (timings belong in tools/). That
  // every tick ran, and that the step did not fail, does not.
  const bool timing_passed = output.find("[pass] Scheduler rate: 200 ticks;") != std::string::npos;
  const bool timing_warned = output.find("[warn] Scheduler rate: ") != std::string::npos &&
                             output.find(" of 200 ticks overran their period") != std::string::npos;
  EXPECT_TRUE(timing_passed || timing_warned) << output;
  std::FILE* json = std::fopen((base + ".json").c_str(), "r");
  ASSERT_NE(json, nullptr);
  std::string text;
  for (std::size_t n = 0; (n = std::fread(buf, 1, sizeof buf, json)) > 0;) text.append(buf, n);
  std::fclose(json);
  EXPECT_THAT(text, HasSubstr("\"passed\": true"));
}

}  // namespace
}  // namespace toonforce::bringup
