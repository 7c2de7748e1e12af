// SPDX-License-Identifier: Apache-2.0
// The shared ball's cartoon effects (effects/between.hpp, control/world.hpp): the slippery
// surface and the impact transient of spec effects.md §3-4 on a sphere that moves, against
// their laws with the HIP's velocity relative to the ball's; Newton's third law and the
// momentum of ball and HIPs; the passivity stage at a device's port against the single-device
// slippery surface's; a simulated hand striking the ball and feeling the recoil.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "servo_support.hpp"
#include "world_support.hpp"
#include "toonforce/control/world.hpp"
#include "toonforce/effects/between.hpp"
#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/host_sim/hand_intent.hpp"
#include "toonforce/host_sim/sim_device.hpp"

namespace toonforce::test {
namespace {

using between::BallHipForce;
using between::BallHipState;
using between::BallParams;
using between::BallState;

constexpr double kT = 1e-3;  // [s] the tick period of these tests

BallParams weightless_ball() {
  BallParams p;
  p.radius_m = 0.02;
  p.mass_kg = 0.1;
  p.stiffness_n_per_m = 800.0;
  p.damping_n_s_per_m = 1.0;
  p.drag_n_s_per_m = 0.0;
  p.gravity_m_per_s2 = {};
  return p;
}

BallParams slippery_ball(double mu, double max_n) {
  BallParams p = weightless_ball();
  p.has_slippery = true;
  p.slippery.mu_n_s_per_m = mu;
  p.slippery.max_tangential_force_n = max_n;
  return p;
}

BallParams impact_ball() {
  BallParams p = weightless_ball();
  p.has_impact = true;
  p.impact.recoil_gain_n_per_m = 300.0;
  p.impact.oscillation_gain_n_per_m = 500.0;
  p.impact.duration_s = 0.05;
  p.impact.frequency_hz = 7.0;
  p.impact.min_impact_speed_m_per_s = 0.05;
  p.impact.rearm_distance_m = 0.001;
  p.impact.sine = SineMethod::kLibrary;
  return p;
}

BallHipForce at(const BallParams& p, const BallState& ball, BallHipState& s, const Vec3<double>& x,
                const Vec3<double>& v, std::int64_t k) {
  return between::ball_force_on_hip(p, ball, s, x, v, Instant{k, 0}, kT);
}

// ---- the laws on the ball -----------------------------------------------------------------

TEST(BallEffects, WithBothOffTheForceIsThePlainBallsBitForBit) {
  BallParams p = weightless_ball();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.03, 0.03);
  BallHipState s;
  for (int i = 0; i < 2000; ++i) {
    const BallState ball{{u(rng), u(rng), u(rng)}, {10 * u(rng), 10 * u(rng), 10 * u(rng)}, false};
    const Vec3<double> x{u(rng), u(rng), u(rng)};
    const Vec3<double> v{10 * u(rng), 10 * u(rng), 10 * u(rng)};
    const BallHipForce h = at(p, ball, s, x, v, i);
    ASSERT_EQ(h.force_n, between::ball_force_on_hip(p, ball, x, v)) << i;
    ASSERT_EQ(h.slippery_n, (Vec3<double>{})) << i;
    ASSERT_EQ(h.impact_n, (Vec3<double>{})) << i;
  }
}

TEST(BallEffects, TheSlipperyForceIsMuTimesTheTangentialRelativeVelocity) {
  const double mu = 4.0;
  const BallParams p = slippery_ball(mu, 100.0);  // a cap it does not reach
  // The ball moves; the HIP, inside, moves too: what counts is the difference, across n.
  const BallState ball{{0.01, -0.02, 0.005}, {0.05, 0.1, -0.02}, false};
  const Vec3<double> dir = Vec3<double>{1.0, 2.0, -0.5} * (1.0 / std::sqrt(5.25));
  const Vec3<double> x = ball.position_m + dir * (p.radius_m - 0.003);
  const Vec3<double> v_hip{0.3, -0.1, 0.2};
  BallHipState s;
  const BallHipForce h = at(p, ball, s, x, v_hip, 0);
  const Vec3<double> v = v_hip - ball.velocity_m_per_s;
  const Vec3<double> v_t = v - dir * dot(v, dir);
  const Vec3<double> want = v_t * mu;
  EXPECT_TRUE(h.in_contact);
  EXPECT_NEAR(h.slippery_n.x, want.x, 1e-12);
  EXPECT_NEAR(h.slippery_n.y, want.y, 1e-12);
  EXPECT_NEAR(h.slippery_n.z, want.z, 1e-12);
  EXPECT_NEAR(dot(h.slippery_n, dir), 0.0, 1e-12);  // along the surface only
  // The rest is the plain ball's spring and damper, unchanged.
  EXPECT_EQ(h.force_n, between::ball_force_on_hip(p, ball, x, v_hip) + h.slippery_n);
  // Moving with the ball: no relative velocity, no slippery force.
  EXPECT_EQ(at(p, ball, s, x, ball.velocity_m_per_s, 1).slippery_n, (Vec3<double>{}));
  // Outside the ball: nothing at all.
  const BallHipForce out = at(p, ball, s, ball.position_m + dir * (p.radius_m + 0.001), v_hip, 2);
  EXPECT_FALSE(out.in_contact);
  EXPECT_EQ(out.force_n, (Vec3<double>{}));
}

TEST(BallEffects, TheSlipperyForceIsCappedWithItsDirectionKept) {
  const double mu = 4.0;
  const double cap = 2.0;
  const BallParams p = slippery_ball(mu, cap);
  const BallState ball{{0, 0, 0}, {0.0, -0.4, 0.0}, false};
  const Vec3<double> x{0.0, 0.0, p.radius_m - 0.002};  // n = +z
  const Vec3<double> v_hip{0.5, 0.3, -0.05};
  BallHipState s;
  const BallHipForce h = at(p, ball, s, x, v_hip, 0);
  const Vec3<double> v_t{0.5, 0.7, 0.0};  // relative, across +z
  ASSERT_GT(mu * norm(v_t), cap);         // the law alone would exceed the cap
  EXPECT_NEAR(norm(h.slippery_n), cap, 1e-12);
  const Vec3<double>& f = h.slippery_n;
  EXPECT_NEAR(f.x * v_t.y - f.y * v_t.x, 0.0, 1e-12);  // parallel to v_t (and in the plane) ...
  EXPECT_EQ(f.z, 0.0);
  EXPECT_GT(dot(h.slippery_n, v_t), 0.0);  // ... and along it
}

TEST(BallEffects, TheImpactFollowsTheLawAtItsStartHalfwayAndEndsAfterItsDuration) {
  const BallParams p = impact_ball();
  const auto& i = p.impact;
  const double r = p.radius_m;
  // The ball comes at the HIP at 0.1 m/s while the HIP comes at the ball at 0.2 m/s.
  const BallState ball{{0, 0, 0}, {0.1, 0, 0}, false};
  const Vec3<double> v_hip{-0.2, 0, 0};
  BallHipState s;
  EXPECT_FALSE(at(p, ball, s, {r + 0.002, 0, 0}, v_hip, 10).impact_triggered);  // outside
  const BallHipForce first = at(p, ball, s, {r - 0.0005, 0, 0}, v_hip, 11);     // enters: t = 0
  ASSERT_TRUE(first.impact_triggered);
  const double v_i = 0.3;  // closing speed, HIP relative to the ball
  EXPECT_DOUBLE_EQ(s.impact.impact_speed_m_per_s, v_i);
  EXPECT_NEAR(first.impact_n.x, v_i * i.duration_s * i.recoil_gain_n_per_m, 1e-12);  // sin 0 = 0
  EXPECT_EQ(first.impact_n.y, 0.0);
  EXPECT_EQ(first.force_n, between::ball_force_on_hip(p, ball, {r - 0.0005, 0, 0}, v_hip) + first.impact_n);

  // Halfway (d / 2 = 25 ticks later), wherever the HIP is: along +n as the HIP is now (+y).
  const auto half_ticks = static_cast<std::int64_t>(std::lround(i.duration_s / 2 / kT));
  const double t = static_cast<double>(half_ticks) * kT;
  const double omega = 2.0 * std::numbers::pi * i.frequency_hz;
  const BallHipForce half = at(p, ball, s, {0, r + 0.01, 0}, {}, 11 + half_ticks);
  EXPECT_TRUE(half.impact_running);
  const double want =
      v_i * (i.duration_s - t) * (i.recoil_gain_n_per_m + i.oscillation_gain_n_per_m * std::sin(omega * t));
  EXPECT_NEAR(half.impact_n.y, want, 1e-9);
  EXPECT_EQ(half.impact_n.x, 0.0);
  EXPECT_EQ(half.force_n, half.impact_n);  // outside: the transient alone (paper, figure 3)

  // At t = d the law is zero; after it the transient is over.
  const auto d_ticks = static_cast<std::int64_t>(std::lround(i.duration_s / kT));
  EXPECT_NEAR(norm(at(p, ball, s, {0, r + 0.01, 0}, {}, 11 + d_ticks).impact_n), 0.0, 1e-12);
  const BallHipForce after = at(p, ball, s, {0, r + 0.01, 0}, {}, 12 + d_ticks);
  EXPECT_FALSE(after.impact_running);
  EXPECT_EQ(after.force_n, (Vec3<double>{}));
}

TEST(BallEffects, TheImpactReArmsOnlyOnceTheHipIsOutByTheRearmDistance) {
  const BallParams p = impact_ball();
  const double r = p.radius_m;
  const double rearm = p.impact.rearm_distance_m;
  const BallState ball{{0, 0, 0}, {}, false};
  const Vec3<double> in{r - 0.0005, 0, 0};
  const Vec3<double> closing{-0.2, 0, 0};
  BallHipState s;
  std::int64_t k = 0;
  at(p, ball, s, {r + 0.002, 0, 0}, closing, k++);
  ASSERT_TRUE(at(p, ball, s, in, closing, k++).impact_triggered);
  // Out, but not by the re-arm distance: a new entry does not trigger.
  at(p, ball, s, {r + 0.5 * rearm, 0, 0}, {}, k++);
  EXPECT_FALSE(at(p, ball, s, in, closing, k++).impact_triggered);
  EXPECT_FALSE(s.impact.armed);
  // Out by the re-arm distance: armed; a slow entry neither triggers nor disarms.
  at(p, ball, s, {r + 1.5 * rearm, 0, 0}, {}, k++);
  EXPECT_TRUE(s.impact.armed);
  const Vec3<double> slow{-0.5 * p.impact.min_impact_speed_m_per_s, 0, 0};
  EXPECT_FALSE(at(p, ball, s, in, slow, k++).impact_triggered);
  EXPECT_TRUE(s.impact.armed);
  // Out and in fast: a retrigger restarts the transient with the new v_i, t = 0.
  at(p, ball, s, {r + 0.002, 0, 0}, {}, k++);
  const BallHipForce again = at(p, ball, s, in, closing * 2.0, k);
  EXPECT_TRUE(again.impact_triggered);
  EXPECT_EQ(s.impact.trigger.tick, k);
  EXPECT_NEAR(again.impact_n.x, 0.4 * p.impact.duration_s * p.impact.recoil_gain_n_per_m, 1e-12);
}

TEST(BallEffects, TheBallFeelsTheExactNegationAndMomentumIsConserved) {
  // Two HIPs sweep through a free, weightless ball with both effects on; what the HIPs get
  // (their impulse) and the ball's momentum sum to what the ball had.
  BallParams p = slippery_ball(3.0, 2.0);
  const BallParams with_impact = impact_ball();
  p.has_impact = true;
  p.impact = with_impact.impact;
  p.damping_n_s_per_m = 2.0;
  ASSERT_STREQ(between::check_and_normalise(p), "");
  BallState ball{{0, 0, 0}, {0.02, 0, 0}, false};
  std::array<BallHipState, 2> s{};
  const Vec3<double> p0 = ball.velocity_m_per_s * p.mass_kg;
  Vec3<double> hips_impulse{};
  bool slipped = false;
  bool struck = false;
  for (std::int64_t k = 0; k < 1500; ++k) {
    const double t = static_cast<double>(k) * kT;
    const Vec3<double> a{0.03 - 0.1 * t, 0.005, 0.003 * std::sin(9.0 * t)};
    const Vec3<double> va{-0.1, 0.0, 0.027 * std::cos(9.0 * t)};
    const Vec3<double> b{-0.03 + 0.05 * t, -0.004 + 0.01 * t, 0.0};
    const Vec3<double> vb{0.05, 0.01, 0.0};
    const BallHipForce fa = between::ball_force_on_hip(p, ball, s[0], a, va, Instant{k, 0}, kT);
    const BallHipForce fb = between::ball_force_on_hip(p, ball, s[1], b, vb, Instant{k, 0}, kT);
    slipped = slipped || norm(fa.slippery_n) > 0.01 || norm(fb.slippery_n) > 0.01;
    struck = struck || fa.impact_triggered || fb.impact_triggered;
    between::step_ball(p, ball, -(fa.force_n + fb.force_n), kT);
    hips_impulse += (fa.force_n + fb.force_n) * kT;
    const Vec3<double> total = ball.velocity_m_per_s * p.mass_kg + hips_impulse;
    ASSERT_NEAR(total.x, p0.x, 1e-12) << k;
    ASSERT_NEAR(total.y, p0.y, 1e-12) << k;
    ASSERT_NEAR(total.z, p0.z, 1e-12) << k;
  }
  EXPECT_TRUE(slipped);
  EXPECT_TRUE(struck);
}

TEST(BallEffects, TheirParametersAreCheckedWhenOn) {
  BallParams p = slippery_ball(0.0, 2.0);
  EXPECT_STRNE(between::check_and_normalise(p), "");  // mu is required, > 0
  p.has_slippery = false;
  EXPECT_STREQ(between::check_and_normalise(p), "");  // off: not looked at
  p = impact_ball();
  EXPECT_STREQ(between::check_and_normalise(p), "");
  p.impact.duration_s = 0.0;
  EXPECT_STRNE(between::check_and_normalise(p), "");
  p = impact_ball();
  p.impact.rearm_distance_m = -0.001;
  EXPECT_STRNE(between::check_and_normalise(p), "");
}

// ---- in a world ---------------------------------------------------------------------------

std::string nothing_toml() {  // a surface a metre below: only the world's forces act
  return "[[surface]]\npoint = [0.0, 0.0, -1.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 1.0\n";
}

using FakeWorld2 = World<FakeDevice, RuntimeScene<double>, 2>;
using FakeWorld1 = World<FakeDevice, RuntimeScene<double>, 1>;

TEST(WorldBall, EachDevicesForceHasItsExactNegationOnTheBallAndMomentumIsKept) {
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{&dev[0]}, FakeDevice{&dev[1]}};
  WorldConfig c;
  c.has_ball = true;
  c.ball = slippery_ball(3.0, 2.0);
  c.ball.has_impact = true;
  c.ball.impact = impact_ball().impact;
  ASSERT_EQ(check(c, 2), "");
  FakeWorld2 world(
      std::array<FakeWorld2::Member, 2>{
          FakeWorld2::Member{&fakes[0], scene_from<double>(nothing_toml()), DeviceFrame{}, bare_config()},
          FakeWorld2::Member{&fakes[1], scene_from<double>(nothing_toml()), DeviceFrame{}, bare_config()}},
      c);
  bool slipped = false;
  bool struck = false;
  Vec3<double> before = world.ball().velocity_m_per_s * c.ball.mass_kg;
  for (std::int64_t k = 0; k < 1500; ++k) {
    const double t = static_cast<double>(k) * kT;
    dev[0].position_m = {0.035 - 0.1 * t, 0.004, 0.002 * std::sin(11.0 * t)};
    dev[1].position_m = {-0.03 + 0.03 * t, 0.006 * std::cos(5.0 * t), 0.0};
    world.tick(k);
    slipped = slipped || norm(world.ball_slippery_n(0)) > 0.01 || norm(world.ball_slippery_n(1)) > 0.01;
    struck = struck || world.ball_hip_state(0).impact.running || world.ball_hip_state(1).impact.running;
    // The ball's momentum changed by exactly what the HIPs felt, negated (nothing else acts).
    const Vec3<double> after = world.ball().velocity_m_per_s * c.ball.mass_kg;
    const Vec3<double> change = after - before + (world.ball_force_n(0) + world.ball_force_n(1)) * kT;
    ASSERT_NEAR(norm(change), 0.0, 1e-15) << k;
    before = after;
  }
  EXPECT_TRUE(slipped);
  EXPECT_TRUE(struck);
}

TEST(WorldBall, ADeviceThatLeavesTheWorldComesBackArmedWithNoTransient) {
  std::array<FakeDeviceState, 1> dev{};
  std::array<FakeDevice, 1> fakes{FakeDevice{&dev[0]}};
  WorldConfig c;
  c.has_ball = true;
  c.ball = impact_ball();
  FakeWorld1 world(std::array<FakeWorld1::Member, 1>{FakeWorld1::Member{&fakes[0], scene_from<double>(nothing_toml()),
                                                                        DeviceFrame{}, bare_config()}},
                   c);
  const double r = c.ball.radius_m;
  dev[0].has_velocity = true;
  dev[0].velocity_m_per_s = {-0.2, 0, 0};
  dev[0].position_m = {r + 0.002, 0, 0};
  world.tick(0);
  dev[0].position_m = {r - 0.0005, 0, 0};
  world.tick(1);
  ASSERT_TRUE(world.ball_hip_state(0).impact.running);
  ASSERT_FALSE(world.ball_hip_state(0).impact.armed);
  EXPECT_GT(world.ball_impact_n(0).x, 0.0);
  dev[0].read_status = DeviceStatus::kTimeout;  // out of the world for a tick
  world.tick(2);
  EXPECT_FALSE(world.ball_hip_state(0).impact.running);
  EXPECT_TRUE(world.ball_hip_state(0).impact.armed);
  EXPECT_EQ(world.ball_impact_n(0), (Vec3<double>{}));
  dev[0].read_status = DeviceStatus::kOk;  // back, still inside: no entry, so no trigger
  world.tick(3);
  EXPECT_FALSE(world.ball_hip_state(0).impact.running);
}

/// E_obs at the port of one fake device that slides its HIP 2 mm deep along a slippery
/// surface at `speed` for 1.5 s after coming in from outside, either a plane (the
/// single-device surface, a scene effect) or the world's ball (an effect between HIPs);
/// `least` gets the observer's least energy, `damped` whether the controller acted.
struct Slide {
  double energy_j;
  double least_j;
  bool damped;
  double worst_episode_j;
};
Slide slide(bool on_ball, bool controller) {
  constexpr double kDepth = 0.002;
  constexpr double kSpeed = 0.3;
  constexpr double kMu = 4.0;
  constexpr double kStiffness = 1500.0;
  std::array<FakeDeviceState, 1> dev{};
  std::array<FakeDevice, 1> fakes{FakeDevice{&dev[0]}};
  WorldConfig c;
  std::string toml = nothing_toml();
  const double radius = 0.05;
  if (on_ball) {
    c.has_ball = true;
    c.ball = slippery_ball(kMu, 2.0);
    c.ball.radius_m = radius;
    c.ball.stiffness_n_per_m = kStiffness;
    c.ball.damping_n_s_per_m = 0.0;
    c.ball.mass_kg = 1e9;  // held still, like the plane: the energy goes to the hand alone
  } else {
    toml = floor_toml(kStiffness, "  [surface.slippery]\n  mu = 4.0\n  max_tangential_force = 2.0\n");
  }
  ServoConfig config = bare_config();
  config.safety.passivity.controller = controller;
  config.safety.passivity.budget_j = 0.05;
  config.safety.passivity.max_damping_n_s_per_m = 10.0;
  FakeWorld1 world(
      std::array<FakeWorld1::Member, 1>{FakeWorld1::Member{&fakes[0], scene_from<double>(toml), DeviceFrame{}, config}},
      c);
  dev[0].has_velocity = true;
  Slide out{0.0, 0.0, false, 0.0};
  for (std::int64_t k = 0; k < 1800; ++k) {
    // 0.1 s outside, 0.1 s coming in to kDepth, then the slide.
    const double t = static_cast<double>(k) * kT;
    const double in = std::clamp((t - 0.1) / 0.1, 0.0, 1.0);
    const double depth = -0.001 + in * (kDepth + 0.001);
    const double depth_rate = t > 0.1 && t < 0.2 ? (kDepth + 0.001) / 0.1 : 0.0;
    const double s = std::max(0.0, t - 0.3) * kSpeed;  // [m] slid
    const double speed = t > 0.3 ? kSpeed : 0.0;
    if (on_ball) {  // round the ball's equator at radius - depth
      const double rho = radius - depth;
      const double theta = s / (radius - kDepth);
      dev[0].position_m = {rho * std::cos(theta), rho * std::sin(theta), 0.0};
      dev[0].velocity_m_per_s = {-speed * std::sin(theta) - depth_rate * std::cos(theta),
                                 speed * std::cos(theta) - depth_rate * std::sin(theta), 0.0};
    } else {  // along x on the floor, depth below it
      dev[0].position_m = {s, 0.0, -depth};
      dev[0].velocity_m_per_s = {speed, 0.0, -depth_rate};
    }
    const WorldStatus<1> status = world.tick(k);
    const auto& passivity = world.loop(0).passivity();
    out.least_j = std::min(out.least_j, passivity.observer().energy().to_double());
    out.damped = out.damped || has(status.devices[0].limits, Limit::kPassivity);
    out.worst_episode_j =
        std::max(out.worst_episode_j, passivity.controller().max_episode_energy(passivity.slots()).to_double());
  }
  out.energy_j = world.loop(0).passivity().observer().energy().to_double();
  return out;
}

TEST(WorldBall, ThePassivityStageAtTheDevicesPortSeesTheBallsSlipperyEnergyAsTheSurfaces) {
  // Without the controller the observer at the port records what the slippery push gave the
  // hand, mu v^2 over the slide (1.5 s at 0.3 m/s, 4 N s/m: 0.54 J), on the ball as on the
  // plane; the ball's spring does (nearly) no work on a path round it.
  const Slide plane = slide(false, false);
  const Slide ball = slide(true, false);
  const double injected = 4.0 * 0.3 * 0.3 * 1.5;
  EXPECT_NEAR(plane.energy_j, -injected, 0.05 * injected);
  EXPECT_NEAR(ball.energy_j, plane.energy_j, 0.02 * injected);
  EXPECT_FALSE(ball.damped);
  // With it, the controller budgets the ball's slippery surface as an active part, as it does
  // the plane's: both episodes end near the budget (0.05 J), the port's energy with them.
  const Slide plane_held = slide(false, true);
  const Slide ball_held = slide(true, true);
  EXPECT_TRUE(plane_held.damped);
  EXPECT_TRUE(ball_held.damped);
  EXPECT_LT(ball_held.worst_episode_j, 0.06);
  EXPECT_GT(ball_held.worst_episode_j, 0.04);
  EXPECT_GT(ball_held.least_j, -0.1);
  EXPECT_NEAR(ball_held.energy_j, plane_held.energy_j, 0.02);
}

// ---- a simulated hand strikes the ball ----------------------------------------------------

struct Strike {
  std::vector<Vec3<double>> commanded;  ///< device 0's loop's force, after its safety chain
  std::vector<Vec3<double>> applied;    ///< what device 0 applied (saturated, quantised)
  std::vector<Vec3<double>> impact;     ///< the ball's impact part on device 0
  std::vector<std::int64_t> triggers;   ///< the ticks the impact (re)started on
  double impact_speed = 0.0;            ///< v_i of the first
};

Strike strike(bool impact) {
  WorldConfig config;
  config.has_ball = true;
  config.ball = weightless_ball();
  config.ball.gravity_m_per_s2 = {0.0, 0.0, -9.81};
  config.ball.drag_n_s_per_m = 0.5;
  config.ball.start_m = {0.0, 0.0, 0.02};
  config.ball.has_wall = true;
  config.ball.wall_point_m = {0.0, 0.0, 0.0};
  config.ball.wall_normal = {0.0, 0.0, 1.0};
  config.ball.has_impact = impact;
  config.ball.impact = impact_ball().impact;
  config.ball.impact.recoil_gain_n_per_m = 400.0;
  config.ball.impact.oscillation_gain_n_per_m = 200.0;
  config.ball.impact.frequency_hz = 30.0;
  EXPECT_EQ(check(config, 2), "");
  ServoConfig c = bare_config();
  c.safety.soft_start_s = 0.1;
  // Device 0 comes down on the ball's top from 4 cm above it; device 1 stays well away.
  std::array<host_sim::SimDevice, 2> devices{sim_device({0.0, 0, 0.08}, {0.0, 0, 0.035}, 0.3),
                                             sim_device({0.1, 0, 0.06}, {0.1, 0, 0.06}, 0.3)};
  SimWorld2 world(
      std::array<SimWorld2::Member, 2>{
          SimWorld2::Member{&devices[0], scene_from<double>(nothing_toml()), DeviceFrame{}, c},
          SimWorld2::Member{&devices[1], scene_from<double>(nothing_toml()), DeviceFrame{}, c}},
      config);
  Strike out;
  for (std::int64_t k = 0; k < 1200; ++k) {
    EXPECT_FALSE(world.tick(k).held) << k;
    out.commanded.push_back(world.loop(0).force());
    out.applied.push_back(devices[0].applied_force_n());
    out.impact.push_back(world.ball_impact_n(0));
    if (world.ball_hip_state(0).impact.running && world.ball_hip_state(0).impact.trigger.tick == k) {
      if (out.triggers.empty()) out.impact_speed = world.ball_hip_state(0).impact.impact_speed_m_per_s;
      out.triggers.push_back(k);
    }
  }
  return out;
}

TEST(WorldBallOnSimulatedDevices, AHandStrikingTheBallFeelsTheRecoilThroughItsDevice) {
  const Strike plain = strike(false);
  const Strike struck = strike(true);
  ASSERT_FALSE(struck.triggers.empty()) << "the hand never struck the ball fast enough";
  const auto k0 = static_cast<std::size_t>(struck.triggers.front());
  const BallParams p = impact_ball();
  const double d = p.impact.duration_s;
  // At the trigger (t = 0) the recoil is v_i d k_r, up (the HIP came down on the ball's top,
  // so n is +z to within the hand's sideways wobble).
  EXPECT_GE(struck.impact_speed, p.impact.min_impact_speed_m_per_s);
  EXPECT_NEAR(struck.impact[k0].z, struck.impact_speed * d * 400.0, 1e-3 * struck.impact[k0].z);
  EXPECT_GT(struck.impact[k0].z, 0.5);
  // Up to the trigger both runs are one and the same; on it, the device's force differs by
  // the recoil: it went through the device's safety chain, which had nothing to cut, to the
  // device (whose motors quantise it).
  for (std::size_t k = 0; k < k0; ++k) ASSERT_EQ(struck.commanded[k], plain.commanded[k]) << k;
  const Vec3<double> recoil = struck.commanded[k0] - plain.commanded[k0];
  EXPECT_NEAR(recoil.x, struck.impact[k0].x, 1e-9);
  EXPECT_NEAR(recoil.z, struck.impact[k0].z, 1e-9);
  EXPECT_NEAR((struck.applied[k0] - plain.applied[k0]).z, struck.impact[k0].z, 0.01 * struck.impact[k0].z);
  // The transient acts for d after each (re)trigger and not after: k_r > k_osc, so the law is
  // not zero before t = d. (The recoil throws the hand out of the ball past the re-arm
  // distance, and the hand comes down again: the cartoon bounce.)
  const auto d_ticks = static_cast<std::int64_t>(std::lround(d / kT));
  std::size_t quiet = 0;
  for (std::size_t k = k0; k < struck.impact.size(); ++k) {
    std::int64_t since = -1;
    for (const std::int64_t t : struck.triggers) {
      if (t <= static_cast<std::int64_t>(k)) since = static_cast<std::int64_t>(k) - t;
    }
    if (since < d_ticks) {
      ASSERT_GT(norm(struck.impact[k]), 0.0) << k;
    } else {
      ASSERT_EQ(struck.impact[k], (Vec3<double>{})) << k;
      ++quiet;
    }
  }
  EXPECT_GT(quiet, 100U);  // it ends
}

}  // namespace
}  // namespace toonforce::test
