// SPDX-License-Identifier: Apache-2.0
// Live scenes from an untrusted process (docs/spec/live-scenes.md, "What the loop checks"): the
// mailbox is in memory shared with the viewer's server process, which may write any bytes there
// at any time. Each test writes what such a process could (through ForgeAccess, the hook the
// library leaves for tests) and checks that the loop refuses the update, counts it, keeps the
// scene it had and its force within the clamp, and still applies an honest update afterwards.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

#include "support/alloc_counter.hpp"
#include "toonforce/control/servo_loop.hpp"

namespace toonforce {

/// What a process sharing the mailbox can write: any member of the update's scene and of the
/// mailbox itself.
struct ForgeAccess {
  template <class SceneT>
  static std::size_t& effect_count(SceneT& s) {
    return s.effect_count_;
  }
  template <class SceneT>
  static std::size_t& active_slots(SceneT& s) {
    return s.active_slots_;
  }
  template <class SceneT>
  static std::size_t& value_count(SceneT& s) {
    return s.value_count_;
  }
  template <class SceneT>
  static auto& counts(SceneT& s) {
    return s.counts_;
  }
  template <class SceneT>
  static auto& entry(SceneT& s, std::size_t i) {
    return s.order_[i];
  }
  template <std::size_t I, class SceneT>
  static auto& params(SceneT& s, std::size_t n) {
    return std::get<I>(s.params_)[n];
  }
  template <class M>
  static auto& head(M& m) {
    return m.head_;
  }
  template <class M>
  static auto& tail(M& m) {
    return m.tail_;
  }
  template <class M>
  static auto& slot(M& m, std::size_t n) {
    return m.slots_[n % M::capacity()];
  }
};

namespace {

constexpr double kPeriodS = 0.001;
constexpr double kMaxForceN = 10.0;
constexpr double kTolerance = 5e-3;  // [N] Q16.16 rounds the 2 mm and the stiffness

struct HeldDevice {
  const Vec3<double>* position_m;
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = *position_m;
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>&) noexcept { return DeviceStatus::kOk; }
};

ServoConfig config() {
  ServoConfig c;
  c.period_s = kPeriodS;
  c.safety.engage_force_n = 1e3;  // engage at once
  c.safety.soft_start_s = 0.0;
  c.safety.update_fade_s = 0.0;  // an applied update is felt at once: the force says which scene runs
  c.limits.max_force_n = kMaxForceN;
  c.limits.has_max_force = true;
  return c;
}

template <Scalar S>
Vec3<S> vec(double x, double y, double z) {
  return {scalar_cast<S>(x), scalar_cast<S>(y), scalar_cast<S>(z)};
}

/// A floor at z = `height` of stiffness `k`, with an impact (its event is "impact").
template <Scalar S>
typename RuntimeSurface<S>::Params floor_at(double height, double k) {
  typename RuntimeSurface<S>::Params p{};
  p.plane.point_m = vec<S>(0.0, 0.0, height);
  p.plane.normal = vec<S>(0.0, 0.0, 1.0);
  p.wall.stiffness_n_per_m = scalar_cast<S>(k);
  p.impact.enabled = true;
  p.impact.law.recoil_gain_n_per_m = scalar_cast<S>(300.0);
  p.impact.law.oscillation_gain_n_per_m = scalar_cast<S>(0.0);
  p.impact.law.duration_s = scalar_cast<S>(0.1);
  p.impact.law.frequency_hz = scalar_cast<S>(30.0);
  p.impact.law.min_impact_speed_m_per_s = scalar_cast<S>(0.05);
  p.impact.law.rearm_distance_m = scalar_cast<S>(0.001);
  p.impact.law.sine = SineMethod::kPolynomial;
  return p;
}

/// A cliff whose ground is the floor z = 0 (its event is "look_down").
template <Scalar S>
typename CartoonCliff<S>::Params cliff() {
  typename CartoonCliff<S>::Params p{};
  p.ground.point_m = vec<S>(0.0, 0.0, -1.0);  // far below: not touched here
  p.ground.normal = vec<S>(0.0, 0.0, 1.0);
  p.axis = vec<S>(1.0, 0.0, 0.0);
  p.gap_min_m = scalar_cast<S>(0.0);
  p.gap_max_m = scalar_cast<S>(0.02);
  p.wall.stiffness_n_per_m = scalar_cast<S>(1000.0);
  p.speed_threshold_m_per_s = scalar_cast<S>(0.05);
  p.tau_s = scalar_cast<S>(0.02);
  p.rearm_height_m = scalar_cast<S>(0.001);
  return p;
}

/// A live loop on a floor of 1000 N/m with the HIP held 2 mm into it (2 N), and its mailbox,
/// in the scalar S.
template <Scalar S, class SceneT = RuntimeScene<S>>
struct Live {
  using Update = SceneUpdate<SceneT>;
  using Mailbox = SceneMailbox<SceneT>;
  using Loop = ServoLoop<HeldDevice, SceneT, NullPins, kLiveStages>;

  Live() {
    SceneT scene;
    EXPECT_TRUE(scene.template add<RuntimeSurface<S>>(floor_at<S>(0.0, 1000.0)));
    mailbox = std::make_unique<Mailbox>();
    loop = std::make_unique<Loop>(HeldDevice{&position}, scene, config());
    loop->listen(*mailbox);
    for (int i = 0; i < 5; ++i) step();
    EXPECT_NEAR(force_z(), 2.0, kTolerance);
  }
  /// An honest update: the floor with stiffness `k`, continuing the floor the loop has.
  static Update floor_update(double k, std::uint64_t sequence) {
    Update u;
    EXPECT_TRUE(u.scene.template add<RuntimeSurface<S>>(floor_at<S>(0.0, k)));
    u.continues.fill(-1);
    u.continues[0] = 0;
    u.sequence = sequence;
    return u;
  }
  void step() {
    loop->tick(k++);
    const Vec3<double> f = to_double(loop->force());
    EXPECT_TRUE(std::isfinite(f.x) && std::isfinite(f.y) && std::isfinite(f.z));
    EXPECT_LE(std::sqrt(dot(f, f)), kMaxForceN + kTolerance) << "within the clamp";
  }
  double force_z() const { return to_double(loop->scene_force().z); }

  /// Pushes `forged` as the producer would, ticks, and checks that it was refused and the loop
  /// kept its floor; then that an honest update still goes through.
  void expect_refused(const Update& forged) {
    const std::uint64_t refused = loop->updates_refused();
    const std::uint64_t applied = loop->updates_applied();
    ASSERT_TRUE(mailbox->push(forged));
    step();
    EXPECT_EQ(loop->updates_refused(), refused + 1) << "counted";
    EXPECT_EQ(loop->updates_applied(), applied) << "not applied";
    EXPECT_EQ(mailbox->refused(), refused + 1) << "and said to the application";
    EXPECT_EQ(loop->scene().effect_count(), 1U) << "the scene it had";
    EXPECT_NEAR(force_z(), 2.0, kTolerance) << "the force it had";
    for (int i = 0; i < 3; ++i) step();
    EXPECT_NEAR(force_z(), 2.0, kTolerance);
    expect_honest_update_applies();
  }
  void expect_honest_update_applies() {
    const std::uint64_t applied = loop->updates_applied();
    ASSERT_TRUE(mailbox->push(floor_update(3000.0, 77)));
    step();
    EXPECT_EQ(loop->updates_applied(), applied + 1) << "the mailbox still works";
    EXPECT_EQ(mailbox->applied(), 77U);
    EXPECT_NEAR(force_z(), 6.0, kTolerance);
    ASSERT_TRUE(mailbox->push(floor_update(1000.0, 78)));  // and back, for the next case
    step();
    EXPECT_EQ(loop->updates_applied(), applied + 2);
    EXPECT_NEAR(force_z(), 2.0, kTolerance);
  }

  Vec3<double> position{0.0, 0.0, -0.002};
  std::unique_ptr<Mailbox> mailbox;
  std::unique_ptr<Loop> loop;
  std::int64_t k = 0;
};

template <class S>
class UntrustedUpdate : public ::testing::Test {};
using Scalars = ::testing::Types<double, float, Q16_16>;
TYPED_TEST_SUITE(UntrustedUpdate, Scalars);

TYPED_TEST(UntrustedUpdate, AnEffectCountOverCapacityIsRefused) {
  using S = TypeParam;
  Live<S> live;
  // A full scene (16 surfaces, 8 cliffs: kMaxEffects, 24) that says it has more.
  auto u = Live<S>::floor_update(1000.0, 5);
  for (int i = 1; i < 16; ++i) ASSERT_TRUE(u.scene.template add<RuntimeSurface<S>>(floor_at<S>(0.0, 1000.0)));
  for (int i = 0; i < 8; ++i) ASSERT_TRUE(u.scene.template add<CartoonCliff<S>>(cliff<S>()));
  ASSERT_EQ(u.scene.effect_count(), RuntimeScene<S>::kMaxEffects);
  for (const std::size_t forged : {std::size_t{25}, std::size_t{255}, std::numeric_limits<std::size_t>::max()}) {
    ForgeAccess::effect_count(u.scene) = forged;
    live.expect_refused(u);
  }
}

TYPED_TEST(UntrustedUpdate, AnActiveSlotCountOrOffsetOutOfRangeIsRefused) {
  using S = TypeParam;
  Live<S> live;
  auto u = Live<S>::floor_update(3000.0, 5);
  ForgeAccess::active_slots(u.scene) = 255;  // passivity slots: the stage has kActiveCapacity + 1
  live.expect_refused(u);
  u = Live<S>::floor_update(3000.0, 5);
  ForgeAccess::entry(u.scene, 0).active_offset = 200;  // the surface's impact slot, past the array
  live.expect_refused(u);
  u = Live<S>::floor_update(3000.0, 5);
  ForgeAccess::entry(u.scene, 0).value_offset = 60000;
  live.expect_refused(u);
  u = Live<S>::floor_update(3000.0, 5);
  ForgeAccess::value_count(u.scene) = 1000;
  live.expect_refused(u);
}

TYPED_TEST(UntrustedUpdate, AnOrderEntryIndex255IsRefused) {
  using S = TypeParam;
  Live<S> live;
  auto u = Live<S>::floor_update(3000.0, 5);
  ForgeAccess::entry(u.scene, 0).index = 255;  // 255 surfaces past an array of 16
  live.expect_refused(u);
  u = Live<S>::floor_update(3000.0, 5);
  ASSERT_TRUE(u.scene.template add<RuntimeSurface<S>>(floor_at<S>(0.05, 1000.0)));
  u.continues[1] = -1;
  ForgeAccess::entry(u.scene, 1).index = 0;  // two surfaces numbered 0: one of them unseen
  live.expect_refused(u);
  u = Live<S>::floor_update(3000.0, 5);
  ForgeAccess::counts(u.scene)[0] = 16;  // counts that are not the order's
  live.expect_refused(u);
}

TYPED_TEST(UntrustedUpdate, AKindOutOfRangeIsRefused) {
  using S = TypeParam;
  Live<S> live;
  auto u = Live<S>::floor_update(3000.0, 5);
  ForgeAccess::entry(u.scene, 0).kind = 2;  // RuntimeScene has kinds 0 (surface) and 1 (cliff)
  live.expect_refused(u);
  ForgeAccess::entry(u.scene, 0).kind = 200;
  live.expect_refused(u);
}

TYPED_TEST(UntrustedUpdate, ANonFiniteOrOutOfRangeParameterIsRefused) {
  using S = TypeParam;
  Live<S> live;
  const auto forge = [&](auto&& change) {
    auto u = Live<S>::floor_update(3000.0, 5);
    change(ForgeAccess::params<0>(u.scene, 0));
    live.expect_refused(u);
  };
  if constexpr (!kIsFixed<S>) {
    forge([](auto& p) { p.wall.stiffness_n_per_m = std::numeric_limits<S>::quiet_NaN(); });
    forge([](auto& p) { p.plane.point_m.z = std::numeric_limits<S>::infinity(); });
    forge([](auto& p) { p.impact.law.duration_s = std::numeric_limits<S>::infinity(); });
  }
  forge([](auto& p) { p.wall.stiffness_n_per_m = scalar_cast<S>(-1000.0); });  // the schema: > 0
  forge([](auto& p) { p.wall.damping_n_s_per_m = scalar_cast<S>(-1.0); });     // >= 0
  forge([](auto& p) { p.plane.normal = vec<S>(0.0, 0.0, 100.0); });            // unit length
  forge([](auto& p) { p.impact.law.duration_s = S{}; });                       // > 0
  forge([](auto& p) {  // friction that pushes along the motion: <= 0
    p.tangential.kind = TangentialKind::kFriction;
    p.tangential.friction.viscous_n_s_per_m = scalar_cast<S>(5.0);
    p.tangential.friction.regularization_speed_m_per_s = scalar_cast<S>(0.02);
  });
  forge([](auto& p) {  // a tangential law that is none of the three
    const auto bad = std::uint8_t{9};
    std::memcpy(&p.tangential.kind, &bad, 1);
  });
  forge([](auto& p) {  // a flag that is neither true nor false
    const auto bad = std::uint8_t{7};
    std::memcpy(&p.impact.enabled, &bad, 1);
  });
  forge([](auto& p) {  // a sine that is none of the names
    const auto bad = std::uint8_t{40};
    std::memcpy(&p.impact.law.sine, &bad, 1);
  });
  // A cliff's check across keys (its axis in the ground plane, gap_min < gap_max).
  auto u = Live<S>::floor_update(3000.0, 5);
  auto c = cliff<S>();
  c.gap_max_m = scalar_cast<S>(-1.0);
  ASSERT_TRUE(u.scene.template add<CartoonCliff<S>>(c));
  u.continues[1] = -1;
  live.expect_refused(u);
}

TYPED_TEST(UntrustedUpdate, AContinuesIndexOutOfRangeIsRefused) {
  using S = TypeParam;
  Live<S> live;
  auto u = Live<S>::floor_update(3000.0, 5);
  u.continues[0] = 200;  // the state of a surface 200 the loop never had
  live.expect_refused(u);
  u.continues[0] = 1;  // nor a second one
  live.expect_refused(u);
  u.continues[0] = -7;
  live.expect_refused(u);
}

TYPED_TEST(UntrustedUpdate, AnEventOutOfRangeIsRefused) {
  using S = TypeParam;
  Live<S> live;
  const auto forge = [&](std::uint8_t count, SceneEvent e) {
    auto u = Live<S>::floor_update(3000.0, 5);
    u.event_count = count;
    u.events[0] = e;
    live.expect_refused(u);
  };
  {  // 200 events in an array of 8 (the 8 there valid)
    auto u = Live<S>::floor_update(3000.0, 5);
    u.events.fill(SceneEvent{0, 0, 0.3});
    u.event_count = 200;
    live.expect_refused(u);
  }
  forge(1, SceneEvent{300, 0, 0.3});  // an effect the scene does not have
  forge(1, SceneEvent{1, 0, 0.3});
  forge(1, SceneEvent{0, 5, 0.3});  // a surface has one event
  forge(1, SceneEvent{0, 0, std::numeric_limits<double>::quiet_NaN()});
  if constexpr (!std::is_same_v<S, double>) forge(1, SceneEvent{0, 0, 1e300});  // not a number S holds
}

TYPED_TEST(UntrustedUpdate, HonestUpdatesWithEventsAreStillApplied) {
  using S = TypeParam;
  Live<S> live;
  auto u = Live<S>::floor_update(1000.0, 9);
  u.event_count = 1;
  u.events[0] = SceneEvent{0, 0, 0.3};
  // A cliff tilted off the axes, as a file's normal and axis round in S.
  auto c = cliff<S>();
  c.ground.normal = vec<S>(0.6, 0.0, 0.8);
  c.axis = vec<S>(0.8, 0.0, -0.6);
  c.ground.point_m = vec<S>(0.0, 0.0, -1.0);
  ASSERT_TRUE(u.scene.template add<CartoonCliff<S>>(c));
  u.continues[1] = -1;
  ASSERT_TRUE(live.mailbox->push(u));
  live.step();
  EXPECT_EQ(live.loop->updates_refused(), 0U);
  EXPECT_EQ(live.loop->updates_applied(), 1U);
  EXPECT_EQ(live.loop->scene().effect_count(), 2U);
  EXPECT_GT(live.force_z(), 2.0 + kTolerance) << "the impact fired";
}

TYPED_TEST(UntrustedUpdate, AForgedHeadIsAHintAndAForgedTailIsNeverReadBack) {
  using S = TypeParam;
  Live<S> live;
  // A head far ahead of anything pushed: the loop takes one slot a tick (its own index modulo
  // the capacity), finds no update numbered so there, and refuses it, tick after tick.
  ForgeAccess::head(*live.mailbox).store(1'000'000);
  for (std::uint64_t i = 1; i <= 6; ++i) {
    live.step();
    EXPECT_EQ(live.loop->updates_refused(), i) << "one a tick";
    EXPECT_NEAR(live.force_z(), 2.0, kTolerance);
  }
  EXPECT_EQ(live.loop->updates_applied(), 0U);
  // The producer's head back where the loop is (6 taken): an honest update goes through.
  ForgeAccess::head(*live.mailbox).store(6);
  ForgeAccess::tail(*live.mailbox).store(6);
  live.expect_honest_update_applies();
  // The tail rewound to update 6 and its slot (which still says "update 6") rewritten with an
  // empty scene: the loop keeps its own index, so it neither takes that slot again nor drops
  // its floor.
  ForgeAccess::tail(*live.mailbox).store(6);
  auto& slot = ForgeAccess::slot(*live.mailbox, 6);
  slot.update = typename Live<S>::Update{};
  for (int i = 0; i < 5; ++i) live.step();
  EXPECT_EQ(live.loop->updates_applied(), 2U);
  EXPECT_NEAR(live.force_z(), 2.0, kTolerance);
}

TYPED_TEST(UntrustedUpdate, ATickWithoutAnUpdateAndOneThatIsRefusedAllocateNothing) {
  using S = TypeParam;
  Live<S> live;
  auto u = Live<S>::floor_update(3000.0, 5);
  ForgeAccess::effect_count(u.scene) = 255;
  ASSERT_TRUE(live.mailbox->push(u));
  test::AllocationScope scope;
  live.loop->tick(live.k++);
  live.loop->tick(live.k++);
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(live.loop->updates_refused(), 1U);
}

}  // namespace

// A writer that changes the slot while the loop copies it: the loop's copy of the bytes is
// this specialisation's, for a scene type only this test uses (surfaces only).
using TornScene = RuntimeSceneOf<double, RuntimeSurface>;
using TornMailbox = SceneMailbox<TornScene>;

namespace {
struct TornWriter {
  TornMailbox* mailbox = nullptr;
  bool armed = false;
  std::uint64_t writes = 0;
};
TornWriter torn_writer;
}  // namespace

template <>
struct SceneUpdateCopy<TornScene> {
  static void copy(void* to, const void* from, std::size_t n) noexcept {
    // The first half, then the writer starts over (odd sequence) and rewrites the update with
    // the floor 40 mm higher (a valid scene: only the sequence can tell), then the second half.
    std::memcpy(to, from, n / 2);
    if (torn_writer.armed) {
      ++torn_writer.writes;
      for (std::size_t i = 0; i < TornMailbox::capacity(); ++i) {
        auto& slot = ForgeAccess::slot(*torn_writer.mailbox, i);
        if (static_cast<const void*>(&slot.update) != from) continue;
        ForgeAccess::params<0>(slot.update.scene, 0).plane.point_m.z = 0.04;
        // A write starts (the sequence goes odd) or, if it was under way, ends (odd + 1: the
        // number the loop expects).
        slot.sequence.store(slot.sequence.load() + 1);
      }
    }
    std::memcpy(static_cast<unsigned char*>(to) + n / 2, static_cast<const unsigned char*>(from) + n / 2, n - n / 2);
  }
};

namespace {

TEST(UntrustedUpdate, ACopyTornByAConcurrentWriterIsRefused) {
  Live<double, TornScene> live;
  torn_writer = TornWriter{live.mailbox.get(), true, 0};
  auto u = Live<double, TornScene>::floor_update(3000.0, 5);
  ASSERT_TRUE(live.mailbox->push(u));
  live.step();
  EXPECT_EQ(torn_writer.writes, 1U);
  EXPECT_EQ(live.loop->updates_refused(), 1U) << "the sequence changed during the copy";
  EXPECT_EQ(live.loop->updates_applied(), 0U);
  EXPECT_NEAR(live.force_z(), 2.0, 1e-9) << "neither the 6 N of the update nor the 126 N of the torn copy";
  for (int i = 0; i < 3; ++i) live.step();
  EXPECT_NEAR(live.force_z(), 2.0, 1e-9);
  torn_writer.armed = false;
  live.expect_honest_update_applies();
}

TEST(UntrustedUpdate, ACopyStartedWhileTheWriterWasMidWriteIsRefused) {
  // The slot's sequence is odd when the loop looks (a writer is at it) and the writer finishes
  // during the copy: the sequence after the copy is the expected one, but the copy's first
  // half is from before.
  Live<double, TornScene> live;
  torn_writer = TornWriter{live.mailbox.get(), true, 0};
  ASSERT_TRUE(live.mailbox->push(Live<double, TornScene>::floor_update(3000.0, 5)));
  auto& slot = ForgeAccess::slot(*live.mailbox, 0);
  slot.sequence.store(slot.sequence.load() - 1);  // 2 (0 + 1) - 1: being written
  live.step();
  EXPECT_EQ(live.loop->updates_refused(), 1U) << "the sequence was odd before the copy";
  EXPECT_EQ(live.loop->updates_applied(), 0U);
  EXPECT_NEAR(live.force_z(), 2.0, 1e-9);
  torn_writer.armed = false;
  live.expect_honest_update_applies();
}

TEST(UntrustedUpdate, ASlotWrittenAgainWithAnotherNumberIsRefused) {
  // An update whose slot holds the sequence of a later lap (or an odd one: being written) is
  // not the one the loop's index names.
  Live<double> live;
  ASSERT_TRUE(live.mailbox->push(Live<double>::floor_update(3000.0, 5)));
  ForgeAccess::slot(*live.mailbox, 0).sequence.store(2 * 4 + 2);
  live.step();
  EXPECT_EQ(live.loop->updates_refused(), 1U);
  ASSERT_TRUE(live.mailbox->push(Live<double>::floor_update(3000.0, 5)));
  ForgeAccess::slot(*live.mailbox, 1).sequence.store(3);
  live.step();
  EXPECT_EQ(live.loop->updates_refused(), 2U);
  EXPECT_NEAR(live.force_z(), 2.0, 1e-9);
  live.expect_honest_update_applies();
}

}  // namespace
}  // namespace toonforce
