// SPDX-License-Identifier: Apache-2.0
// OmniDevice against the fake libHD: opening, limits, frames, the device-clocked tick, the
// lock-free status, overruns and every HD error class. The fake is our own code; these tests
// prove the binding against the documented HD API behaviour, not against the real driver.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "omni_test_support.hpp"
#include "toonforce/hal/omni/hd_errors.hpp"

namespace toonforce {
namespace {

using test::OmniFixture;
using ::testing::HasSubstr;

constexpr double kEncoderTolM = 1e-4;  // 15 000 counts/rev on 133 mm links: ~0.06 mm

class OmniDeviceTest : public OmniFixture {};

TEST_F(OmniDeviceTest, OpensWithTheLimitsTheDeviceReports) {
  options.max_force_n = 0.0;  // the default cap
  fake.set_limits(2.5, 0.7, 1.1, 0.003);
  OmniDevice& d = open();
  const OmniLimits& l = d.limits();
  EXPECT_DOUBLE_EQ(l.max_force_n, 2.5);
  EXPECT_DOUBLE_EQ(l.max_continuous_force_n, 0.7);
  EXPECT_DOUBLE_EQ(l.max_stiffness_n_per_m, 1100.0);  // N/mm -> N/m
  EXPECT_DOUBLE_EQ(l.max_damping_n_s_per_m, 3.0);
  EXPECT_DOUBLE_EQ(l.force_cap_n, 0.7) << "the continuous force by default";
  EXPECT_TRUE(l.has_motor_temperature);
  EXPECT_EQ(l.input_dof, 6);
  EXPECT_EQ(l.output_dof, 3);
  EXPECT_EQ(l.calibration_style, hd::kCalibrationInkwell);
  EXPECT_DOUBLE_EQ(l.software_velocity_limit_m_per_s, 1.0);          // 1000 mm/s
  EXPECT_DOUBLE_EQ(l.software_force_impulse_limit_n_per_s, 3000.0);  // 3 N/ms
  // The fake's usable workspace x -80..80, y -65..55, z -40..30 mm, centred on (0, -5, -5):
  // scene x = x, scene y = -(z + 5), scene z = y + 5.
  EXPECT_NEAR(l.usable_workspace_min_m.x, -0.080, 1e-12);
  EXPECT_NEAR(l.usable_workspace_min_m.y, -0.035, 1e-12);
  EXPECT_NEAR(l.usable_workspace_min_m.z, -0.060, 1e-12);
  EXPECT_NEAR(l.usable_workspace_max_m.x, 0.080, 1e-12);
  EXPECT_NEAR(l.usable_workspace_max_m.y, 0.035, 1e-12);
  EXPECT_NEAR(l.usable_workspace_max_m.z, 0.060, 1e-12);
  const DeviceInfo& info = d.info();
  EXPECT_EQ(info.clocking, Clocking::kDeviceThread);
  EXPECT_DOUBLE_EQ(info.max_force_n, 0.7);
  EXPECT_DOUBLE_EQ(info.max_continuous_force_n, 0.7);
  EXPECT_DOUBLE_EQ(info.nominal_rate_hz, 1000.0);
  EXPECT_THAT(info.name, HasSubstr("serial FAKE-0001"));
  EXPECT_THAT(info.name, HasSubstr("OpenHaptics 3.4.0"));
}

TEST_F(OmniDeviceTest, TheCapIsTheContinuousForceUnlessRaisedAndNeverAboveThePeak) {
  options.max_force_n = 0.0;  // the default cap
  fake.set_limits(3.3, 0.88, 1.26, 0.004);
  EXPECT_DOUBLE_EQ(open().limits().force_cap_n, 0.88);
  EXPECT_THAT(omni->limits().force_cap_source, HasSubstr("HD_NOMINAL_MAX_CONTINUOUS_FORCE"));
  omni.reset();
  options.max_force_n = 2.0;  // raised for short bursts
  EXPECT_DOUBLE_EQ(open().limits().force_cap_n, 2.0);
  EXPECT_DOUBLE_EQ(omni->info().max_force_n, 2.0);
  omni.reset();
  options.max_force_n = 5.0;  // more than the device's peak: the peak
  EXPECT_DOUBLE_EQ(open().limits().force_cap_n, 3.3);
  EXPECT_THAT(omni->limits().force_cap_source, HasSubstr("peak"));
  omni.reset();
  options.max_force_n = 0.0;
  fake.set_limits(3.3, 0.0, 1.26, 0.004);  // no continuous force reported: the peak
  EXPECT_DOUBLE_EQ(open().limits().force_cap_n, 3.3);
  EXPECT_THAT(omni->limits().force_cap_source, HasSubstr("reports no continuous force"));
}

TEST_F(OmniDeviceTest, ByDefaultTheCommandedForceStopsAtTheContinuousForce) {
  options.max_force_n = 0.0;  // the default cap
  fake.set_limits(3.3, 0.88, 1.26, 0.004);
  OmniDevice& d = start_probe();
  probe.force = {0.0, 0.0, 3.0};  // scene +z: device +y
  fake.step(2000);                // past the enable ramp
  EXPECT_EQ(d.status().phase, OmniPhase::kRunning);
  EXPECT_NEAR(fake.stats().max_force_norm_n, 0.88, 1e-9);
  EXPECT_NEAR(fake.stats().last_force_n[1], 0.88, 1e-9);
}

TEST_F(OmniDeviceTest, WithoutANominalMaximumForceItRefusesToOpen) {
  fake.set_limits(0.0, 0.7, 1.1, 0.003);
  auto result = open_omni(options);
  ASSERT_FALSE(result.ok());
  EXPECT_THAT(result.error(), HasSubstr("HD_NOMINAL_MAX_FORCE"));
  EXPECT_EQ(fake.stats().device_initialized, 0);
}

TEST_F(OmniDeviceTest, InitFailureNamesTheHdErrorAndTheUsualFixes) {
  fake.inject_error(hd::kDeviceFault, -7, TF_FAKE_HD_AT_INIT, 1);
  auto result = open_omni(options);
  ASSERT_FALSE(result.ok());
  EXPECT_THAT(result.error(), HasSubstr("HD_DEVICE_FAULT (0x300, internal -7"));
  EXPECT_THAT(result.error(), HasSubstr("Touch_Setup"));
  EXPECT_THAT(result.error(), HasSubstr("LC_NUMERIC=en_US.UTF-8"));
}

TEST_F(OmniDeviceTest, OnlyOneDeviceIsOpenAtATime) {
  open();
  auto second = open_omni(options);
  ASSERT_FALSE(second.ok());
  EXPECT_THAT(second.error(), HasSubstr("already open"));
  omni.reset();
  auto third = open_omni(options);
  EXPECT_TRUE(third.ok()) << third.error();
}

// ---- hdDisableDevice on close (sawSensablePhantom: it crashes FireWire Omnis) ----

TEST(OmniFireWire, TheStackIsRecognisedByItsVersionElseByTheModel) {
  EXPECT_TRUE(is_firewire_stack("3.00.66", "PHANTOM Omni"));  // AE 3.0's header version
  EXPECT_TRUE(is_firewire_stack("3.0.0", "Touch"));
  EXPECT_FALSE(is_firewire_stack("3.4.0", "Touch"));
  EXPECT_FALSE(is_firewire_stack("3.30", "Touch"));
  EXPECT_FALSE(is_firewire_stack("3.4.0", "PHANTOM Omni"));  // 3.4 has no FireWire driver
  EXPECT_TRUE(is_firewire_stack("", "Sensable PHANTOM Omni"));
  EXPECT_FALSE(is_firewire_stack("", "Geomagic Touch"));
}

TEST_F(OmniDeviceTest, ClosingATouchDisablesTheDevice) {
  OmniDevice& d = open();
  EXPECT_TRUE(d.disables_device_on_close());
  omni.reset();
  EXPECT_EQ(fake.stats().disable_device_calls, 1U);
  EXPECT_EQ(fake.stats().device_initialized, 0);
}

TEST_F(OmniDeviceTest, ClosingAFireWireOmniLeavesHdDisableDeviceAlone) {
  fake.set_version("3.00.66");
  fake.set_model("PHANTOM Omni");
  OmniDevice& d = start_probe();
  fake.step(10);
  EXPECT_FALSE(d.disables_device_on_close());
  d.request_stop();
  fake.step(1);
  omni.reset();
  const TfFakeHdStats s = fake.stats();
  EXPECT_EQ(s.disable_device_calls, 0U);
  EXPECT_EQ(s.scheduler_running, 0) << "the scheduler is stopped all the same";
  EXPECT_EQ(s.force_output_enabled, 0) << "and forces are off";
}

TEST_F(OmniDeviceTest, AFailedOpenOfAFireWireOmniLeavesHdDisableDeviceAlone) {
  fake.set_version("3.00.66");
  fake.set_model("PHANTOM Omni");
  fake.set_limits(0.0, 0.7, 1.1, 0.003);  // refused after hdInitDevice
  ASSERT_FALSE(open_omni(options).ok());
  EXPECT_EQ(fake.stats().disable_device_calls, 0U);
}

TEST_F(OmniDeviceTest, DisableOnCloseIsAnOptionEitherWay) {
  fake.set_version("3.00.66");
  fake.set_model("PHANTOM Omni");
  options.disable_device_on_close = true;
  EXPECT_TRUE(open().disables_device_on_close());
  omni.reset();
  EXPECT_EQ(fake.stats().disable_device_calls, 1U);

  fake.set_version("3.4.0");
  fake.set_model("Touch");
  options.disable_device_on_close = false;
  EXPECT_FALSE(open().disables_device_on_close());
  omni.reset();
  EXPECT_EQ(fake.stats().disable_device_calls, 1U) << "no second call";
}

TEST_F(OmniDeviceTest, BadOptionsAreRefusedBeforeAnythingIsLoaded) {
  options.scheduler_rate_hz = 0.0;
  EXPECT_THAT(open_omni(options).error(), HasSubstr("scheduler rate"));
  options = {};
  options.library_path = test::kFakeHd;
  options.max_force_n = -1.0;
  EXPECT_THAT(open_omni(options).error(), HasSubstr("max force"));
  options.max_force_n = 0.0;
  options.max_consecutive_overruns = 0;
  EXPECT_THAT(open_omni(options).error(), HasSubstr("max_consecutive_overruns"));
  EXPECT_EQ(fake.stats().init_calls, 0U);
}

TEST_F(OmniDeviceTest, ARateTheSchedulerRefusesIsReported) {
  options.scheduler_rate_hz = 1234.0;
  auto result = open_omni(options);
  ASSERT_FALSE(result.ok());
  EXPECT_THAT(result.error(), HasSubstr("refused 1234 Hz"));
  EXPECT_THAT(result.error(), HasSubstr("HD_INVALID_VALUE"));
  EXPECT_EQ(fake.stats().device_initialized, 0);
}

TEST_F(OmniDeviceTest, PositionsAreReadInTheSceneFrameInMetres) {
  fake.pin_hand(10.0, 20.0, 30.0);  // device frame [mm]
  start_probe();
  ASSERT_EQ(fake.step(3), 3U);
  ASSERT_EQ(probe.records.size(), 3U);
  const DeviceReading& r = probe.records.back().reading;
  // scene = (x, -(z - cz), y - cy) / 1000 with centre (0, -5, -5) mm.
  EXPECT_NEAR(r.position_m.x, 0.010, kEncoderTolM);
  EXPECT_NEAR(r.position_m.y, -0.035, kEncoderTolM);
  EXPECT_NEAR(r.position_m.z, 0.025, kEncoderTolM);
  EXPECT_EQ(probe.records.back().status, DeviceStatus::kOk);
  // The status published to other threads agrees.
  const OmniStatus s = omni->status();
  EXPECT_NEAR(s.position_m.z, 0.025, kEncoderTolM);
  EXPECT_EQ(s.frames, 3);
}

TEST_F(OmniDeviceTest, DeviceVelocityIsPassedOnInTheSceneFrameWhenAsked) {
  options.use_device_velocity = true;
  start_probe();
  // 0.1 mm per 1 ms tick along device +y (up): 0.1 m/s along scene +z.
  for (int i = 1; i <= 200; ++i) {
    fake.pin_hand(0.0, -5.0 + 0.1 * i, -5.0);
    fake.step(1);
  }
  // Encoder steps (~0.06 mm) make single readings noisy; their mean over the last 100 ticks
  // is the motion.
  Vec3<double> mean{};
  for (std::size_t i = probe.records.size() - 100; i < probe.records.size(); ++i) {
    EXPECT_TRUE(probe.records[i].reading.has_velocity);
    mean += probe.records[i].reading.velocity_m_per_s * 0.01;
  }
  EXPECT_NEAR(mean.z, 0.1, 0.005);
  EXPECT_NEAR(mean.x, 0.0, 0.005);
  EXPECT_NEAR(mean.y, 0.0, 0.005);
}

TEST_F(OmniDeviceTest, ByDefaultTheControllerEstimatesVelocity) {
  start_probe();
  fake.step(2);
  EXPECT_FALSE(probe.records.back().reading.has_velocity);
}

TEST_F(OmniDeviceTest, ForcesAreCommandedInTheDeviceFrame) {
  options.enable_ramp_s = 0.0;
  start_probe();
  probe.force = {1.0, 0.5, 0.25};
  fake.step(5);
  const TfFakeHdStats s = fake.stats();
  // F_device = (Fx, Fz, -Fy)
  EXPECT_NEAR(s.last_force_n[0], 1.0, 1e-12);
  EXPECT_NEAR(s.last_force_n[1], 0.25, 1e-12);
  EXPECT_NEAR(s.last_force_n[2], -0.5, 1e-12);
  EXPECT_EQ(s.force_output_enabled, 1);
  EXPECT_EQ(probe.records.back().write_status, DeviceStatus::kOk);
}

TEST_F(OmniDeviceTest, ForcesRampInAfterEnabling) {
  options.enable_ramp_s = 0.1;  // 100 ticks
  start_probe();
  probe.force = {0.0, 0.0, 2.0};
  fake.step(51);
  EXPECT_NEAR(fake.stats().last_force_n[1], 1.0, 1e-9);  // half-way: tick 50 of 100
  fake.step(60);
  EXPECT_NEAR(fake.stats().last_force_n[1], 2.0, 1e-9);
}

TEST_F(OmniDeviceTest, TheForceNeverExceedsTheNominalMaximumWhateverTheTickAsks) {
  options.enable_ramp_s = 0.0;
  start_probe();
  for (int i = 0; i < 300; ++i) {
    // Up to 10 N, slowly enough not to trip the impulse check.
    probe.force = {0.0, 0.0, std::min(10.0, 0.04 * i)};
    fake.step(1);
  }
  const TfFakeHdStats s = fake.stats();
  EXPECT_LE(s.max_force_norm_n, 3.3);  // HD_NOMINAL_MAX_FORCE of the fake
  EXPECT_NEAR(s.last_force_n[1], 3.3, 1e-9);
  EXPECT_EQ(s.errors_raised, 0U) << "last HD error 0x" << std::hex << omni->status().last_hd_error << " on tick "
                                 << std::dec << omni->status().tick;  // the library never saw too much
}

TEST_F(OmniDeviceTest, AUserCapBelowTheNominalMaximumIsEnforced) {
  options.enable_ramp_s = 0.0;
  options.max_force_n = 1.2;
  start_probe();
  EXPECT_DOUBLE_EQ(omni->limits().force_cap_n, 1.2);
  EXPECT_DOUBLE_EQ(omni->info().max_force_n, 1.2);
  probe.force = {0.0, 0.0, 1.0};
  fake.step(5);
  probe.force = {0.0, 0.0, 3.0};
  fake.step(5);
  EXPECT_NEAR(fake.stats().max_force_norm_n, 1.2, 1e-9);
  EXPECT_LE(fake.stats().max_force_norm_n, 1.2);
}

TEST_F(OmniDeviceTest, ANonFiniteForceCommandsZero) {
  options.enable_ramp_s = 0.0;
  start_probe();
  probe.force = {0.0, std::nan(""), 1.0};
  fake.step(3);
  EXPECT_EQ(probe.records.back().write_status, DeviceStatus::kProtocolError);
  EXPECT_EQ(fake.stats().max_force_norm_n, 0.0);
}

TEST_F(OmniDeviceTest, ButtonsArePassedOn) {
  fake.set_buttons(2);
  start_probe();
  fake.step(1);
  EXPECT_EQ(probe.records.back().reading.buttons, 2U);
}

TEST_F(OmniDeviceTest, ReadAndWriteOutsideTheTickSayNotReady) {
  OmniDevice& d = open();
  DeviceReading r;
  EXPECT_EQ(d.read(r), DeviceStatus::kNotReady);
  EXPECT_EQ(d.write({0.0, 0.0, 1.0}), DeviceStatus::kNotReady);
}

TEST_F(OmniDeviceTest, TheTickClockCountsPeriodsFromZero) {
  start_probe();
  fake.step(4);
  ASSERT_EQ(probe.records.size(), 4U);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(probe.records[i].clock.tick, static_cast<std::int64_t>(i));
    EXPECT_DOUBLE_EQ(probe.records[i].clock.dt_s, 1e-3);
    EXPECT_DOUBLE_EQ(probe.records[i].clock.period_s, 1e-3);
  }
}

TEST_F(OmniDeviceTest, ASchedulerThatWillNotStartIsReportedAndLeavesNothingBehind) {
  OmniDevice& d = open();
  probe.device = &d;
  fake.inject_error(hd::kTimerError, 0, TF_FAKE_HD_AT_START, 1);
  auto started = d.start(&test::Probe::tick, &probe);
  ASSERT_FALSE(started.ok());
  EXPECT_THAT(started.error(), HasSubstr("did not start: HD_TIMER_ERROR"));
  EXPECT_THAT(started.error(), HasSubstr("lower rate"));
  EXPECT_FALSE(d.running());
  EXPECT_EQ(fake.stats().async_callbacks, 0);
  ASSERT_TRUE(d.start(&test::Probe::tick, &probe).ok());  // and it can try again
  fake.step(2);
  EXPECT_EQ(probe.records.size(), 2U);
}

TEST_F(OmniDeviceTest, StopsCleanlyWhileTheSchedulerRunsFreely) {
  // The fake's scheduler ticks on its own clock here, as the vendor's does: stop() must end
  // the run from the owner thread through the closing frame. The deadline only guards
  // against a hang; no timing is asserted.
  fake.set_manual(0);
  OmniDevice& d = start_probe();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (d.status_version() < 50 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_GE(d.status_version(), 50U);
  d.stop(std::chrono::seconds(5));
  EXPECT_FALSE(d.running());
  const TfFakeHdStats s = fake.stats();
  EXPECT_EQ(s.scheduler_running, 0);
  EXPECT_EQ(s.async_callbacks, 0);
  EXPECT_EQ(s.force_output_enabled, 0);
  EXPECT_EQ(d.status().phase, OmniPhase::kStopped);
}

TEST_F(OmniDeviceTest, StartTwiceIsRefusedAndStopIsIdempotent) {
  OmniDevice& d = start_probe();
  EXPECT_TRUE(d.running());
  auto again = d.start(&test::Probe::tick, &probe);
  ASSERT_FALSE(again.ok());
  EXPECT_THAT(again.error(), HasSubstr("already running"));
  d.request_stop();
  fake.step(1);
  d.stop();
  d.stop();
  EXPECT_FALSE(d.running());
  const TfFakeHdStats s = fake.stats();
  EXPECT_EQ(s.scheduler_running, 0);
  EXPECT_EQ(s.async_callbacks, 0);
  EXPECT_EQ(s.force_output_enabled, 0);
  EXPECT_EQ(d.status().phase, OmniPhase::kStopped);
}

TEST_F(OmniDeviceTest, ItCanStartAgainAfterAStop) {
  OmniDevice& d = start_probe();
  fake.step(10);
  d.request_stop();
  fake.step(1);
  d.stop();
  probe.records.clear();
  ASSERT_TRUE(d.start(&test::Probe::tick, &probe).ok());
  fake.step(3);
  ASSERT_EQ(probe.records.size(), 3U);
  EXPECT_EQ(probe.records.front().clock.tick, 0);
  EXPECT_EQ(probe.records.back().status, DeviceStatus::kOk);
}

TEST_F(OmniDeviceTest, TheTickCanEndTheRun) {
  options.enable_ramp_s = 0.0;
  OmniDevice& d = start_probe();
  probe.force = {0.0, 0.0, 1.0};
  probe.stop_at_tick = 10;
  fake.step(20);
  EXPECT_FALSE(d.running());
  EXPECT_EQ(probe.records.size(), 11U);  // ticks 0..10, then unscheduled
  const TfFakeHdStats s = fake.stats();
  EXPECT_EQ(s.async_callbacks, 0);
  EXPECT_EQ(s.force_output_enabled, 0);
  EXPECT_EQ(s.last_force_n[1], 0.0);  // the last frame commanded zero
  EXPECT_THAT(d.last_error(), HasSubstr("asked to stop"));
}

TEST_F(OmniDeviceTest, EmergencyZeroFromAnotherThreadTakesEffectAtTheNextFrame) {
  options.enable_ramp_s = 0.0;
  OmniDevice& d = start_probe();
  probe.force = {0.0, 0.0, 1.0};
  fake.step(5);
  ASSERT_NEAR(fake.stats().last_force_n[1], 1.0, 1e-12);
  std::thread watchdog([&] { d.emergency_zero(); });
  watchdog.join();
  fake.step(1);
  TfFakeHdStats s = fake.stats();
  EXPECT_EQ(s.last_force_n[1], 0.0);
  EXPECT_EQ(s.force_output_enabled, 0);
  EXPECT_EQ(probe.records.back().status, DeviceStatus::kDeviceFault);
  fake.step(100);  // it stays off; the loop still reads positions
  s = fake.stats();
  EXPECT_EQ(s.last_force_n[1], 0.0);
  EXPECT_EQ(s.force_output_enabled, 0);
  EXPECT_TRUE(d.running());
  EXPECT_THAT(d.last_error(), HasSubstr("emergency zero"));
}

TEST_F(OmniDeviceTest, AFrameAllocatesNothing) {
  options.enable_ramp_s = 0.0;
  start_probe();
  probe.force = {0.0, 0.0, 1.0};
  fake.step(2000);
  ASSERT_EQ(probe.records.size(), 2000U);
  // Between two ticks the servo thread ran our frame's end, the fake's scheduler (which
  // allocates nothing) and our next frame's start: any allocation shows up here.
  for (std::size_t i = 2; i < probe.records.size(); ++i) {
    ASSERT_EQ(probe.records[i].allocations, probe.records[i - 1].allocations) << "tick " << i;
  }
}

TEST_F(OmniDeviceTest, AnOverrunPassesTheTrueDtAndIsCounted) {
  start_probe();
  fake.step(5);
  fake.inject_overrun(3);
  fake.step(1);
  fake.step(1);
  ASSERT_EQ(probe.records.size(), 7U);
  EXPECT_EQ(probe.records[5].clock.tick, 4 + 3);  // two periods skipped
  EXPECT_NEAR(probe.records[5].clock.dt_s, 3e-3, 1e-12);
  EXPECT_EQ(probe.records[6].clock.tick, 8);
  EXPECT_NEAR(probe.records[6].clock.dt_s, 1e-3, 1e-12);
  EXPECT_EQ(omni->status().overruns, 1U);
  EXPECT_TRUE(omni->running());
}

TEST_F(OmniDeviceTest, TooManyOverrunsInARowStopTheLoop) {
  options.max_consecutive_overruns = 5;
  options.enable_ramp_s = 0.0;
  OmniDevice& d = start_probe();
  probe.force = {0.0, 0.0, 1.0};
  fake.step(3);
  fake.set_callback_time(2.5e-3);  // every callback now takes longer than its 1 ms period
  fake.step(10);
  EXPECT_FALSE(d.running());
  // Five overrunning ticks, then the closing frame, in which the tick hears why.
  ASSERT_EQ(probe.records.size(), 3U + 5U + 1U);
  EXPECT_EQ(probe.records.back().status, DeviceStatus::kDeviceFault);
  EXPECT_EQ(fake.stats().last_force_n[1], 0.0);
  EXPECT_EQ(fake.stats().force_output_enabled, 0);
  EXPECT_THAT(d.last_error(), HasSubstr("overran its 1000 Hz period on 5 ticks in a row"));
}

TEST_F(OmniDeviceTest, TheMotorTemperatureModelIsPublished) {
  options.temperature_period_s = 0.01;
  start_probe();
  fake.set_motor_temperature(0.4);
  fake.step(12);
  EXPECT_DOUBLE_EQ(omni->status().motor_temperature, 0.4);
}

TEST_F(OmniDeviceTest, ADeviceWithoutATemperatureModelIsNotAFault) {
  fake.set_temperature_supported(0);
  start_probe();
  fake.step(300);
  EXPECT_FALSE(omni->limits().has_motor_temperature);
  EXPECT_EQ(omni->status().motor_temperature, -1.0);
  EXPECT_TRUE(omni->running());
  EXPECT_EQ(omni->status().hd_errors, 0U);
}

// ---- every HD error class (hd_errors.hpp) ----------------------------------------------------

struct ErrorCase {
  hd::HDerror code;
  DeviceStatus fatal_status;  // kOk: a force error (degrade, ramp back)
};

class OmniHdErrors : public OmniFixture, public ::testing::WithParamInterface<ErrorCase> {};

// Raised at the end of a frame while a steady 1 N is commanded.
TEST_P(OmniHdErrors, AreHandledByTheirClass) {
  const ErrorCase c = GetParam();
  options.enable_ramp_s = 0.0;
  options.force_error_hold_s = 0.05;  // 50 ticks
  options.recovery_ramp_s = 0.1;      // 100 ticks
  options.warm_motors_hold_s = 0.05;
  OmniDevice& d = start_probe();
  probe.force = {0.0, 0.0, 1.0};
  fake.step(20);
  ASSERT_NEAR(fake.stats().last_force_n[1], 1.0, 1e-12);
  fake.inject_error(c.code, -3, TF_FAKE_HD_AT_END, 1);
  fake.step(1);  // the error is raised as this frame ends
  const std::string name(hd::error_name(c.code));

  if (c.fatal_status == DeviceStatus::kOk) {
    // Degrade: zero force while held (the tick hears kNotReady), then a linear ramp back.
    fake.step(1);
    EXPECT_EQ(probe.records.back().status, DeviceStatus::kNotReady);
    EXPECT_EQ(fake.stats().last_force_n[1], 0.0);
    EXPECT_EQ(d.status().phase, OmniPhase::kHeld);
    EXPECT_THAT(d.last_error(), HasSubstr(name));
    fake.step(48);
    EXPECT_EQ(fake.stats().last_force_n[1], 0.0);
    double previous = 0.0;
    for (int i = 0; i < 100; ++i) {
      fake.step(1);
      const double f = fake.stats().last_force_n[1];
      EXPECT_GE(f, previous - 1e-12) << "the ramp back never steps down";
      EXPECT_LE(f, 1.0 + 1e-12);
      previous = f;
    }
    fake.step(5);
    EXPECT_NEAR(fake.stats().last_force_n[1], 1.0, 1e-12);
    EXPECT_EQ(probe.records.back().status, DeviceStatus::kOk);
    EXPECT_EQ(d.status().phase, OmniPhase::kRunning);
    EXPECT_EQ(d.status().force_errors, 1U);
    EXPECT_TRUE(d.running());
    return;
  }
  // Stop: the next frame is the last one; its tick hears the mapped status; zero force,
  // output off, callback unscheduled; the message names the HD error.
  fake.step(5);
  EXPECT_FALSE(d.running());
  EXPECT_EQ(probe.records.back().status, c.fatal_status);
  EXPECT_EQ(probe.records.size(), 20U + 1U + 1U);
  const TfFakeHdStats s = fake.stats();
  EXPECT_EQ(s.last_force_n[1], 0.0);
  EXPECT_EQ(s.force_output_enabled, 0);
  EXPECT_EQ(s.async_callbacks, 0);
  EXPECT_THAT(d.last_error(), HasSubstr(name));
  EXPECT_THAT(d.last_error(), HasSubstr("internal -3"));
  EXPECT_EQ(d.status().phase, OmniPhase::kStopped);
}

INSTANTIATE_TEST_SUITE_P(
    EveryClass, OmniHdErrors,
    ::testing::Values(
        // function errors: a fault of this binding inside the loop
        ErrorCase{hd::kInvalidEnum, DeviceStatus::kProtocolError},
        ErrorCase{hd::kInvalidValue, DeviceStatus::kProtocolError},
        ErrorCase{hd::kInvalidOperation, DeviceStatus::kProtocolError},
        ErrorCase{hd::kInvalidInputType, DeviceStatus::kProtocolError},
        ErrorCase{hd::kBadHandle, DeviceStatus::kProtocolError},
        // force errors: degrade and ramp back
        ErrorCase{hd::kWarmMotors, DeviceStatus::kOk}, ErrorCase{hd::kExceededMaxForce, DeviceStatus::kOk},
        ErrorCase{hd::kExceededMaxForceImpulse, DeviceStatus::kOk},
        ErrorCase{hd::kExceededMaxVelocity, DeviceStatus::kOk}, ErrorCase{hd::kForceError, DeviceStatus::kOk},
        // device, communication, timer
        ErrorCase{hd::kDeviceFault, DeviceStatus::kDeviceFault},
        ErrorCase{hd::kDeviceAlreadyInitiated, DeviceStatus::kDeviceFault},
        ErrorCase{hd::kCommError, DeviceStatus::kDisconnected},
        ErrorCase{hd::kCommConfigError, DeviceStatus::kDisconnected},
        ErrorCase{hd::kTimerError, DeviceStatus::kDeviceFault},
        // frame errors
        ErrorCase{hd::kIllegalBegin, DeviceStatus::kProtocolError},
        ErrorCase{hd::kIllegalEnd, DeviceStatus::kProtocolError},
        ErrorCase{hd::kFrameError, DeviceStatus::kProtocolError},
        // scheduler, licence, and a code the reference does not list
        ErrorCase{hd::kInvalidPriority, DeviceStatus::kDeviceFault},
        ErrorCase{hd::kSchedulerFull, DeviceStatus::kDeviceFault},
        ErrorCase{hd::kInvalidLicense, DeviceStatus::kDeviceFault}, ErrorCase{0x0777, DeviceStatus::kDeviceFault}),
    [](const ::testing::TestParamInfo<ErrorCase>& param) {
      std::string name(hd::error_name(param.param.code));
      if (name == "HD error") name = "unlisted_code";
      for (char& ch : name) {
        if (ch == ' ') ch = '_';
      }
      return name;
    });

// Raised in hdBeginFrame: the same frame is already the last one. (Force errors come with a
// frame's commands, at its end: they are covered above.)
class OmniFatalHdErrors : public OmniFixture, public ::testing::WithParamInterface<hd::HDerror> {};

TEST_P(OmniFatalHdErrors, RaisedAtTheStartOfAFrameActOnThatFrame) {
  const hd::HDerror code = GetParam();
  options.enable_ramp_s = 0.0;
  OmniDevice& d = start_probe();
  probe.force = {0.0, 0.0, 1.0};
  fake.step(10);
  fake.inject_error(code, 0, TF_FAKE_HD_AT_BEGIN, 1);
  fake.step(3);
  EXPECT_FALSE(d.running());
  EXPECT_EQ(probe.records.size(), 11U);
  EXPECT_EQ(probe.records.back().status, hd::device_status(hd::classify(code)));
  EXPECT_NE(probe.records.back().status, DeviceStatus::kOk);
  EXPECT_EQ(fake.stats().last_force_n[1], 0.0);
  EXPECT_EQ(fake.stats().force_output_enabled, 0);
  EXPECT_THAT(d.last_error(), HasSubstr(hd::error_name(code)));
}

INSTANTIATE_TEST_SUITE_P(EveryFatalCode, OmniFatalHdErrors,
                         ::testing::Values(hd::kInvalidEnum, hd::kInvalidValue, hd::kInvalidOperation,
                                           hd::kInvalidInputType, hd::kBadHandle, hd::kDeviceFault,
                                           hd::kDeviceAlreadyInitiated, hd::kCommError, hd::kCommConfigError,
                                           hd::kTimerError, hd::kIllegalBegin, hd::kIllegalEnd, hd::kFrameError,
                                           hd::kInvalidPriority, hd::kSchedulerFull, hd::kInvalidLicense, 0x0777U));

TEST_F(OmniDeviceTest, WarmMotorsHoldUntilTheThermalModelCools) {
  options.enable_ramp_s = 0.0;
  options.warm_motors_hold_s = 0.05;
  options.recovery_ramp_s = 0.01;
  options.temperature_period_s = 0.001;
  OmniDevice& d = start_probe();
  probe.force = {0.0, 0.0, 0.5};
  fake.step(5);
  fake.set_motor_temperature(0.95);
  fake.inject_error(hd::kWarmMotors, 0, TF_FAKE_HD_AT_END, 1);
  fake.step(200);  // well past the 50-tick minimum hold: still too warm
  EXPECT_EQ(fake.stats().last_force_n[1], 0.0);
  EXPECT_EQ(d.status().phase, OmniPhase::kHeld);
  fake.set_motor_temperature(0.5);
  fake.step(30);
  EXPECT_NEAR(fake.stats().last_force_n[1], 0.5, 1e-12);
  EXPECT_EQ(d.status().phase, OmniPhase::kRunning);
}

TEST_F(OmniDeviceTest, AKickTheLibraryCatchesIsAForceErrorThatRecovers) {
  // No ramp of ours: a 0 -> 3 N step in one tick exceeds the fake library's impulse limit
  // (3 N/ms), which raises HD_EXCEEDED_MAX_FORCE_IMPULSE by itself.
  options.enable_ramp_s = 0.0;
  options.force_error_hold_s = 0.01;
  options.recovery_ramp_s = 0.1;
  OmniDevice& d = start_probe();
  fake.step(2);
  probe.force = {0.0, 0.0, 3.2};
  fake.step(200);
  EXPECT_EQ(d.status().force_errors, 1U);
  EXPECT_EQ(d.status().last_hd_error, hd::kExceededMaxForceImpulse);
  EXPECT_NEAR(fake.stats().last_force_n[1], 3.2, 1e-9);  // ramped back without another kick
  EXPECT_TRUE(d.running());
}

}  // namespace
}  // namespace toonforce
