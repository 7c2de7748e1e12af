// SPDX-License-Identifier: Apache-2.0
// The servo loop as replay runs it (effects.md §6 stages only): velocity estimator, the safety
// stage of effects.md §6, the non-finite guard, determinism, and no allocation in a tick.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "alloc_counter.hpp"
#include "spec_loop.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"

namespace toonforce::test {
namespace {

constexpr double kDt = 1e-3;
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

using Floor = Scene<Surface<PenaltyWall<double>>>;
Floor floor_scene(double k = 1000.0, double b = 0.0) {
  return Floor(Surface<PenaltyWall<double>>::Params{{{0, 0, 0}, {0, 0, 1}}, {k, b}, {}, {}});
}

ServoConfig config(ForceLimits limits = {}) {
  ServoConfig c;
  c.limits = limits;
  c.period_s = kDt;
  return c;
}

TEST(ForceSafety, ClampsTheMagnitudeKeepingDirection) {
  SpecLoop ctl(floor_scene(1000.0), config({8.0, 0.0, true, false}));
  const auto r = ctl.tick(sample(0, {0, 0, -0.02}));  // 20 N asked
  EXPECT_NEAR(r.force_n.z, 8.0, 1e-12);
  EXPECT_NEAR(r.scene_force_n.z, 20.0, 1e-12);
  EXPECT_EQ(r.limits, static_cast<std::uint8_t>(Limit::kClamped));
}

TEST(ForceSafety, LimitsTheRateOfChangeFromThePreviousOutput) {
  SpecLoop ctl(floor_scene(1000.0), config({0.0, 2000.0, false, true}));  // 2 N per 1 ms tick
  double previous = 0.0;
  for (int k = 0; k < 5; ++k) {
    const auto r = ctl.tick(sample(k, {0, 0, -0.007}));  // a 7 N step
    EXPECT_NEAR(r.force_n.z, std::min(7.0, previous + 2.0), 1e-12) << k;
    previous = r.force_n.z;
  }
  EXPECT_NEAR(previous, 7.0, 1e-12);
}

TEST(ForceSafety, RateLimitScalesTheStepAlongItsDirection) {
  Surface<PenaltyWall<double>>::Params a{{{0, 0, 0}, {0, 0, 1}}, {1000.0, 0.0}, {}, {}};
  Surface<PenaltyWall<double>>::Params b{{{0, 0, 0}, {1, 0, 0}}, {1000.0, 0.0}, {}, {}};
  SpecLoop ctl(Scene<Surface<PenaltyWall<double>>, Surface<PenaltyWall<double>>>(a, b),
               config({0.0, 1000.0, false, true}));
  const auto r = ctl.tick(sample(0, {-0.003, 0, -0.004}));  // (3, 0, 4) N asked, 1 N allowed
  EXPECT_NEAR(r.force_n.x, 0.6, 1e-12);
  EXPECT_NEAR(r.force_n.z, 0.8, 1e-12);
}

TEST(ForceSafety, ClampsAfterTheRateLimit) {
  // Rate limit allows 5 N/tick from 0; the clamp at 3 N must still hold.
  SpecLoop ctl(floor_scene(1000.0), config({3.0, 5000.0, true, true}));
  const auto r = ctl.tick(sample(0, {0, 0, -0.01}));
  EXPECT_NEAR(r.force_n.z, 3.0, 1e-12);
  EXPECT_EQ(r.limits, static_cast<std::uint8_t>(Limit::kRateLimited) | Limit::kClamped);
}

TEST(ForceSafety, AppliesNothingWithoutLimits) {
  SpecLoop ctl(floor_scene(1e6), config());
  EXPECT_NEAR(ctl.tick(sample(0, {0, 0, -0.1})).force_n.z, 1e5, 1e-6);
}

TEST(NonFiniteGuard, NanPositionGivesExactlyZeroAndAFault) {
  SpecLoop ctl(floor_scene(1000.0), config({8.0, 2000.0, true, true}));
  for (int k = 0; k < 10; ++k) ctl.tick(sample(k, {0, 0, -0.005}));
  const auto r = ctl.tick(sample(10, {0, kNan, -0.005}));
  EXPECT_EQ(r.force_n, (Vec3<double>{}));  // bypasses the rate limit
  EXPECT_TRUE(r.faults.has(Fault::kNonFiniteInput));
  // The previous output became 0: the next tick ramps from 0 at the rate limit.
  EXPECT_NEAR(ctl.tick(sample(11, {0, 0, -0.005})).force_n.z, 2.0, 1e-12);
}

TEST(NonFiniteGuard, InfiniteVelocityInputIsAFault) {
  SpecLoop ctl(floor_scene(1000.0), config());
  Sample s = sample(0, {0, 0, -0.001});
  s.has_velocity = true;
  s.velocity_m_per_s = {std::numeric_limits<double>::infinity(), 0, 0};
  const auto r = ctl.tick(s);
  EXPECT_EQ(r.force_n, (Vec3<double>{}));
  EXPECT_TRUE(r.faults.has(Fault::kNonFiniteInput));
}

TEST(NonFiniteGuard, NonFiniteSceneForceGivesZeroAndKeepsEffectStates) {
  // A finite but absurd position overflows the wall force to infinity.
  using Wall = Surface<PenaltyWall<double>, NoTangential<double>, ImpactTransient<double>>;
  Wall::Params p{};
  p.plane = {{0, 0, 0}, {0, 0, 1}};
  p.wall = {1000.0, 0.0};
  p.impact = {300.0, 600.0, 0.15, 30.0, 0.05, 0.001, SineMethod::kLibrary};
  SpecLoop ctl(Scene<Wall>(p), config());
  Sample s = sample(0, {0, 0, 0.001});
  s.has_velocity = true;
  s.velocity_m_per_s = {0, 0, -0.2};
  ctl.tick(s);
  s = sample(1, {0, 0, -1e306});
  s.has_velocity = true;
  s.velocity_m_per_s = {0, 0, -0.2};
  const auto bad = ctl.tick(s);
  EXPECT_EQ(bad.force_n, (Vec3<double>{}));
  EXPECT_TRUE(bad.faults.has(Fault::kNonFiniteForce));
  // Had the impact state advanced on the bad tick, this entry would not count as one.
  s = sample(2, {0, 0, -0.0001});
  s.has_velocity = true;
  s.velocity_m_per_s = {0, 0, -0.2};
  const auto r = ctl.tick(s);
  EXPECT_NEAR(r.force_n.z, 0.1 + 0.2 * 0.15 * 300.0, 1e-9);
  EXPECT_FALSE(r.faults);
}

// Stiffness = 1e308 gave a finite force (1e305 N) whose square overflows; the clamp
// measured it as infinite and scaled it to a silent 0 with no fault ("peak 0 N, faults none").
// Such a force is a fault, with zero force, like a non-finite one.
TEST(NonFiniteGuard, AFiniteForceWhoseSquareOverflowsIsAFaultNotASilentZero) {
  SpecLoop ctl(floor_scene(1e308), config({8.0, 0.0, true, false}));
  const auto bad = ctl.tick(sample(0, {0, 0, -0.001}));
  EXPECT_EQ(bad.force_n, (Vec3<double>{}));
  EXPECT_TRUE(bad.faults.has(Fault::kNonFiniteForce));
  // With the rate limit too (it would hold the last force), and with the rate limit alone.
  for (const ForceLimits limits : {ForceLimits{8.0, 1000.0, true, true}, ForceLimits{8.0, 1000.0, false, true}}) {
    SpecLoop limited(floor_scene(1e308), config(limits));
    const auto r = limited.tick(sample(0, {0, 0, -0.001}));
    EXPECT_EQ(r.force_n, (Vec3<double>{}));
    EXPECT_TRUE(r.faults.has(Fault::kNonFiniteForce));
  }
  // The same wall at a sane stiffness is clamped, not faulted.
  SpecLoop sane(floor_scene(1e12), config({8.0, 0.0, true, false}));
  const auto ok = sane.tick(sample(0, {0, 0, -0.001}));
  EXPECT_NEAR(ok.force_n.z, 8.0, 1e-12);
  EXPECT_FALSE(ok.faults);
}

TEST(VelocityEstimator, FollowsTheSpecsLowPassOfTheBackwardDifference) {
  // A damped wall makes the estimate visible in the force: F = k delta - b (n.v).
  const double b = 10.0;
  SpecLoop ctl(floor_scene(1000.0, b), config());
  const double a = kDt / (kDt + 1.0 / (2.0 * M_PI * 50.0));
  double v = 0.0;
  double z_previous = -0.001;
  for (int k = 0; k < 50; ++k) {
    const double z = -0.001 - 0.05 * k * kDt;  // moving in at 5 cm/s
    const auto r = ctl.tick(sample(k, {0, 0, z}));
    if (k > 0) v += a * ((z - z_previous) / kDt - v);  // first tick: 0
    z_previous = z;
    EXPECT_NEAR(r.force_n.z, std::max(0.0, -1000.0 * z - b * v), 1e-9) << k;
  }
  EXPECT_NEAR(v, -0.05, 0.01);  // it has converged toward the true speed
}

TEST(VelocityEstimator, AfterADroppedSampleUsesTheTimeSinceTheLastGoodOne) {
  SpecLoop ctl(floor_scene(1000.0, 10.0), config());
  const double a1 = kDt / (kDt + 1.0 / (2.0 * M_PI * 50.0));
  const double a2 = 2 * kDt / (2 * kDt + 1.0 / (2.0 * M_PI * 50.0));
  ctl.tick(sample(0, {0, 0, -0.001}));
  ctl.tick(sample(1, {0, 0, -0.0011}));  // v1 = a1 * (-0.1)
  ctl.tick(sample(2, {0, 0, kNan}));
  const auto r = ctl.tick(sample(3, {0, 0, -0.0013}));  // 0.2 mm in 2 ms: still -0.1 m/s
  const double v1 = a1 * -0.1;
  const double v3 = v1 + a2 * (-0.1 - v1);
  EXPECT_NEAR(r.force_n.z, 1.3 - 10.0 * v3, 1e-9);
}

TEST(SpecLoop, GivenVelocityIsUsedAsItIs) {
  SpecLoop ctl(floor_scene(1000.0, 10.0), config());
  Sample s = sample(0, {0, 0, -0.001});
  s.has_velocity = true;
  s.velocity_m_per_s = {0, 0, -0.3};
  EXPECT_NEAR(ctl.tick(s).force_n.z, 1.0 + 3.0, 1e-12);  // no estimator: first tick is not 0
}

TEST(SpecLoop, SameInputsGiveBitIdenticalForces) {
  const auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/cartoon_wall.toml");
  ASSERT_TRUE(scene) << scene.error();
  std::vector<Vec3<double>> first, second;
  for (auto* out : {&first, &second}) {
    SpecLoop ctl(make_runtime_scene<double>(scene.value()), servo_config(scene.value(), kDt));
    std::mt19937_64 rng(7);
    std::normal_distribution<double> noise(0.0, 2e-5);
    for (int k = 0; k < 5000; ++k) {
      const double z = 0.01 * std::cos(k * 0.004) - 0.004 + noise(rng);
      out->push_back(ctl.tick(sample(k, {0, 0, z})).force_n);
    }
  }
  ASSERT_EQ(first.size(), second.size());
  for (std::size_t i = 0; i < first.size(); ++i) ASSERT_EQ(first[i], second[i]) << i;
}

TEST(SpecLoop, Q16SaturationRaisesItsFault) {
  const auto scene = parse_scene("[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 20000\n",
                                 "stiff.toml", ScalarKind::kQ16_16);
  ASSERT_TRUE(scene) << scene.error();
  SpecLoop ctl(make_runtime_scene<Q16_16>(scene.value()), servo_config(scene.value(), kDt));
  EXPECT_FALSE(ctl.tick(sample(0, {0, 0, -0.001})).faults);  // 20 N fits
  const auto r = ctl.tick(sample(1, {0, 0, -2.0}));          // 40000 N does not
  EXPECT_TRUE(r.faults.has(Fault::kFixedSaturation));
  EXPECT_EQ(r.force_n.z, Q16_16::max());  // saturated, not wrapped
}

TEST(ForceSafety, Q16LimitsHoldWhenTheRequestIsHuge) {
  // Found by tests/fuzz/tick_fuzz.cpp: scaling a 30000 N request down to a 13 N step by the
  // ratio 13/30000, itself rounded to an LSB (29 LSB, 2% off), overshot the rate limit by
  // 0.2 N. The limits scale by (v * limit) / |v| in 64 bits instead.
  const auto scene = parse_scene("[device]\nmax_force = 20\nmax_force_rate = 2000\n[[surface]]\npoint = [0, 0, 0]\n"
                                 "normal = [0, 0, 1]\nstiffness = 30000\n",
                                 "huge.toml", ScalarKind::kQ16_16);
  ASSERT_TRUE(scene) << scene.error();
  // Stamped time, 6.6 ms apart: allows 13.2 N per tick.
  SpecLoop ctl(make_runtime_scene<Q16_16>(scene.value()), replay_config(scene.value(), 0.0066));
  constexpr double kLsb = 1.0 / 65536.0;
  Sample s = sample(0, {0, 0, -0.999});  // asks for 29970 N
  const auto first = ctl.tick(s, 0);
  EXPECT_LE(first.force_n.z.to_double(), 2000.0 * 0.0066 + 2 * kLsb);
  EXPECT_GE(first.force_n.z.to_double(), 2000.0 * 0.0066 - 2 * kLsb);
  s = sample(1, {0, 0, -0.999});
  const auto second = ctl.tick(s, 6'600'000);
  EXPECT_LE(second.force_n.z.to_double(), 20.0 + 2 * kLsb);  // then the clamp holds
  EXPECT_GE(second.force_n.z.to_double(), 20.0 - 2 * kLsb);
}

TEST(ForceSafety, Q16RateLimitHoldsOnTicksShorterThanItsRateCanHold) {
  // Found by tests/fuzz/tick_fuzz.cpp: stamps 10 us apart are 100 kHz, which Q16.16 cannot
  // hold (32,767 is its largest value). The step max_force_rate / rate_hz used the saturated
  // rate, 2000 / 32768 = 0.061 N where 0.02 N is allowed; when that step was computed once at
  // construction (the configured period) the step's saturation raised no fault either. The
  // step comes from the integer dt instead: 2000 N/s * 10 us, rounded down.
  const auto scene = parse_scene("[device]\nmax_force = 8\nmax_force_rate = 2000\n[[surface]]\npoint = [0, 0, 0]\n"
                                 "normal = [0, 0, 1]\nstiffness = 1000\n",
                                 "fast.toml", ScalarKind::kQ16_16);
  ASSERT_TRUE(scene) << scene.error();
  constexpr std::int64_t kStepNs = 10'000;
  constexpr double kAllowed = 2000.0 * 1e-5;
  for (const std::int64_t configured_ns : {kStepNs, std::int64_t{1'000'000}}) {  // the period's step, and any dt's
    SpecLoop ctl(make_runtime_scene<Q16_16>(scene.value()),
                 replay_config(scene.value(), static_cast<double>(configured_ns) / 1e9));
    double previous = 0.0;
    for (std::int64_t k = 0; k < 20; ++k) {
      Sample s = sample(k, {0, 0, -0.005});  // asks for 5 N
      s.has_velocity = true;
      const auto r = ctl.tick(s, k * kStepNs);
      const double f = r.force_n.z.to_double();
      if (k == 0) {  // the first tick's dt is the configured period
        previous = f;
        continue;
      }
      // 1/dt itself saturates (replay refuses such rows: fixed_point::check_rate); the limit holds even so.
      EXPECT_TRUE(r.faults.has(Fault::kFixedSaturation)) << configured_ns << " tick " << k;
      EXPECT_LE(f - previous, kAllowed) << configured_ns << " tick " << k;
      EXPECT_GE(f - previous, kAllowed - 2.0 / 65536.0) << configured_ns << " tick " << k;  // and it is used
      previous = f;
    }
  }
}

TEST(ForceSafety, Q16ClampHoldsWhenTheForcesNormIsBeyondTheQ16Range) {
  // Found by tests/fuzz/tick_fuzz.cpp (CI, 2026-11-23): a force of 32767 N on every axis has a
  // norm of 56755 N, which a Q16.16 norm saturates at 32768; scaled by 8 / 32768 each axis gave
  // 8 N, (8, 8, 8), 13.9 N out of an 8 N clamp. The ratio is taken with the true norm then.
  ForceLimits limits;
  limits.has_max_force = true;
  limits.max_force_n = 8.0;
  ForceSafety<Q16_16> safety(limits);
  const Vec3<Q16_16> huge{Q16_16::max(), Q16_16::max(), Q16_16::lowest()};
  const auto out = safety.limit(huge, scalar_cast<Q16_16>(1000.0));
  const Vec3<double> f = to_double(out.force_n);
  constexpr double kLsb = 1.0 / 65536.0;
  EXPECT_LE(std::sqrt(dot(f, f)), 8.0 + 2 * kLsb);
  EXPECT_NEAR(f.x, 8.0 / std::sqrt(3.0), 2 * kLsb) << "direction kept";
  EXPECT_NEAR(f.z, -8.0 / std::sqrt(3.0), 2 * kLsb);
  // The rate limit's step the same way, and limit_magnitude too.
  ForceLimits rate_only;
  rate_only.has_max_force_rate = true;
  rate_only.max_force_rate_n_per_s = 5000.0;  // 5 N per tick at 1 kHz
  ForceSafety<Q16_16> step(rate_only);
  const Vec3<double> g = to_double(step.limit(huge, scalar_cast<Q16_16>(1000.0)).force_n);
  EXPECT_LE(std::sqrt(dot(g, g)), 5.0 + 2 * kLsb);
  const Vec3<double> h = to_double(limit_magnitude(huge, scalar_cast<Q16_16>(3.0)));
  EXPECT_LE(std::sqrt(dot(h, h)), 3.0 + 2 * kLsb);
}

TEST(ForceSafety, Q16RateLimitStepsTowardARequestBeyondTheRange) {
  // From -20000 N to +30000 N on x (and back on y) the difference, 50000 N, is past the Q16.16
  // range and saturates; the step is scaled from it and added to the previous output without
  // a saturation test (plus_in_range): it must still land between the two, the limit's size
  // along the difference's direction.
  ForceLimits rate_only;
  rate_only.has_max_force_rate = true;
  rate_only.max_force_rate_n_per_s = 1.0;  // any: the step is given
  ForceSafety<Q16_16> safety(rate_only);
  const Vec3<Q16_16> from = vec_cast<Q16_16>(Vec3<double>{-20000.0, 20000.0, 0.0});
  ASSERT_EQ(safety.limit_step(from, scalar_cast<Q16_16>(30000.0)).limits, 0);  // 28284 N: not limited
  const auto out =
      safety.limit_step(vec_cast<Q16_16>(Vec3<double>{30000.0, -30000.0, 0.0}), scalar_cast<Q16_16>(20000.0));
  EXPECT_TRUE(has(out.limits, Limit::kRateLimited));
  const Vec3<double> f = to_double(out.force_n);
  const double step = 20000.0 / std::sqrt(2.0);
  EXPECT_NEAR(f.x, -20000.0 + step, 0.01);
  EXPECT_NEAR(f.y, 20000.0 - step, 0.01);
  EXPECT_EQ(f.z, 0.0);
  EXPECT_EQ(out.force_n, safety.previous_output());
}

TEST(ForceSafety, Q16LimitsCompareTheSquaresExactly) {
  // The limits compared Q16.16 squares, rounded to 2^-16: a 0.02 N step's square is 26 LSB, so
  // steps up to 6 LSB (0.5 %) over a 0.02 N rate limit passed unlimited, and up to 38 % over a
  // 0.002 N one (2 N/s at 1 kHz); a square above 32,768 N^2 saturated, so a 200 N clamp let
  // 250 N out (with a saturation fault, after the write). Every step from 10 LSB under the
  // limit to 60 over, along an axis and a diagonal: limited exactly when its norm is over.
  constexpr double kLsb = 1.0 / 65536.0;
  ForceLimits rate_only;
  rate_only.has_max_force_rate = true;
  rate_only.max_force_rate_n_per_s = 1.0;  // any: the step is given
  for (const double limit_n : {0.02, 0.002}) {
    const Q16_16 max_step = scalar_cast<Q16_16>(limit_n);
    for (const Vec3<double> direction : {Vec3<double>{1, 0, 0}, Vec3<double>{0.6, -0.48, 0.64}}) {
      for (std::int32_t over = -10; over <= 60; ++over) {
        ForceSafety<Q16_16> safety(rate_only);
        const Vec3<Q16_16> wanted = vec_cast<Q16_16>(direction * ((max_step.raw() + over) * kLsb));
        const Vec3<double> w = to_double(wanted);
        const double wanted_n = std::sqrt(dot(w, w));
        static_cast<void>(take_fixed_saturated());
        const auto out = safety.limit_step(wanted, max_step);
        const Vec3<double> f = to_double(out.force_n);
        const bool over_limit = wanted_n > max_step.to_double();
        EXPECT_EQ(has(out.limits, Limit::kRateLimited), over_limit) << limit_n << " N, " << over << " LSB over";
        EXPECT_LE(std::sqrt(dot(f, f)), max_step.to_double() + kLsb) << limit_n << " N, " << over << " LSB over";
        if (!over_limit) {
          EXPECT_EQ(out.force_n, wanted);
        }
        EXPECT_FALSE(take_fixed_saturated());
      }
    }
  }
  ForceLimits clamp_only;
  clamp_only.has_max_force = true;
  clamp_only.max_force_n = 200.0;
  ForceSafety<Q16_16> clamp(clamp_only);
  static_cast<void>(take_fixed_saturated());
  const auto out = clamp.limit_step(vec_cast<Q16_16>(Vec3<double>{150.0, -120.0, 160.0}), Q16_16{});  // 250 N
  const Vec3<double> f = to_double(out.force_n);
  EXPECT_TRUE(has(out.limits, Limit::kClamped));
  EXPECT_LE(std::sqrt(dot(f, f)), 200.0 + 2 * kLsb);
  EXPECT_GE(std::sqrt(dot(f, f)), 200.0 - 2 * kLsb);
  EXPECT_NEAR(f.x, 120.0, 2 * kLsb) << "direction kept";
  EXPECT_FALSE(take_fixed_saturated()) << "250 N is well inside Q16.16";
}

/// A tick of every bundled scene, in every scalar type, allocates nothing.
template <Scalar S>
void expect_no_allocation(const std::string& name, ScalarKind kind) {
  const auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/" + name + ".toml", kind);
  ASSERT_TRUE(scene) << scene.error();
  SpecLoop ctl(make_runtime_scene<S>(scene.value()), servo_config(scene.value(), kDt));
  test::AllocationScope scope;
  for (int k = 0; k < 10000; ++k) {
    // Sweeps across the gap, into and out of the floor, through the impact transient.
    const double x = -0.03 + 0.06 * std::fmod(k * 1e-3, 1.0);
    const double z = 0.006 * std::sin(k * 0.02) - 0.002;
    static_cast<void>(ctl.tick(sample(k, {x, 0.0, k % 997 == 0 ? kNan : z})));
  }
  EXPECT_EQ(scope.count(), 0U) << name << " " << scalar_kind_name(kind);
}

TEST(SpecLoop, TicksOfEveryBundledSceneAllocateNothing) {
  for (const char* name : {"wall", "realistic_friction", "slippery", "cartoon_wall", "cliff"}) {
    expect_no_allocation<double>(name, ScalarKind::kDouble);
    expect_no_allocation<float>(name, ScalarKind::kFloat);
    expect_no_allocation<Q16_16>(name, ScalarKind::kQ16_16);
  }
}

TEST(SpecLoop, TicksOfCompileTimeScenesAllocateNothing) {
  SpecLoop ctl(floor_scene(1000.0, 1.0), config({8.0, 2000.0, true, true}));
  test::AllocationScope scope;
  for (int k = 0; k < 10000; ++k) static_cast<void>(ctl.tick(sample(k, {0, 0, 0.003 * std::sin(k * 0.01)})));
  EXPECT_EQ(scope.count(), 0U);
}

TEST(AllocationCounter, SeesAnAllocation) {  // the counter itself can fail
  test::AllocationScope scope;
  void* p = ::operator new(16);  // a direct call: not elidable like a new-expression
  ::operator delete(p);
  EXPECT_EQ(scope.count(), 1U);
}

}  // namespace
}  // namespace toonforce::test
