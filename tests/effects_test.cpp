// SPDX-License-Identifier: Apache-2.0
// Each force law against the closed forms of docs/spec/effects.md, edges included, in
// double (the reference scalar). Scalar agreement is in scalar_agreement_test.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "toonforce/effects/scene.hpp"

namespace toonforce {
namespace {

constexpr double kDt = 1e-3;
constexpr double kTol = 1e-12;

TickInput<double> at(Vec3<double> x, Vec3<double> v = {}, std::int64_t tick = 0) {
  TickInput<double> in{};
  in.position_m = x;
  in.velocity_m_per_s = v;
  in.rate_hz = 1.0 / kDt;
  in.now = Instant{tick, 0};
  in.period_s = kDt;
  return in;
}

const Plane<double> kFloor{{0, 0, 0}, {0, 0, 1}};

// ---- §1 penalty wall ---------------------------------------------------------------------

TEST(PenaltyWall, PushesAlongNormalInProportionToPenetration) {
  const PenaltyWall<double>::Params p{1500.0, 0.0};
  const auto c = kFloor.contact(at({0.01, -0.02, -0.002}));
  EXPECT_NEAR(PenaltyWall<double>::normal_force(p, c), 1500.0 * 0.002, kTol);
}

TEST(PenaltyWall, IsZeroExactlyAtTheSurfaceAndOutside) {
  const PenaltyWall<double>::Params p{1500.0, 5.0};
  EXPECT_EQ(PenaltyWall<double>::normal_force(p, kFloor.contact(at({0, 0, 0}, {0, 0, -1}))), 0.0);
  EXPECT_EQ(PenaltyWall<double>::normal_force(p, kFloor.contact(at({0, 0, 1e-9}, {0, 0, -1}))), 0.0);
}

TEST(PenaltyWall, DampingResistsEntryButNeverPullsIn) {
  const PenaltyWall<double>::Params p{1000.0, 20.0};
  // Moving in at 0.1 m/s, 1 mm deep: k delta - b (n.v) = 1 + 2 = 3 N.
  EXPECT_NEAR(PenaltyWall<double>::normal_force(p, kFloor.contact(at({0, 0, -0.001}, {0, 0, -0.1}))), 3.0, kTol);
  // Leaving fast: k delta - b (n.v) = 1 - 20 * 0.5 < 0, so max(0, .) = 0, not a pull.
  EXPECT_EQ(PenaltyWall<double>::normal_force(p, kFloor.contact(at({0, 0, -0.001}, {0, 0, 0.5}))), 0.0);
}

TEST(PenaltyWall, WorksForAnObliquePlane) {
  const double s = 1.0 / std::sqrt(2.0);
  const Plane<double> wall{{0.01, 0, 0}, {-s, 0, s}};
  const PenaltyWall<double>::Params p{800.0, 0.0};
  const Vec3<double> x{0.02, 0, 0.0};  // delta = -n.(x - p0) = s * 0.01
  EXPECT_NEAR(PenaltyWall<double>::normal_force(p, wall.contact(at(x))), 800.0 * s * 0.01, kTol);
}

TEST(SpringWall, IgnoresVelocityEntirely) {
  static_assert(!has(SpringWall<double>::kNeeds, Needs::kVelocity));
  const SpringWall<double>::Params p{1000.0, 50.0};
  EXPECT_NEAR(SpringWall<double>::normal_force(p, kFloor.contact(at({0, 0, -0.001}, {0, 0, 3}))), 1.0, kTol);
}

// ---- §2 realistic friction ---------------------------------------------------------------

using FrictionSurface = Surface<PenaltyWall<double>, RealisticFriction<double>>;

FrictionSurface::Params friction_surface(double mu_v, double mu_c, double v_reg) {
  FrictionSurface::Params p{};
  p.plane = kFloor;
  p.wall = {1000.0, 0.0};
  p.tangential = {mu_v, mu_c, v_reg};
  return p;
}

TEST(RealisticFriction, ViscousOpposesTangentialVelocity) {
  const auto p = friction_surface(-2.0, 0.0, 0.02);
  FrictionSurface::State s{};
  const auto f = FrictionSurface::force(p, s, at({0, 0, -0.002}, {0.1, -0.05, -0.3}));
  EXPECT_NEAR(f.x, -2.0 * 0.1, kTol);
  EXPECT_NEAR(f.y, -2.0 * -0.05, kTol);
  EXPECT_NEAR(f.z, 1000.0 * 0.002, kTol);  // the normal part is the wall alone
}

TEST(RealisticFriction, CoulombHasMagnitudeMuNAboveTheRegularizationSpeed) {
  const auto p = friction_surface(0.0, 0.3, 0.02);
  FrictionSurface::State s{};
  const auto f = FrictionSurface::force(p, s, at({0, 0, -0.004}, {0.06, 0.08, 0}));  // |v_t| = 0.1
  const double n = 1000.0 * 0.004;
  EXPECT_NEAR(f.x, -0.3 * n * 0.6, kTol);
  EXPECT_NEAR(f.y, -0.3 * n * 0.8, kTol);
}

TEST(RealisticFriction, CoulombIsContinuousThroughZeroTangentialSpeed) {
  const auto p = friction_surface(0.0, 0.3, 0.02);
  FrictionSurface::State s{};
  const double n = 1000.0 * 0.004;
  // Below v_reg it is a damper of mu_c N / v_reg; at zero speed it is exactly zero.
  for (const double vx : {0.01, 1e-6, 0.0, -1e-6, -0.01}) {
    const auto f = FrictionSurface::force(p, s, at({0, 0, -0.004}, {vx, 0, 0}));
    EXPECT_NEAR(f.x, -0.3 * n / 0.02 * vx, kTol) << vx;
  }
  const auto at_reg = FrictionSurface::force(p, s, at({0, 0, -0.004}, {0.02, 0, 0}));
  EXPECT_NEAR(std::abs(at_reg.x), 0.3 * n, kTol);  // both branches meet at v_reg
}

TEST(RealisticFriction, UsesTheWallForceOfTheSameTickIncludingDamping) {
  auto p = friction_surface(0.0, 0.5, 0.02);
  p.wall.damping_n_s_per_m = 10.0;
  FrictionSurface::State s{};
  const auto f = FrictionSurface::force(p, s, at({0, 0, -0.001}, {0.1, 0, -0.05}));
  const double n = 1000.0 * 0.001 + 10.0 * 0.05;
  EXPECT_NEAR(f.z, n, kTol);
  EXPECT_NEAR(f.x, -0.5 * n, kTol);
}

TEST(RealisticFriction, ActsOnlyInContact) {
  const auto p = friction_surface(-2.0, 0.3, 0.02);
  FrictionSurface::State s{};
  const auto f = FrictionSurface::force(p, s, at({0, 0, 0.0}, {0.1, 0, 0}));
  EXPECT_EQ(f, (Vec3<double>{}));
}

// ---- §3 super-slippery surface -----------------------------------------------------------

using SlipperySurface = Surface<PenaltyWall<double>, SuperSlippery<double>>;

SlipperySurface::Params slippery_surface(double mu, double cap) {
  SlipperySurface::Params p{};
  p.plane = kFloor;
  p.wall = {1000.0, 0.0};
  p.tangential = {mu, cap};
  return p;
}

TEST(SuperSlippery, PushesAlongTheMotion) {
  const auto p = slippery_surface(4.0, 2.0);
  SlipperySurface::State s{};
  const auto f = SlipperySurface::force(p, s, at({0, 0, -0.001}, {0.1, -0.05, -0.2}));
  EXPECT_NEAR(f.x, 0.4, kTol);
  EXPECT_NEAR(f.y, -0.2, kTol);
  EXPECT_NEAR(f.z, 1.0, kTol);
}

TEST(SuperSlippery, IsCappedAtMaxTangentialForceWithItsDirectionKept) {
  const auto p = slippery_surface(4.0, 2.0);
  SlipperySurface::State s{};
  const auto f = SlipperySurface::force(p, s, at({0, 0, -0.001}, {0.6, 0.8, 0}));  // mu |v_t| = 4 N
  EXPECT_NEAR(std::hypot(f.x, f.y), 2.0, kTol);
  EXPECT_NEAR(f.x / f.y, 0.6 / 0.8, kTol);
}

TEST(SuperSlippery, ActsOnlyInContact) {
  const auto p = slippery_surface(4.0, 2.0);
  SlipperySurface::State s{};
  EXPECT_EQ(SlipperySurface::force(p, s, at({0, 0, 0.001}, {0.1, 0, 0})), (Vec3<double>{}));
}

// ---- §4 impact recoil and oscillation ----------------------------------------------------

using CartoonWall = Surface<PenaltyWall<double>, NoTangential<double>, ImpactTransient<double>>;

CartoonWall::Params cartoon_wall() {
  CartoonWall::Params p{};
  p.plane = kFloor;
  p.wall = {1000.0, 0.0};
  p.impact = {300.0, 600.0, 0.15, 30.0, 0.05, 0.001, SineMethod::kLibrary};
  return p;
}

double transient(double v_i, double t) {
  return t <= 0.15 ? v_i * (0.15 - t) * (300.0 + 600.0 * std::sin(2 * M_PI * 30.0 * t)) : 0.0;
}

/// Runs the cartoon wall along z(t) = z[k] with velocity vz[k], one tick each.
struct WallRun {
  CartoonWall::Params p = cartoon_wall();
  CartoonWall::State s{};
  std::int64_t tick = 0;
  Vec3<double> step(double z, double vz) { return CartoonWall::force(p, s, at({0, 0, z}, {0, 0, vz}, tick++)); }
};

TEST(ImpactTransient, TriggersOnEntryAndFollowsTheClosedFormThroughItsDuration) {
  WallRun run;
  run.step(0.001, -0.2);  // outside
  // Enters at 0.2 m/s on tick 1, then the HIP stays 1 mm inside, still.
  const auto first = run.step(-0.0002, -0.2);
  EXPECT_NEAR(first.z, 1000.0 * 0.0002 + transient(0.2, 0.0), 1e-9);
  for (int k = 1; k <= 200; ++k) {
    const double t = k * kDt;
    const auto f = run.step(-0.001, 0.0);
    EXPECT_NEAR(f.z, 1.0 + transient(0.2, t), 1e-9) << "t = " << t;
  }
}

TEST(ImpactTransient, KeepsRunningAfterContactEnds) {
  WallRun run;
  run.step(0.001, -0.3);
  run.step(-0.001, -0.3);  // trigger, v_i = 0.3
  for (int k = 1; k <= 100; ++k) {
    const auto f = run.step(0.005, 0.2);  // thrown out of the wall, no wall force
    EXPECT_NEAR(f.z, transient(0.3, k * kDt), 1e-9);
  }
  EXPECT_NE(transient(0.3, 0.05), 0.0);  // the check above is not vacuous
}

TEST(ImpactTransient, PullsTowardTheWallForPartOfACycleWhenOscillationDominates) {
  WallRun run;
  run.step(0.001, -0.2);
  run.step(-0.0001, -0.2);
  double most_negative = 0.0;
  for (int k = 1; k <= 150; ++k) most_negative = std::min(most_negative, run.step(0.01, 0.0).z);
  EXPECT_LT(most_negative, -0.1);  // signed, not max(0, .)
}

TEST(ImpactTransient, SlowerEntryNeitherTriggersNorDisarms) {
  WallRun run;
  run.step(0.001, -0.01);
  EXPECT_NEAR(run.step(-0.0005, -0.04).z, 0.5, 1e-12);  // 0.04 < 0.05: wall only
  // Out by less than the re-arm distance, then in fast: still armed, so it triggers.
  run.step(0.0002, 0.01);
  EXPECT_NEAR(run.step(-0.0001, -0.1).z, 0.1 + transient(0.1, 0.0), 1e-9);
}

TEST(ImpactTransient, DoesNotTriggerOnTheFirstTick) {
  WallRun run;
  EXPECT_NEAR(run.step(-0.001, -0.5).z, 1.0, 1e-12);
}

TEST(ImpactTransient, RetriggerNeedsTheRearmDistanceAndRestartsWithTheNewSpeed) {
  WallRun run;
  run.step(0.001, -0.2);
  run.step(-0.0001, -0.2);           // trigger 1, v_i 0.2, t0 = tick 1
  run.step(0.0005, 0.1);             // out by 0.5 mm < 1 mm: not re-armed
  auto f = run.step(-0.0001, -0.4);  // entry at t = 2 ms: no new trigger
  EXPECT_NEAR(f.z, 0.1 + transient(0.2, 0.002), 1e-9);
  run.step(0.0011, 0.1);        // out by 1.1 mm: re-armed; transient 1 still running
  f = run.step(-0.0001, -0.4);  // trigger 2 at tick 5 with v_i 0.4
  EXPECT_NEAR(f.z, 0.1 + transient(0.4, 0.0), 1e-9);
  f = run.step(-0.0001, 0.0);
  EXPECT_NEAR(f.z, 0.1 + transient(0.4, 0.001), 1e-9);
}

TEST(ImpactTransient, EndsAfterItsDuration) {
  WallRun run;
  run.step(0.001, -0.2);
  run.step(-0.0001, -0.2);
  for (int k = 1; k <= 149; ++k) run.step(0.01, 0.0);
  EXPECT_NEAR(run.step(0.01, 0.0).z, transient(0.2, 0.150), 1e-9);  // t = d: (d - t) = 0
  EXPECT_EQ(run.step(0.01, 0.0).z, 0.0);
  EXPECT_FALSE(run.s.impact.running);
}

TEST(ImpactTransient, TimeComesFromTickCountsNotAnAccumulatedClock) {
  // 24 hours into a 10 kHz run, t is as exact as at start (spec §0).
  CartoonWall::Params p = cartoon_wall();
  CartoonWall::State s{};
  const std::int64_t day = 24LL * 3600 * 10000;
  auto in = at({0, 0, 0.001}, {0, 0, -0.2}, day);
  in.period_s = 1e-4;
  in.rate_hz = 1e4;
  CartoonWall::force(p, s, in);
  in.now.tick = day + 1;
  in.position_m.z = -0.0001;
  CartoonWall::force(p, s, in);
  in.now.tick = day + 1 + 337;  // 33.7 ms later
  in.position_m.z = 0.01;
  EXPECT_NEAR(CartoonWall::force(p, s, in).z, transient(0.2, 0.0337), 1e-12);
}

// ---- §5 cartoon cliff --------------------------------------------------------------------

CartoonCliff<double>::Params cliff() {
  CartoonCliff<double>::Params p{};
  p.ground = kFloor;
  p.axis = {1, 0, 0};
  p.gap_min_m = 0.0;
  p.gap_max_m = 0.02;
  p.wall = {1000.0, 0.0};
  p.speed_threshold_m_per_s = 0.08;
  p.tau_s = 0.02;
  p.rearm_height_m = 0.001;
  p.fall_force_n = 0.0;
  return p;
}

struct CliffRun {
  CartoonCliff<double>::Params p = cliff();
  CartoonCliff<double>::State s{};
  std::int64_t tick = 0;
  Vec3<double> step(Vec3<double> x, Vec3<double> v) { return CartoonCliff<double>::force(p, s, at(x, v, tick++)); }
};

TEST(CartoonCliff, FiltersLateralSpeedEveryTickWherever) {
  CliffRun run;
  const double a = kDt / (0.02 + kDt);
  run.step({-0.05, 0, 0.03}, {0.1, 0.0, 0.7});                // in the air, far from the strip
  EXPECT_NEAR(run.s.filtered_speed_m_per_s, a * 0.1, 1e-15);  // only the lateral part counts
  run.step({-0.05, 0, 0.03}, {0.0, 0.1, 0.0});
  EXPECT_NEAR(run.s.filtered_speed_m_per_s, a * 0.1 + a * (0.1 - a * 0.1), 1e-15);
}

TEST(CartoonCliff, BridgesTheGapWhenCrossedFast) {
  CliffRun run;
  for (int k = 0; k < 300; ++k) run.step({-0.05, 0, -0.001}, {0.2, 0, 0});  // s_f -> 0.2
  const auto f = run.step({0.01, 0, -0.001}, {0.2, 0, 0});                  // over the gap, 1 mm down
  EXPECT_FALSE(run.s.fallen);
  EXPECT_NEAR(f.z, 1.0, 1e-12);  // the ground holds: a penalty wall over the gap
}

TEST(CartoonCliff, DropsTheHipWhenItSlowsOverTheGap) {
  CliffRun run;
  for (int k = 0; k < 300; ++k) run.step({-0.05, 0, -0.001}, {0.03, 0, 0});
  const auto f = run.step({0.01, 0, -0.001}, {0.03, 0, 0});
  EXPECT_TRUE(run.s.fallen);
  EXPECT_EQ(f, (Vec3<double>{}));  // no upward force over the strip
}

TEST(CartoonCliff, StaysFallenWhileInsideEvenWhenFastAgain) {
  CliffRun run;
  for (int k = 0; k < 300; ++k) run.step({0.01, 0, -0.001}, {0.0, 0, 0});
  ASSERT_TRUE(run.s.fallen);
  // Speeding up while still below ground level in the strip must not build the surface
  // around the HIP: re-arming needs rearm_height above ground.
  for (int k = 0; k < 300; ++k) EXPECT_EQ(run.step({0.01, 0, -0.01}, {0.3, 0, 0}), (Vec3<double>{}));
  EXPECT_TRUE(run.s.fallen);
  // Just under rearm_height above ground, fast: still fallen.
  run.step({0.01, 0, 0.0009}, {0.3, 0, 0});
  EXPECT_TRUE(run.s.fallen);
  // At rearm_height above ground and fast: supported again.
  run.step({0.01, 0, 0.001}, {0.3, 0, 0});
  EXPECT_FALSE(run.s.fallen);
}

TEST(CartoonCliff, RearmsOutsideTheStripOnlyAboveGround) {
  CliffRun run;
  for (int k = 0; k < 300; ++k) run.step({0.01, 0, -0.001}, {0.0, 0, 0});
  ASSERT_TRUE(run.s.fallen);
  run.step({0.03, 0, -0.002}, {0.0, 0, 0});  // slow, outside the strip, under the ledge
  EXPECT_TRUE(run.s.fallen);
  run.step({0.03, 0, 0.0015}, {0.0, 0, 0});  // slow, outside, above by rearm_height
  EXPECT_FALSE(run.s.fallen);
}

TEST(CartoonCliff, SideFacesPushTowardTheStripWhenUnderALedge) {
  CliffRun run;
  for (int k = 0; k < 300; ++k) run.step({0.01, 0, -0.001}, {0.0, 0, 0});
  ASSERT_TRUE(run.s.fallen);
  auto f = run.step({0.023, 0, -0.005}, {0, 0, 0});  // 3 mm past gap_max, under the ledge
  EXPECT_NEAR(f.x, -1000.0 * 0.003, 1e-12);
  EXPECT_EQ(f.z, 0.0);
  f = run.step({-0.002, 0, -0.005}, {0, 0, 0});  // 2 mm before gap_min
  EXPECT_NEAR(f.x, 1000.0 * 0.002, 1e-12);
  EXPECT_EQ(f.z, 0.0);
  EXPECT_EQ(run.step({-0.002, 0, 0.0005}, {0, 0, 0}), (Vec3<double>{}));  // above ground: nothing
}

TEST(CartoonCliff, FallForcePullsDownWhileFallenInTheStrip) {
  CliffRun run;
  run.p.fall_force_n = 0.7;
  const auto f = run.step({0.01, 0, -0.001}, {0, 0, 0});  // s_f = 0 < threshold at once
  EXPECT_TRUE(run.s.fallen);
  EXPECT_NEAR(f.z, -0.7, 1e-12);
}

TEST(CartoonCliff, StripEdgesAreInclusive) {
  CliffRun run;
  run.step({0.0, 0, -0.001}, {0, 0, 0});
  EXPECT_TRUE(run.s.fallen);
  CliffRun run2;
  run2.step({0.02, 0, -0.001}, {0, 0, 0});
  EXPECT_TRUE(run2.s.fallen);
}

TEST(CartoonCliff, ZeroTauFollowsTheSpeedAtOnce) {
  CliffRun run;
  run.p.tau_s = 0.0;
  run.step({-0.05, 0, 0.01}, {0.3, 0.4, 0});
  EXPECT_NEAR(run.s.filtered_speed_m_per_s, 0.5, 1e-15);
}

// ---- AxisPlane: Plane's results bit for bit, with an axis for the normal --------------------

// Raw values at the edges of the range, around zero and at random.
std::vector<std::int32_t> edge_and_random_raws(std::mt19937_64& random, int count) {
  std::vector<std::int32_t> raws{0,           1,          -1,         65536,           -65536,
                                 32768,       -32768,     2147483647, -2147483647 - 1, 2147483646,
                                 -2147483647, 1073741824, -1073741824};
  for (int i = 0; i < count; ++i) raws.push_back(static_cast<std::int32_t>(random() >> (random() % 33)));
  return raws;
}

template <int kAxis, int kSign>
void expect_axis_plane_is_plane() {
  using Q = Q16_16;
  std::mt19937_64 random(29 + 3 * kAxis + kSign);
  const auto raws = edge_and_random_raws(random, 40);
  const auto pick = [&] { return Q::from_raw(raws[random() % raws.size()]); };
  const auto vec = [&] { return Vec3<Q>{pick(), pick(), pick()}; };
  const AxisPlane<Q, kAxis, kSign> axis{vec()};
  Plane<Q> plane{axis.point_m, {}};
  plane.normal = AxisPlane<Q, kAxis, kSign>::normal;
  const auto same = [](const Vec3<Q>& a, const Vec3<Q>& b) {
    return a.x.raw() == b.x.raw() && a.y.raw() == b.y.raw() && a.z.raw() == b.z.raw();
  };
  // Each result and whether it raised the saturation flag.
  const auto flagged = [](auto f) {
    static_cast<void>(take_fixed_saturated());
    const auto r = f();
    return std::pair{r, take_fixed_saturated()};
  };
  for (int i = 0; i < 4000; ++i) {
    TickInput<Q> in{};
    in.position_m = vec();
    in.velocity_m_per_s = vec();
    const Q k = pick();
    const auto [c_plane, c_plane_flag] = flagged([&] { return plane.contact(in); });
    const auto [c_axis, c_axis_flag] = flagged([&] { return axis.contact(in); });
    ASSERT_EQ(c_axis.penetration_m.raw(), c_plane.penetration_m.raw()) << i;
    ASSERT_EQ(c_axis.normal_speed_m_per_s.raw(), c_plane.normal_speed_m_per_s.raw()) << i;
    ASSERT_EQ(c_axis_flag, c_plane_flag) << i;
    ASSERT_TRUE(same(axis.push(k), plane.push(k))) << i << " k " << k.raw();
    ASSERT_TRUE(same(axis.along(k), plane.along(k))) << i << " k " << k.raw();
    for (const Q n_dot_v : {c_plane.normal_speed_m_per_s, k}) {
      const auto [t_plane, t_plane_flag] = flagged([&] { return plane.tangential(in.velocity_m_per_s, n_dot_v); });
      const auto [t_axis, t_axis_flag] = flagged([&] { return axis.tangential(in.velocity_m_per_s, n_dot_v); });
      ASSERT_TRUE(same(t_axis, t_plane)) << i << " n.v " << n_dot_v.raw();
      ASSERT_EQ(t_axis_flag, t_plane_flag) << i;
    }
  }
}

TEST(AxisPlane, IsPlaneBitForBitWithThatNormalSaturationsIncluded) {
  expect_axis_plane_is_plane<0, 1>();
  expect_axis_plane_is_plane<0, -1>();
  expect_axis_plane_is_plane<1, 1>();
  expect_axis_plane_is_plane<1, -1>();
  expect_axis_plane_is_plane<2, 1>();
  expect_axis_plane_is_plane<2, -1>();
}

// A surface on it gives the scene's forces and active parts bit for bit, the impact's state
// included, over strikes of a floor.
template <class Tangential, class Impact>
void expect_axis_surface_is_surface(const typename Tangential::Params& tangential,
                                    const typename Impact::Params& impact) {
  using Q = Q16_16;
  using General = Surface<SpringWall<Q>, Tangential, Impact>;
  using Axis = Surface<SpringWall<Q>, Tangential, Impact, AxisPlane<Q, 2, 1>>;
  const typename SpringWall<Q>::Params wall{scalar_cast<Q>(1500.0), Q{}};
  const Vec3<Q> point{Q{}, Q{}, scalar_cast<Q>(0.01)};
  const typename General::Params pg{{point, {Q{}, Q{}, scalar_cast<Q>(1.0)}}, wall, tangential, impact};
  const typename Axis::Params pa{{point}, wall, tangential, impact};
  typename General::State sg{};
  typename Axis::State sa{};
  std::mt19937_64 random(7);
  const auto uniform = [&](double lo, double hi) {
    return scalar_cast<Q>(lo + (hi - lo) * static_cast<double>(random() >> 11) * 0x1p-53);
  };
  int in_contact = 0;
  for (std::int64_t k = 0; k < 20000; ++k) {
    TickInput<Q> in{};
    in.position_m = {uniform(-0.05, 0.05), uniform(-0.05, 0.05), uniform(-0.01, 0.02)};
    in.velocity_m_per_s = {uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)};
    in.rate_hz = scalar_cast<Q>(1000.0);
    in.period_ns = 1'000'000;
    in.now = Instant{k, 0};
    ActiveForce<Q> ag[2]{};
    ActiveForce<Q> aa[2]{};
    const Vec3<Q> fg = General::force(pg, sg, in, ag);
    const Vec3<Q> fa = Axis::force(pa, sa, in, aa);
    ASSERT_EQ(fa.x.raw(), fg.x.raw()) << k;
    ASSERT_EQ(fa.y.raw(), fg.y.raw()) << k;
    ASSERT_EQ(fa.z.raw(), fg.z.raw()) << k;
    for (std::size_t i = 0; i < General::kActiveSlots; ++i) {
      ASSERT_EQ(aa[i].force_n.z.raw(), ag[i].force_n.z.raw()) << k;
      ASSERT_EQ(aa[i].force_n.x.raw(), ag[i].force_n.x.raw()) << k;
      ASSERT_EQ(aa[i].in_episode, ag[i].in_episode) << k;
      ASSERT_EQ(aa[i].triggered, ag[i].triggered) << k;
    }
    if (fg.z.raw() != 0) ++in_contact;
  }
  EXPECT_GT(in_contact, 5000);  // the strikes reach the surface
}

TEST(AxisPlane, SurfacesOnItAreTheSurfacesOnThePlaneBitForBit) {
  using Q = Q16_16;
  expect_axis_surface_is_surface<SuperSlippery<Q>, NoImpact<Q>>({scalar_cast<Q>(3.0), scalar_cast<Q>(2.0)}, {});
  expect_axis_surface_is_surface<RealisticFriction<Q>, NoImpact<Q>>(
      {scalar_cast<Q>(-2.0), scalar_cast<Q>(0.4), scalar_cast<Q>(0.01)}, {});
  expect_axis_surface_is_surface<NoTangential<Q>, ImpactTransient<Q>>(
      {}, {scalar_cast<Q>(200.0), scalar_cast<Q>(400.0), scalar_cast<Q>(0.15), scalar_cast<Q>(30.0),
           scalar_cast<Q>(0.05), scalar_cast<Q>(0.001), SineMethod::kAuto});
}

}  // namespace
}  // namespace toonforce
