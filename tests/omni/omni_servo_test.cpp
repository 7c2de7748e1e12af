// SPDX-License-Identifier: Apache-2.0
// The device-clocked path end to end, as `toonforce run --device omni` drives it: the vendor
// scheduler (the fake libHD's) calls our frame, which calls a plain tick function that runs
// the servo loop (every stage) on the RuntimeScene of scenes/wall.toml. The fake is our own
// simulated Omni: these tests prove the binding and the device-clocked loop against the
// documented HD API behaviour, not against the real driver.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include "omni_test_support.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/hal/omni/hd_errors.hpp"

namespace toonforce {
namespace {

using ::testing::HasSubstr;
using Scene = RuntimeScene<double>;

constexpr double kWallStiffness = 1500.0;  // scenes/wall.toml
constexpr double kEncoderTolM = 1e-4;

/// The servo loop in the device's thread, one tick per frame, recording what each tick read
/// and wrote; a fatal read status ends the run.
struct WallLoop {
  struct Row {
    ClockedTick clock;
    DeviceStatus status = DeviceStatus::kOk;
    Vec3<double> position_m;
    Vec3<double> force_n;
    std::size_t allocations = 0;
  };

  OmniDevice* device = nullptr;
  std::optional<ServoLoop<DriverRef, Scene>> servo;
  std::vector<Row> rows;

  WallLoop() { rows.reserve(20000); }

  static TickVerdict tick(void* context, const ClockedTick& clock) noexcept {
    auto& self = *static_cast<WallLoop*>(context);
    Row row;
    row.clock = clock;
    row.allocations = test::allocation_count();
    const TickStatus status = self.servo->tick(clock.tick);
    row.status = status.read;
    row.force_n = to_double(self.servo->force());
    TelemetryFrame frame;
    self.servo->fill_frame(frame);
    row.position_m = frame.position_m;
    if (self.rows.size() < self.rows.capacity()) self.rows.push_back(row);
    const bool fatal = row.status != DeviceStatus::kOk && row.status != DeviceStatus::kNotReady;
    return fatal ? TickVerdict::kStop : TickVerdict::kContinue;
  }
};

class OmniWallTest : public test::OmniFixture {
 protected:
  /// Opens the device, builds the wall scene and its loop with the configuration `run` would
  /// use (the scene's, the device's limits filling the gaps: the clamp is the smaller of the
  /// scene's and the device's, effects.md §6). Two departures, for what these device tests
  /// look at: the handle is pinned where a test puts it, in the wall too, so the loop engages
  /// wherever it is (engage_force above any force here); and the thermal model stays out (its
  /// derating, over seconds at the wall's 3 N, would move the force the tests read).
  OmniDevice& start_wall() {
    OmniDevice& d = open();
    auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/wall.toml");
    EXPECT_TRUE(scene.ok()) << scene.error();
    ServoConfig config = with_device(servo_config(scene.value(), 1.0 / d.info().nominal_rate_hz), d.info());
    config.safety.engage_force_n = 1e3;
    config.safety.thermal.continuous_force_n = config.limits.max_force_n;
    EXPECT_EQ(check_servo_config(config), "");
    loop.device = &d;
    loop.servo.emplace(DriverRef(d), make_runtime_scene<double>(scene.value()), config);
    auto started = d.start(&WallLoop::tick, &loop);
    EXPECT_TRUE(started.ok()) << started.error();
    EXPECT_DOUBLE_EQ(started.value().period_s, config.period_s);
    return d;
  }

  /// The device-frame y component of the last force the fake was given (scene +z).
  double commanded_up_n() const { return fake.stats().last_force_n[1]; }

  WallLoop loop;
};

TEST_F(OmniWallTest, TheWallHoldsTheHandWhereHandAndWallForcesBalance) {
  // The hand: a spring of 200 N/m toward 10 mm below the surface, well damped (10 N s/m,
  // above the K T / 2 = 0.75 N s/m a 1500 N/m wall needs at 1 kHz).
  pin_scene({0.0, 0.0, 0.002});
  start_wall();
  double target[3];
  scene_to_device_mm({0.0, 0.0, -0.010}, target);
  fake.spring_hand(target[0], target[1], target[2], 200.0, 10.0);
  fake.step(3000);
  ASSERT_EQ(loop.rows.size(), 3000U);

  // Equilibrium: 1500 delta = 200 (0.010 - delta) -> delta = 2 / 1700 m, force 1.76 N.
  const double delta = 2.0 / 1700.0;
  const WallLoop::Row& last = loop.rows.back();
  EXPECT_EQ(last.status, DeviceStatus::kOk);
  EXPECT_NEAR(last.position_m.z, -delta, kEncoderTolM);
  EXPECT_NEAR(last.force_n.z, kWallStiffness * delta, kWallStiffness * kEncoderTolM);
  EXPECT_NEAR(commanded_up_n(), last.force_n.z, 1e-9);  // the wall pushes the handle up
  EXPECT_NEAR(fake.stats().position_mm[1], target[1] + 10.0 - delta * 1000.0, 0.1);

  for (const WallLoop::Row& row : loop.rows) {
    // A floor's force is along its normal only, and never pulls into the floor.
    EXPECT_EQ(row.force_n.x, 0.0);
    EXPECT_EQ(row.force_n.y, 0.0);
    EXPECT_GE(row.force_n.z, 0.0);
    EXPECT_LE(row.force_n.z, 3.3 + 1e-12);  // the clamp, to a rounding
  }
}

TEST_F(OmniWallTest, OutOfContactThereIsNoForce) {
  pin_scene({0.0, 0.0, 0.004});
  start_wall();
  fake.step(1000);
  for (const WallLoop::Row& row : loop.rows) EXPECT_EQ(row.force_n.z, 0.0);
  EXPECT_EQ(fake.stats().max_force_norm_n, 0.0);
}

TEST_F(OmniWallTest, InContactTheForcePushesOutOfTheWallAndNeverExceedsTheNominalMaximum) {
  // 5 mm deep: the wall asks 7.5 N; the scene allows 8 N, the device HD_NOMINAL_MAX_FORCE.
  pin_scene({0.0, 0.0, -0.005});
  start_wall();
  fake.step(3000);
  const TfFakeHdStats s = fake.stats();
  EXPECT_LE(s.max_force_norm_n, 3.3);
  EXPECT_NEAR(s.last_force_n[1], 3.3, 1e-9);  // out of the floor: device +y
  EXPECT_EQ(s.last_force_n[0], 0.0);
  EXPECT_EQ(s.last_force_n[2], 0.0);
  EXPECT_EQ(s.errors_raised, 0U);
}

TEST_F(OmniWallTest, TheLimitIsTheOneTheDeviceReportsNotAFixedNumber) {
  fake.set_limits(2.0, 0.6, 1.0, 0.003);  // the option's 3.3 N is above this device's peak
  pin_scene({0.0, 0.0, -0.005});
  start_wall();
  fake.step(2000);
  EXPECT_LE(fake.stats().max_force_norm_n, 2.0);
  EXPECT_NEAR(commanded_up_n(), 2.0, 1e-9);
}

TEST_F(OmniWallTest, StartedOutOfTheInkwellTheLoopWaitsAndSaysWhatToDoThenTheWallRampsIn) {
  // The stylus is out of the inkwell at start: the fake, as the real library, refuses an update
  // while manual input is needed. The loop must neither ask for one nor stop: it waits, forces
  // off, and tells the person what to do (OpenHaptics' calibration example, the ROS node).
  fake.set_calibration(hd::kCalibrationNeedsManualInput, hd::kCalibrationInkwell);
  pin_scene({0.0, 0.0, -0.002});  // 2 mm into the wall: 3 N once forces are on
  OmniDevice& d = start_wall();
  fake.step(1000);
  TfFakeHdStats s = fake.stats();
  EXPECT_TRUE(d.running()) << d.last_error();
  EXPECT_EQ(s.calibration_updates, 0U) << "no update while manual input is needed";
  EXPECT_EQ(s.calibration_update_errors, 0U);
  EXPECT_EQ(s.nonzero_uncalibrated_frames, 0U);
  EXPECT_EQ(s.enabled_uncalibrated_frames, 0U);  // output disabled, not just zero commanded
  EXPECT_EQ(s.max_force_norm_n, 0.0);
  ASSERT_EQ(loop.rows.size(), 1000U);
  for (const WallLoop::Row& row : loop.rows) EXPECT_EQ(row.status, DeviceStatus::kNotReady);
  EXPECT_EQ(d.status().phase, OmniPhase::kCalibrating);
  EXPECT_THAT(d.last_error(), HasSubstr("put the stylus in the inkwell"));

  fake.set_inkwell(1);  // the person docks the stylus: the device now needs an update
  fake.step(100);       // one check period: the loop updates, outside the frame
  s = fake.stats();
  EXPECT_EQ(s.calibration, hd::kCalibrationOk);
  EXPECT_EQ(s.calibration_updates, 1U);
  EXPECT_EQ(s.calibration_updates_in_frame, 0U) << "hdUpdateCalibration belongs before hdBeginFrame";
  EXPECT_EQ(s.force_output_enabled, 1);
  fake.set_inkwell(0);  // and takes it out again to use it
  fake.step(1000);      // enable ramp (0.5 s), then the wall at full strength
  EXPECT_NEAR(commanded_up_n(), kWallStiffness * 0.002, kWallStiffness * kEncoderTolM);
  EXPECT_EQ(d.status().phase, OmniPhase::kRunning);
  EXPECT_EQ(fake.stats().nonzero_uncalibrated_frames, 0U);
  EXPECT_TRUE(d.running());
}

TEST_F(OmniWallTest, AnAutoCalibratingDeviceIsUpdatedByTheLoopOutsideTheFrame) {
  fake.set_calibration(hd::kCalibrationNeedsUpdate, hd::kCalibrationAuto);
  pin_scene({0.0, 0.0, -0.002});
  OmniDevice& d = start_wall();
  fake.step(1);
  EXPECT_EQ(fake.stats().calibration_updates, 1U);
  EXPECT_EQ(fake.stats().calibration_updates_in_frame, 0U);
  EXPECT_EQ(fake.stats().calibration, hd::kCalibrationOk);
  fake.step(1000);
  EXPECT_EQ(d.status().phase, OmniPhase::kRunning);
  EXPECT_NEAR(commanded_up_n(), 3.0, kWallStiffness * kEncoderTolM);
}

TEST_F(OmniWallTest, AnAutoCalibratingDeviceWaitsForTheArmToSweepItsWorkspace) {
  fake.set_calibration(hd::kCalibrationNeedsManualInput, hd::kCalibrationAuto);
  pin_scene({0.0, 0.0, 0.01});  // above the wall: no force either way
  OmniDevice& d = start_wall();
  fake.step(500);
  EXPECT_TRUE(d.running());
  EXPECT_EQ(d.status().phase, OmniPhase::kCalibrating);
  EXPECT_THAT(d.last_error(), HasSubstr("move the arm slowly through its whole workspace"));
  EXPECT_EQ(fake.stats().calibration_updates, 0U);
  // The person sweeps the arm: left, right, up, down, in, out (device frame, mm).
  for (const auto& p : {std::array<double, 3>{-70, 20, 0},
                        {70, 20, 0},
                        {0, 60, -40},
                        {0, -60, 40},
                        {0, 20, -60},
                        {0, 20, 60},
                        {0, 5, 5}}) {
    fake.pin_hand(p[0], p[1], p[2]);
    fake.step(20);
  }
  fake.step(200);
  EXPECT_EQ(fake.stats().calibration, hd::kCalibrationOk);
  EXPECT_EQ(fake.stats().calibration_updates, 1U);
  EXPECT_EQ(fake.stats().calibration_update_errors, 0U);
  EXPECT_NE(d.status().phase, OmniPhase::kCalibrating);
  EXPECT_TRUE(d.running());
}

TEST_F(OmniWallTest, AnErrorFromTheCalibrationUpdateMeansStillCalibratingNotTheEnd) {
  // Whatever the library answers an update with, here a device fault, the run goes on with
  // forces off and the next check tries again (sawSensablePhantom: "calibration failed").
  fake.set_calibration(hd::kCalibrationNeedsUpdate, hd::kCalibrationInkwell);
  fake.inject_error(hd::kDeviceFault, -7, TF_FAKE_HD_AT_CALIBRATION_UPDATE, 1);
  pin_scene({0.0, 0.0, -0.002});
  OmniDevice& d = start_wall();
  fake.step(50);
  EXPECT_TRUE(d.running()) << d.last_error();
  EXPECT_EQ(fake.stats().calibration_updates, 1U);
  EXPECT_EQ(d.status().phase, OmniPhase::kCalibrating);
  EXPECT_EQ(d.status().calibration_errors, 1U);
  EXPECT_THAT(d.last_error(), HasSubstr("answered HD_DEVICE_FAULT: still calibrating"));
  EXPECT_EQ(fake.stats().max_force_norm_n, 0.0);
  fake.step(100);  // the next check updates without an error
  EXPECT_EQ(fake.stats().calibration_updates, 2U);
  EXPECT_EQ(fake.stats().calibration, hd::kCalibrationOk);
  fake.step(1000);
  EXPECT_TRUE(d.running());
  EXPECT_NEAR(commanded_up_n(), 3.0, kWallStiffness * kEncoderTolM);
}

TEST_F(OmniWallTest, LosingCalibrationTurnsForcesOffUntilItIsBack) {
  fake.set_calibration(hd::kCalibrationOk, hd::kCalibrationAuto);
  pin_scene({0.0, 0.0, -0.002});
  OmniDevice& d = start_wall();
  fake.step(1000);
  ASSERT_GT(commanded_up_n(), 2.5);
  fake.set_calibration(hd::kCalibrationNeedsManualInput, hd::kCalibrationAuto);
  fake.step(101);  // one calibration check period
  EXPECT_EQ(commanded_up_n(), 0.0);
  EXPECT_EQ(fake.stats().force_output_enabled, 0);
  EXPECT_EQ(loop.rows.back().status, DeviceStatus::kNotReady);
  EXPECT_EQ(d.status().phase, OmniPhase::kCalibrating);
  const auto lost_frames = fake.stats().nonzero_uncalibrated_frames;
  EXPECT_LE(lost_frames, 100U);  // at most until the check noticed
  fake.step(500);
  EXPECT_EQ(fake.stats().nonzero_uncalibrated_frames, lost_frames);
  // The device has learnt again (an auto-calibrating device, as the arm moved): it needs an
  // update, which the loop makes.
  fake.set_calibration(hd::kCalibrationNeedsUpdate, hd::kCalibrationAuto);
  fake.step(1000);
  EXPECT_EQ(fake.stats().calibration, hd::kCalibrationOk);
  EXPECT_EQ(fake.stats().calibration_updates, 1U);
  EXPECT_NEAR(commanded_up_n(), 3.0, kWallStiffness * kEncoderTolM);
}

TEST_F(OmniWallTest, AnOverrunGivesTheLoopTheTrueDtAndItGoesOn) {
  pin_scene({0.0, 0.0, -0.002});
  OmniDevice& d = start_wall();
  fake.step(1500);
  fake.inject_overrun(4);
  fake.step(1500);
  EXPECT_TRUE(d.running());
  EXPECT_EQ(d.status().overruns, 1U);
  const auto skipped = std::adjacent_find(loop.rows.begin(), loop.rows.end(), [](const auto& a, const auto& b) {
    return b.clock.tick - a.clock.tick != 1;
  });
  ASSERT_NE(skipped, loop.rows.end());
  EXPECT_EQ((skipped + 1)->clock.tick - skipped->clock.tick, 4);
  EXPECT_NEAR((skipped + 1)->clock.dt_s, 4e-3, 1e-12);
  EXPECT_EQ(loop.rows.back().clock.tick, 2999 + 3);
  EXPECT_NEAR(commanded_up_n(), 3.0, kWallStiffness * kEncoderTolM);
}

TEST_F(OmniWallTest, TheLoopTickAllocatesNothing) {
  double target[3];
  scene_to_device_mm({0.0, 0.0, -0.010}, target);
  pin_scene({0.0, 0.0, 0.002});
  start_wall();
  fake.spring_hand(target[0], target[1], target[2], 200.0, 10.0);
  fake.step(3000);
  for (std::size_t i = 2; i < loop.rows.size(); ++i) {
    ASSERT_EQ(loop.rows[i].allocations, loop.rows[i - 1].allocations) << "tick " << i;
  }
}

// Every HD error while the wall holds 3 N: force errors let the wall come back; every other
// error ends the run with zero force and a message naming it.
class OmniWallErrors : public OmniWallTest, public ::testing::WithParamInterface<hd::HDerror> {};

TEST_P(OmniWallErrors, AreHandledAsTheirClassRequires) {
  const hd::HDerror code = GetParam();
  pin_scene({0.0, 0.0, -0.002});
  OmniDevice& d = start_wall();
  fake.step(1000);
  ASSERT_NEAR(commanded_up_n(), 3.0, kWallStiffness * kEncoderTolM);
  fake.inject_error(code, -28, TF_FAKE_HD_AT_END, 1);
  fake.step(2000);
  const std::string name(hd::error_name(code));
  const TfFakeHdStats s = fake.stats();
  if (hd::classify(code) == hd::ErrorClass::kForce) {
    EXPECT_TRUE(d.running());
    const auto held = std::count_if(loop.rows.begin(), loop.rows.end(),
                                    [](const auto& r) { return r.status == DeviceStatus::kNotReady; });
    EXPECT_GE(held, 100);  // at least the 0.1 s hold (warm motors: 2 s)
    if (code == hd::kWarmMotors) {
      EXPECT_EQ(commanded_up_n(), 0.0);  // held for at least 2 s
      fake.step(3000);
    }
    EXPECT_NEAR(commanded_up_n(), 3.0, kWallStiffness * kEncoderTolM);
    EXPECT_EQ(d.status().force_errors, 1U);
    EXPECT_EQ(d.status().last_hd_error, code);
  } else {
    EXPECT_FALSE(d.running());
    EXPECT_EQ(s.last_force_n[1], 0.0);
    EXPECT_EQ(s.force_output_enabled, 0);
    EXPECT_EQ(s.async_callbacks, 0);
    EXPECT_EQ(loop.rows.back().status, hd::device_status(hd::classify(code)));
    EXPECT_EQ(loop.rows.size(), 1002U);  // the error frame, then the closing frame
    EXPECT_THAT(d.last_error(), HasSubstr(name));
  }
  EXPECT_LE(s.max_force_norm_n, 3.3);
}

INSTANTIATE_TEST_SUITE_P(
    EveryCode, OmniWallErrors,
    ::testing::Values(hd::kInvalidEnum, hd::kInvalidValue, hd::kInvalidOperation, hd::kInvalidInputType, hd::kBadHandle,
                      hd::kWarmMotors, hd::kExceededMaxForce, hd::kExceededMaxForceImpulse, hd::kExceededMaxVelocity,
                      hd::kForceError, hd::kDeviceFault, hd::kDeviceAlreadyInitiated, hd::kCommError,
                      hd::kCommConfigError, hd::kTimerError, hd::kIllegalBegin, hd::kIllegalEnd, hd::kFrameError,
                      hd::kInvalidPriority, hd::kSchedulerFull, hd::kInvalidLicense),
    [](const ::testing::TestParamInfo<hd::HDerror>& param) { return std::string(hd::error_name(param.param)); });

}  // namespace
}  // namespace toonforce
