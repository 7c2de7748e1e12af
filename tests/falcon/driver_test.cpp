// SPDX-License-Identifier: Apache-2.0
// FalconDriver (the DeviceDriver) against the emulated Falcon over the in-process transport:
// homing, positions in the scene frame, force -> motor words, split and merged replies, and
// each fault (dropped, garbled, USB timeout, unplugged). The same scenarios run over the real
// libusb path under umockdev in usb_test.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numbers>

#include "alloc_counter.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/hal/falcon/driver.hpp"
#include "toonforce/hal/falcon/emulator/emulator_transport.hpp"
#include "toonforce/hal/falcon/emulator/falcon_emulator.hpp"
#include "toonforce/hal/falcon/ftdi.hpp"

namespace toonforce::falcon {
namespace {

using emulator::EmulatorOptions;
using emulator::EmulatorTransport;
using emulator::FalconEmulator;

const Vec3<double> kCentre{0.0, 0.0, 0.110};
constexpr double kCountTolerance_m = 1e-4;  // a few encoder counts anywhere in the workspace

struct Rig {
  explicit Rig(EmulatorOptions o = with_firmware(), const FalconOptions& f = FalconOptions())
      : emu(std::move(o)), options(f) {
    auto t = std::make_unique<EmulatorTransport>(emu);
    transport = t.get();
    EXPECT_EQ(ftdi::enter_normal_mode(*t), TransportStatus::kOk);
    driver = std::make_unique<FalconDriver>(std::move(t), options, "Novint Falcon (emulated)");
  }
  static EmulatorOptions with_firmware() {
    EmulatorOptions o;
    o.firmware_loaded = true;
    return o;
  }
  DeviceStatus tick(const Vec3<double>& force = {}) {
    const DeviceStatus s = driver->read(reading);
    last_write = driver->write(s == DeviceStatus::kOk ? force : Vec3<double>{});
    return s;
  }
  /// Pull the grip all the way out, push it back in (FALCON.md §4). With a hand model the
  /// grip follows its target over some ticks.
  void home() {
    emu.set_grip_position({0, 0, 0.178});
    for (int i = 0; i < 2000 && emu.grip_position().z < 0.172; ++i) tick();
    tick();
    emu.set_grip_position({0, 0, 0.09});
    for (int i = 0; i < 2000 && !driver->homed(); ++i) tick();
    emu.set_grip_position(kCentre);
    for (int i = 0; i < 3; ++i) tick();
    ASSERT_TRUE(driver->homed());
  }

  FalconEmulator emu;
  FalconOptions options;
  EmulatorTransport* transport = nullptr;
  std::unique_ptr<FalconDriver> driver;
  DeviceReading reading;
  DeviceStatus last_write = DeviceStatus::kOk;
};

// ---- homing (FALCON.md §4) ----

TEST(FalconDriver, NotReadyWithRedLedUntilHomedThenGreenAndPositions) {
  Rig rig;
  EXPECT_EQ(rig.tick({1, 2, 3}), DeviceStatus::kNotReady);
  EXPECT_EQ(rig.driver->fault(), FalconFault::kNotHomed);
  EXPECT_NE(rig.driver->last_error().find("pull the grip all the way out"), std::string::npos);
  EXPECT_EQ(rig.emu.last_command().flags, kHomingRequest | kLedRed);
  EXPECT_EQ(rig.emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0})) << "no force before homing";

  rig.emu.set_grip_position({0, 0, 0.175});  // all the way out
  EXPECT_EQ(rig.tick(), DeviceStatus::kNotReady);
  EXPECT_FALSE(rig.emu.homed());
  rig.emu.set_grip_position({0.0, 0.0, 0.095});  // straight back in
  rig.tick();                                    // this command is the one that completes homing in the emulator
  EXPECT_EQ(rig.tick(), DeviceStatus::kOk);
  EXPECT_TRUE(rig.driver->homed());
  EXPECT_EQ(rig.emu.last_command().flags, kHomingRequest | kLedGreen);
  const Vec3<double> expected = falcon_to_scene({0.0, 0.0, 0.095}, kCentre);
  EXPECT_NEAR(rig.reading.position_m.x, expected.x, kCountTolerance_m);
  EXPECT_NEAR(rig.reading.position_m.y, expected.y, kCountTolerance_m);
  EXPECT_NEAR(rig.reading.position_m.z, expected.z, kCountTolerance_m);
  EXPECT_NEAR(rig.reading.position_m.y, 0.015, kCountTolerance_m) << "pushed in = away from the user";
  EXPECT_TRUE(rig.driver->last_error().empty());
}

TEST(FalconDriver, EveryCommandHoldsTheHomingBit) {
  Rig rig;
  rig.home();
  for (int k = 0; k < 50; ++k) rig.tick({0.5, 0, 0});
  rig.driver->emergency_zero();
  for (const Command& c : rig.emu.command_log()) ASSERT_TRUE(c.flags & kHomingRequest);
  EXPECT_EQ(rig.emu.homing_bit_dropped(), 0u);
  EXPECT_TRUE(rig.emu.homed());
}

TEST(FalconDriver, EncodersBeforeHomingAreRelativeAndNotUsed) {
  Rig rig;
  rig.tick();
  EXPECT_EQ(rig.driver->last_status().encoder, rig.emu.encoder_counts());
  EXPECT_FALSE(rig.driver->last_status().homed());
  rig.home();
  // After homing the offsets are gone: the counts are absolute.
  Angles t{};
  ASSERT_TRUE(inverse_kinematics(FalconGeometry{}, kCentre, t));
  EXPECT_NEAR(rig.driver->last_status().encoder[0], theta1_rad_to_encoder(t[0]), 0.5);
}

// ---- a few hundred ticks: read, write, force -> motor words ----

TEST(FalconDriver, ServoTicksTrackThePositionAndSendTheTransposedForce) {
  Rig rig;
  rig.home();
  const auto path = [](int k) {
    const double phase = 2 * std::numbers::pi * k / 400.0;
    return Vec3<double>{0.03 * std::cos(phase), 0.02 * std::sin(phase), 0.11 + 0.02 * std::sin(2 * phase)};
  };
  rig.emu.set_grip_position(path(0));
  rig.tick();
  rig.tick();
  Vec3<double> sampled = path(0);  // where the grip was when the device answered the last command
  for (int k = 0; k < 400; ++k) {
    // read() returns the reply to the previous tick's command: the grip as it was then.
    ASSERT_EQ(rig.driver->read(rig.reading), DeviceStatus::kOk) << k << ": " << rig.driver->last_error();
    ASSERT_LT(norm(rig.reading.position_m - falcon_to_scene(sampled, kCentre)), kCountTolerance_m) << k;
    const double phase = 2 * std::numbers::pi * k / 400.0;
    const Vec3<double> grip = path(k + 1);
    rig.emu.set_grip_position(grip);
    sampled = grip;
    const Vec3<double> force{1.5 * std::sin(phase), -1.0, 2.0 * std::cos(phase)};  // scene frame [N]
    ASSERT_EQ(rig.driver->write(force), DeviceStatus::kOk) << k;
    // The words on the wire are -10000 J^T F at the estimated pose, F in the Falcon frame...
    Mat3 j;
    ASSERT_TRUE(position_jacobian(FalconGeometry{}, rig.driver->position_falcon_m(), j));
    const MotorWords w = force_to_motor_words(j, scene_force_to_falcon(force));
    ASSERT_EQ(rig.emu.last_command().motor, w.word) << k;
    // ...and the emulated motors push the grip with that force (J^-T tau at the true pose,
    // which moved by under a millimetre since the estimate).
    const Vec3<double> applied = rig.emu.motor_force_n();
    const Vec3<double> wanted = scene_force_to_falcon(force);
    ASSERT_LT(norm(applied - wanted), 0.03 * norm(wanted) + 0.005) << k;
  }
  const FalconStats& s = rig.driver->stats();
  EXPECT_EQ(s.timeouts + s.protocol_errors, 0u);
  EXPECT_LE(s.max_fk_iterations, 6);  // the first tick after homing starts from the centre
}

TEST(FalconDriver, TicksDoNotAllocate) {
  Rig rig;
  rig.home();
  for (int k = 0; k < 10; ++k) rig.tick({0, 0, 1});
  test::AllocationScope scope;
  for (int k = 0; k < 500; ++k) {
    rig.emu.set_grip_position({0.0001 * (k % 50), 0.0, 0.11});
    rig.tick({0.2, 0.1, 1.0});
  }
  EXPECT_EQ(scope.count(), 0u);
}

TEST(FalconDriver, ClosedLoopForceMovesTheHeldGripAlongTheSceneAxis) {
  // The grip is held by a 200 N/m hand; a constant scene force F settles it at F/k from the
  // hand's target, along F: this checks frame conversion and transpose end to end.
  struct Case {
    Vec3<double> force_scene;
  };
  for (const Case c : {Case{{0, 0, 2}}, Case{{0, 2, 0}}, Case{{2, 0, 0}}, Case{{-1.2, 1.2, -1.2}}}) {
    EmulatorOptions o = Rig::with_firmware();
    o.hand_stiffness_n_per_m = 200.0;
    o.hand_damping_n_s_per_m = 6.0;
    Rig rig(o);
    rig.home();
    for (int k = 0; k < 200; ++k) rig.tick();  // settle at the hand's target
    const Vec3<double> rest = rig.reading.position_m;
    for (int k = 0; k < 800; ++k) ASSERT_EQ(rig.tick(c.force_scene), DeviceStatus::kOk) << k;
    const Vec3<double> moved = rig.reading.position_m - rest;
    const Vec3<double> expected = c.force_scene * (1.0 / 200.0);
    EXPECT_LT(norm(moved - expected), 0.05 * norm(expected))
        << moved.x << " " << moved.y << " " << moved.z << " for " << c.force_scene.x << " " << c.force_scene.y << " "
        << c.force_scene.z;
  }
}

TEST(FalconDriver, GripButtonsArriveInTheReading) {
  Rig rig;
  rig.home();
  rig.emu.set_buttons(kButtonCentre | kButtonMinus);
  rig.tick();  // the command that samples the buttons
  ASSERT_EQ(rig.tick(), DeviceStatus::kOk);
  EXPECT_EQ(rig.reading.buttons, std::uint32_t{kButtonCentre | kButtonMinus});
  rig.emu.set_buttons(kButtonPlus);
  rig.tick();
  rig.tick();
  EXPECT_EQ(rig.reading.buttons, std::uint32_t{kButtonPlus});
}

TEST(FalconDriver, InfoIsInTheSceneFrame) {
  Rig rig;
  const DeviceInfo& info = rig.driver->info();
  EXPECT_EQ(info.name, "Novint Falcon (emulated)");
  EXPECT_EQ(info.nominal_rate_hz, 1000.0);
  EXPECT_EQ(info.clocking, Clocking::kHostTimer);
  EXPECT_GT(info.max_force_n, 0.0);
  // The HDAL box (-60..60, -60..60, 75..175) mm about z = 110 mm, as (x, -z, y).
  EXPECT_NEAR(info.workspace_min_m.x, -0.060, 1e-12);
  EXPECT_NEAR(info.workspace_max_m.x, 0.060, 1e-12);
  EXPECT_NEAR(info.workspace_min_m.y, -0.065, 1e-12);
  EXPECT_NEAR(info.workspace_max_m.y, 0.035, 1e-12);
  EXPECT_NEAR(info.workspace_min_m.z, -0.060, 1e-12);
  EXPECT_NEAR(info.workspace_max_m.z, 0.060, 1e-12);
}

// ---- the force envelope ----

TEST(FalconDriver, TheAdvertisedMaximumIsWhatTheWordsGiveInEveryDirectionAtTheCentre) {
  Rig rig;
  ForceEnvelope centre;
  ASSERT_TRUE(force_envelope_at(FalconGeometry{}, kCentre, MotorScale{}, centre));
  EXPECT_DOUBLE_EQ(rig.driver->info().max_force_n, centre.every_direction_n);
  EXPECT_LE(rig.driver->info().max_continuous_force_n, rig.driver->info().max_force_n);
  // At the centre a force of that size goes out as asked whichever way it points.
  rig.home();
  for (const Vec3<double>& u : {Vec3<double>{1, 0, 0}, Vec3<double>{0, 1, 0}, Vec3<double>{0, 0, -1},
                                Vec3<double>{0.6, -0.48, 0.64}, Vec3<double>{-0.36, 0.48, 0.8}}) {
    rig.tick(u * (0.999 * rig.driver->info().max_force_n));
    ASSERT_EQ(rig.tick(), DeviceStatus::kOk);
    EXPECT_FALSE(rig.reading.force_limited) << u.x << " " << u.y << " " << u.z;
  }
  EXPECT_EQ(rig.driver->stats().saturated_writes, 0u);

  // A calibrated constant changes it: twice the words per N m, half the force.
  FalconOptions doubled;
  doubled.motor.words_per_n_m = 20000.0;
  Rig stiff(Rig::with_firmware(), doubled);
  EXPECT_NEAR(stiff.driver->info().max_force_n, centre.every_direction_n / 2, 1e-12);
}

TEST(FalconDriver, ASaturatedWriteKeepsItsDirectionAndIsFlaggedOnTheNextRead) {
  Rig rig;
  rig.home();
  ASSERT_EQ(rig.tick({0, 0, 1}), DeviceStatus::kOk);
  ASSERT_EQ(rig.tick(), DeviceStatus::kOk);
  EXPECT_FALSE(rig.reading.force_limited);

  // Far beyond the envelope along scene (1, 1, 1): the words are scaled back to +-4095.
  const Vec3<double> asked{30, 30, 30};
  rig.tick(asked);
  const Command sent = rig.driver->last_command();
  EXPECT_EQ(std::max({std::abs(sent.motor[0]), std::abs(sent.motor[1]), std::abs(sent.motor[2])}), 4095);
  ASSERT_EQ(rig.tick(), DeviceStatus::kOk);
  EXPECT_TRUE(rig.reading.force_limited) << "the read after the saturated write says so";
  EXPECT_EQ(rig.driver->stats().saturated_writes, 1u);
  // What the emulated motors push with: the asked direction, less than asked, at the envelope.
  rig.tick(asked);
  const Vec3<double> given = rig.emu.motor_force_n();  // Falcon frame
  const Vec3<double> asked_falcon = scene_force_to_falcon(asked);
  EXPECT_NEAR(dot(given, asked_falcon) / (norm(given) * norm(asked_falcon)), 1.0, 1e-3) << "the direction is kept";
  Mat3 j;
  ASSERT_TRUE(position_jacobian(FalconGeometry{}, rig.emu.grip_position(), j));
  EXPECT_NEAR(norm(given), max_force_along(j, asked_falcon), 0.01 * norm(given)) << "as much as the words give";
  EXPECT_LT(norm(given), norm(asked));

  rig.tick({0, 0, 0.5});  // back inside: the flag clears
  ASSERT_EQ(rig.tick(), DeviceStatus::kOk);
  EXPECT_FALSE(rig.reading.force_limited);
}

TEST(FalconDriver, ServoLoopRendersTheWallSceneOnTheEmulatedFalcon) {
  // The servo loop, every stage, on the emulated Falcon (scenes/wall.toml: floor z = 0,
  // 1500 N/m), against an emulated grip pushed 10 mm into the floor by a 200 N/m hand once the
  // loop is engaged above it. The floor must hold it at the force balance:
  // 1500 d = 200 (0.010 - d), d = 1.18 mm, 1.76 N up.
  auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/wall.toml");
  ASSERT_TRUE(scene) << scene.error();
  EmulatorOptions o = Rig::with_firmware();
  o.hand_stiffness_n_per_m = 200.0;
  o.hand_damping_n_s_per_m = 6.0;
  Rig rig(o);
  rig.home();
  const ServoConfig config = with_device(servo_config(scene.value(), 0.001), rig.driver->info());
  ASSERT_EQ(check_servo_config(config), "");
  ServoLoop<DriverRef, RuntimeScene<double>> loop(DriverRef(*rig.driver), make_runtime_scene<double>(scene.value()),
                                                  config);
  rig.emu.set_grip_position(scene_to_falcon({0, 0, 0.02}, kCentre));
  std::int64_t k = 0;
  for (; k < 300; ++k) ASSERT_TRUE(loop.tick(k).ok()) << k;  // engages above the floor, ramps in
  EXPECT_EQ(loop.state(), LoopState::kActive);
  rig.emu.set_grip_position(scene_to_falcon({0, 0, -0.010}, kCentre));  // the hand pushes down
  for (; k < 1800; ++k) {
    const TickStatus s = loop.tick(k);
    ASSERT_TRUE(s.ok()) << k << ": " << rig.driver->last_error() << " faults " << s.faults.bits();
  }
  TelemetryFrame f;
  loop.fill_frame(f);
  const double penetration = -f.position_m.z;
  EXPECT_NEAR(penetration, 0.010 * 200.0 / 1700.0, 0.15e-3);
  EXPECT_NEAR(loop.force().z, 1500.0 * penetration, 0.05);
  // The device pushes the grip up (scene +z = Falcon +y) with the scene's force.
  const Vec3<double> pushed = rig.emu.motor_force_n();
  EXPECT_NEAR(pushed.y, loop.force().z, 0.05);
  EXPECT_NEAR(pushed.x, 0.0, 0.05);
  EXPECT_NEAR(pushed.z, 0.0, 0.05);
}

// ---- replies split or merged across USB packets (FALCON.md §3) ----

TEST(FalconDriver, RepliesSplitAcrossTransfersAreReassembled) {
  Rig rig;
  rig.home();
  rig.emu.set_max_payload_per_transfer(5);  // a frame over 4 transfers: within a tick's budget
  for (int k = 0; k < 50; ++k) ASSERT_EQ(rig.tick({0, 0, 1}), DeviceStatus::kOk) << k;
  EXPECT_EQ(rig.driver->stats().timeouts, 0u);
}

TEST(FalconDriver, AReplyTooSplitForOneTickCompletesOnTheNext) {
  Rig rig;
  rig.home();
  rig.emu.set_max_payload_per_transfer(3);  // 6 transfers per frame, 4 allowed per tick
  EXPECT_EQ(rig.tick(), DeviceStatus::kTimeout);
  EXPECT_EQ(rig.tick(), DeviceStatus::kOk) << "the rest of the frame was kept";
}

TEST(FalconDriver, MergedRepliesKeepTheNewest) {
  Rig rig;
  rig.home();
  rig.emu.delay_replies(1);
  EXPECT_EQ(rig.tick(), DeviceStatus::kOk);  // the previous reply; this tick's is held back
  rig.emu.set_grip_position({0.01, 0, 0.11});
  EXPECT_EQ(rig.tick(), DeviceStatus::kTimeout);  // nothing; this tick's command releases both
  EXPECT_EQ(rig.tick(), DeviceStatus::kOk);       // two replies in one packet: the newest wins
  EXPECT_NEAR(rig.reading.position_m.x, 0.01, kCountTolerance_m);
  EXPECT_EQ(rig.tick(), DeviceStatus::kOk);
}

// ---- faults: the status says what, the force goes to zero, last_error says what to do ----

TEST(FalconDriver, DroppedReplyIsATimeoutWithZeroForceThenRecovers) {
  Rig rig;
  rig.home();
  rig.tick({0, 0, 2});
  ASSERT_NE(rig.emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
  rig.emu.drop_replies(1);
  rig.tick({0, 0, 2});  // this command's reply is dropped
  DeviceReading r;
  EXPECT_EQ(rig.driver->read(r), DeviceStatus::kTimeout);
  EXPECT_EQ(rig.driver->fault(), FalconFault::kNoReply);
  EXPECT_NE(rig.driver->last_error().find("did not answer the last command"), std::string::npos);
  // The loop would send zero; even if it asks for force, the driver sends zero.
  EXPECT_EQ(rig.driver->write({0, 0, 2}), DeviceStatus::kNotReady);
  EXPECT_EQ(rig.emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
  EXPECT_EQ(rig.tick({0, 0, 2}), DeviceStatus::kOk);
  EXPECT_EQ(rig.driver->stats().timeouts, 1u);
}

TEST(FalconDriver, GarbledReplyIsAProtocolErrorThenRecovers) {
  Rig rig;
  rig.home();
  rig.emu.garble_replies(1);
  rig.tick({1, 0, 0});
  EXPECT_EQ(rig.tick({1, 0, 0}), DeviceStatus::kProtocolError);
  EXPECT_EQ(rig.driver->fault(), FalconFault::kGarbled);
  EXPECT_NE(rig.driver->last_error().find("sent 16 bytes that did not form a valid 16-byte frame"), std::string::npos)
      << rig.driver->last_error();
  EXPECT_EQ(rig.emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
  EXPECT_EQ(rig.tick({1, 0, 0}), DeviceStatus::kOk);
  EXPECT_EQ(rig.driver->stats().garbled_bytes, 16u);
}

TEST(FalconDriver, StalledUsbReadIsATimeoutNamingTheBridge) {
  Rig rig;
  rig.home();
  rig.emu.stall_in_transfers(1);
  EXPECT_EQ(rig.tick(), DeviceStatus::kTimeout);
  EXPECT_EQ(rig.driver->fault(), FalconFault::kUsbTimeout);
  EXPECT_NE(rig.driver->last_error().find("the FTDI USB bridge stopped answering"), std::string::npos);
  EXPECT_EQ(rig.tick(), DeviceStatus::kOk);  // the late reply or the next one
}

TEST(FalconDriver, RepeatedFaultsCountTicksInARow) {
  Rig rig;
  rig.home();
  rig.emu.drop_replies(3);
  rig.tick();
  for (int k = 0; k < 3; ++k) rig.tick();
  EXPECT_NE(rig.driver->last_error().find("(3 ticks in a row)"), std::string::npos) << rig.driver->last_error();
}

TEST(FalconDriver, UnplugIsLatchedAsDisconnected) {
  Rig rig;
  rig.home();
  rig.tick({0, 0, 1});
  rig.emu.unplug();
  DeviceReading r;
  EXPECT_EQ(rig.driver->read(r), DeviceStatus::kDisconnected);
  EXPECT_EQ(rig.driver->write({0, 0, 1}), DeviceStatus::kDisconnected);
  EXPECT_EQ(rig.driver->read(r), DeviceStatus::kDisconnected);
  const std::string e = rig.driver->last_error();
  EXPECT_NE(e.find("LIBUSB_ERROR_NO_DEVICE"), std::string::npos) << e;
  EXPECT_NE(e.find("Plug it back in"), std::string::npos) << e;
  EXPECT_NE(e.find("toonforce falcon firmware FILE"), std::string::npos) << e;
}

TEST(FalconDriver, NonFiniteForceSendsZero) {
  Rig rig;
  rig.home();
  rig.tick({0, 0, 1});
  DeviceReading r;
  ASSERT_EQ(rig.driver->read(r), DeviceStatus::kOk);
  EXPECT_EQ(rig.driver->write({std::nan(""), 0, 0}), DeviceStatus::kNotReady);
  EXPECT_EQ(rig.emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
}

TEST(FalconDriver, OneCommandOutstanding) {
  Rig rig;
  rig.home();
  DeviceReading r;
  ASSERT_EQ(rig.driver->read(r), DeviceStatus::kOk);
  const std::size_t before = rig.emu.commands_received();
  EXPECT_EQ(rig.driver->write({0, 0, 1}), DeviceStatus::kOk);
  EXPECT_EQ(rig.driver->write({0, 0, 2}), DeviceStatus::kOk);  // the first is still outstanding
  EXPECT_EQ(rig.emu.commands_received(), before + 1);
  EXPECT_EQ(rig.driver->stats().deferred_writes, 1u);
  // Two reads in a row: the second sends a zero-force command to have a reply to wait for.
  ASSERT_EQ(rig.driver->read(r), DeviceStatus::kOk);
  ASSERT_EQ(rig.driver->read(r), DeviceStatus::kOk);
  EXPECT_EQ(rig.emu.commands_received(), before + 2);
  EXPECT_EQ(rig.emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
}

TEST(FalconDriver, EmergencyZeroSendsAZeroForceCommandAtOnce) {
  Rig rig;
  rig.home();
  rig.tick({0, 0, 3});
  ASSERT_NE(rig.emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
  rig.driver->emergency_zero();
  EXPECT_EQ(rig.transport->emergency_writes(), 1u);
  EXPECT_EQ(rig.emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
  EXPECT_EQ(rig.emu.last_command().flags, kHomingRequest | kLedGreen);
  // The extra reply is absorbed: the exchange goes on, and readings are not a tick behind.
  for (int k = 0; k < 5; ++k) EXPECT_EQ(rig.tick(), DeviceStatus::kOk);
  rig.emu.set_grip_position({0.012, 0.0, 0.11});
  rig.tick();  // this tick's command samples the new position
  DeviceReading r;
  ASSERT_EQ(rig.driver->read(r), DeviceStatus::kOk);
  EXPECT_NEAR(r.position_m.x, 0.012, kCountTolerance_m) << "the reply to the last command, not an older one";
}

TEST(FalconDriver, ClosingSendsZeroForce) {
  EmulatorOptions o = Rig::with_firmware();
  auto rig = std::make_unique<Rig>(o);
  rig->home();
  rig->tick({0, 0, 3});
  FalconEmulator& emu = rig->emu;
  rig->driver.reset();
  EXPECT_EQ(emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
}

}  // namespace
}  // namespace toonforce::falcon

namespace toonforce::falcon {
namespace {

// ---- the emulator's hardware faults (what bring-up must catch; tests of the emulator itself) ----

TEST(FalconEmulatorFaults, AReversedMotorPushesTheOtherWay) {
  EmulatorOptions healthy = Rig::with_firmware();
  EmulatorOptions reversed = healthy;
  reversed.motor_reversed = {false, true, false};
  Rig a(healthy);
  Rig b(reversed);
  a.home();
  b.home();
  // A torque on motor 2 alone (word -400): the grip force it makes is J^-T tau.
  for (Rig* r : {&a, &b}) {
    Mat3 j;
    ASSERT_TRUE(position_jacobian(FalconGeometry{}, r->emu.grip_position(), j));
    Mat3 jt;
    for (std::size_t i = 0; i < 3; ++i) {
      for (std::size_t k = 0; k < 3; ++k) jt(i, k) = j(k, i);
    }
    Mat3 jt_inv;
    ASSERT_TRUE(invert(jt, jt_inv));
    const Vec3<double> tau{0, 0.04, 0};
    const Vec3<double> f{jt_inv(0, 1) * tau.y, jt_inv(1, 1) * tau.y, jt_inv(2, 1) * tau.y};
    r->tick(falcon_force_to_scene(f));
    r->tick(falcon_force_to_scene(f));
  }
  const Vec3<double> fa = a.emu.motor_force_n();
  const Vec3<double> fb = b.emu.motor_force_n();
  EXPECT_GT(norm(fa), 0.1);
  EXPECT_NEAR(norm(fa + fb), 0.0, 1e-3 * norm(fa)) << "the same words, the opposite force";
}

TEST(FalconEmulatorFaults, ADeadEncoderNeverCounts) {
  EmulatorOptions o = Rig::with_firmware();
  o.encoder_dead = {false, false, true};
  FalconEmulator emu(o);
  const auto before = emu.encoder_counts();
  emu.set_grip_position({0.03, -0.02, 0.13});
  const auto after = emu.encoder_counts();
  EXPECT_NE(after[0], before[0]);
  EXPECT_NE(after[1], before[1]);
  EXPECT_EQ(after[2], before[2]);
}

TEST(FalconEmulatorFaults, AnAxisThatNeverHomesKeepsTheDriverNotReady) {
  EmulatorOptions o = Rig::with_firmware();
  o.axis_never_homes = {false, true, false};
  Rig rig(o);
  rig.emu.set_grip_position({0, 0, 0.178});
  for (int i = 0; i < 5; ++i) rig.tick();
  rig.emu.set_grip_position({0, 0, 0.09});
  for (int i = 0; i < 5; ++i) rig.tick();
  EXPECT_FALSE(rig.driver->homed());
  EXPECT_EQ(rig.driver->last_status().homed_mask(), kHomedArm1 | kHomedArm3);
  EXPECT_EQ(rig.driver->fault(), FalconFault::kNotHomed);
}

TEST(FalconEmulatorFaults, AWeightPullsTheReleasedGripDown) {
  Rig rig;
  rig.home();
  rig.emu.set_hand_spring(0.0, 0.0);
  rig.emu.hang_weight(0.2);
  const double y0 = rig.emu.grip_position().y;
  for (int i = 0; i < 50; ++i) rig.tick();
  EXPECT_LT(rig.emu.grip_position().y, y0 - 0.002) << "falls under 1.96 N";
}

}  // namespace
}  // namespace toonforce::falcon
