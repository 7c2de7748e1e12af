// SPDX-License-Identifier: Apache-2.0
// Two Omnis in one process, as OpenHaptics' HDAPI runs them: each opened by its own name
// (hdInitDevice), both before the one scheduler starts; every device schedules its own frame,
// which makes its device current; the first start() starts the scheduler, the last stop()
// stops it. Against the fake libHD configured with two named devices (fake_hd_control.h).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "omni_test_support.hpp"

namespace toonforce::test {
namespace {

using ::testing::HasSubstr;

class OmniTwoDevicesTest : public OmniFixture {
 protected:
  void SetUp() override {
    OmniFixture::SetUp();
    ASSERT_EQ(fake.add_device("Left", "FAKE-L"), 0);
    ASSERT_EQ(fake.add_device("Right", "FAKE-R"), 1);
    options.enable_ramp_s = 0.0;  // full force from the first calibrated frame
  }
  void TearDown() override {
    if (right && right->running()) {
      right->request_stop();
      fake.step(1);
    }
    right.reset();
    OmniFixture::TearDown();
  }

  Result<std::unique_ptr<OmniDevice>> open_named(const char* name) {
    OmniOptions o = options;
    o.device_name = name;
    return open_omni(o);
  }

  /// Left (the fixture's own device) and Right (`right`), each opened by its name.
  OmniDevice& open_left_and_right() {
    options.device_name = "Left";
    OmniDevice& left = open();
    auto opened = open_named("Right");
    EXPECT_TRUE(opened.ok()) << opened.error();
    if (opened.ok()) right = std::move(opened).value();
    return left;
  }

  /// Starts both, each with its probe asking for its own force.
  void start_both(OmniDevice& left, const Vec3<double>& left_n, const Vec3<double>& right_n) {
    probe.device = &left;
    probe.force = left_n;
    right_probe.device = right.get();
    right_probe.force = right_n;
    ASSERT_TRUE(left.start(&Probe::tick, &probe).ok());
    ASSERT_TRUE(right->start(&Probe::tick, &right_probe).ok());
  }

  /// The selected device's counts.
  TfFakeHdStats stats_of(const char* name) {
    EXPECT_GE(fake.select_device(name), 0) << name;
    const TfFakeHdStats s = fake.stats();
    fake.select_device(nullptr);
    return s;
  }

  std::unique_ptr<OmniDevice> right;
  Probe right_probe;
};

TEST_F(OmniTwoDevicesTest, EachRunsByItsNameOnTheOneSchedulerWithItsOwnForce) {
  OmniDevice& left = open_left_and_right();
  ASSERT_NE(right, nullptr);
  EXPECT_THAT(left.info().name, HasSubstr("serial FAKE-L"));
  EXPECT_THAT(right->info().name, HasSubstr("serial FAKE-R"));
  EXPECT_EQ(stats_of("Left").init_calls, 1U);
  EXPECT_EQ(stats_of("Right").init_calls, 1U);

  ASSERT_NO_FATAL_FAILURE(start_both(left, {0.5, 0.0, 0.0}, {0.0, 0.0, -0.7}));
  EXPECT_EQ(fake.stats().async_callbacks, 2) << "each device schedules its own frame";
  ASSERT_EQ(fake.step(20), 20U);

  // One scheduler: every tick ran both frames, each on its own device.
  EXPECT_EQ(probe.records.size(), 20U);
  EXPECT_EQ(right_probe.records.size(), 20U);
  const TfFakeHdStats l = stats_of("Left");
  const TfFakeHdStats r = stats_of("Right");
  EXPECT_EQ(l.frames, 20U);
  EXPECT_EQ(r.frames, 20U);
  EXPECT_EQ(l.ticks, 20U);
  EXPECT_NE(l.handle, r.handle);
  const Vec3<double> lf = omni::Frame::device_force_n(probe.force);
  const Vec3<double> rf = omni::Frame::device_force_n(right_probe.force);
  EXPECT_DOUBLE_EQ(l.last_force_n[0], lf.x);
  EXPECT_DOUBLE_EQ(l.last_force_n[1], lf.y);
  EXPECT_DOUBLE_EQ(l.last_force_n[2], lf.z);
  EXPECT_DOUBLE_EQ(r.last_force_n[0], rf.x);
  EXPECT_DOUBLE_EQ(r.last_force_n[1], rf.y);
  EXPECT_DOUBLE_EQ(r.last_force_n[2], rf.z);
  EXPECT_EQ(left.status().force_n, probe.force);
  EXPECT_EQ(right->status().force_n, right_probe.force);

  // The first to stop leaves the scheduler to the other, which goes on.
  left.request_stop();
  fake.step(1);
  left.stop();
  EXPECT_EQ(fake.stats().scheduler_running, 1) << "the other device still runs";
  EXPECT_EQ(stats_of("Left").force_output_enabled, 0) << "its last frame turned its forces off";
  ASSERT_EQ(fake.step(5), 5U);
  EXPECT_EQ(stats_of("Left").frames, 21U);
  EXPECT_EQ(stats_of("Right").frames, 26U);
  EXPECT_TRUE(right->running());
  // The last stops it.
  right->request_stop();
  fake.step(1);
  right->stop();
  EXPECT_EQ(fake.stats().scheduler_running, 0);
}

TEST_F(OmniTwoDevicesTest, EachDeviceIsCalibratedOnItsOwn) {
  // Right waits for its stylus in the inkwell; Left is calibrated. hdCheckCalibration acts on
  // the current device, so each frame must make its own device current before checking.
  ASSERT_GE(fake.select_device("Right"), 0);
  fake.set_calibration(hd::kCalibrationNeedsManualInput, hd::kCalibrationInkwell);
  fake.select_device(nullptr);
  OmniDevice& left = open_left_and_right();
  ASSERT_NE(right, nullptr);
  ASSERT_NO_FATAL_FAILURE(start_both(left, {0.5, 0.0, 0.0}, {0.0, 0.4, 0.0}));
  ASSERT_EQ(fake.step(20), 20U);
  EXPECT_EQ(left.status().phase, OmniPhase::kRunning);
  EXPECT_EQ(left.status().force_n, probe.force);
  EXPECT_EQ(right->status().phase, OmniPhase::kCalibrating);
  EXPECT_EQ(right->status().force_n, Vec3<double>{});
  EXPECT_EQ(stats_of("Right").nonzero_uncalibrated_frames, 0U);
  EXPECT_EQ(stats_of("Right").enabled_uncalibrated_frames, 0U);
  EXPECT_EQ(right_probe.records.back().status, DeviceStatus::kNotReady);

  // Its stylus docked, its next periodic check (every 0.1 s) updates it, and its force comes.
  ASSERT_GE(fake.select_device("Right"), 0);
  fake.set_inkwell(1);
  fake.select_device(nullptr);
  ASSERT_EQ(fake.step(150), 150U);
  EXPECT_EQ(right->status().phase, OmniPhase::kRunning);
  EXPECT_EQ(right->status().force_n, right_probe.force);
  EXPECT_EQ(stats_of("Right").calibration, hd::kCalibrationOk);
}

TEST_F(OmniTwoDevicesTest, OneDevicesErrorEndsItsRunNotTheOthers) {
  // A communication error in Right's frame: Right's loop stops, Left's goes on.
  OmniDevice& left = open_left_and_right();
  ASSERT_NE(right, nullptr);
  ASSERT_NO_FATAL_FAILURE(start_both(left, {0.5, 0.0, 0.0}, {0.0, 0.4, 0.0}));
  ASSERT_EQ(fake.step(10), 10U);
  ASSERT_GE(fake.select_device("Right"), 0);
  fake.inject_error(hd::kCommError, -28, TF_FAKE_HD_AT_END, 1);
  fake.select_device(nullptr);
  ASSERT_EQ(fake.step(10), 10U);
  EXPECT_FALSE(right->running());
  EXPECT_THAT(right->last_error(), HasSubstr("HD_COMM_ERROR"));
  EXPECT_EQ(right->status().force_n, Vec3<double>{});
  EXPECT_TRUE(left.running());
  EXPECT_EQ(left.status().hd_errors, 0U);
  EXPECT_EQ(left.status().force_n, probe.force);
  EXPECT_EQ(stats_of("Left").frames, 20U);
  EXPECT_EQ(fake.stats().scheduler_running, 1);
}

TEST_F(OmniTwoDevicesTest, AnUnknownNameIsAClearError) {
  auto result = open_named("Middle");
  ASSERT_FALSE(result.ok());
  EXPECT_THAT(result.error(), HasSubstr("could not open the device \"Middle\""));
  EXPECT_THAT(result.error(), HasSubstr("HD_COMM_CONFIG_ERROR"));
  EXPECT_THAT(result.error(), HasSubstr("Touch_Setup"));
  // Nothing was left claimed: both configured devices still open.
  options.device_name = "Left";
  open();
  auto second = open_named("Right");
  EXPECT_TRUE(second.ok()) << second.error();
}

TEST_F(OmniTwoDevicesTest, TheSameNameTwiceIsRefused) {
  options.device_name = "Right";
  open();
  auto again = open_named("Right");
  ASSERT_FALSE(again.ok());
  EXPECT_THAT(again.error(), HasSubstr("the Omni/Touch \"Right\" is already open in this process"));
  EXPECT_EQ(stats_of("Right").init_calls, 1U) << "refused before the library was asked";
}

TEST_F(OmniTwoDevicesTest, EveryDeviceOpensBeforeTheSchedulerStarts) {
  options.device_name = "Left";
  start_probe();
  auto late = open_named("Right");
  ASSERT_FALSE(late.ok());
  EXPECT_THAT(late.error(), HasSubstr("open every Omni first, then start them"));
  EXPECT_EQ(stats_of("Right").init_calls, 0U);
}

TEST_F(OmniTwoDevicesTest, TheDevicesShareOneSchedulerRate) {
  options.device_name = "Left";
  open();
  OmniOptions o = options;
  o.device_name = "Right";
  o.scheduler_rate_hz = 500.0;
  auto other = open_omni(o);
  ASSERT_FALSE(other.ok());
  EXPECT_THAT(other.error(), HasSubstr("one scheduler, at one rate"));
}

}  // namespace
}  // namespace toonforce::test
