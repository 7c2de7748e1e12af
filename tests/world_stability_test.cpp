// SPDX-License-Identifier: Apache-2.0
// The virtual coupling's stability map (tools/bench/world_stability.hpp, docs/performance/
// world.md): points of the map on two simulated Falcon-class devices, hand a letting go of its
// handle, hand b stepping 5 mm. Deterministic counts and simulated quantities only (the
// simulation is bit-reproducible), never a time.
#include <gtest/gtest.h>

#include "toonforce/control/passivity_bound.hpp"
#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/host_sim/hand_script.hpp"
#include "world_stability.hpp"

namespace toonforce::test {
namespace {

bench::PointSpec point(double k, double b, int delay_a, int delay_b, bool controller = false) {
  bench::PointSpec s;
  s.stiffness_n_per_m = k;
  s.damping_n_s_per_m = b;
  s.delay_a_ticks = delay_a;
  s.delay_b_ticks = delay_b;
  s.controller = controller;
  s.a_releases = true;
  return s;
}

/// The bound the map compares with: the two devices' dampings in series (a's handle free, b's
/// held by a hand), the larger delay.
double series_damping() {
  const double b_device = host_sim::falcon_params().damping_n_s_per_m;
  const double b_a = b_device;
  const double b_b = b_device + host_sim::HandImpedance{}.damping_n_s_per_m;
  return b_a * b_b / (b_a + b_b);
}

TEST(CouplingStability, ACouplingInsideTheDelayAwareBoundIsStableAndGivesNoEnergy) {
  const bench::PointSpec spec = point(50.0, 0.0, 1, 1);
  ASSERT_GT(series_damping(), damping_needed_n_s_per_m(50.0, spec.period_s, 1));  // inside the bound
  const bench::PointResult r = bench::run_point(spec);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_FALSE(r.held);
  EXPECT_TRUE(r.stable) << "gap " << r.steady_largest_gap_m << " m, speed " << r.steady_largest_speed_m_per_s;
  // The handles end together (within the friction's reach on a 50 N/m spring: 0.2 N / 50 N/m),
  // at rest, and the coupling as a two-port gave out no more than rounding.
  EXPECT_LT(r.steady_largest_gap_m, 0.2 / 50.0);
  EXPECT_GT(r.least_true_sum_energy_j, -0.01);
}

TEST(CouplingStability, AStiffCouplingFarOutsideTheBoundOscillatesAtTheClampAndNoSafetyStageStopsIt) {
  const bench::PointResult r = bench::run_point(point(6000.0, 0.0, 1, 1));
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_FALSE(r.stable);
  EXPECT_FALSE(r.held);  // no latched fault: the world goes on driving the oscillation
  EXPECT_GT(r.steady_largest_speed_m_per_s, 0.1);
  EXPECT_DOUBLE_EQ(r.peak_force_n, host_sim::falcon_params().max_force_n);
  // The devices did work on the hands: more than the passivity budget (0.5 J) came out.
  EXPECT_LT(r.least_true_sum_energy_j, -0.5);
}

TEST(CouplingStability, ThePassivityControllerLeavesTheCouplingAsItIs) {
  // The controller dissipates only what the scene's active effects inject over their budgets
  // (control/passivity.hpp); a world's coupling force is not one of them, so switching it on
  // changes nothing, to the bit: the unstable point stays unstable.
  const bench::PointResult off = bench::run_point(point(6000.0, 0.0, 1, 1, false));
  const bench::PointResult on = bench::run_point(point(6000.0, 0.0, 1, 1, true));
  ASSERT_TRUE(off.ok && on.ok);
  EXPECT_FALSE(on.stable);
  EXPECT_EQ(on.least_energy_j, off.least_energy_j);
  EXPECT_EQ(on.least_true_sum_energy_j, off.least_true_sum_energy_j);
  EXPECT_EQ(on.steady_largest_gap_m, off.steady_largest_gap_m);
  EXPECT_EQ(on.peak_force_n, off.peak_force_n);
}

TEST(CouplingStability, WithFourTicksOfDelayTheObserverSeesAbsorptionWhereTheDevicesGiveEnergyOut) {
  // A limit cycle at the clamp (about 25 Hz) with a damped coupling: the observer at each port
  // pairs each force with the reading, four ticks late, and sees the coupling absorb; the force
  // on the handles' true motion gives energy out. An observer at a delayed port cannot be the
  // test of this coupling's stability; the map judges the motion.
  const bench::PointResult r = bench::run_point(point(1600.0, 10.0, 4, 4));
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_FALSE(r.stable);
  EXPECT_FALSE(r.held);
  EXPECT_GE(r.least_sum_energy_j, 0.0);
  EXPECT_LT(r.least_true_sum_energy_j, -0.5);
}

}  // namespace
}  // namespace toonforce::test
