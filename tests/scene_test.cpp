// Scenes: compile-time composition pays only for its effects; the run-time scene sums its
// effects in file order and matches the compile-time one.
#include <gtest/gtest.h>

#include <type_traits>

#include "toonforce/control/controller.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {
namespace {

using SpringFloor = Scene<Surface<SpringWall<double>>>;
using DampedFloor = Scene<Surface<PenaltyWall<double>>>;
using CliffScene = Scene<CartoonCliff<double>>;
using CartoonWallScene = Scene<Surface<PenaltyWall<double>, NoTangential<double>, ImpactTransient<double>>>;

// A scene made only of spring walls needs no velocity, so its controller has no estimator.
static_assert(!has(SpringFloor::kNeeds, Needs::kVelocity));
static_assert(has(DampedFloor::kNeeds, Needs::kVelocity));
static_assert(has(CliffScene::kNeeds, Needs::kVelocity));
static_assert(has(CartoonWallScene::kNeeds, Needs::kVelocity));
static_assert(std::is_same_v<Controller<SpringFloor>::Estimator, NoVelocityEstimator<double>>);
static_assert(std::is_empty_v<Controller<SpringFloor>::Estimator>);
static_assert(std::is_same_v<Controller<CliffScene>::Estimator, VelocityEstimator<double>>);
static_assert(sizeof(Controller<SpringFloor>) < sizeof(Controller<DampedFloor>),
              "the estimator of a scene that needs none must take no room");
// A plain surface carries no impact or tangential state; a cartoon wall does.
static_assert(std::is_empty_v<Surface<SpringWall<double>>::State>);
static_assert(!std::is_empty_v<Surface<PenaltyWall<double>, NoTangential<double>, ImpactTransient<double>>::State>);
// The cliff's lateral-speed filter lives in the cliff's state: no cliff, no filter.
static_assert(sizeof(Scene<Surface<SpringWall<double>>>::State) < sizeof(CliffScene::State));

TickInput<double> at(Vec3<double> x, Vec3<double> v, std::int64_t tick) {
  TickInput<double> in{};
  in.position_m = x;
  in.velocity_m_per_s = v;
  in.rate_hz = 1000.0;
  in.now = Instant{tick, 0.0};
  in.period_s = 1e-3;
  return in;
}

TEST(Scene, SumsItsEffects) {
  Surface<PenaltyWall<double>>::Params floor{{{0, 0, 0}, {0, 0, 1}}, {1000.0, 0.0}, {}, {}};
  Surface<PenaltyWall<double>>::Params wall{{{0.01, 0, 0}, {-1, 0, 0}}, {500.0, 0.0}, {}, {}};
  Scene<Surface<PenaltyWall<double>>, Surface<PenaltyWall<double>>> corner(floor, wall);
  decltype(corner)::State state{};
  const auto f = corner.force(at({0.012, 0, -0.002}, {}, 0), state);
  EXPECT_NEAR(f.x, -500.0 * 0.002, 1e-12);
  EXPECT_NEAR(f.z, 1000.0 * 0.002, 1e-12);
}

TEST(RuntimeScene, MatchesTheCompileTimeSceneBitForBit) {
  using Law = ImpactTransient<double>;
  using Compiled = Scene<Surface<PenaltyWall<double>, NoTangential<double>, Law>, CartoonCliff<double>>;
  Surface<PenaltyWall<double>, NoTangential<double>, Law>::Params wall{};
  wall.plane = {{0, 0, 0.01}, {0, 0, -1}};  // a ceiling 1 cm up
  wall.wall = {900.0, 3.0};
  wall.impact = {250.0, 500.0, 0.12, 25.0, 0.05, 0.001, SineMethod::kLibrary};
  CartoonCliff<double>::Params cliff{};
  cliff.ground = {{0, 0, 0}, {0, 0, 1}};
  cliff.axis = {1, 0, 0};
  cliff.gap_min_m = 0.0;
  cliff.gap_max_m = 0.02;
  cliff.wall = {1200.0, 1.0};
  cliff.speed_threshold_m_per_s = 0.08;
  cliff.tau_s = 0.02;
  cliff.rearm_height_m = 0.001;
  cliff.fall_force_n = 0.3;

  const Compiled compiled(wall, cliff);
  RuntimeScene<double> runtime;
  RuntimeScene<double>::SurfaceEffect::Params any{};
  any.plane = wall.plane;
  any.wall = wall.wall;
  any.impact = {true, wall.impact};
  ASSERT_TRUE(runtime.add_surface(any));
  ASSERT_TRUE(runtime.add_cliff(cliff));
  EXPECT_TRUE(has(runtime.needs(), Needs::kVelocity));

  Compiled::State cs{};
  RuntimeScene<double>::State rs{};
  for (int k = 0; k < 3000; ++k) {
    const double t = k * 1e-3;
    // Up and down through both the floor (with its gap) and the ceiling, sideways along x.
    const Vec3<double> x{-0.03 + 0.02 * t, 0.0, 0.004 + 0.009 * std::sin(7.0 * t)};
    const Vec3<double> v{0.02, 0.0, 0.063 * std::cos(7.0 * t)};
    const auto in = at(x, v, k);
    const auto a = compiled.force(in, cs);
    const auto b = runtime.force(in, rs);
    ASSERT_EQ(a, b) << "tick " << k;  // the same law code in the same order: identical bits
  }
}

TEST(RuntimeScene, NeedsVelocityOnlyWhenAnEffectUsesIt) {
  RuntimeScene<double> spring_only;
  RuntimeScene<double>::SurfaceEffect::Params p{};
  p.plane = {{0, 0, 0}, {0, 0, 1}};
  p.wall = {1000.0, 0.0};
  ASSERT_TRUE(spring_only.add_surface(p));
  EXPECT_FALSE(has(spring_only.needs(), Needs::kVelocity));
  p.wall.damping_n_s_per_m = 1.0;
  ASSERT_TRUE(spring_only.add_surface(p));
  EXPECT_TRUE(has(spring_only.needs(), Needs::kVelocity));
}

TEST(RuntimeScene, RefusesMoreThanItsCapacity) {
  RuntimeScene<double> scene;
  RuntimeScene<double>::SurfaceEffect::Params p{};
  p.plane = {{0, 0, 0}, {0, 0, 1}};
  p.wall = {1000.0, 0.0};
  for (std::size_t i = 0; i < RuntimeScene<double>::kMaxSurfaces; ++i) ASSERT_TRUE(scene.add_surface(p));
  EXPECT_FALSE(scene.add_surface(p));
  EXPECT_EQ(scene.surface_count(), RuntimeScene<double>::kMaxSurfaces);
}

}  // namespace
}  // namespace toonforce
