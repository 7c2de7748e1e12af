// SPDX-License-Identifier: Apache-2.0
// What makes the servo loop fit for real time, checked by counts, never by times: the same
// inputs give bit-identical forces; a tick allocates nothing (with every safety feature on);
// the telemetry ring never blocks, keeps order, counts what it drops and allocates nothing.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "alloc_counter.hpp"
#include "servo_support.hpp"
#include "sim_simple.hpp"

namespace toonforce::test {
namespace {

template <class S>
class ServoRuntime : public ::testing::Test {};
TYPED_TEST_SUITE(ServoRuntime, ServoScalars);

const std::string kEverything =
    floor_toml(1500.0, "  [surface.slippery]\n  mu = 4.0\n"
                       "  [surface.impact]\n  recoil_gain = 200.0\n  oscillation_gain = 400.0\n"
                       "  duration = 0.15\n  frequency = 30.0\n") +
    "[[cliff]]\npoint = [0.0, 0.0, -0.02]\nnormal = [0.0, 0.0, 1.0]\naxis = [1.0, 0.0, 0.0]\n"
    "gap_min = 0.0\ngap_max = 0.02\nstiffness = 1500.0\nspeed_threshold = 0.08\n";

/// Every safety feature on, with limits tight enough that each one acts in the scenario.
ServoConfig everything_on() {
  ServoConfig c;
  c.period_s = kPeriodS;
  c.limits = {4.0, 1500.0, true, true};
  c.safety.soft_start_s = 0.2;
  c.safety.has_max_velocity = true;
  c.safety.max_velocity_m_per_s = 0.5;
  c.safety.has_workspace = true;
  c.safety.workspace_min_m = {-0.05, -0.05, -0.05};
  c.safety.workspace_max_m = {0.05, 0.05, 0.05};
  c.safety.thermal = ThermalConfig{1.0, 1.0, 0.3};
  c.safety.passivity = PassivityConfig{true, 0.01, 10.0};
  return c;
}

template <Scalar S>
std::vector<double> forces_of_a_run(std::int64_t ticks) {
  SimpleSimConfig sim;
  sim.real_time = false;
  SimpleSimDevice device(sim);
  auto loop = std::make_unique<ServoLoop<DriverRef, RuntimeScene<S>>>(DriverRef(device), scene_from<S>(kEverything),
                                                                      everything_on());
  std::vector<double> forces;
  forces.reserve(static_cast<std::size_t>(3 * ticks));
  for (std::int64_t k = 0; k < ticks; ++k) {
    loop->tick(k + k / 500);  // a skipped deadline every 500 ticks
    const Vec3<double> f = to_double(loop->force());
    forces.insert(forces.end(), {f.x, f.y, f.z});
  }
  return forces;
}

TYPED_TEST(ServoRuntime, SameInputsGiveBitIdenticalForces) {
  const std::vector<double> a = forces_of_a_run<TypeParam>(6000);
  const std::vector<double> b = forces_of_a_run<TypeParam>(6000);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0);
  double peak = 0.0;
  for (const double f : a) peak = std::max(peak, std::abs(f));
  EXPECT_GT(peak, 0.5) << "the scenario must produce forces";
}

TYPED_TEST(ServoRuntime, ATickAllocatesNothingWithEverySafetyFeatureOn) {
  SimpleSimConfig sim;
  sim.real_time = false;
  SimpleSimDevice device(sim);
  PinState pin_state;
  auto loop = std::make_unique<ServoLoop<DriverRef, RuntimeScene<TypeParam>, TestPins>>(
      DriverRef(device), scene_from<TypeParam>(kEverything), everything_on(), test_pins(pin_state));
  std::uint32_t faults = 0;
  std::uint8_t limits = 0;
  TelemetryFrame frame;
  AllocationScope scope;
  for (std::int64_t k = 0; k < 10'000; ++k) {
    if (k == 4000) pin_state.estop = PinLevel::kActive;
    if (k == 4100) pin_state.estop = PinLevel::kInactive;
    if (k == 4200) loop->request_rearm();
    const TickStatus s = loop->tick(k + (k == 6000 ? 40 : 0) + (k > 6000 ? 40 : 0));  // one watchdog trip
    if (k == 6100) loop->request_rearm();
    faults |= s.faults.bits();
    limits = static_cast<std::uint8_t>(limits | s.limits);
    loop->fill_frame(frame);
  }
  static_cast<void>(loop->shutdown(20'000));
  EXPECT_EQ(scope.count(), 0U);
  // The scenario exercised the features it claims to.
  for (const Fault f : {Fault::kEstop, Fault::kWatchdog})
    EXPECT_NE(faults & static_cast<std::uint32_t>(f), 0U) << fault_name(f);
  for (const Limit l : {Limit::kSoftStart, Limit::kClamped, Limit::kRateLimited, Limit::kPassivity, Limit::kThermal}) {
    EXPECT_TRUE(has(limits, l)) << static_cast<int>(l);
  }
}

// ---- telemetry ring ------------------------------------------------------------------------------

TEST(SpscRing, KeepsOrderDropsAndCountsWhenFullAndNeverBlocks) {
  auto ring = std::make_unique<SpscRing<std::int64_t, 8>>();
  for (std::int64_t i = 0; i < 8; ++i) EXPECT_TRUE(ring->push(i));
  EXPECT_FALSE(ring->push(8));
  EXPECT_FALSE(ring->push(9));
  EXPECT_EQ(ring->dropped(), 2U);
  std::int64_t v = -1;
  for (std::int64_t i = 0; i < 8; ++i) {
    ASSERT_TRUE(ring->pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(ring->pop(v));
  EXPECT_TRUE(ring->push(10));  // room again after popping
  ASSERT_TRUE(ring->pop(v));
  EXPECT_EQ(v, 10);
}

TEST(SpscRing, PushAndPopAllocateNothing) {
  auto ring = std::make_unique<SpscRing<TelemetryFrame, 64>>();
  TelemetryFrame f;
  AllocationScope scope;
  for (int i = 0; i < 1000; ++i) {
    f.tick = i;
    static_cast<void>(ring->push(f));
    if (i % 3 != 0) static_cast<void>(ring->pop(f));
  }
  EXPECT_EQ(scope.count(), 0U);
}

TEST(SpscRing, TwoThreadsLoseNothingButWhatTheyCountAsDropped) {
  auto ring = std::make_unique<SpscRing<std::int64_t, 256>>();
  constexpr std::int64_t kItems = 200'000;
  std::atomic<bool> done{false};
  std::int64_t received = 0;
  std::int64_t last = -1;
  bool ordered = true;
  std::thread consumer([&] {
    std::int64_t v = 0;
    for (;;) {
      if (ring->pop(v)) {
        ordered = ordered && v > last;
        last = v;
        ++received;
      } else if (done.load(std::memory_order_acquire)) {
        while (ring->pop(v)) {
          ordered = ordered && v > last;
          last = v;
          ++received;
        }
        return;
      }
    }
  });
  std::int64_t pushed = 0;
  for (std::int64_t i = 0; i < kItems; ++i) pushed += ring->push(i) ? 1 : 0;
  done.store(true, std::memory_order_release);
  consumer.join();
  EXPECT_TRUE(ordered);
  EXPECT_EQ(received, pushed);
  EXPECT_EQ(static_cast<std::uint64_t>(kItems - pushed), ring->dropped());
}

}  // namespace
}  // namespace toonforce::test
