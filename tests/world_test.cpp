// SPDX-License-Identifier: Apache-2.0
// Several devices in one world (control/world.hpp) and the laws between HIPs
// (effects/between.hpp): the coupling and the ball against their equations and Newton's third
// law, the device frames against the power they must preserve, the world's tick against each
// device's own loop (one device: the loop bit for bit), one stop for all and its re-arm, no
// allocation, and two simulated hands on two simulated devices feeling each other.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "servo_support.hpp"
#include "world_support.hpp"
#include "support/alloc_counter.hpp"
#include "toonforce/control/world.hpp"
#include "toonforce/effects/between.hpp"
#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/host_sim/hand_intent.hpp"
#include "toonforce/host_sim/sim_device.hpp"

namespace toonforce::test {
namespace {

using between::BallParams;
using between::BallState;
using between::CouplingParams;

// ---- the coupling -------------------------------------------------------------------------

TEST(Coupling, PullsTheHipsTogetherWithEqualAndOppositeForces) {
  const CouplingParams p{200.0, 0.0, 0.0};
  const Vec3<double> a{0.01, 0.0, 0.002};
  const Vec3<double> b{-0.01, 0.0, 0.0};
  const Vec3<double> f = between::coupling_force<double>(p, a, {}, b, {});
  EXPECT_DOUBLE_EQ(f.x, -200.0 * 0.02);  // -k (x_a - x_b)
  EXPECT_DOUBLE_EQ(f.z, -200.0 * 0.002);
  // Swapping the ends gives the negation (what b feels is -f, exactly).
  EXPECT_EQ(between::coupling_force<double>(p, b, {}, a, {}), -f);
}

TEST(Coupling, TheDamperOpposesTheRelativeVelocityOnly) {
  const CouplingParams p{0.0, 3.0, 0.0};
  // Both moving together: no relative velocity, no force.
  EXPECT_EQ(between::coupling_force<double>(p, {0.01, 0, 0}, {0.2, 0.1, 0}, {0, 0, 0}, {0.2, 0.1, 0}),
            (Vec3<double>{}));
  const Vec3<double> f = between::coupling_force<double>(p, {0.01, 0, 0}, {0.2, 0, 0}, {0, 0, 0}, {-0.1, 0, 0});
  EXPECT_DOUBLE_EQ(f.x, -3.0 * 0.3);
}

TEST(Coupling, AtItsRestLengthTheSpringGivesNothingAndPushesApartWhenNearer) {
  const CouplingParams p{100.0, 0.0, 0.05};
  EXPECT_NEAR(norm(between::coupling_force<double>(p, {0.05, 0, 0}, {}, {0, 0, 0}, {})), 0.0, 1e-12);
  EXPECT_NEAR(between::coupling_force<double>(p, {0.08, 0, 0}, {}, {0, 0, 0}, {}).x, -100.0 * 0.03, 1e-12);  // pulls
  EXPECT_NEAR(between::coupling_force<double>(p, {0.02, 0, 0}, {}, {0, 0, 0}, {}).x, 100.0 * 0.03, 1e-12);   // pushes
  EXPECT_EQ(between::coupling_force<double>(p, {0, 0, 0}, {}, {0, 0, 0}, {}), (Vec3<double>{}));  // no direction
}

TEST(Coupling, RefusesWhatIsNotAPassiveSpringDamper) {
  EXPECT_STREQ(between::check(CouplingParams{}), "");
  EXPECT_STRNE(between::check(CouplingParams{-1.0, 0.0, 0.0}), "");
  EXPECT_STRNE(between::check(CouplingParams{1.0, -0.1, 0.0}), "");
  EXPECT_STRNE(between::check(CouplingParams{std::nan(""), 0.0, 0.0}), "");
  EXPECT_STRNE(between::check(CouplingParams{1.0, 0.0, -0.01}), "");
}

// ---- the ball -----------------------------------------------------------------------------

BallParams free_ball() {
  BallParams p;
  p.radius_m = 0.02;
  p.mass_kg = 0.1;
  p.stiffness_n_per_m = 800.0;
  p.damping_n_s_per_m = 0.0;
  p.drag_n_s_per_m = 0.0;
  p.gravity_m_per_s2 = {};  // weightless: the bounce keeps its speed
  return p;
}

TEST(Ball, AHipOutsideFeelsNothingAndOneInsideIsPushedOutAlongTheNormal) {
  const BallParams p = free_ball();
  const BallState ball{{0, 0, 0}, {}, false};
  EXPECT_EQ(between::ball_force_on_hip(p, ball, {0.03, 0, 0}, {}), (Vec3<double>{}));
  EXPECT_EQ(between::ball_force_on_hip(p, ball, {0.02, 0, 0}, {}), (Vec3<double>{}));  // on the surface
  const Vec3<double> f = between::ball_force_on_hip(p, ball, {0.0, 0.015, 0.0}, {});
  EXPECT_NEAR(f.y, 800.0 * 0.005, 1e-12);  // k * depth, out along +y
  EXPECT_NEAR(f.x, 0.0, 1e-15);
  EXPECT_EQ(between::ball_force_on_hip(p, ball, {std::nan(""), 0, 0}, {}), (Vec3<double>{}));
}

TEST(Ball, ItsDamperActsOnlyWhileTheHipPressesIn) {
  BallParams p = free_ball();
  p.damping_n_s_per_m = 2.0;
  const BallState ball{{0, 0, 0}, {}, false};
  const Vec3<double> in = between::ball_force_on_hip(p, ball, {0.015, 0, 0}, {-0.1, 0, 0});
  EXPECT_NEAR(in.x, 800.0 * 0.005 + 2.0 * 0.1, 1e-12);
  const Vec3<double> out = between::ball_force_on_hip(p, ball, {0.015, 0, 0}, {0.1, 0, 0});
  EXPECT_NEAR(out.x, 800.0 * 0.005, 1e-12);  // leaving: the spring alone, never a pull
}

TEST(Ball, ItBouncesOffItsWallWithItsSpeedWhenNothingDamps) {
  BallParams p = free_ball();
  p.has_wall = true;
  p.wall_point_m = {0, 0, 0};
  p.wall_normal = {0, 0, 2};  // normalised by the check
  p.wall_stiffness_n_per_m = 2000.0;
  p.wall_damping_n_s_per_m = 0.0;
  ASSERT_STREQ(between::check_and_normalise(p), "");
  EXPECT_DOUBLE_EQ(p.wall_normal.z, 1.0);
  BallState ball{{0, 0, 0.03}, {0, 0, -0.2}, false};
  bool touched = false;
  for (int k = 0; k < 1000; ++k) {
    between::step_ball(p, ball, {}, 1e-3);
    touched = touched || ball.touched_wall;
  }
  EXPECT_TRUE(touched);
  EXPECT_GT(ball.velocity_m_per_s.z, 0.0);  // going back up
  // Symplectic Euler on a spring contact: the rebound speed within 1 % of the approach.
  EXPECT_NEAR(ball.velocity_m_per_s.z, 0.2, 0.002);

  p.wall_damping_n_s_per_m = 5.0;  // a damped wall loses energy
  BallState damped{{0, 0, 0.03}, {0, 0, -0.2}, false};
  for (int k = 0; k < 1000; ++k) between::step_ball(p, damped, {}, 1e-3);
  EXPECT_LT(damped.velocity_m_per_s.z, 0.19);
  EXPECT_GT(damped.velocity_m_per_s.z, 0.0);
}

TEST(Ball, RefusesWhatCannotMove) {
  BallParams p = free_ball();
  EXPECT_STREQ(between::check_and_normalise(p), "");
  p.mass_kg = 0.0;
  EXPECT_STRNE(between::check_and_normalise(p), "");
  p = free_ball();
  p.has_wall = true;
  p.wall_normal = {};
  EXPECT_STRNE(between::check_and_normalise(p), "");
}

// ---- device frames ------------------------------------------------------------------------

TEST(DeviceFrame, APowerIsTheSameInTheDevicesFrameAndTheWorlds) {
  DeviceFrame f = DeviceFrame::yaw(0.7, {0.1, -0.2, 0.05}, 1.7);
  ASSERT_EQ(check(f), "");
  const Vec3<double> v_device{0.3, -0.1, 0.25};
  const Vec3<double> f_world{1.5, 2.0, -0.5};
  const double world_power = dot(f_world, f.velocity_to_world(v_device));
  const double device_power = dot(f.force_to_device(f_world), v_device);
  EXPECT_NEAR(world_power, device_power, 1e-12);
  // A position maps with the same scale and rotation, plus the offset.
  const Vec3<double> x = f.position_to_world(Vec3<double>{0.0, 0.0, 0.0});
  EXPECT_EQ(x, (Vec3<double>{0.1, -0.2, 0.05}));
  // Half a turn: the device's +x is the world's -x.
  const DeviceFrame facing = DeviceFrame::yaw(std::numbers::pi);
  EXPECT_NEAR(facing.position_to_world(Vec3<double>{0.01, 0, 0}).x, -0.01, 1e-15);
}

TEST(DeviceFrame, RefusesShearMirrorsAndAScaleThatIsNotPositive) {
  DeviceFrame f;
  EXPECT_EQ(check(f), "");
  EXPECT_TRUE(f.identity());
  f.rotation[0] = {1.0, 0.1, 0.0};
  EXPECT_NE(check(f), "");
  f = DeviceFrame{};
  f.rotation[2] = {0.0, 0.0, -1.0};  // a mirror
  EXPECT_NE(check(f).find("mirror"), std::string::npos);
  f = DeviceFrame{};
  f.scale = 0.0;
  EXPECT_NE(check(f), "");
  f.scale = std::nan("");
  EXPECT_NE(check(f), "");
}

// ---- the world on fake devices ------------------------------------------------------------

using FakeWorld2 = World<FakeDevice, RuntimeScene<double>, 2>;

/// A scene whose one surface is a metre below: only the world's forces act.
std::string empty_toml() {
  return "[[surface]]\npoint = [0.0, 0.0, -1.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 1.0\n";
}

WorldConfig coupled(double k, double b = 0.0, StopPolicy stop = StopPolicy::kAll) {
  WorldConfig c;
  c.stop = stop;
  c.coupling_count = 1;
  c.couplings[0] = {0, 1, {k, b, 0.0}};
  return c;
}

// The devices live in the rig; FakeDevice holds a pointer to its state.
std::unique_ptr<FakeWorld2> make_world(std::array<FakeDeviceState, 2>& dev, std::array<FakeDevice, 2>& fakes,
                                       WorldConfig config, const std::string& toml = empty_toml(),
                                       std::array<DeviceFrame, 2> frames = {}, ServoConfig c = bare_config()) {
  EXPECT_EQ(check(config, 2), "");
  fakes = {FakeDevice{&dev[0]}, FakeDevice{&dev[1]}};
  return std::make_unique<FakeWorld2>(
      std::array<FakeWorld2::Member, 2>{FakeWorld2::Member{&fakes[0], scene_from<double>(toml), frames[0], c},
                                        FakeWorld2::Member{&fakes[1], scene_from<double>(toml), frames[1], c}},
      config);
}

TEST(World, ACouplingsForcesAreEqualAndOppositeAtEveryTickAndReachBothDevices) {
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{nullptr}, FakeDevice{nullptr}};
  auto world = make_world(dev, fakes, coupled(150.0, 1.0));
  for (std::int64_t k = 0; k < 400; ++k) {
    // The hands move apart and back (engaging first: 0.2 N at most, so they start together).
    const double s = 0.02 * std::sin(static_cast<double>(k) * 0.01);
    dev[0].position_m = {s, 0.001, 0.0};
    dev[1].position_m = {-s, 0.0, 0.0};
    const WorldStatus<2> status = world->tick(k);
    ASSERT_FALSE(status.held);
    EXPECT_EQ(world->world_force_n(0), -world->world_force_n(1)) << k;  // exactly, every tick
    EXPECT_EQ(world->coupling_force_n(0), world->world_force_n(0));
    if (k > 10) {
      // What each device was written is its share, after its own safety chain (clamp 8 N).
      EXPECT_NEAR(dev[0].last_written.x, world->world_force_n(0).x, 1e-9) << k;
      EXPECT_NEAR(dev[1].last_written.x, world->world_force_n(1).x, 1e-9) << k;
    }
  }
  // Apart by 2 s sin(4): the spring pulls them together.
  EXPECT_LT(dev[0].last_written.x * dev[0].position_m.x, 0.0);
}

TEST(World, EachDevicesOwnClampLimitsItsShareOfACouplingForce) {
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{nullptr}, FakeDevice{nullptr}};
  auto world = make_world(dev, fakes, coupled(1000.0));
  dev[0].position_m = dev[1].position_m = {};
  world->tick(0);                    // engage with the hands together
  dev[0].position_m = {0.02, 0, 0};  // 20 N asked of each
  world->tick(1);
  EXPECT_DOUBLE_EQ(world->world_force_n(0).x, -20.0);
  EXPECT_NEAR(dev[0].last_written.x, -8.0, 1e-12);  // bare_config's clamp
  EXPECT_NEAR(dev[1].last_written.x, 8.0, 1e-12);
}

TEST(World, TheWorldsForceIsTurnedIntoEachDevicesFrame) {
  // Device 1 faces device 0 (half a turn about z, 0.1 m away): the same world coupling force
  // along world -x on device 0 is along +x of device 1's own axes... and its HIP at its own
  // +x is the world's -x.
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{nullptr}, FakeDevice{nullptr}};
  const std::array<DeviceFrame, 2> frames{DeviceFrame{}, DeviceFrame::yaw(std::numbers::pi, {0.1, 0, 0})};
  auto world = make_world(dev, fakes, coupled(100.0), empty_toml(), frames);
  dev[0].position_m = {0.05, 0, 0};
  dev[1].position_m = {0.05, 0, 0};  // world: 0.1 - 0.05 = 0.05, the same point
  world->tick(0);
  EXPECT_NEAR(world->hip_m(1).x, 0.05, 1e-15);
  dev[0].position_m = {0.04, 0, 0};  // device 0 moves 1 cm toward the world's origin
  world->tick(1);
  EXPECT_NEAR(world->world_force_n(0).x, 1.0, 1e-12);   // pulled back toward device 1's HIP
  EXPECT_NEAR(world->world_force_n(1).x, -1.0, 1e-12);  // device 1 pulled toward world -x ...
  EXPECT_NEAR(dev[1].last_written.x, 1.0, 1e-12);       // ... which is its own +x
  EXPECT_NEAR(dev[0].last_written.x, 1.0, 1e-12);
}

TEST(World, TheScenesEffectsActInTheWorldFrame) {
  // A floor at world z = 0; device 1's origin sits 5 cm above it: at its own z = -0.052 it is
  // 2 mm in the floor, device 0 at the same reading is 52 mm in (clamped).
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{nullptr}, FakeDevice{nullptr}};
  DeviceFrame lifted;
  lifted.offset_m = {0, 0, 0.05};
  WorldConfig none;
  auto world = make_world(dev, fakes, none, floor_toml(1000.0), {DeviceFrame{}, lifted});
  dev[0].position_m = {0, 0, 0.01};
  dev[1].position_m = {0, 0, -0.04};
  world->tick(0);
  dev[0].position_m = {0, 0, -0.052};
  dev[1].position_m = {0, 0, -0.052};
  world->tick(1);
  EXPECT_NEAR(dev[1].last_written.z, 2.0, 1e-9);
  EXPECT_NEAR(dev[0].last_written.z, 8.0, 1e-9);
}

TEST(World, OneDevicesLatchedFaultHoldsEveryDeviceAtZeroUntilReArmed) {
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{nullptr}, FakeDevice{nullptr}};
  auto world = make_world(dev, fakes, coupled(100.0));
  std::int64_t k = 0;
  for (; k < 50; ++k) {
    dev[0].position_m = {0.001 * static_cast<double>(k) / 50.0, 0, 0};
    world->tick(k);
  }
  dev[0].position_m = {0.02, 0, 0};
  world->tick(k++);
  ASSERT_NEAR(dev[0].last_written.x, -2.0, 1e-9);
  ASSERT_NEAR(dev[1].last_written.x, 2.0, 1e-9);
  // Device 1 stops answering: its reads fail until its supervisor latches kDeviceSilent (10 in
  // a row); the tick after, device 0 is held too and both stay at zero.
  dev[1].read_status = DeviceStatus::kTimeout;
  std::int64_t silent_at = -1;
  for (int i = 0; i < 30; ++i, ++k) {
    const WorldStatus<2> s = world->tick(k);
    if (s.held && silent_at < 0) {
      silent_at = k;
      EXPECT_EQ(s.held_by, 1U);
      EXPECT_TRUE(world->loop(1).latched().has(Fault::kDeviceSilent));
    }
    if (silent_at >= 0 && k > silent_at) {
      EXPECT_EQ(dev[0].last_written, (Vec3<double>{})) << k;
      EXPECT_TRUE(world->loop(0).latched().has(Fault::kEstop));
      EXPECT_EQ(s.devices[0].state, LoopState::kFaulted);
    }
  }
  ASSERT_GE(silent_at, 0) << "the silent device never latched";
  // A re-arm while device 1 is still silent: it latches again and holds again.
  world->request_rearm();
  WorldStatus<2> s = world->tick(k++);
  EXPECT_TRUE(s.held);
  EXPECT_EQ(s.held_by, 1U);
  s = world->tick(k++);
  EXPECT_EQ(dev[0].last_written, (Vec3<double>{}));
  // Device 1 answers again and the world is re-armed: both come back (engaging first).
  dev[1].read_status = DeviceStatus::kOk;
  dev[0].position_m = dev[1].position_m = {};
  world->request_rearm();
  s = world->tick(k++);
  EXPECT_FALSE(s.held);
  dev[0].position_m = {0.02, 0, 0};
  for (int i = 0; i < 3; ++i) s = world->tick(k++);
  EXPECT_FALSE(s.held);
  EXPECT_NEAR(dev[0].last_written.x, -2.0, 1e-9);
  EXPECT_NEAR(dev[1].last_written.x, 2.0, 1e-9);
}

TEST(World, IndependentStationsStopEachOnItsOwn) {
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{nullptr}, FakeDevice{nullptr}};
  WorldConfig each;
  each.stop = StopPolicy::kEach;
  auto world = make_world(dev, fakes, each, floor_toml(1000.0));
  dev[0].position_m = dev[1].position_m = {0, 0, 0.01};
  std::int64_t k = 0;
  world->tick(k++);
  dev[0].position_m = {0, 0, -0.002};
  dev[1].read_status = DeviceStatus::kDisconnected;
  for (int i = 0; i < 30; ++i) {
    const WorldStatus<2> s = world->tick(k++);
    EXPECT_FALSE(s.held);
  }
  EXPECT_TRUE(world->loop(1).latched().has(Fault::kDeviceSilent));
  EXPECT_NEAR(dev[0].last_written.z, 2.0, 1e-9);  // device 0's floor is still felt
}

TEST(World, WithOneDeviceItIsThatDevicesLoopBitForBit) {
  // The same scene, configuration and motion through a one-device world (identity frame,
  // nothing between HIPs) and through the plain loop: the same forces, every tick, to the bit.
  ServoConfig c = bare_config();
  c.safety.soft_start_s = 0.2;
  c.safety.has_max_velocity = true;
  c.limits.has_max_force_rate = true;
  c.limits.max_force_rate_n_per_s = 2000.0;
  const std::string toml = floor_toml(900.0);
  FakeDeviceState a{};
  FakeDeviceState b{};
  FakeDevice fake_a{&a};
  using World1 = World<FakeDevice, RuntimeScene<double>, 1>;
  World1 world(std::array<World1::Member, 1>{World1::Member{&fake_a, scene_from<double>(toml), DeviceFrame{}, c}},
               WorldConfig{});
  ServoLoop<FakeDevice, RuntimeScene<double>> loop(FakeDevice{&b}, scene_from<double>(toml), c);
  int differing = 0;
  int pushed = 0;
  for (std::int64_t k = 0; k < 3000; ++k) {
    const Vec3<double> x{0.01 * std::sin(static_cast<double>(k) * 0.003), 0.0,
                         0.004 * std::sin(static_cast<double>(k) * 0.011) - 0.001};
    a.position_m = b.position_m = x;
    world.tick(k);
    loop.tick(k);
    if (a.last_written != b.last_written) ++differing;
    if (b.last_written.z > 0.1) ++pushed;
  }
  EXPECT_EQ(differing, 0);
  EXPECT_GT(pushed, 500);  // the floor did push: the comparison is not of zeros
}

TEST(World, AHipBackFromTicksWithoutAPositionGivesTheDamperNoKick) {
  // A damper-only coupling; device 1 moves steadily at 0.1 m/s, device 0 stands still. Device
  // 1's reads fail for 5 ticks (not enough to latch it silent): when it answers again, the
  // velocity starts afresh instead of 6 ticks of motion taken as one tick's.
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{nullptr}, FakeDevice{nullptr}};
  WorldConfig c;
  c.coupling_count = 1;
  c.couplings[0] = {0, 1, {0.0, 10.0, 0.0}};
  auto world = make_world(dev, fakes, c);
  double steady = 0.0;
  double after = 0.0;
  for (std::int64_t k = 0; k < 400; ++k) {
    dev[1].position_m = {1e-4 * static_cast<double>(k), 0.0, 0.0};  // 0.1 m/s at 1 kHz
    dev[1].read_status = k >= 300 && k < 305 ? DeviceStatus::kTimeout : DeviceStatus::kOk;
    world->tick(k);
    if (k == 299) steady = std::abs(world->coupling_force_n(0).x);
    if (k >= 305) after = std::max(after, std::abs(world->coupling_force_n(0).x));
  }
  EXPECT_NEAR(steady, 10.0 * 0.1, 1e-3);  // b |v_rel|, the estimate settled
  EXPECT_LE(after, steady * 1.001);
}

TEST(World, AHandleWhoseForceIsCutLeavesTheCouplingAndComesBackRamped) {
  // Device 0 leaves its workspace: its own loop cuts its force, and from the next tick the
  // coupling lets device 1 go too (it was pulled at its 8 N clamp toward the lost handle).
  // Back inside, the coupling comes back over the soft start (0.1 s), not as a step.
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{nullptr}, FakeDevice{nullptr}};
  ServoConfig c = bare_config();
  c.safety.has_workspace = true;
  c.safety.workspace_min_m = {-0.05, -0.05, -0.05};
  c.safety.workspace_max_m = {0.05, 0.05, 0.05};
  c.safety.soft_start_s = 0.1;
  auto world = make_world(dev, fakes, coupled(200.0), empty_toml(), {}, c);
  std::int64_t k = 0;
  for (; k < 200; ++k) world->tick(k);  // together at the origin: engaged, soft start done
  dev[0].position_m = {0.02, 0.0, 0.0};
  for (int i = 0; i < 5; ++i) world->tick(k++);
  ASSERT_NEAR(dev[1].last_written.x, 4.0, 1e-9);  // 200 N/m x 2 cm, toward device 0
  dev[0].position_m = {0.06, 0.0, 0.0};           // out of its workspace
  world->tick(k++);
  EXPECT_TRUE(world->loop(0).last_status().faults.has(Fault::kOutsideWorkspace));
  EXPECT_EQ(dev[0].last_written, (Vec3<double>{}));
  for (int i = 0; i < 20; ++i) {
    world->tick(k++);
    EXPECT_EQ(dev[1].last_written, (Vec3<double>{})) << "device 1 pulled toward a handle whose force is off";
    EXPECT_EQ(world->world_force_n(0), (Vec3<double>{}));
  }
  EXPECT_FALSE(world->held());           // not a latched fault: no one stop
  dev[0].position_m = {0.02, 0.0, 0.0};  // back inside
  world->tick(k++);                      // device 0's loop counts this tick: the coupling comes back the next
  double previous = 0.0;
  for (int i = 0; i < 100; ++i) {
    world->tick(k++);
    const double f = dev[1].last_written.x;
    EXPECT_LE(f, previous + 4.0 * 0.01 + 1e-9) << i;  // at most 1/100 of the force a tick
    previous = f;
  }
  EXPECT_NEAR(dev[1].last_written.x, 4.0, 1e-9);
  EXPECT_EQ(world->world_force_n(0), -world->world_force_n(1));
}

TEST(World, ATickAllocatesNothing) {
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{nullptr}, FakeDevice{nullptr}};
  WorldConfig c = coupled(100.0, 1.0);
  c.has_ball = true;
  c.ball = free_ball();
  auto world = make_world(dev, fakes, c, floor_toml(500.0));
  AllocationScope scope;
  for (std::int64_t k = 0; k < 5000; ++k) {
    dev[0].position_m = {0.03 * std::sin(static_cast<double>(k) * 0.002), 0, 0.002};
    dev[1].position_m = {-0.01, 0.0, 0.003 * std::sin(static_cast<double>(k) * 0.01)};
    dev[1].read_status = k % 997 == 0 ? DeviceStatus::kTimeout : DeviceStatus::kOk;
    world->tick(k);
  }
  EXPECT_EQ(scope.count(), 0U);
}

// ---- two simulated hands on two simulated devices -----------------------------------------

ServoConfig sim_config() {
  ServoConfig c = bare_config();
  c.safety.soft_start_s = 0.1;
  return c;
}

TEST(WorldOnSimulatedDevices, TwoHandsMovingApartFeelEachOtherPullAndEachPortStaysPassive) {
  // The hands start together (engaging needs the scene's force under 0.2 N) and move apart,
  // to hold their handles 15 mm from each other. A 200 N/m coupling against the hands' own
  // 200 N/m holds the handles about 5 mm apart: each is pulled 2.5 mm toward the other.
  std::array<host_sim::SimDevice, 2> devices{sim_device({0.0002, 0, 0}, {0.0075, 0, 0}),
                                             sim_device({-0.0002, 0, 0}, {-0.0075, 0, 0})};
  WorldConfig config = coupled(200.0, 1.0);
  ASSERT_EQ(check(config, 2), "");
  SimWorld2 world(
      std::array<SimWorld2::Member, 2>{
          SimWorld2::Member{&devices[0], scene_from<double>(empty_toml()), DeviceFrame{}, sim_config()},
          SimWorld2::Member{&devices[1], scene_from<double>(empty_toml()), DeviceFrame{}, sim_config()}},
      config);
  double least_energy_j = 0.0;
  for (std::int64_t k = 0; k < 3000; ++k) {
    const WorldStatus<2> s = world.tick(k);
    ASSERT_FALSE(s.held) << k;
    ASSERT_EQ(world.world_force_n(0), -world.world_force_n(1)) << k;
    for (std::size_t i = 0; i < 2; ++i) {
      least_energy_j = std::min(least_energy_j, world.loop(i).passivity().observer().energy().to_double());
    }
  }
  // Pulled together: the handles sit nearer than the hands hold them (15 mm), and each device
  // applies a force toward the other.
  const double gap = devices[0].plant().position_m().x - devices[1].plant().position_m().x;
  EXPECT_NEAR(gap, 0.005, 0.0005);
  EXPECT_NEAR(devices[0].applied_force_n().x, -1.0, 0.1);  // k (gap): toward the other
  EXPECT_NEAR(devices[1].applied_force_n().x, 1.0, 0.1);
  // At each device's port the observer's energy (>= 0: passive so far) never shows the coupling
  // giving out more than it took: a passive spring-damper, sampled at 1 kHz.
  EXPECT_GE(least_energy_j, -1e-5);
}

TEST(WorldOnSimulatedDevices, TwoHandsPressTheBallIntoTheFloorAndEachFeelsItPushBack) {
  // A ball (2 cm, 0.1 kg) resting on a floor at z = 0; two hands come down on it from above,
  // one each side of its top, and press. Each feels the ball push up and out (away from the
  // other); the floor holds the ball; by symmetry the ball does not slide sideways.
  WorldConfig config;
  config.has_ball = true;
  config.ball.radius_m = 0.02;
  config.ball.mass_kg = 0.1;
  config.ball.stiffness_n_per_m = 800.0;
  config.ball.damping_n_s_per_m = 1.0;
  config.ball.drag_n_s_per_m = 0.5;
  config.ball.start_m = {0.0, 0.0, 0.02};
  config.ball.has_wall = true;
  config.ball.wall_point_m = {0.0, 0.0, 0.0};
  config.ball.wall_normal = {0.0, 0.0, 1.0};
  ASSERT_EQ(check(config, 2), "");
  std::array<host_sim::SimDevice, 2> devices{sim_device({0.01, 0, 0.06}, {0.01, 0, 0.03}),
                                             sim_device({-0.01, 0, 0.06}, {-0.01, 0, 0.03})};
  SimWorld2 world(
      std::array<SimWorld2::Member, 2>{
          SimWorld2::Member{&devices[0], scene_from<double>(empty_toml()), DeviceFrame{}, sim_config()},
          SimWorld2::Member{&devices[1], scene_from<double>(empty_toml()), DeviceFrame{}, sim_config()}},
      config);
  bool touched_floor = false;
  Vec3<double> momentum_change{};  // what the HIPs gave the ball, summed (impulse)
  for (std::int64_t k = 0; k < 2000; ++k) {
    ASSERT_FALSE(world.tick(k).held) << k;
    touched_floor = touched_floor || world.ball().touched_wall;
    momentum_change -= (world.world_force_n(0) + world.world_force_n(1)) * 1e-3;
  }
  const Vec3<double> f0 = devices[0].applied_force_n();
  const Vec3<double> f1 = devices[1].applied_force_n();
  EXPECT_GT(f0.z, 0.3);
  EXPECT_GT(f1.z, 0.3);
  EXPECT_GT(f0.x, 0.1);  // device 0, on the +x side, is pushed further out to +x
  EXPECT_LT(f1.x, -0.1);
  EXPECT_NEAR(f0.x, -f1.x, 0.05);
  EXPECT_TRUE(touched_floor);
  EXPECT_NEAR(world.ball().position_m.x, 0.0, 1e-4);
  EXPECT_GT(world.ball().position_m.z, 0.015);  // pressed into the floor a little, not through it
  EXPECT_LT(world.ball().position_m.z, 0.02);
  // The HIPs pushed the ball down, and the ball, held by the floor, is at rest.
  EXPECT_LT(momentum_change.z, 0.0);
  EXPECT_NEAR(norm(world.ball().velocity_m_per_s), 0.0, 1e-3);
}

}  // namespace
}  // namespace toonforce::test
