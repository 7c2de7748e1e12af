// SPDX-License-Identifier: Apache-2.0
// Scenes: compile-time composition pays only for its effects; the run-time scene sums its
// effects in file order and matches the compile-time one.
#include <gtest/gtest.h>

#include <cmath>
#include <type_traits>

#include "toonforce/control/servo_loop.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {
namespace {

using SpringFloor = Scene<Surface<SpringWall<double>>>;
using DampedFloor = Scene<Surface<PenaltyWall<double>>>;
using CliffScene = Scene<CartoonCliff<double>>;
using CartoonWallScene = Scene<Surface<PenaltyWall<double>, NoTangential<double>, ImpactTransient<double>>>;

// A scene made only of spring walls needs no velocity, so replay's loop (no velocity limit, no
// passivity controller) has no estimator; one with every stage has it (the velocity limit).
static_assert(!has(SpringFloor::kNeeds, Needs::kVelocity));
static_assert(has(DampedFloor::kNeeds, Needs::kVelocity));
static_assert(has(CliffScene::kNeeds, Needs::kVelocity));
static_assert(has(CartoonWallScene::kNeeds, Needs::kVelocity));
struct NoDevice {
  DeviceStatus read(DeviceReading&) noexcept { return DeviceStatus::kOk; }
  DeviceStatus write(const Vec3<double>&) noexcept { return DeviceStatus::kOk; }
};
template <class SceneT, LoopStages kStages>
using LoopOf = ServoLoop<NoDevice, SceneT, NullPins, kStages>;
static_assert(!LoopOf<SpringFloor, kSpecStages>::kMayEstimate);
static_assert(LoopOf<DampedFloor, kSpecStages>::kMayEstimate);
static_assert(LoopOf<SpringFloor, kEveryStage>::kMayEstimate);
static_assert(sizeof(LoopOf<SpringFloor, kSpecStages>) < sizeof(LoopOf<DampedFloor, kSpecStages>),
              "the estimator of a loop that needs none must take no room");
// A loop built without a stage carries none of its state.
static_assert(sizeof(LoopOf<DampedFloor, kSpecStages>) < sizeof(LoopOf<DampedFloor, kEveryStage>));
// Active parts: a plain or friction surface has none, the slippery one and the impact one each.
static_assert(SpringFloor::kActiveCapacity == 0);
static_assert(Scene<Surface<SpringWall<double>, RealisticFriction<double>>>::kActiveCapacity == 0);
static_assert(Scene<Surface<SpringWall<double>, SuperSlippery<double>>>::kActiveCapacity == 1);
static_assert(CartoonWallScene::kActiveCapacity == 1);
static_assert(RuntimeScene<double>::kActiveCapacity == 2 * 16);
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
  in.now = Instant{tick, 0};
  in.period_s = 1e-3;
  return in;
}

TEST(Scene, SumsItsEffects) {
  Surface<PenaltyWall<double>>::Params floor{{{0, 0, 0}, {0, 0, 1}}, {1000.0, 0.0}, {}, {}};
  Surface<PenaltyWall<double>>::Params wall{{{0.01, 0, 0}, {-1, 0, 0}}, {500.0, 0.0}, {}, {}};
  Scene<Surface<PenaltyWall<double>>, Surface<PenaltyWall<double>>> corner(floor, wall);
  decltype(corner)::State state{};
  const auto f = corner.force(at({0.012, 0, -0.002}, {}, 0), state, nullptr);
  EXPECT_NEAR(f.x, -500.0 * 0.002, 1e-12);
  EXPECT_NEAR(f.z, 1000.0 * 0.002, 1e-12);
}

TEST(RuntimeScene, MatchesTheCompileTimeSceneBitForBit) {
  using Law = ImpactTransient<double>;
  using Compiled = Scene<Surface<PenaltyWall<double>, NoTangential<double>, Law>, CartoonCliff<double>>;
  Surface<PenaltyWall<double>, NoTangential<double>, Law>::Params wall{};
  wall.plane = {{0, 0, 0.01}, {0, 0, -1}};  // a ceiling 1 cm up
  wall.wall = {900.0, 3.0};
  wall.impact = {250.0, 500.0, 0.12, 25.0, 0.02, 0.001, SineMethod::kLibrary};  // the path enters at 0.047 m/s
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
  RuntimeSurface<double>::Params any{};
  any.plane = wall.plane;
  any.wall = wall.wall;
  any.impact = {true, wall.impact};
  ASSERT_TRUE(runtime.add<RuntimeSurface<double>>(any));
  ASSERT_TRUE(runtime.add<CartoonCliff<double>>(cliff));
  EXPECT_TRUE(has(runtime.needs(), Needs::kVelocity));

  Compiled::State cs{};
  RuntimeScene<double>::State rs{};
  ActiveForce<double> ca[Compiled::kActiveCapacity]{};
  ActiveForce<double> ra[RuntimeScene<double>::kActiveCapacity]{};
  double cv[Compiled::kValueCapacity]{};
  double rv[RuntimeScene<double>::kValueCapacity]{};
  bool triggered = false;
  for (int k = 0; k < 3000; ++k) {
    const double t = k * 1e-3;
    // Up and down through both the floor (with its gap) and the ceiling, sideways along x.
    const Vec3<double> x{-0.03 + 0.02 * t, 0.0, 0.004 + 0.009 * std::sin(7.0 * t)};
    const Vec3<double> v{0.02, 0.0, 0.063 * std::cos(7.0 * t)};
    const auto in = at(x, v, k);
    const auto a = compiled.force(in, cs, ca);
    const auto b = runtime.force(in, rs, ra);
    ASSERT_EQ(a, b) << "tick " << k;  // the same law code in the same order: identical bits
    // The impact's active part: slot 0 of both (the runtime surface has no slippery law, so
    // its impact takes the first slot it was given).
    ASSERT_EQ(ca[0].force_n, ra[0].force_n) << "tick " << k;
    ASSERT_EQ(ca[0].in_episode, ra[0].in_episode) << "tick " << k;
    triggered = triggered || ca[0].triggered;
    // And what they show: contact and impact time of the wall, state and speed of the cliff.
    ASSERT_EQ(compiled.describe(cs, in, cv), runtime.describe(rs, in, rv));
    for (std::size_t i = 0; i < compiled.value_count(); ++i) {
      ASSERT_TRUE(cv[i] == rv[i] || (std::isnan(cv[i]) && std::isnan(rv[i]))) << "value " << i << " tick " << k;
    }
  }
  EXPECT_TRUE(triggered);                 // the path does strike the ceiling
  EXPECT_EQ(runtime.active_slots(), 1u);  // the impact's; the cliff injects nothing
  EXPECT_EQ(runtime.value_count(), 4u);
  EXPECT_EQ(runtime.effect_info(1).key, "cliff");
  EXPECT_EQ(runtime.effect_info(1).value_offset, 2u);
  EXPECT_EQ(runtime.effect_info(1).values[0].name, "state");
}

TEST(Scene, NamesItsEffectsByKeyAndNumberInOrder) {
  using Floor = Surface<SpringWall<double>>;
  Floor::Params p{{{0, 0, 0}, {0, 0, 1}}, {1000.0, 0.0}, {}, {}};
  const Scene<Floor, CartoonCliff<double>, Floor> scene(p, CartoonCliff<double>::Params{}, p);
  EXPECT_EQ(scene.effect_count(), 3u);
  EXPECT_EQ(scene.effect_info(0).number, 1u);
  EXPECT_EQ(scene.effect_info(1).number, 1u);
  EXPECT_EQ(scene.effect_info(2).key, "surface");
  EXPECT_EQ(scene.effect_info(2).number, 2u);
  EXPECT_EQ(scene.effect_info(2).value_offset, 3u);  // surface1.contact, cliff1.state, cliff1.speed
}

TEST(RuntimeScene, NeedsVelocityOnlyWhenAnEffectUsesIt) {
  RuntimeScene<double> spring_only;
  RuntimeSurface<double>::Params p{};
  p.plane = {{0, 0, 0}, {0, 0, 1}};
  p.wall = {1000.0, 0.0};
  ASSERT_TRUE(spring_only.add<RuntimeSurface<double>>(p));
  EXPECT_FALSE(has(spring_only.needs(), Needs::kVelocity));
  p.wall.damping_n_s_per_m = 1.0;
  ASSERT_TRUE(spring_only.add<RuntimeSurface<double>>(p));
  EXPECT_TRUE(has(spring_only.needs(), Needs::kVelocity));
}

TEST(RuntimeScene, RefusesMoreThanItsCapacity) {
  RuntimeScene<double> scene;
  RuntimeSurface<double>::Params p{};
  p.plane = {{0, 0, 0}, {0, 0, 1}};
  p.wall = {1000.0, 0.0};
  for (std::size_t i = 0; i < RuntimeSurface<double>::kMaxPerScene; ++i)
    ASSERT_TRUE(scene.add<RuntimeSurface<double>>(p));
  EXPECT_FALSE(scene.add<RuntimeSurface<double>>(p));
  EXPECT_EQ(scene.count<RuntimeSurface<double>>(), RuntimeSurface<double>::kMaxPerScene);
  EXPECT_TRUE(scene.add<CartoonCliff<double>>(CartoonCliff<double>::Params{}));  // another kind has room
}

/// A kind the library does not know: a program's own effect in a run-time scene.
template <Scalar S>
struct Bump {
  using Scalar = S;
  struct Params {
    S height_n{};
  };
  struct State {
    int ticks = 0;
  };
  static constexpr std::string_view kKey = "bump";
  static constexpr Needs kNeeds = Needs::kNone;
  static constexpr std::size_t kActiveSlots = 1;
  static constexpr std::array<ValueInfo, 1> kValues{{{"ticks", "", ""}}};
  static Vec3<S> force(const Params& p, State& s, const TickInput<S>&, ActiveForce<S>* active) noexcept {
    ++s.ticks;
    active[0] = {{S{}, S{}, p.height_n}, true, s.ticks == 1};
    return {S{}, S{}, p.height_n};
  }
  static bool describe(const Params&, const State& s, const TickInput<S>&, double* values) noexcept {
    values[0] = s.ticks;
    return false;
  }
};

TEST(RuntimeScene, TakesAProgramsOwnKindBesideTheLibrarys) {
  RuntimeSceneOf<double, RuntimeSurface, Bump> scene;
  RuntimeSurface<double>::Params floor{};
  floor.plane = {{0, 0, 0}, {0, 0, 1}};
  floor.wall = {1000.0, 0.0};
  ASSERT_TRUE(scene.add<Bump<double>>({0.5}));
  ASSERT_TRUE(scene.add<RuntimeSurface<double>>(floor));
  EXPECT_EQ(scene.active_slots(), 1u);  // the bump's; a plain floor injects nothing
  decltype(scene)::State state{};
  ActiveForce<double> active[decltype(scene)::kActiveCapacity]{};
  const auto f = scene.force(at({0, 0, -0.001}, {}, 0), state, active);
  EXPECT_NEAR(f.z, 0.5 + 1.0, 1e-12);
  EXPECT_TRUE(active[0].in_episode);
  EXPECT_EQ(active[0].force_n.z, 0.5);
  double values[8]{};
  static_cast<void>(scene.describe(state, at({0, 0, -0.001}, {}, 0), values));
  EXPECT_EQ(values[0], 1.0);  // bump1.ticks
  EXPECT_EQ(values[1], 1.0);  // surface1.contact
  EXPECT_EQ(scene.effect_info(0).key, "bump");
  // A slippery surface with an impact has two slots, in that order, after the bump's.
  floor.tangential.kind = TangentialKind::kSlippery;
  floor.tangential.slippery = {4.0, 2.0};
  floor.impact.enabled = true;
  floor.impact.law = {300.0, 600.0, 0.15, 30.0, 0.05, 0.001, SineMethod::kAuto};
  ASSERT_TRUE(scene.add<RuntimeSurface<double>>(floor));
  EXPECT_EQ(scene.active_slots(), 3u);
  EXPECT_EQ(scene.effect_info(2).active_offset, 1u);
  EXPECT_EQ(scene.effect_info(2).active_slots, 2u);
}

}  // namespace
}  // namespace toonforce
