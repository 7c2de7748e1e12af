// SPDX-License-Identifier: Apache-2.0
// The servo loop's safety layer, one behaviour at a time (spec effects.md §6), in
// double and in Q16.16 (the firmware scalar): clamp, rate limit, soft start, engage, velocity
// limit, workspace, watchdog latch and re-arm, device silence, e-stop, enable, homing, lights,
// integer time.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "servo_support.hpp"

namespace toonforce::test {
namespace {

template <class S>
class ServoSafety : public ::testing::Test {};
TYPED_TEST_SUITE(ServoSafety, ServoScalars);

constexpr Vec3<double> kAbove{0.0, 0.0, 0.01};

// ---- clamp and rate limit (effects.md §6, the controller's stage, through the loop) -------

TYPED_TEST(ServoSafety, ClampsTheForceToMaxForceKeepingItsDirection) {
  Rig<TypeParam> rig(floor_toml(1000.0), bare_config());
  rig.at(kAbove);                                  // engage outside the wall
  const TickStatus s = rig.at({0.0, 0.0, -0.02});  // 20 N asked
  EXPECT_NEAR(rig.force().z, 8.0, kForceTol<TypeParam>);
  EXPECT_NEAR(rig.force().x, 0.0, 1e-12);
  EXPECT_TRUE(has(s.limits, Limit::kClamped));
  EXPECT_EQ(s.state, LoopState::kActive);
  EXPECT_FALSE(s.faults);
}

TYPED_TEST(ServoSafety, LimitsTheForceRateAndASkippedTickAllowsTwiceTheStep) {
  ServoConfig c = bare_config();
  c.limits.has_max_force_rate = true;
  c.limits.max_force_rate_n_per_s = 1000.0;  // 1 N per 1 ms tick
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  rig.at(kAbove);
  rig.at({0, 0, -0.006});  // a 6 N step
  EXPECT_NEAR(rig.force().z, 1.0, kForceTol<TypeParam>);
  rig.k += 1;  // the next deadline is skipped: dt = 2T
  const TickStatus s = rig.at({0, 0, -0.006});
  EXPECT_NEAR(rig.force().z, 3.0, kForceTol<TypeParam>);
  EXPECT_TRUE(has(s.limits, Limit::kRateLimited));
}

TYPED_TEST(ServoSafety, ADeviceThatCouldNotGiveTheForceIsFlaggedInTheLimitsNotAsAFault) {
  // The Falcon outside its force envelope (motor words capped) says so in its next reading:
  // the tick carries the device-envelope limit bit, the force is the loop's as before.
  Rig<TypeParam> rig(floor_toml(1000.0), bare_config());
  rig.at(kAbove);
  const TickStatus within = rig.at({0.0, 0.0, -0.005});
  EXPECT_FALSE(has(within.limits, Limit::kDeviceLimited));
  rig.device.force_limited = true;
  const TickStatus limited = rig.at({0.0, 0.0, -0.005});
  EXPECT_TRUE(has(limited.limits, Limit::kDeviceLimited));
  EXPECT_NEAR(rig.force().z, 5.0, kForceTol<TypeParam>);
  EXPECT_FALSE(limited.faults);
  EXPECT_EQ(limited.state, LoopState::kActive);
  rig.device.force_limited = false;
  EXPECT_FALSE(has(rig.at({0.0, 0.0, -0.005}).limits, Limit::kDeviceLimited));
}

// ---- engage and soft start ---------------------------------------------------------------

TYPED_TEST(ServoSafety, DoesNotEngageInsideAWallUntilTheSceneForceIsBelowEngageForce) {
  ServoConfig c = bare_config();
  c.safety.engage_force_n = 0.2;
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  for (int i = 0; i < 50; ++i) {
    const TickStatus s = rig.at({0, 0, -0.005});  // 5 N inside the wall
    EXPECT_EQ(rig.force(), (Vec3<double>{})) << i;
    EXPECT_EQ(s.state, LoopState::kEngaging);
    EXPECT_TRUE(has(s.limits, Limit::kEngaging));
  }
  rig.at({0, 0, -0.0003});  // 0.3 N: still above 0.2 N
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  rig.at({0, 0, -0.0001});  // 0.1 N: engages (soft start 0: full force at once)
  EXPECT_NEAR(rig.force().z, 0.1, kForceTol<TypeParam>);
  rig.at({0, 0, -0.005});  // and stays engaged back in the wall
  EXPECT_NEAR(rig.force().z, 5.0, kForceTol<TypeParam>);
}

TYPED_TEST(ServoSafety, SoftStartRampsLinearlyFromTheEngagingTick) {
  ServoConfig c = bare_config();
  c.safety.soft_start_s = 0.1;  // 100 ticks
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  rig.at(kAbove);  // engages at k = 0: gain 0
  for (int k = 1; k <= 120; ++k) {
    const TickStatus s = rig.at({0, 0, -0.004});  // 4 N
    const double gain = std::min(1.0, k * kPeriodS / 0.1);
    EXPECT_NEAR(rig.force().z, 4.0 * gain, kForceTol<TypeParam>) << k;
    EXPECT_EQ(has(s.limits, Limit::kSoftStart), gain < 1.0) << k;
    EXPECT_EQ(s.state, gain < 1.0 ? LoopState::kRamping : LoopState::kActive) << k;
  }
}

// In Q16.16 the ramp is the tick count times a 32-bit fraction per tick, no division: the
// exactly rounded (k - start) T / soft_start except within (k - start) 2^-17 LSB of a tie.
TEST(Engage, Q16RampIsTheRoundedQuotientOfTheElapsedTime) {
  struct Ramp {
    double soft_start_s;
    double period_s;
  };
  for (const Ramp r :
       {Ramp{1.0, 1e-3}, Ramp{0.1, 1e-3}, Ramp{0.25, 2.5e-4}, Ramp{3.7, 1e-3}, Ramp{10.0, 1e-4}, Ramp{0.0021, 1e-3}}) {
    Engage<Q16_16> engage(EngageConfig{0.2, r.soft_start_s, r.period_s});
    const std::int64_t period_ns = ns_from_seconds(r.period_s);
    const std::int64_t soft_start_ns = ns_from_seconds(r.soft_start_s);
    const std::int64_t start = 5;
    ASSERT_EQ(engage.gain(Vec3<Q16_16>{}, start), Q16_16{});  // engages: the ramp starts here
    for (std::int64_t k = start + 1;; ++k) {
      const Q16_16 gain = engage.gain(Vec3<Q16_16>{}, k);
      const std::int64_t elapsed_ns = (k - start) * period_ns;
      if (elapsed_ns >= soft_start_ns) {
        EXPECT_EQ(gain, Q16_16::from_raw(65536)) << r.soft_start_s << " s at " << r.period_s << " s, tick " << k;
        EXPECT_EQ(engage.state(), LoopState::kActive);
        break;
      }
      ASSERT_EQ(engage.state(), LoopState::kRamping);
      const Q16_16 exact = Q16_16::from_ratio(elapsed_ns, soft_start_ns);
      if (gain == exact) continue;
      // Off by one only near a tie: |2 (elapsed 2^16 mod soft_start) - soft_start| is then tiny.
      const std::int64_t twice_remainder = 2 * ((elapsed_ns << 16) % soft_start_ns);
      ASSERT_EQ(std::abs(gain.raw() - exact.raw()), 1) << k;
      ASSERT_LE(std::abs(twice_remainder - soft_start_ns) * (std::int64_t{1} << 16), soft_start_ns * (k - start))
          << r.soft_start_s << " s at " << r.period_s << " s, tick " << k << " is not near a tie";
    }
  }
}

// A ramp of more than 2^16 ticks whose step per tick was rounded up adds up its rounding: the
// gain is capped at 1 (the loop scales the force by it without a saturation test). A 300 s
// soft start at about 1 kHz, the period chosen so that the step is rounded up by 0.4 or more:
// 2 LSB over the ramp's 300,000 ticks, past 1 at its end without the cap.
TEST(Engage, Q16RampOfManyTicksNeverPassesOne) {
  const std::int64_t soft_start_ns = 300'000'000'000LL;
  std::int64_t period_ns = 1'000'000;
  __extension__ typedef unsigned __int128 U128;          // exact 2^32 T (g++)
  const auto tenths = [soft_start_ns](std::int64_t t) {  // of 2^32 T / soft_start's fraction
    const U128 rest = (static_cast<U128>(t) << 32) % static_cast<U128>(soft_start_ns);
    return static_cast<int>(rest * 10 / static_cast<U128>(soft_start_ns));
  };
  while (tenths(period_ns) != 5) ++period_ns;  // a fraction in [0.5, 0.6): rounded up by 0.4 or more
  Engage<Q16_16> engage(
      EngageConfig{0.2, static_cast<double>(soft_start_ns) * 1e-9, static_cast<double>(period_ns) * 1e-9});
  ASSERT_EQ(engage.gain(Vec3<Q16_16>{}, 0), Q16_16{});
  for (std::int64_t k = 1; engage.state() == LoopState::kRamping; ++k) {
    ASSERT_LE(engage.gain(Vec3<Q16_16>{}, k).raw(), 65536) << "tick " << k << " of a " << period_ns << " ns period";
  }
}

TYPED_TEST(ServoSafety, RampsAgainFromZeroAfterEveryFault) {
  ServoConfig c = bare_config();
  c.safety.soft_start_s = 0.01;  // 10 ticks
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  rig.at(kAbove);
  for (int i = 0; i < 20; ++i) rig.at({0, 0, -0.004});
  EXPECT_NEAR(rig.force().z, 4.0, kForceTol<TypeParam>);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const TickStatus bad = rig.at({0, 0, nan});
  EXPECT_TRUE(bad.faults.has(Fault::kNonFiniteInput));
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  for (int i = 0; i <= 10; ++i) {  // gain 0, 0.1, ... 1 on the ticks after the fault
    rig.at({0, 0, -0.004});
    EXPECT_NEAR(rig.force().z, 0.4 * i, kForceTol<TypeParam>) << i;
  }
}

// ---- velocity limit and workspace ----------------------------------------------------------

TYPED_TEST(ServoSafety, ForceIsOffAboveMaxVelocityAndComesBackThroughTheRamp) {
  ServoConfig c = bare_config();
  c.safety.has_max_velocity = true;
  c.safety.max_velocity_m_per_s = 1.0;
  c.safety.soft_start_s = 0.002;
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  rig.device.has_velocity = true;  // the device measures velocity
  rig.at(kAbove);
  for (int i = 0; i < 5; ++i) rig.at({0, 0, -0.002});
  EXPECT_NEAR(rig.force().z, 2.0, kForceTol<TypeParam>);
  rig.device.velocity_m_per_s = {1.5, 0.0, 0.0};
  const TickStatus fast = rig.at({0, 0, -0.002});
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  EXPECT_TRUE(fast.faults.has(Fault::kOverspeed));
  EXPECT_FALSE(fast.faults.latched());
  rig.device.velocity_m_per_s = {0.5, 0.0, 0.0};
  rig.at({0, 0, -0.002});
  EXPECT_NEAR(rig.force().z, 0.0, kForceTol<TypeParam>);  // gain 0 on the first tick after
  rig.at({0, 0, -0.002});
  EXPECT_NEAR(rig.force().z, 1.0, kForceTol<TypeParam>);  // gain 0.5
  rig.at({0, 0, -0.002});
  EXPECT_NEAR(rig.force().z, 2.0, kForceTol<TypeParam>);
}

// Q16.16 compared rounded squares: a 0.01 m/s limit's square is 6.5 LSB, so up to 0.0107 m/s
// passed it. Speeds from 5 LSB under the limit to 60 over, along an axis and a diagonal: an
// overspeed exactly when the speed is over.
TEST(MotionLimits, Q16OverspeedComparesTheSquaresExactly) {
  MotionLimitsConfig config;
  config.max_velocity_m_per_s = 0.01;
  const MotionLimits<Q16_16> limits(config);
  const std::int64_t limit_raw = scalar_cast<Q16_16>(0.01).raw();
  for (const Vec3<double> direction : {Vec3<double>{0, 0, -1}, Vec3<double>{0.6, -0.48, 0.64}}) {
    for (std::int64_t over = -5; over <= 60; ++over) {
      const Vec3<Q16_16> v = vec_cast<Q16_16>(direction * (static_cast<double>(limit_raw + over) / 65536.0));
      const std::int64_t squares = std::int64_t{v.x.raw()} * v.x.raw() + std::int64_t{v.y.raw()} * v.y.raw() +
                                   std::int64_t{v.z.raw()} * v.z.raw();
      EXPECT_EQ(limits.check(Vec3<Q16_16>{}, v).has(Fault::kOverspeed), squares > limit_raw * limit_raw)
          << over << " LSB over";
    }
  }
}

// A loop on its period only (no LoopStages::stamps) takes 1/dt after a gap of g periods from
// g with a 32-bit division: the same rate as 1e9 / (g T) by the 64-bit quotient, for periods
// from 31 us to 10 s and gaps from 1 to past the one where the rate rounds to 0.
TEST(HipSensor, Q16RateAfterAGapIsTheExactQuotientsFromTheTickCount) {
  for (const std::int64_t period_ns : {30'518LL, 31'000LL, 62'500LL, 100'000LL, 125'000LL, 333'333LL, 1'000'000LL,
                                       1'000'001LL, 2'000'000LL, 16'666'667LL, 10'000'000'000LL}) {
    const PeriodsRate<Q16_16> rate = PeriodsRate<Q16_16>::of(period_ns);
    ASSERT_TRUE(rate.fits) << period_ns;
    std::vector<std::int64_t> gaps = {1, 2, 3, 7, 30, 31, 1000, 65'535, 65'536, 1'000'003};
    for (const std::uint64_t g :
         {rate.twice_q_b / 2, rate.twice_q_b - 1, rate.twice_q_b, rate.twice_q_b + 1, rate.twice_q_b + 2}) {
      if (g >= 1) gaps.push_back(static_cast<std::int64_t>(g));
    }
    for (const std::int64_t g : gaps) {
      static_cast<void>(take_fixed_saturated());
      EXPECT_EQ(rate.after(g), Q16_16::from_ratio(kNsPerS, g * period_ns)) << period_ns << " ns times " << g;
      EXPECT_FALSE(take_fixed_saturated());
    }
  }
  // Under 30.5 us one period's rate is past Q16.16: every rate saturates, with the flag.
  const PeriodsRate<Q16_16> fast = PeriodsRate<Q16_16>::of(25'000);
  EXPECT_FALSE(fast.fits);
  static_cast<void>(take_fixed_saturated());
  EXPECT_EQ(fast.after(1), Q16_16::max());
  EXPECT_TRUE(take_fixed_saturated());
}

// A loop on its period only takes a late tick's filter gain from a table set at configuration:
// the estimate after a gap of up to kTabulatedGaps periods is bit for bit the one the gain
// computed in the tick gives (1/dt from the tick count, then 1 / (1 + rate tau)); past the table
// the gain is 1, the backward difference over the gap itself (the computed gain tends to it).
TEST(HipSensor, Q16LateTickGainIsTheComputedOneAndOnePastTheTable) {
  using Q = Q16_16;
  constexpr double kPeriod = 1e-3;
  using Sensor = HipSensor<Q, true, false>;
  const PeriodsRate<Q> rates = PeriodsRate<Q>::of(1'000'000);
  const VelocityEstimator<Q> reference(VelocityEstimator<Q>::kDefaultCutoffHz);
  for (const std::int64_t gap :
       std::vector<std::int64_t>{1, 2, 7, 31, Sensor::kTabulatedGaps, Sensor::kTabulatedGaps + 1, 100, 5000}) {
    Sensor sensor(VelocityEstimator<Q>::kDefaultCutoffHz, true, kPeriod);
    BasicDeviceReading<Q> reading{};
    const Vec3<Q> start = vec_cast<Q>({0.01, -0.02, 0.03});
    reading.position_m = start;
    TickTime first;
    first.now = Instant{1, 0};
    sensor.commit(sensor.sense(reading, first), first);  // the first estimate: 0
    VelocityEstimator<Q> expected(VelocityEstimator<Q>::kDefaultCutoffHz);
    expected.commit(reading.position_m, Vec3<Q>{});
    reading.position_m = vec_cast<Q>({0.0137, -0.0211, 0.0288});
    TickTime late;
    late.now = Instant{1 + gap, 0};
    late.gap = gap;
    const Hip<Q> hip = sensor.sense(reading, late);
    const Q rate = rates.after(gap);
    const Q gain = gap <= Sensor::kTabulatedGaps ? reference.gain(rate) : scalar_cast<Q>(1.0);
    EXPECT_EQ(hip.rate_hz, rate) << gap;
    EXPECT_EQ(hip.velocity_m_per_s, expected.estimate(reading.position_m, rate, gain)) << gap;
    if (gap > Sensor::kTabulatedGaps) {  // the backward difference itself, to a unit of the last place
      const Vec3<double> difference = to_double(reading.position_m) - to_double(start);
      EXPECT_NEAR(to_double(hip.velocity_m_per_s.x), difference.x * to_double(rate), 1e-4) << gap;
    }
  }
}

// The estimator's gain 1 / (1 + rate tau) by one 32-bit division: the quotient the 64-bit
// division gives, over the whole range of denominators >= 1 (and a smaller one counts as 1).
TEST(VelocityEstimator, Q16GainIsTheExactReciprocal) {
  std::mt19937_64 rng(32);
  std::vector<std::int32_t> denominators = {65536, 65537, 98304, 131071, 131072, 196608, 1 << 30, INT32_MAX};
  for (int i = 0; i < 200000; ++i) {
    denominators.push_back(static_cast<std::int32_t>(65536 + rng() % (std::uint64_t{INT32_MAX} - 65536)));
  }
  const Q16_16 one = Q16_16::from_raw(65536);
  for (const std::int32_t d : denominators) {
    ASSERT_EQ(Q16_16::reciprocal_of_at_least_one(Q16_16::from_raw(d)), one / Q16_16::from_raw(d)) << d;
  }
  EXPECT_EQ(Q16_16::reciprocal_of_at_least_one(Q16_16::from_raw(1000)), one);
  EXPECT_EQ(Q16_16::reciprocal_of_at_least_one(Q16_16::from_raw(-5)), one);
}

TYPED_TEST(ServoSafety, VelocityLimitAlsoWorksOnTheEstimateWhenTheDeviceGivesNone) {
  ServoConfig c = bare_config();
  c.safety.has_max_velocity = true;
  c.safety.max_velocity_m_per_s = 1.0;
  Rig<TypeParam> rig(floor_toml(1000.0), c);  // a spring-only scene needs no velocity itself
  rig.at(kAbove);
  bool cut = false;
  double x = 0.0;
  for (int i = 0; i < 100 && !cut; ++i) {
    x += 0.002;  // 2 m/s along x, 2 mm under the floor
    cut = rig.at({x, 0, -0.002}).faults.has(Fault::kOverspeed);
  }
  EXPECT_TRUE(cut) << "the filtered estimate should pass 1 m/s within 100 ms";
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
}

TYPED_TEST(ServoSafety, ForceIsOffOutsideTheWorkspace) {
  ServoConfig c = bare_config();
  c.safety.has_workspace = true;
  c.safety.workspace_min_m = {-0.05, -0.05, -0.05};
  c.safety.workspace_max_m = {0.05, 0.05, 0.05};
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  rig.at(kAbove);
  rig.at({0.049, 0, -0.003});
  EXPECT_NEAR(rig.force().z, 3.0, kForceTol<TypeParam>);
  const TickStatus out = rig.at({0.051, 0, -0.003});
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  EXPECT_TRUE(out.faults.has(Fault::kOutsideWorkspace));
  rig.at({0.049, 0, -0.003});
  EXPECT_NEAR(rig.force().z, 3.0, kForceTol<TypeParam>);  // soft start 0 here: back at once
}

// ---- watchdog, device silence, e-stop, enable ------------------------------------------------

TYPED_TEST(ServoSafety, WatchdogLatchesOnAGapBeyondItsPeriodsUntilReArmed) {
  ServoConfig c = bare_config();
  c.safety.watchdog_periods = 30;
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  rig.at(kAbove);
  rig.at({0, 0, -0.003});
  rig.k += 29;  // a gap of exactly 30 periods is tolerated
  EXPECT_FALSE(rig.at({0, 0, -0.003}).faults);
  EXPECT_NEAR(rig.force().z, 3.0, kForceTol<TypeParam>);
  rig.k += 30;  // 31 periods: latched
  const TickStatus tripped = rig.at({0, 0, -0.003});
  EXPECT_TRUE(tripped.faults.has(Fault::kWatchdog));
  EXPECT_EQ(tripped.state, LoopState::kFaulted);
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  for (int i = 0; i < 100; ++i) {  // regular ticks again: still latched
    EXPECT_TRUE(rig.at({0, 0, -0.003}).faults.has(Fault::kWatchdog));
    EXPECT_EQ(rig.force(), (Vec3<double>{}));
  }
  rig.loop.request_rearm();
  const TickStatus rearmed = rig.at({0, 0, -0.003});  // re-armed, but inside the wall: engaging
  EXPECT_FALSE(rearmed.faults);
  EXPECT_EQ(rearmed.state, LoopState::kEngaging);
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  rig.at(kAbove);
  rig.at({0, 0, -0.003});
  EXPECT_NEAR(rig.force().z, 3.0, kForceTol<TypeParam>);
}

TYPED_TEST(ServoSafety, ASilentDeviceLatchesAfterItsTimeoutAndReArmWaitsForIt) {
  ServoConfig c = bare_config();
  c.safety.device_timeout_periods = 10;
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  rig.at(kAbove);
  rig.at({0, 0, -0.003});
  rig.device.read_status = DeviceStatus::kTimeout;
  for (int i = 1; i < 10; ++i) {
    const TickStatus s = rig.at({0, 0, -0.003});
    EXPECT_TRUE(s.faults.has(Fault::kDeviceError));
    EXPECT_FALSE(s.faults.has(Fault::kDeviceSilent)) << i;
    EXPECT_EQ(rig.force(), (Vec3<double>{})) << "a failed read commands zero";
  }
  EXPECT_TRUE(rig.at({0, 0, -0.003}).faults.has(Fault::kDeviceSilent));
  rig.loop.request_rearm();
  EXPECT_TRUE(rig.at({0, 0, -0.003}).rearm_refused);
  rig.device.read_status = DeviceStatus::kOk;
  EXPECT_TRUE(rig.at(kAbove).faults.has(Fault::kDeviceSilent)) << "answering again is not a re-arm";
  rig.loop.request_rearm();
  EXPECT_FALSE(rig.at(kAbove).faults);
  rig.at({0, 0, -0.003});
  EXPECT_NEAR(rig.force().z, 3.0, kForceTol<TypeParam>);
}

TYPED_TEST(ServoSafety, EstopZeroesTheForceInTheSameTickAndLatchesUntilReleasedAndReArmed) {
  Rig<TypeParam> rig(floor_toml(1000.0), bare_config());
  rig.at(kAbove);
  rig.at({0, 0, -0.003});
  ASSERT_NEAR(rig.force().z, 3.0, kForceTol<TypeParam>);
  rig.pins.estop = PinLevel::kActive;
  const TickStatus s = rig.at({0, 0, -0.003});
  EXPECT_EQ(rig.force(), (Vec3<double>{}));  // this very tick
  EXPECT_TRUE(s.faults.has(Fault::kEstop));
  rig.loop.request_rearm();
  EXPECT_TRUE(rig.at({0, 0, -0.003}).rearm_refused);
  rig.pins.estop = PinLevel::kInactive;
  EXPECT_TRUE(rig.at({0, 0, -0.003}).faults.has(Fault::kEstop)) << "released is not re-armed";
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  rig.loop.request_rearm();
  rig.at(kAbove);
  rig.at({0, 0, -0.003});
  EXPECT_NEAR(rig.force().z, 3.0, kForceTol<TypeParam>);
}

TYPED_TEST(ServoSafety, AnEstopReadErrorCountsAsEngaged) {
  Rig<TypeParam> rig(floor_toml(1000.0), bare_config());
  rig.at(kAbove);
  rig.pins.estop = PinLevel::kError;
  EXPECT_TRUE(rig.at({0, 0, -0.003}).faults.has(Fault::kEstop));
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
}

TYPED_TEST(ServoSafety, EnableActsAsADeadmanAndReEngagesWhenPressedAgain) {
  Rig<TypeParam> rig(floor_toml(1000.0), bare_config());
  rig.at(kAbove);
  rig.at({0, 0, -0.003});
  rig.pins.enable = PinLevel::kInactive;
  const TickStatus released = rig.at({0, 0, -0.003});
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  EXPECT_EQ(released.state, LoopState::kIdle);
  EXPECT_FALSE(released.faults) << "releasing the deadman is not a fault";
  rig.pins.enable = PinLevel::kActive;
  EXPECT_EQ(rig.at({0, 0, -0.003}).state, LoopState::kEngaging) << "enabling inside the wall waits";
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  rig.at({0, 0, 0.001});
  rig.at({0, 0, -0.003});
  EXPECT_NEAR(rig.force().z, 3.0, kForceTol<TypeParam>);
}

TYPED_TEST(ServoSafety, AHomingDeviceGetsNoForceAndEngagesOnceReady) {
  Rig<TypeParam> rig(floor_toml(1000.0), bare_config());
  rig.device.read_status = DeviceStatus::kNotReady;
  // A device that is not ready says so on its writes too (the Omni while it calibrates): that
  // is no more a device error than the read's.
  rig.device.write_status = DeviceStatus::kNotReady;
  for (int i = 0; i < 20; ++i) {  // longer than the device timeout: homing is not silence
    const TickStatus s = rig.at({0, 0, -0.003});
    EXPECT_EQ(s.state, LoopState::kHoming);
    EXPECT_FALSE(s.faults);
    EXPECT_EQ(rig.force(), (Vec3<double>{}));
  }
  EXPECT_EQ(rig.pins.light, LightState::kHoming);
  rig.device.read_status = DeviceStatus::kOk;
  rig.device.write_status = DeviceStatus::kOk;
  EXPECT_EQ(rig.at(kAbove).state, LoopState::kActive);
  EXPECT_EQ(rig.pins.light, LightState::kArmed);
}

TYPED_TEST(ServoSafety, TogglesTheTickPinEveryTickAndShowsLightsOnlyOnChange) {
  Rig<TypeParam> rig(floor_toml(1000.0), bare_config());
  for (int i = 0; i < 10; ++i) rig.at(kAbove);
  EXPECT_EQ(rig.pins.toggles, 10);
  EXPECT_EQ(rig.pins.light, LightState::kArmed);
  EXPECT_EQ(rig.pins.light_changes, 1);
  rig.pins.estop = PinLevel::kActive;
  rig.at(kAbove);
  rig.at(kAbove);
  EXPECT_EQ(rig.pins.light, LightState::kFault);
  EXPECT_EQ(rig.pins.light_changes, 2);
}

TYPED_TEST(ServoSafety, AFailedWriteIsADeviceErrorAndLatchesWhenItPersists) {
  ServoConfig c = bare_config();
  c.safety.device_timeout_periods = 3;
  Rig<TypeParam> rig(floor_toml(1000.0), c);
  rig.at(kAbove);
  rig.device.write_status = DeviceStatus::kDisconnected;
  EXPECT_TRUE(rig.at(kAbove).faults.has(Fault::kDeviceError));
  EXPECT_FALSE(rig.at(kAbove).faults.has(Fault::kDeviceSilent));
  EXPECT_TRUE(rig.at(kAbove).faults.has(Fault::kDeviceSilent));
}

// ---- integer time ---------------------------------------------------------------------------

TEST(ServoLoop, EffectTimeAfterADayIsAsExactAsInTheFirstSecond) {
  // An impact transient triggered at tick k0 reads t = (k - k0) T: the same at k0 = 0 and at
  // k0 = 86.4 million (a day at 1 kHz), bit for bit.
  const std::string toml = floor_toml(1000.0, "  [surface.impact]\n  recoil_gain = 200.0\n  oscillation_gain = 400.0\n"
                                              "  duration = 0.15\n  frequency = 30.0\n");
  const auto run_from = [&](std::int64_t k0) {
    Rig<double> rig(toml, bare_config());
    rig.k = k0;
    rig.device.has_velocity = true;
    rig.device.velocity_m_per_s = {0, 0, -0.2};
    rig.at({0, 0, 0.0004});
    rig.at({0, 0, 0.0002});
    std::vector<double> forces;
    for (int i = 0; i < 120; ++i) {
      rig.at({0, 0, -0.0002});
      forces.push_back(rig.force().z);
    }
    return forces;
  };
  EXPECT_EQ(run_from(0), run_from(86'400'000));
}

TEST(ServoLoop, TickWithoutArgumentTakesTheNextIntegerTime) {
  Rig<double> rig(floor_toml(), bare_config());
  rig.loop.tick(41);
  rig.loop.tick();
  EXPECT_EQ(rig.loop.last_tick(), 42);
}

// ---- the device seam with a mock driver (libfranka's MockRobotControl pattern) -----------------

class MockDriver : public DeviceDriver {
 public:
  MOCK_METHOD(DeviceStatus, read, (DeviceReading&), (noexcept, override));
  MOCK_METHOD(DeviceStatus, write, (const Vec3<double>&), (noexcept, override));
  MOCK_METHOD(void, emergency_zero, (), (noexcept, override));
  MOCK_METHOD(const DeviceInfo&, info, (), (const, noexcept, override));
};

TEST(ServoLoop, ReadsThenWritesOnceAPerTickThroughTheDriverSeam) {
  using ::testing::_;
  using ::testing::DoAll;
  using ::testing::InSequence;
  using ::testing::Return;
  using ::testing::SetArgReferee;
  MockDriver driver;
  DeviceReading inside;
  inside.position_m = {0, 0, -0.003};
  DeviceReading above;
  above.position_m = {0, 0, 0.01};
  {
    InSequence order;
    EXPECT_CALL(driver, read(_)).WillOnce(DoAll(SetArgReferee<0>(above), Return(DeviceStatus::kOk)));
    EXPECT_CALL(driver, write(Vec3<double>{})).WillOnce(Return(DeviceStatus::kOk));
    EXPECT_CALL(driver, read(_)).WillOnce(DoAll(SetArgReferee<0>(inside), Return(DeviceStatus::kOk)));
    EXPECT_CALL(driver, write(::testing::Field(&Vec3<double>::z, ::testing::DoubleNear(3.0, 1e-12))))
        .WillOnce(Return(DeviceStatus::kOk));
    EXPECT_CALL(driver, read(_)).WillOnce(Return(DeviceStatus::kDisconnected));
    EXPECT_CALL(driver, write(Vec3<double>{})).WillOnce(Return(DeviceStatus::kOk));  // zero at once
  }
  EXPECT_CALL(driver, emergency_zero()).Times(0);
  ServoLoop<DriverRef, RuntimeScene<double>> loop(DriverRef(driver), scene_from<double>(floor_toml(1000.0)),
                                                  bare_config());
  EXPECT_TRUE(loop.tick(0).ok());
  EXPECT_TRUE(loop.tick(1).ok());
  const TickStatus lost = loop.tick(2);
  EXPECT_EQ(lost.read, DeviceStatus::kDisconnected);
  EXPECT_TRUE(lost.faults.has(Fault::kDeviceError));
}

TEST(ServoLoop, ShutdownCommandsZeroAtOnceAndGoesIdle) {
  Rig<double> rig(floor_toml(1000.0), bare_config());
  rig.at(kAbove);
  rig.at({0, 0, -0.005});
  ASSERT_NEAR(rig.force().z, 5.0, 1e-9);
  const TickStatus s = rig.loop.shutdown(rig.k);
  EXPECT_EQ(rig.force(), (Vec3<double>{}));
  EXPECT_EQ(s.state, LoopState::kIdle);
  TelemetryFrame f;
  rig.loop.fill_frame(f);
  EXPECT_EQ(f.force_n, (Vec3<double>{}));
  EXPECT_EQ(f.tick, 2);
}

TEST(ServoConfig, TheDeviceLimitsWhatTheSceneLeavesOpenAndTheSmallerClampWins) {
  ServoConfig c;
  c.period_s = 1e-3;
  c.limits.has_max_force = true;
  c.limits.max_force_n = 10.0;
  DeviceInfo omni;
  omni.max_force_n = 3.3;
  omni.max_continuous_force_n = 0.88;
  omni.workspace_min_m = {-0.08, -0.06, -0.035};
  omni.workspace_max_m = {0.08, 0.06, 0.035};
  const ServoConfig merged = with_device(c, omni);
  EXPECT_EQ(merged.limits.max_force_n, 3.3);
  EXPECT_TRUE(merged.safety.has_workspace);
  EXPECT_EQ(merged.safety.workspace_max_m, omni.workspace_max_m);
  EXPECT_EQ(merged.safety.thermal.continuous_force_n, 0.88);
  EXPECT_EQ(check_servo_config(merged), "");
  c.limits.max_force_n = 2.0;
  EXPECT_EQ(with_device(c, omni).limits.max_force_n, 2.0);
  c.safety.thermal.derate_start = 1.0;
  c.safety.thermal.continuous_force_n = 1.0;
  EXPECT_NE(check_servo_config(c).find("thermal_derate_start"), std::string::npos);
}

}  // namespace
}  // namespace toonforce::test
