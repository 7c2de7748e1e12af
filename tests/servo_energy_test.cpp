// SPDX-License-Identifier: Apache-2.0
// The servo loop's energy-side safety: the first-order thermal model against its closed form
// over simulated minutes, derating with the clamp last; the Hannaford-Ryu observer against the
// simulated device's own work integral; the passivity controller holding a slippery surface's
// injected energy to its budget (and leaving episodes within budget untouched); the active
// effects reproducing the forces the scene added. In double and in Q16.16.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "servo_support.hpp"
#include "sim_simple.hpp"

namespace toonforce::test {
namespace {

template <class S>
class ServoEnergy : public ::testing::Test {};
TYPED_TEST_SUITE(ServoEnergy, ServoScalars);

template <class S>
constexpr double kThetaTol = kIsFixed<S> ? 1e-4 : 1e-9;

// ---- thermal model ------------------------------------------------------------------------

TYPED_TEST(ServoEnergy, ThermalHeatingFollowsTheClosedFormOverMinutes) {
  ThermalConfig c{4.0, 30.0, 0.8};
  ThermalModel<TypeParam> model(c, kPeriodS, 8.0);
  const Vec3<TypeParam> force = vec_cast<TypeParam>({0.0, 0.0, 3.0});  // u = (3/4)^2 = 0.5625
  for (int second = 1; second <= 180; ++second) {
    for (int i = 0; i < 1000; ++i) model.advance(force, 1);
    const double expected = 0.5625 * (1.0 - std::exp(-second / 30.0));
    ASSERT_NEAR(model.temperature().to_double(), expected, kThetaTol<TypeParam>) << second << " s";
  }
}

// Q16.16: the update theta <- u + (theta - u) r^n skips the saturation tests because theta and
// u are >= 0 (theta - u then cannot overflow), so a temperature set below ambient is taken as 0;
// the model then heats from there as from cold.
TEST(ServoEnergyQ16, ThermalTemperatureBelowAmbientIsTakenAsAmbient) {
  using Q = Q16_16;
  ThermalModel<Q> model(ThermalConfig{4.0, 30.0, 0.8}, kPeriodS, 8.0);
  model.set_temperature(Wide<Q>::from_double(-1.0));
  EXPECT_EQ(model.temperature().raw(), 0);
  model.set_temperature(Wide<Q>::from_double(0.25));
  EXPECT_EQ(model.temperature().to_double(), 0.25);
}

// Q16.16: the heating u = |F|^2 / F_c^2 from the exact squares of the force and 1/F_c^2 held to
// 32 bits, so a gap past the table (heating: all the way to u) lands on u within a few 2^-32 of
// it, for a continuous force below 1 N (1/F_c^2 shifted up) and above it. Scaling each component
// by a Q16.16 1/F_c first was off by up to a few 10^-5 of u.
TEST(ServoEnergyQ16, ThermalHeatingTargetIsTheSquaredForceRatio) {
  using Q = Q16_16;
  for (const double continuous_n : {0.88, 3.0, 7.3, 100.0}) {
    for (const Vec3<double> force :
         {Vec3<double>{0.0, 0.0, 0.7}, Vec3<double>{2.5, -1.25, 0.5}, Vec3<double>{-150.0, 40.0, 3.0}}) {
      ThermalModel<Q> model(ThermalConfig{continuous_n, 30.0, 0.8}, kPeriodS, 1000.0);
      const Vec3<Q> held = vec_cast<Q>(force);
      model.advance(held, ThermalModel<Q>::kTabulatedGaps + 1);
      const Vec3<double> exact = to_double(held);
      const double u = dot(exact, exact) / (continuous_n * continuous_n);
      EXPECT_NEAR(model.temperature().to_double(), u, u * 0x1p-30 + 0x1p-31)
          << continuous_n << " N, |F| " << norm(exact);
    }
  }
}

// Q16.16: a force so far past F_c that u leaves Q32.32's range heats to the largest temperature,
// with the saturation flag, and derates to F_c; within the range, no flag.
TEST(ServoEnergyQ16, ThermalHeatingPastTheRangeSaturatesWithTheFlag) {
  using Q = Q16_16;
  ThermalModel<Q> model(ThermalConfig{0.001, 30.0, 0.8}, kPeriodS, 8.0);
  static_cast<void>(take_fixed_saturated());
  model.advance(vec_cast<Q>({0.0, 30.0, 0.0}), 1);  // u = 9e8 < 2^31
  EXPECT_FALSE(take_fixed_saturated());
  EXPECT_NEAR(model.temperature().to_double(), 9e8 * (1.0 - std::exp(-kPeriodS / 30.0)), 1.0);
  model.advance(vec_cast<Q>({0.0, 0.0, 50.0}), ThermalModel<Q>::kTabulatedGaps + 1);  // u = 2.5e9 > 2^31
  EXPECT_TRUE(take_fixed_saturated());
  EXPECT_EQ(model.temperature().raw(), std::numeric_limits<std::int64_t>::max());
  EXPECT_EQ(model.allowed_force(), vec_cast<Q>({0.001, 0.0, 0.0}).x);
}

TYPED_TEST(ServoEnergy, ThermalCoolingOverSkippedTicksIsTheSameExponential) {
  ThermalModel<TypeParam> model(ThermalConfig{4.0, 30.0, 0.8}, kPeriodS, 8.0);
  model.set_temperature(Wide<TypeParam>::from_double(1.0));
  std::int64_t ticks = 0;
  while (ticks < 120'000) {
    const std::int64_t gap = 1 + ticks % 7;  // irregular gaps: the force (0) held over each
    model.advance(Vec3<TypeParam>{}, gap);
    ticks += gap;
  }
  EXPECT_NEAR(model.temperature().to_double(), std::exp(-static_cast<double>(ticks) * kPeriodS / 30.0),
              kThetaTol<TypeParam>);
}

TYPED_TEST(ServoEnergy, ThermalGapsUpToTheTableAreTheExactExponential) {
  // The fixed-point build takes r^n from a table made at configuration time (no power in the
  // tick): each gap's factor is the closed form's, to the Q0.32 factor's rounding.
  using M = ThermalModel<TypeParam>;
  for (std::int64_t gap = 1; gap <= M::kTabulatedGaps; ++gap) {
    M model(ThermalConfig{4.0, 30.0, 0.8}, kPeriodS, 8.0);
    model.set_temperature(Wide<TypeParam>::from_double(1.0));
    model.advance(Vec3<TypeParam>{}, gap);
    EXPECT_NEAR(model.temperature().to_double(), std::exp(-static_cast<double>(gap) * kPeriodS / 30.0), 1e-8) << gap;
  }
}

TYPED_TEST(ServoEnergy, ThermalOverALongGapNeverUnderestimatesTheTemperature) {
  // Past the table the fixed-point build over-estimates (the derating never weaker than the
  // exact model's); the floating-point builds stay exact.
  using M = ThermalModel<TypeParam>;
  const std::int64_t gap = 5 * M::kTabulatedGaps;
  const double decay = std::exp(-static_cast<double>(gap) * kPeriodS / 30.0);
  const double tol = kIsFixed<TypeParam> ? 1e-8 : 1e-12;

  M cooling(ThermalConfig{4.0, 30.0, 0.8}, kPeriodS, 8.0);
  cooling.set_temperature(Wide<TypeParam>::from_double(1.0));
  cooling.advance(Vec3<TypeParam>{}, gap);
  const double cooled = cooling.temperature().to_double();
  EXPECT_GE(cooled, decay - tol);
  EXPECT_LE(cooled, 1.0);

  M heating(ThermalConfig{4.0, 30.0, 0.8}, kPeriodS, 8.0);
  const Vec3<TypeParam> force = vec_cast<TypeParam>({0.0, 0.0, 3.0});  // u = 0.5625
  heating.advance(force, gap);
  const double heated = heating.temperature().to_double();
  EXPECT_GE(heated, 0.5625 * (1.0 - decay) - tol);
  EXPECT_LE(heated, 0.5625 + tol);
  if constexpr (!kIsFixed<TypeParam>) {
    EXPECT_NEAR(cooled, decay, tol);
    EXPECT_NEAR(heated, 0.5625 * (1.0 - decay), tol);
  }
}

// Q16.16 within two units of the last place (from theta in Q32.32, the slope floored), and
// never below F_c.
TYPED_TEST(ServoEnergy, DeratingIsLinearFromDerateStartToTheContinuousForce) {
  ThermalModel<TypeParam> model(ThermalConfig{4.0, 30.0, 0.8}, kPeriodS, 8.0);
  const double tol = kIsFixed<TypeParam> ? 0x1p-15 : 1e-12;
  for (const auto& [theta, allowed] : {std::pair{0.0, 8.0},
                                       {0.5, 8.0},
                                       {0.8, 8.0},
                                       {0.83, 7.4},
                                       {0.9, 6.0},
                                       {0.97, 4.6},
                                       {0.99999, 4.0002},
                                       {1.0, 4.0},
                                       {2.0, 4.0}}) {
    model.set_temperature(Wide<TypeParam>::from_double(theta));
    EXPECT_NEAR(to_double(model.allowed_force()), allowed, tol) << theta;
    EXPECT_GE(to_double(model.allowed_force()), 4.0) << theta;
  }
}

TYPED_TEST(ServoEnergy, TheLoopDeratesASustainedPushDownToTheContinuousForce) {
  ServoConfig c = bare_config();
  c.safety.thermal = ThermalConfig{4.0, 20.0, 0.8};
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  rig.at({0, 0, 0.01});
  const auto allowed = [](double theta) { return theta <= 0.8 ? 8.0 : 8.0 - 4.0 * std::min(1.0, (theta - 0.8) / 0.2); };
  double previous_theta = 0.0;
  bool full_so_far = true;  // every earlier tick commanded the full 8 N
  bool derated = false;
  for (std::int64_t k = 1; k <= 120'000; ++k) {  // two minutes pressing 10 N into the wall
    const TickStatus s = rig.at({0, 0, -0.01});
    const double theta = rig.loop.thermal().temperature().to_double();
    if (full_so_far) {
      const double t = static_cast<double>(k - 1) * kPeriodS;  // 8 N held since tick 1
      ASSERT_NEAR(theta, 4.0 * (1.0 - std::exp(-t / 20.0)), kThetaTol<TypeParam>) << k;
    }
    ASSERT_NEAR(rig.force().z, allowed(theta), kIsFixed<TypeParam> ? 2e-3 : 1e-9) << k;
    if (theta > 0.8) full_so_far = false;  // from this tick on the clamp is derated
    if (rig.force().z < 8.0 - 1e-3) {
      derated = true;
      ASSERT_TRUE(has(s.limits, Limit::kThermal)) << k;
    }
    ASSERT_LE(theta, 1.0 + kThetaTol<TypeParam>) << k;
    ASSERT_GE(theta, previous_theta - kThetaTol<TypeParam>) << k;
    previous_theta = theta;
  }
  EXPECT_TRUE(derated);
  EXPECT_NEAR(previous_theta, 1.0, 0.01);
  EXPECT_NEAR(rig.force().z, 4.0, 0.05);
}

// ---- passivity observer ----------------------------------------------------------------------

/// A closed loop on the simple simulated device, stepped deterministically (one exchange per
/// tick), recording each tick's telemetry.
template <Scalar S>
struct SimRun {
  SimpleSimDevice device;
  ServoLoop<DriverRef, RuntimeScene<S>> loop;
  std::vector<TelemetryFrame> frames;

  SimRun(const std::string& toml, const ServoConfig& config, SimpleSimConfig sim)
      : device(fixed(std::move(sim))), loop(DriverRef(device), scene_from<S>(toml), config) {}
  static SimpleSimConfig fixed(SimpleSimConfig sim) {
    sim.real_time = false;
    sim.exchange_period_s = kPeriodS;
    return sim;
  }
  void run(std::int64_t ticks) {
    frames.reserve(frames.size() + static_cast<std::size_t>(ticks));
    for (std::int64_t k = 0; k < ticks; ++k) {
      loop.tick(k);
      TelemetryFrame f;
      loop.fill_frame(f);
      frames.push_back(f);
    }
  }
};

TYPED_TEST(ServoEnergy, ObserverEnergyIsMinusTheWorkTheDeviceDidOnTheHandle) {
  ServoConfig c = bare_config();
  SimRun<TypeParam> run(floor_toml(1500.0), c, SimpleSimConfig{});  // default strike and stroke
  run.run(6000);
  // The simulation integrates the device's work in 0.1 ms sub-steps with exact positions; the
  // observer sums F_{k-1}.(x_k - x_{k-1}) once per tick. With the force held over each tick
  // they agree (to the Q16.16 position resolution in the fixed build).
  const double tol = kIsFixed<TypeParam> ? 2e-3 : 1e-9;
  EXPECT_NEAR(run.loop.passivity().observer().energy().to_double(), -run.device.device_work_j(), tol);
  EXPECT_GT(std::abs(run.device.device_work_j()), 1e-4) << "the scenario must exchange energy";
}

// ---- passivity controller ---------------------------------------------------------------------

const std::string kSlippery = floor_toml(1500.0, "  [surface.slippery]\n  mu = 4.0\n  max_tangential_force = 2.0\n");

/// Press on the floor, then stroke back and forth along x at 0.1 m/s, never lifting.
SimpleSimConfig long_stroke() {
  SimpleSimConfig sim;
  sim.script = {
      {0.0, {-0.03, 0, 0.01}},   {0.2, {-0.03, 0, 0.01}},  {0.8, {-0.03, 0, -0.004}}, {1.4, {0.03, 0, -0.004}},
      {2.0, {-0.03, 0, -0.004}}, {2.6, {0.03, 0, -0.004}}, {3.2, {-0.03, 0, -0.004}}, {3.8, {0.03, 0, -0.004}},
      {4.4, {-0.03, 0, -0.004}}, {5.0, {0.03, 0, -0.004}}, {5.6, {-0.03, 0, -0.004}}, {6.2, {0.03, 0, -0.004}},
      {6.8, {-0.03, 0, -0.004}}, {7.4, {0.03, 0, -0.004}}, {8.0, {-0.03, 0, -0.004}}, {8.5, {-0.03, 0, 0.01}}};
  return sim;
}

/// From the trace and the penalty law alone (independent of the loop's bookkeeping): the
/// largest energy the non-wall part of the commanded force (the slippery push plus any damping)
/// put into the HIP within one contact. The force commanded at tick k-1 acts over x_{k-1} ->
/// x_k; the wall's part of it is 1500 N/m times the penetration at x_{k-1} along +z.
double max_active_work_per_contact(const std::vector<TelemetryFrame>& frames) {
  double work = 0.0;
  double most = 0.0;
  for (std::size_t k = 1; k < frames.size(); ++k) {
    const TelemetryFrame& a = frames[k - 1];
    const TelemetryFrame& b = frames[k];
    if (!(a.position_m.z < 0.0 && b.position_m.z < 0.0)) {
      work = 0.0;  // out of contact: the next contact is a new episode
      continue;
    }
    const Vec3<double> wall{0.0, 0.0, 1500.0 * -a.position_m.z};
    work += dot(a.force_n - wall, b.position_m - a.position_m);
    most = std::max(most, work);
  }
  return most;
}

TYPED_TEST(ServoEnergy, PassivityControllerKeepsASlipperySurfacesInjectedEnergyUnderItsBudget) {
  ServoConfig c = bare_config();
  c.safety.passivity.budget_j = 0.05;
  c.safety.passivity.controller = false;
  SimRun<TypeParam> free_run(kSlippery, c, long_stroke());
  free_run.run(8500);
  const double unbounded = max_active_work_per_contact(free_run.frames);
  EXPECT_GT(unbounded, 4 * 0.05) << "without the controller the stroke injects far more than the budget";

  c.safety.passivity.controller = true;
  SimRun<TypeParam> bounded_run(kSlippery, c, long_stroke());
  bounded_run.run(8500);
  const double bounded = max_active_work_per_contact(bounded_run.frames);
  // Measured: 0.0502 J (double), 0.0510 J (Q16.16) against 3.9 J without the controller. The
  // margin covers the controller's one-tick lag and the Q16.16 resolution of the excess.
  EXPECT_LE(bounded, 0.05 + 2e-3);
  EXPECT_GT(bounded, 0.05 - 5e-3) << "the effect plays in full up to its budget";
  const auto damped = std::count_if(bounded_run.frames.begin(), bounded_run.frames.end(),
                                    [](const TelemetryFrame& f) { return has(f.limits, Limit::kPassivity); });
  EXPECT_GT(damped, 1000);
}

// The applied share (Passivity::settle) comes from the exact sums: a wanted force
// past 181 N, whose square does not fit Q16.16, clamped while a slippery contact's episode runs,
// is no saturation fault (it was one when the share divided two Q16.16 dot products).
TYPED_TEST(ServoEnergy, AWantedForcePast181NewtonsWhileAnEpisodeRunsIsClampedWithoutAFault) {
  ServoConfig c = bare_config();
  c.safety.passivity.controller = true;
  Rig<TypeParam> rig(floor_toml(20000.0, "  [surface.slippery]\n  mu = 4.0\n  max_tangential_force = 2.0\n"), c);
  for (int i = 0; i < 5; ++i) ASSERT_FALSE(rig.at({0.0, 0.0, 0.01}).faults);  // engaged out of contact
  for (int i = 0; i < 50; ++i) {
    const TickStatus s = rig.at({0.0005 * i, 0.0, -0.02});  // 400 N deep, sliding at 0.5 m/s
    ASSERT_FALSE(s.faults) << "tick " << i << ": " << s.faults.bits();
    ASSERT_NEAR(norm(rig.force()), 8.0, kForceTol<TypeParam>) << "tick " << i;
  }
  EXPECT_TRUE(rig.loop.passivity().controller().in_episode(0));
}

// A Q16.16 loop whose device reads in Q16.16 (a microcontroller's, tools/mcu) takes the step
// since the last counted tick once, in the sensor, for the velocity estimate and the passivity
// observer alike; a loop whose device reads in double keeps the observer's own last
// position. On the same positions (exact Q16.16 values) through a slippery stroke whose episodes
// go over budget, late ticks and a failed read, the two give the same forces, damping,
// velocities and energies, bit for bit.
template <class T>
struct ScriptedPositions {
  const std::vector<Vec3<Q16_16>>* positions;
  const std::size_t* k;
  const DeviceStatus* status;
  Vec3<T> written{};
  DeviceStatus read(BasicDeviceReading<T>& r) noexcept {
    if constexpr (std::same_as<T, double>) {
      r.position_m = to_double((*positions)[*k]);  // exact: a Q16.16 value is a double
    } else {
      r.position_m = (*positions)[*k];
    }
    return *status;
  }
  DeviceStatus write(const Vec3<T>& f) noexcept {
    written = f;
    return DeviceStatus::kOk;
  }
};
struct QScriptedPositions : ScriptedPositions<Q16_16> {
  using Scalar = Q16_16;
};

TEST(ServoEnergyQ16, ALoopReadingInQ16TakesTheStepOnceAndMatchesOneReadingInDoubleBitForBit) {
  using Q = Q16_16;
  ServoConfig c = bare_config();
  c.safety.passivity.controller = true;
  c.safety.passivity.budget_j = 0.01;
  c.safety.has_max_velocity = true;  // the motion limits need the velocity too
  c.safety.max_velocity_m_per_s = 5.0;
  std::vector<Vec3<Q>> positions;
  for (int k = 0; k < 4000; ++k) {
    const double t = k * kPeriodS;
    positions.push_back(vec_cast<Q>(Vec3<double>{0.03 * std::sin(3.0 * t), 0.0, k < 200 ? 0.01 : -0.004}));
  }
  std::size_t row = 0;
  DeviceStatus status = DeviceStatus::kOk;
  ServoLoop<ScriptedPositions<double>, RuntimeScene<Q>> in_double(ScriptedPositions<double>{&positions, &row, &status},
                                                                  scene_from<Q>(kSlippery), c);
  ServoLoop<QScriptedPositions, RuntimeScene<Q>> in_q(QScriptedPositions{{&positions, &row, &status}},
                                                      scene_from<Q>(kSlippery), c);
  static_assert(!decltype(in_double)::kStepShared && decltype(in_q)::kStepShared);
  int damped = 0;
  std::int64_t k = 0;
  for (row = 0; row < positions.size(); ++row) {
    status = row == 2500 ? DeviceStatus::kTimeout : DeviceStatus::kOk;  // a tick without a position
    k += row % 700 == 699 ? 4 : 1;                                      // and late ticks
    const TickStatus a = in_double.tick(k);
    const TickStatus b = in_q.tick(k);
    ASSERT_EQ(a.faults.bits(), b.faults.bits()) << row;
    ASSERT_EQ(a.limits, b.limits) << row;
    ASSERT_EQ(in_double.force(), in_q.force()) << row;
    ASSERT_EQ(in_double.velocity(), in_q.velocity()) << row;
    ASSERT_EQ(in_double.passivity().observer().energy(), in_q.passivity().observer().energy()) << row;
    ASSERT_EQ(in_double.passivity().controller().episode_energy(0), in_q.passivity().controller().episode_energy(0))
        << row;
    damped += has(b.limits, Limit::kPassivity) ? 1 : 0;
  }
  EXPECT_GT(damped, 100) << "the episodes must go over budget for the damping to be compared";
  EXPECT_NE(in_q.passivity().observer().energy(), Wide<Q>{}) << "the stroke must exchange energy";
}

TYPED_TEST(ServoEnergy, PassivityControllerLeavesAnEpisodeWithinBudgetUntouched) {
  ServoConfig c = bare_config();
  c.safety.passivity.budget_j = 100.0;
  c.safety.passivity.controller = false;
  SimRun<TypeParam> off(kSlippery, c, long_stroke());
  off.run(3000);
  c.safety.passivity.controller = true;
  SimRun<TypeParam> on(kSlippery, c, long_stroke());
  on.run(3000);
  for (std::size_t k = 0; k < off.frames.size(); ++k) {
    ASSERT_EQ(off.frames[k].force_n, on.frames[k].force_n) << k;
  }
  EXPECT_GT(on.loop.passivity().controller().max_episode_energy(on.loop.passivity().slots()).to_double(), 0.01);
}

// The damping for an episode over its budget is -alpha v with alpha = min(X rate / |v|^2,
// max_damping, max_force / |v|) (the excess X, HR's rule capped twice), nothing below 1 mm/s:
// each cap binding in turn, against that closed form from the controller's own energy. In
// Q16.16 from the inverse root, within 0.1 % and a few LSB.
TYPED_TEST(ServoEnergy, PassivityDampingIsTheExcessOverTheSpeedSquaredCappedTwice) {
  using S = TypeParam;
  PassivityConfig config;
  config.budget_j = 0.001;
  config.max_damping_n_s_per_m = 20.0;
  constexpr double kMaxForceN = 8.0;
  constexpr double kRateHz = 1000.0;
  struct Case {
    double work_j;  // the episode's work so far (the excess is work - budget)
    double speed_m_per_s;
  };
  // X = 10 mJ, 10 W at 1 kHz: alpha from X rate / |v|^2 (at 2 m/s: 2.5), max_damping (at 0.3
  // m/s: 111 -> 20), max_force / |v| (at 1 m/s: 10 -> 8), and too slow to damp.
  for (const Case k : {Case{0.011, 2.0}, Case{0.011, 0.3}, Case{0.011, 1.0}, Case{0.011, 0.0005}}) {
    PassivityController<S, 1> controller(config, kMaxForceN);
    const ActiveForce<S> start{vec_cast<S>(Vec3<double>{1.0, 0.0, 0.0}), true, true};
    controller.update(&start, 1, Vec3<S>{}, scalar_cast<S>(kRateHz));  // the episode starts at 0 J
    controller.account(vec_cast<S>(Vec3<double>{k.work_j, 0.0, 0.0}), scalar_cast<S>(1.0), 1);  // 1 N over work_j m
    const double excess_j = controller.episode_energy(0).to_double() - controller.budget().to_double();
    ASSERT_GT(excess_j, 0.0);
    const Vec3<double> v{0.6 * k.speed_m_per_s, 0.0, -0.8 * k.speed_m_per_s};
    const ActiveForce<S> running{start.force_n, true, false};
    const Vec3<double> damping = to_double(controller.update(&running, 1, vec_cast<S>(v), scalar_cast<S>(kRateHz)));
    const double speed = std::sqrt(dot(v, v));
    const double alpha = speed > 1e-3 ? std::min({std::min(excess_j, 1.0) * kRateHz / (speed * speed),
                                                  config.max_damping_n_s_per_m, kMaxForceN / speed})
                                      : 0.0;
    // Q16.16: the excess is rounded to 2^-16 J before it is divided (half of it, relative to X),
    // 1 / |v| within 2^-26, and the products' roundings.
    const double tolerance = kIsFixed<S> ? (1e-3 + 0.5 / 65536.0 / excess_j) * alpha * speed + 4.0 / 65536.0 : 1e-12;
    EXPECT_NEAR(damping.x, -alpha * v.x, tolerance) << k.work_j << " J at " << k.speed_m_per_s << " m/s";
    EXPECT_NEAR(damping.y, 0.0, tolerance);
    EXPECT_NEAR(damping.z, -alpha * v.z, tolerance) << k.work_j << " J at " << k.speed_m_per_s << " m/s";
    EXPECT_EQ(controller.damped(), alpha > 0.0);
  }
}

// Q16.16: the damping's force is capped at PassivityController::kMaxFixedForceN whatever
// max_force says, which is what lets its products skip the saturation test (each component at
// most alpha |v| <= that cap plus 2^-2 N). At the format's corner (32 kHz, a whole joule over
// budget, 1 m/s, max_damping and max_force 30,000): 16,384 N against -v, nothing saturated.
TEST(ServoEnergyQ16, PassivityDampingStopsAtItsFixedPointForceCap) {
  using Q = Q16_16;
  using Controller = PassivityController<Q, 1>;
  PassivityConfig config;
  config.budget_j = 0.001;
  config.max_damping_n_s_per_m = 30000.0;
  Controller controller(config, 30000.0);
  const Q rate = scalar_cast<Q>(32000.0);
  const ActiveForce<Q> start{vec_cast<Q>(Vec3<double>{1.0, 0.0, 0.0}), true, true};
  controller.update(&start, 1, Vec3<Q>{}, rate);
  controller.account(vec_cast<Q>(Vec3<double>{2.0, 0.0, 0.0}), scalar_cast<Q>(1.0), 1);  // 2 J: X capped at 1 J
  static_cast<void>(take_fixed_saturated());
  const ActiveForce<Q> running{start.force_n, true, false};
  const Vec3<double> damping =
      to_double(controller.update(&running, 1, vec_cast<Q>(Vec3<double>{0.0, -1.0, 0.0}), rate));
  EXPECT_NEAR(damping.y, Controller::kMaxFixedForceN, 0.25);
  EXPECT_EQ(damping.x, 0.0);
  EXPECT_EQ(damping.z, 0.0);
  EXPECT_FALSE(take_fixed_saturated());
}

// ---- active effects -----------------------------------------------------------------------------

TEST(ActiveEffects, SlotsAreTheForcesTheActiveEffectsAdded) {
  const std::string toml = floor_toml(1000.0, "  [surface.slippery]\n  mu = 4.0\n"
                                              "  [surface.impact]\n  recoil_gain = 200.0\n  oscillation_gain = 400.0\n"
                                              "  duration = 0.15\n  frequency = 30.0\n");
  const RuntimeScene<double> scene = scene_from<double>(toml);
  ASSERT_EQ(scene.active_slots(), 2U);
  RuntimeScene<double>::State state{};
  int triggers = 0;
  int running = 0;
  for (std::int64_t k = 0; k < 200; ++k) {
    TickInput<double> in{};
    in.now = Instant{k, 0};
    in.period_s = kPeriodS;
    in.rate_hz = 1.0 / kPeriodS;
    in.velocity_m_per_s = {0.1, 0.0, k < 3 ? -0.2 : 0.0};
    in.position_m = {0.0001 * static_cast<double>(k), 0.0, k < 2 ? 0.0005 - 0.0002 * static_cast<double>(k) : -0.0002};
    std::array<ActiveForce<double>, RuntimeScene<double>::kActiveCapacity> slots{};
    const Vec3<double> f = scene.force(in, state, slots.data());
    // The wall alone, plus what the two active parts say they added, is the whole force.
    const double delta = -in.position_m.z;
    const Vec3<double> wall{0.0, 0.0, delta > 0 ? 1000.0 * delta : 0.0};
    const Vec3<double> sum = wall + slots[0].force_n + slots[1].force_n;
    EXPECT_NEAR(sum.x, f.x, 1e-12) << k;
    EXPECT_NEAR(sum.y, f.y, 1e-12) << k;
    EXPECT_NEAR(sum.z, f.z, 1e-12) << k;
    EXPECT_EQ(slots[0].in_episode, in.position_m.z < 0.0) << k;  // slippery: in contact
    triggers += slots[1].triggered ? 1 : 0;
    running += slots[1].in_episode ? 1 : 0;
  }
  EXPECT_EQ(triggers, 1);
  EXPECT_EQ(running, 151);  // t = 0 .. 0.15 s inclusive at 1 kHz
}

}  // namespace
}  // namespace toonforce::test
