// SPDX-License-Identifier: Apache-2.0
// The host simulation's physics against closed forms and stated bounds: the free
// mass-spring-damper, each integrator's order of convergence, energy, the simulated device's
// quantisation, delay and saturation, the hand's intent, and the run-time driver.
#include <gtest/gtest.h>

#include <cmath>
#include <thread>
#include <vector>

#include "alloc_counter.hpp"
#include "toonforce/host_sim/sim_driver.hpp"

namespace toonforce::host_sim {
namespace {

/// A device with nothing but a mass and a damper: no friction, quantisation, saturation or delay.
DeviceParams bare_device(double mass_kg, double damping_n_s_per_m) {
  DeviceParams d;
  d.name = "bare test device";
  d.mass_kg = mass_kg;
  d.damping_n_s_per_m = damping_n_s_per_m;
  d.coulomb_n = 0.0;
  d.max_force_n = 0.0;
  d.encoder_step_m = 0.0;
  d.force_step_n = 0.0;
  d.io_delay_ticks = 0;
  return d;
}

Plant make_plant(const DeviceParams& device, HandIntent intent, Integrator integrator, int substeps, double period_s) {
  auto plant = Plant::create(device, std::move(intent), {integrator, substeps, period_s});
  if (!plant) ADD_FAILURE() << plant.error();
  return std::move(plant).value();
}

/// x(t) of m x'' + b x' + k x = 0 (underdamped), from x0, v0: the closed form.
struct Msd {
  double m, k, b;
  double zeta() const { return b / (2.0 * std::sqrt(k * m)); }
  double omega() const { return std::sqrt(k / m); }
  double position(double x0, double v0, double t) const {
    const double w = omega();
    const double z = zeta();
    const double wd = w * std::sqrt(1.0 - z * z);
    return std::exp(-z * w * t) * (x0 * std::cos(wd * t) + (v0 + z * w * x0) / wd * std::sin(wd * t));
  }
  double velocity(double x0, double v0, double t) const {
    const double w = omega();
    const double z = zeta();
    const double wd = w * std::sqrt(1.0 - z * z);
    const double e = std::exp(-z * w * t);
    const double c = std::cos(wd * t);
    const double s = std::sin(wd * t);
    const double a = x0;
    const double bb = (v0 + z * w * x0) / wd;
    return e * (-z * w * (a * c + bb * s) + (-a * wd * s + bb * wd * c));
  }
};

constexpr Vec3<double> kX0{0.01, -0.004, 0.002};
constexpr Vec3<double> kV0{0.0, 0.05, -0.1};

/// Largest distance from the closed form over `seconds`, for a plant released at kX0, kV0
/// with the hand holding the origin (so the whole thing is a free mass-spring-damper).
double free_msd_error(Integrator integrator, int substeps, double period_s, double seconds) {
  const HandImpedance hand{0.1, 200.0, 2.0};
  const DeviceParams device = bare_device(0.15, 0.05);
  Plant plant = make_plant(device, HandIntent::holding({}, hand), integrator, substeps, period_s);
  plant.set_state(kX0, kV0);
  const Msd msd{device.mass_kg + hand.mass_kg, hand.stiffness_n_per_m,
                device.damping_n_s_per_m + hand.damping_n_s_per_m};
  const auto ticks = static_cast<std::int64_t>(std::llround(seconds / period_s));
  double worst = 0.0;
  for (std::int64_t k = 0; k < ticks; ++k) {
    plant.step(k, {});
    const double t = static_cast<double>(k + 1) * period_s;
    const Vec3<double> exact{msd.position(kX0.x, kV0.x, t), msd.position(kX0.y, kV0.y, t),
                             msd.position(kX0.z, kV0.z, t)};
    const Vec3<double> error = plant.position_m() - exact;
    worst = std::max(worst, std::sqrt(dot(error, error)));
  }
  return worst;
}

TEST(FreeMassSpringDamper, ExactStepMatchesTheClosedFormToRoundOff) {
  // 2000 steps of a matrix exponential accurate to a few ulps: the error stays near 1e-16
  // of the 1 cm amplitude times the step count.
  EXPECT_LT(free_msd_error(Integrator::kExact, 1, 1e-3, 2.0), 1e-15);
  EXPECT_LT(free_msd_error(Integrator::kExact, 4, 1e-3, 2.0), 1e-15);
}

TEST(FreeMassSpringDamper, VelocityOfTheExactStepMatchesTooAfterOneSecond) {
  const HandImpedance hand{0.1, 200.0, 2.0};
  const DeviceParams device = bare_device(0.15, 0.05);
  Plant plant = make_plant(device, HandIntent::holding({}, hand), Integrator::kExact, 1, 1e-3);
  plant.set_state(kX0, kV0);
  for (std::int64_t k = 0; k < 1000; ++k) plant.step(k, {});
  const Msd msd{0.25, 200.0, 2.05};
  EXPECT_NEAR(plant.velocity_m_per_s().y, msd.velocity(kX0.y, kV0.y, 1.0), 1e-15);
  EXPECT_NEAR(plant.velocity_m_per_s().z, msd.velocity(kX0.z, kV0.z, 1.0), 1e-15);
}

TEST(FreeMassSpringDamper, Rk4WithSubstepsIsCloseToTheClosedForm) {
  // RK4's error at w h = 28 rad/s x 0.25 ms is ~ (wh)^4 / 120 of the amplitude per period.
  EXPECT_LT(free_msd_error(Integrator::kRk4, 4, 1e-3, 2.0), 1e-11);
}

/// Observed orders log2(e(h) / e(h/2)) as the sub-steps per (long) tick double.
std::vector<double> observed_orders(Integrator integrator) {
  std::vector<double> errors;
  for (const int substeps : {1, 2, 4, 8, 16}) errors.push_back(free_msd_error(integrator, substeps, 0.01, 1.0));
  std::vector<double> orders;
  for (std::size_t i = 1; i < errors.size(); ++i) orders.push_back(std::log2(errors[i - 1] / errors[i]));
  return orders;
}

// Steps h = 10, 5, 2.5, 1.25, 0.625 ms at w = 28 rad/s: small enough to be in the asymptotic
// range, large enough that the errors stay far above round-off.
TEST(ConvergenceOrder, SemiImplicitEulerIsFirstOrder) {
  for (const double p : observed_orders(Integrator::kSemiImplicitEuler)) EXPECT_NEAR(p, 1.0, 0.1);
}
TEST(ConvergenceOrder, VelocityVerletIsSecondOrder) {
  for (const double p : observed_orders(Integrator::kVelocityVerlet)) EXPECT_NEAR(p, 2.0, 0.1);
}
TEST(ConvergenceOrder, Rk4IsFourthOrder) {
  for (const double p : observed_orders(Integrator::kRk4)) EXPECT_NEAR(p, 4.0, 0.15);
}
TEST(ConvergenceOrder, StatedOrdersMatch) {
  EXPECT_EQ(integrator_order(Integrator::kSemiImplicitEuler), 1);
  EXPECT_EQ(integrator_order(Integrator::kVelocityVerlet), 2);
  EXPECT_EQ(integrator_order(Integrator::kRk4), 4);
}

/// The same orders with the hand following a moving intent (a minimum-jerk move, so the
/// reference forces change within every step), against a very fine RK4 reference.
double forced_error(Integrator integrator, int substeps) {
  HandScript script;
  script.start_m = {};
  script.impedance = {0.1, 200.0, 2.0};
  HandSegment hold;
  hold.kind = SegmentKind::kHold;
  hold.duration_s = 0.1;
  HandSegment move;
  move.kind = SegmentKind::kMove;
  move.to_m = {0.02, -0.01, 0.005};
  move.duration_s = 0.5;
  script.segments = {hold, move};
  PlanError error;
  const auto intent = HandIntent::plan(script, error);
  EXPECT_TRUE(intent.has_value()) << error.problem;
  const DeviceParams device = bare_device(0.15, 0.05);
  Plant plant = make_plant(device, *intent, integrator, substeps, 0.01);
  Plant reference = make_plant(device, *intent, Integrator::kRk4, 512, 0.01);
  double worst = 0.0;
  for (std::int64_t k = 0; k < 100; ++k) {
    plant.step(k, {});
    reference.step(k, {});
    const Vec3<double> e = plant.position_m() - reference.position_m();
    worst = std::max(worst, std::sqrt(dot(e, e)));
  }
  return worst;
}

TEST(ConvergenceOrder, OrdersHoldWithAMovingIntent) {
  const auto order = [](Integrator i, int s) { return std::log2(forced_error(i, s) / forced_error(i, 2 * s)); };
  for (const int s : {2, 4}) {
    EXPECT_NEAR(order(Integrator::kSemiImplicitEuler, s), 1.0, 0.15);
    EXPECT_NEAR(order(Integrator::kVelocityVerlet, s), 2.0, 0.15);
    EXPECT_NEAR(order(Integrator::kRk4, s), 4.0, 0.3);
    // The exact step holds the reference forces linearly over a step: second order in them.
    EXPECT_NEAR(order(Integrator::kExact, s), 2.0, 0.15);
  }
}

TEST(Integrators, RejectAStepTooLongForTheModelAndSayWhatWouldDo) {
  DeviceParams omni = omni_params();  // light: its friction smoothing is the fastest rate
  HandScript script;
  script.segments.push_back(HandSegment{});
  script.segments.back().kind = SegmentKind::kRelease;
  PlanError error;
  const auto released = HandIntent::plan(script, error);
  ASSERT_TRUE(released.has_value());
  const auto plant = Plant::create(omni, *released, {Integrator::kRk4, 1, 1e-3});
  ASSERT_FALSE(plant);
  EXPECT_NE(plant.error().find("--substeps 3"), std::string::npos) << plant.error();
  EXPECT_TRUE(Plant::create(omni, *released, {Integrator::kRk4, 3, 1e-3}));
}

TEST(MatrixExponential, OfANilpotentMatrixIsItsFiniteSeries) {
  std::array<std::array<double, 4>, 4> a{};
  a[0][1] = 2.0;
  a[1][2] = 3.0;  // a^2 has only [0][2] = 6, a^3 = 0
  const auto e = matrix_exponential(a);
  EXPECT_DOUBLE_EQ(e[0][0], 1.0);
  EXPECT_DOUBLE_EQ(e[0][1], 2.0);
  EXPECT_DOUBLE_EQ(e[0][2], 3.0);  // a^2 / 2
  EXPECT_DOUBLE_EQ(e[1][2], 3.0);
  EXPECT_DOUBLE_EQ(e[3][3], 1.0);
}

// ---- energy ----------------------------------------------------------------------------

/// An undamped, frictionless spring-mass driven by a sampled penalty wall (a held force that
/// changes every tick, as the controller's does). Whatever the wall does, the plant's energy
/// change must equal the work the held force did, up to the integrator's stated bound.
double worst_energy_gain(Integrator integrator, int substeps, double& bound_out) {
  const HandImpedance hand{0.1, 200.0, 0.0};
  const DeviceParams device = bare_device(0.15, 0.0);
  constexpr double kPeriod = 1e-3;
  Plant plant = make_plant(device, HandIntent::holding({0.0, 0.0, -0.002}, hand), integrator, substeps, kPeriod);
  plant.set_state({0.0, 0.0, 0.02}, {0.0, 0.0, -0.3});
  const double e0 = plant.mechanical_energy_j(0.0);
  double worst = 0.0;
  double peak = e0;
  for (std::int64_t k = 0; k < 3000; ++k) {
    const double depth = -plant.position_m().z;
    const Vec3<double> wall{0.0, 0.0, depth > 0.0 ? 1500.0 * depth : 0.0};
    plant.step(k, wall);
    const double t = static_cast<double>(k + 1) * kPeriod;
    const double e = plant.mechanical_energy_j(t);
    peak = std::max(peak, e);
    worst = std::max(worst, (e - e0 - plant.device_work_j()) / peak);
  }
  const double omega_h = plant.hand_omega_rad_per_s() * kPeriod / substeps;
  bound_out = energy_gain_bound(integrator, omega_h);
  return worst;
}

TEST(Energy, NoIntegratorGainsMoreThanItsStatedBound) {
  for (const Integrator i :
       {Integrator::kSemiImplicitEuler, Integrator::kVelocityVerlet, Integrator::kRk4, Integrator::kExact}) {
    for (const int substeps : {1, 4}) {
      double bound = 0.0;
      const double gain = worst_energy_gain(i, substeps, bound);
      EXPECT_LE(gain, bound + 1e-12) << integrator_name(i) << " with " << substeps << " sub-steps";
    }
  }
}

TEST(Energy, TheSymplecticBoundIsNotVacuous) {
  // The first-order method does use a good part of its bound: the bound says something.
  double bound = 0.0;
  const double gain = worst_energy_gain(Integrator::kSemiImplicitEuler, 1, bound);
  EXPECT_GT(gain, 0.1 * bound);
}

// ---- the simulated device ---------------------------------------------------------------

SimDevice make_device(DeviceParams params, const Vec3<double>& hold = {}) {
  auto device = SimDevice::create(params, HandIntent::holding(hold), {Integrator::kRk4, 4, 1e-3});
  if (!device) ADD_FAILURE() << device.error();
  return std::move(device).value();
}

TEST(SimDevice, ReportsThePositionOneTickLateOnTheEncoderGrid) {
  DeviceParams p = falcon_params();
  SimDevice device = make_device(p);
  device.set_state({0.0123456, -0.0031, 0.0}, {0.05, 0.02, -0.03});
  Vec3<double> previous_true = device.plant().position_m();
  for (int k = 0; k < 50; ++k) {
    DeviceReading reading;
    ASSERT_EQ(device.read(reading), DeviceStatus::kOk);
    EXPECT_FALSE(reading.has_velocity);
    if (k > 0) {
      // One tick of delay: what the handle was at the previous tick, rounded to 20 um.
      for (const int axis : {0, 1, 2}) {
        const double truth = axis == 0 ? previous_true.x : axis == 1 ? previous_true.y : previous_true.z;
        const double read = axis == 0 ? reading.position_m.x : axis == 1 ? reading.position_m.y : reading.position_m.z;
        EXPECT_NEAR(read, truth, p.encoder_step_m / 2 + 1e-12);
        const double counts = read / p.encoder_step_m;
        EXPECT_NEAR(counts, std::round(counts), 1e-6);
      }
    }
    previous_true = device.plant().position_m();
    ASSERT_EQ(device.write({}), DeviceStatus::kOk);
  }
}

TEST(SimDevice, SaturatesAndQuantisesTheForceTowardZero) {
  const DeviceParams p = falcon_params();
  SimDevice device = make_device(p);
  ASSERT_EQ(device.write({30.0, -40.0, 0.0}), DeviceStatus::kOk);  // 50 N asked, 8 N possible
  const Vec3<double> f = device.applied_force_n();
  EXPECT_LE(std::sqrt(dot(f, f)), p.max_force_n);
  EXPECT_GT(std::sqrt(dot(f, f)), p.max_force_n - 2 * p.force_step_n);
  EXPECT_NEAR(f.x / f.y, -0.75, 1e-3);  // direction kept
  const Vec3<double> small = device.shape_force({0.0051, -0.0051, 0.0});
  EXPECT_DOUBLE_EQ(small.x, 2 * p.force_step_n);  // 0.0051 N = 2.6 steps -> 2 steps
  EXPECT_DOUBLE_EQ(small.y, -2 * p.force_step_n);
  const Vec3<double> nan = device.shape_force({std::nan(""), 0.0, 1.0});
  EXPECT_EQ(nan, (Vec3<double>{}));
}

TEST(SimDevice, NoiseIsSeededAndReproducible) {
  DeviceParams p = falcon_params();
  p.sensor_noise_m = 50e-6;
  const auto readings = [&p](std::uint64_t seed) {
    auto device = SimDevice::create(p, HandIntent::holding({}), {Integrator::kRk4, 4, 1e-3}, seed);
    std::vector<double> zs;
    for (int k = 0; k < 200; ++k) {
      DeviceReading r;
      static_cast<void>(device->read(r));
      zs.push_back(r.position_m.z);
      static_cast<void>(device->write({}));
    }
    return zs;
  };
  EXPECT_EQ(readings(7), readings(7));
  EXPECT_NE(readings(7), readings(8));
  // About 50 um of spread around a handle at rest: the noise is there, at its size.
  const auto zs = readings(7);
  double sum2 = 0.0;
  for (const double z : zs) sum2 += z * z;
  EXPECT_NEAR(std::sqrt(sum2 / static_cast<double>(zs.size())), 50e-6, 15e-6);
}

TEST(SimDevice, ExchangesAllocateNothing) {
  SimDevice device = make_device(falcon_params());
  DeviceReading reading;
  const test::AllocationScope scope;
  for (int k = 0; k < 1000; ++k) {
    static_cast<void>(device.read(reading));
    static_cast<void>(device.write({0.0, 0.0, 0.5}));
  }
  EXPECT_EQ(scope.count(), 0U);
}

TEST(SimDevice, ARestingHandleOnAFrictionlessDeviceStaysPut) {
  SimDevice device = make_device(bare_device(0.15, 0.1), {0.01, 0.02, -0.03});
  for (int k = 0; k < 500; ++k) static_cast<void>(device.write({}));
  EXPECT_EQ(device.plant().position_m(), (Vec3<double>{0.01, 0.02, -0.03}));
}

TEST(SimDevice, AForceAgainstTheHandSettlesWhereTheArmSpringBalancesIt) {
  // 1 N up against a 200 N/m hand: 5 mm, whatever the integrator.
  for (const Integrator i :
       {Integrator::kSemiImplicitEuler, Integrator::kVelocityVerlet, Integrator::kRk4, Integrator::kExact}) {
    auto device = SimDevice::create(bare_device(0.15, 0.1), HandIntent::holding({}), {i, 4, 1e-3});
    ASSERT_TRUE(device);
    for (int k = 0; k < 3000; ++k) static_cast<void>(device->write({0.0, 0.0, 1.0}));
    EXPECT_NEAR(device->plant().position_m().z, 1.0 / 200.0, 1e-9) << integrator_name(i);
  }
}

// ---- the hand's intent ------------------------------------------------------------------

HandIntent plan_or_fail(const HandScript& script) {
  PlanError error;
  auto intent = HandIntent::plan(script, error);
  if (!intent) ADD_FAILURE() << "segment " << error.segment << " " << error.key << ": " << error.problem;
  return intent.value_or(HandIntent::holding({}));
}

HandSegment segment(SegmentKind kind, Vec3<double> to = {}, std::optional<double> speed = {},
                    std::optional<double> duration = {}) {
  HandSegment s;
  s.kind = kind;
  s.to_m = to;
  s.speed_m_per_s = speed;
  s.duration_s = duration;
  return s;
}

TEST(HandIntent, AMoveIsMinimumJerkFromRestToRest) {
  HandScript script;
  script.start_m = {0.0, 0.0, 0.01};
  script.segments = {segment(SegmentKind::kMove, {0.04, 0.0, 0.01}, {}, 0.4)};
  const HandIntent intent = plan_or_fail(script);
  EXPECT_DOUBLE_EQ(intent.duration_s(), 0.4);
  EXPECT_EQ(intent.at(0.0).velocity_m_per_s, (Vec3<double>{}));
  EXPECT_NEAR(intent.at(0.2).position_m.x, 0.02, 1e-15);                      // half way at half time
  EXPECT_NEAR(intent.at(0.2).velocity_m_per_s.x, 1.875 * 0.04 / 0.4, 1e-12);  // peak 15/8 of mean
  EXPECT_NEAR(intent.at(0.4).position_m.x, 0.04, 1e-15);
  EXPECT_EQ(intent.at(0.4).velocity_m_per_s, (Vec3<double>{}));
  EXPECT_EQ(intent.at(1.0).position_m, (Vec3<double>{0.04, 0.0, 0.01}));  // keeps its last intent
}

TEST(HandIntent, AStrokeRampsCruisesAndStopsExactlyAtItsEnd) {
  HandScript script;
  HandSegment stroke = segment(SegmentKind::kStroke, {0.05, 0.0, 0.0}, 0.1);
  stroke.ramp_s = 0.1;
  stroke.force_n = 1.5;
  script.segments = {stroke};
  const HandIntent intent = plan_or_fail(script);
  // 5 cm at 0.1 m/s with two 0.1 s smoothstep ramps (each covering 5 mm): 0.6 s.
  EXPECT_NEAR(intent.duration_s(), 0.6, 1e-12);
  EXPECT_NEAR(intent.at(0.1).position_m.x, 0.005, 1e-15);
  EXPECT_NEAR(intent.at(0.3).velocity_m_per_s.x, 0.1, 1e-15);
  EXPECT_NEAR(intent.at(0.6 - 1e-9).position_m.x, 0.05, 1e-9);
  EXPECT_NEAR(intent.at(0.3).force_n.z, -1.5, 1e-15);     // presses along -normal
  EXPECT_NEAR(intent.at(0.025).force_n.z, -0.75, 1e-12);  // half way up its 0.05 s force ramp
}

TEST(HandIntent, ACrossingKeepsItsSpeedIntoTheNextSegmentOrSlowsDown) {
  HandScript script;
  HandSegment run = segment(SegmentKind::kCross, {0.02, 0.0, 0.0}, 0.2);
  run.force_n = 1.0;
  run.stop = false;
  HandSegment slow = segment(SegmentKind::kCross, {0.04, 0.0, 0.0}, 0.05);
  slow.force_n = 1.0;
  slow.stop = true;
  script.segments = {run, slow};
  const HandIntent intent = plan_or_fail(script);
  const double boundary = intent.segment_start_s(1);
  // Speed and position are continuous at the boundary: the second segment starts at 0.2 m/s.
  EXPECT_NEAR(intent.at(boundary - 1e-9).velocity_m_per_s.x, 0.2, 1e-6);
  EXPECT_NEAR(intent.at(boundary).velocity_m_per_s.x, 0.2, 1e-12);
  EXPECT_NEAR(intent.at(boundary).position_m.x, 0.02, 1e-12);
  EXPECT_NEAR(intent.at(boundary + 0.1).velocity_m_per_s.x, 0.05, 1e-12);  // slowed over its ramp
}

TEST(HandIntent, ReportsASegmentTooShortForItsRamps) {
  HandScript script;
  HandSegment stroke = segment(SegmentKind::kStroke, {0.005, 0.0, 0.0}, 0.2);
  stroke.ramp_s = 0.1;  // 2 x 1 cm of ramps on a 5 mm path
  stroke.force_n = 1.0;
  script.segments = {stroke};
  PlanError error;
  EXPECT_FALSE(HandIntent::plan(script, error).has_value());
  EXPECT_EQ(error.segment, 0U);
  EXPECT_EQ(error.key, "to");
}

TEST(HandIntent, AReleaseEndsTheGraspAndTheDeviceMovesOnItsOwn) {
  HandScript script;
  script.segments = {segment(SegmentKind::kHold, {}, {}, 0.1), segment(SegmentKind::kRelease)};
  const HandIntent intent = plan_or_fail(script);
  EXPECT_TRUE(intent.at(0.05).grasping);
  EXPECT_FALSE(intent.at(0.1).grasping);
  // Released, a push of 0.01 N for 0.2 s moves the 0.15 kg handle by F t^2 / 2m = 1.33 mm
  // (the hand's spring and mass are gone).
  auto device = SimDevice::create(bare_device(0.15, 0.0), intent, {Integrator::kExact, 1, 1e-3});
  ASSERT_TRUE(device);
  for (int k = 0; k < 100; ++k) static_cast<void>(device->write({}));
  for (int k = 0; k < 200; ++k) static_cast<void>(device->write({0.01, 0.0, 0.0}));
  EXPECT_NEAR(device->plant().position_m().x, 0.01 * 0.2 * 0.2 / (2 * 0.15), 1e-12);
}

// ---- the run-time driver ----------------------------------------------------------------

TEST(SimDriver, EachExchangeAdvancesOnePeriodAndEmergencyZeroLatchesUntilRearmed) {
  auto driver = SimDriver::create(falcon_params(), HandIntent::holding({}), {Integrator::kRk4, 4, 1e-3});
  ASSERT_TRUE(driver);
  DeviceDriver& d = *driver.value();
  EXPECT_NE(d.info().name.find("host simulation"), std::string::npos);
  EXPECT_DOUBLE_EQ(d.info().max_force_n, 8.0);
  DeviceReading reading;
  for (int k = 0; k < 10; ++k) {
    ASSERT_EQ(d.read(reading), DeviceStatus::kOk);
    ASSERT_EQ(d.write({0.0, 0.0, 1.0}), DeviceStatus::kOk);
  }
  EXPECT_EQ(driver.value()->device().tick(), 10);
  EXPECT_GT(driver.value()->device().applied_force_n().z, 0.99);

  std::thread watchdog([&d] { d.emergency_zero(); });  // from another thread
  watchdog.join();
  for (int k = 0; k < 5; ++k) ASSERT_EQ(d.write({0.0, 0.0, 1.0}), DeviceStatus::kOk);
  EXPECT_EQ(driver.value()->device().applied_force_n(), (Vec3<double>{}));
  driver.value()->rearm();
  ASSERT_EQ(d.write({0.0, 0.0, 1.0}), DeviceStatus::kOk);
  EXPECT_GT(driver.value()->device().applied_force_n().z, 0.99);
}

TEST(SimDriver, SatisfiesTheServoDeviceConceptThroughDriverRef) {
  auto driver = SimDriver::create(omni_params(), HandIntent::holding({}), {Integrator::kExact, 4, 1e-3});
  ASSERT_TRUE(driver);
  DriverRef ref(*driver.value());
  static_assert(ServoDevice<DriverRef>);
  DeviceReading reading;
  EXPECT_EQ(ref.read(reading), DeviceStatus::kOk);
  EXPECT_EQ(ref.write({0.0, 5.0, 0.0}), DeviceStatus::kOk);
  EXPECT_LE(driver.value()->device().applied_force_n().y, 3.3);  // the Omni's peak
}

}  // namespace
}  // namespace toonforce::host_sim
