// SPDX-License-Identifier: Apache-2.0
// Live scenes (docs/spec/live-scenes.md): changes from the application's thread reach
// the servo loop whole at a tick boundary, checked as scene files are, and cannot kick the
// handle: the force stays continuous and the difference fades out, counted by the passivity
// controller; events fire the effects' own laws.

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <memory>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include <fmt/format.h>

#include "support/alloc_counter.hpp"
#include "toonforce/config/scene_editor.hpp"
#include "toonforce/control/servo_loop.hpp"

namespace toonforce {
namespace {

constexpr double kPeriodS = 0.001;

struct HeldDevice {
  const Vec3<double>* position_m;
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = *position_m;
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>&) noexcept { return DeviceStatus::kOk; }
};

using Scene = RuntimeScene<double>;
using Loop = ServoLoop<HeldDevice, Scene, NullPins, kLiveStages>;
using Mailbox = SceneMailbox<Scene>;

ServoConfig live_config(double fade_s = 0.25) {
  ServoConfig c;
  c.period_s = kPeriodS;
  c.safety.engage_force_n = 1e3;  // engage at once: these tests look at the scene's force
  c.safety.soft_start_s = 0.0;
  c.safety.update_fade_s = fade_s;
  return c;
}

/// A loop on the scene `text`, the HIP held where `position` says, and its editor.
struct LiveLoop {
  explicit LiveLoop(const std::string& text, double fade_s = 0.25) {
    mailbox = std::make_unique<Mailbox>();
    auto opened = SceneEditor<double>::open(text, "live.toml", *mailbox);
    if (!opened) throw std::runtime_error(opened.error());
    editor.emplace(std::move(opened.value()));
    loop =
        std::make_unique<Loop>(HeldDevice{&position}, make_runtime_scene<double>(editor->scene()), live_config(fade_s));
    loop->listen(*mailbox);
  }
  Vec3<double> step() {
    loop->tick(k++);
    return loop->scene_force();
  }
  Vec3<double> position{0.0, 0.0, 0.01};
  std::unique_ptr<Mailbox> mailbox;
  std::optional<SceneEditor<double>> editor;
  std::unique_ptr<Loop> loop;
  std::int64_t k = 0;
};

const std::string kFloor = "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\n";

TEST(LiveScene, ASurfaceThatAppearsAroundTheHandleRampsInOverTheFadeInsteadOfKickingIt) {
  LiveLoop live(kFloor);
  live.position = {0.0, 0.0, -0.002};  // 2 mm into the floor
  for (int i = 0; i < 5; ++i) live.step();
  EXPECT_NEAR(live.step().z, 2.0, 1e-9);  // K delta
  // A second floor 3 mm above appears with the HIP 5 mm inside it: 5 N more, felt as a ramp.
  ASSERT_TRUE(live.editor->add("surface", "point = [0, 0, 0.003]\nnormal = [0, 0, 1]\nstiffness = 1000"));
  const int fade_ticks = 250;
  double previous = 2.0;
  for (int i = 0; i < fade_ticks; ++i) {
    const double f = live.step().z;
    // Tick i after the update: 2 N + 5 N * i / 250, never a step above one fade step.
    EXPECT_NEAR(f, 2.0 + 5.0 * i / fade_ticks, 1e-9) << "tick " << i;
    EXPECT_LE(f - previous, 5.0 / fade_ticks + 1e-9) << "tick " << i;
    previous = f;
  }
  EXPECT_NEAR(live.step().z, 7.0, 1e-12) << "the new scene's own force once the fade is over";
  EXPECT_EQ(live.loop->updates_applied(), 1U);
  EXPECT_EQ(live.editor->applied(), 1U);
}

TEST(LiveScene, WithoutAFadeTheSameUpdateIsAStep) {
  // The fade is what makes the previous test pass: with none, the new force comes at once.
  LiveLoop live(kFloor, 0.0);
  live.position = {0.0, 0.0, -0.002};
  for (int i = 0; i < 5; ++i) live.step();
  ASSERT_TRUE(live.editor->add("surface", "point = [0, 0, 0.003]\nnormal = [0, 0, 1]\nstiffness = 1000"));
  EXPECT_NEAR(live.step().z, 7.0, 1e-9);
}

TEST(LiveScene, AStiffnessJumpIsFeltAsARampAndTheFadeIsBookedAsAnActivePart) {
  LiveLoop live(kFloor);
  live.position = {0.0, 0.0, -0.002};
  for (int i = 0; i < 5; ++i) live.step();
  ASSERT_TRUE(live.editor->set("surface1", "stiffness = 3000"));
  EXPECT_NEAR(live.step().z, 2.0, 1e-9) << "continuous at the update's tick";
  const auto& passivity = live.loop->passivity();
  const std::size_t fade_slot = passivity.slots() - 1;
  EXPECT_TRUE(passivity.controller().in_episode(fade_slot)) << "the fading difference is an active part";
  EXPECT_NEAR(live.step().z, 2.0 + 4.0 / 250, 1e-9);
  for (int i = 0; i < 300; ++i) live.step();
  EXPECT_NEAR(live.step().z, 6.0, 1e-12);
  EXPECT_FALSE(passivity.controller().in_episode(fade_slot)) << "the episode ends with the fade";
  EXPECT_DOUBLE_EQ(live.editor->scene().of<RuntimeSurface>()[0].wall.stiffness_n_per_m, 3000.0);
}

TEST(LiveScene, AMovedSurfaceKeepsItsOtherKeys) {
  LiveLoop live("[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\ndamping = 2\n"
                "[surface.impact]\nrecoil_gain = 300\noscillation_gain = 900\nduration = 0.1\nfrequency = 30\n");
  ASSERT_TRUE(live.editor->set("surface1", "point = [0, 0, 0.01]\n[impact]\nduration = 0.2"));
  const auto& s = live.editor->scene().of<RuntimeSurface>()[0];
  EXPECT_DOUBLE_EQ(s.plane.point_m.z, 0.01);
  EXPECT_DOUBLE_EQ(s.wall.stiffness_n_per_m, 1000.0);
  EXPECT_DOUBLE_EQ(s.wall.damping_n_s_per_m, 2.0);
  EXPECT_DOUBLE_EQ(s.impact.law.duration_s, 0.2);
  EXPECT_DOUBLE_EQ(s.impact.law.recoil_gain_n_per_m, 300.0) << "a sub-table is merged key by key";
}

TEST(LiveScene, ABadChangeIsRefusedWithTheSceneFilesMessageAndNothingReachesTheLoop) {
  LiveLoop live(kFloor);
  // The same typo in a scene file and in a change: the same words about the key.
  const auto file = parse_scene(kFloor + "stifness = 800\n", "typo.toml");
  ASSERT_FALSE(file);
  const auto change = live.editor->set("surface1", "stifness = 800");
  ASSERT_FALSE(change);
  const std::string said = file.error().substr(file.error().find("surface[1]"));
  EXPECT_NE(change.error().find(said.substr(0, said.find('\n'))), std::string::npos)
      << "file: " << file.error() << "change: " << change.error();
  EXPECT_NE(change.error().find("set surface1:1:"), std::string::npos)
      << "the line in the change's text: " << change.error();
  // Out of range, unknown kinds and effects, a bad event: refused, each saying why.
  EXPECT_FALSE(live.editor->set("surface1", "stiffness = -5"));
  EXPECT_FALSE(live.editor->set("surface2", "stiffness = 5"));
  EXPECT_FALSE(live.editor->add("wall", "stiffness = 5"));
  EXPECT_FALSE(live.editor->add("surface", "stiffness = 5"));  // no point, no normal
  EXPECT_FALSE(live.editor->remove("cliff1"));
  const auto shake = live.editor->fire("surface1", "impact", 0.3);
  ASSERT_FALSE(shake);
  EXPECT_NE(shake.error().find("no impact table"), std::string::npos) << shake.error();
  EXPECT_EQ(live.mailbox->pending(), 0U) << "nothing was pushed";
  live.step();
  EXPECT_EQ(live.loop->updates_applied(), 0U);
  EXPECT_DOUBLE_EQ(live.editor->scene().of<RuntimeSurface>()[0].wall.stiffness_n_per_m, 1000.0);
}

TEST(LiveScene, ASceneWithOtherSafetyLimitsIsRefused) {
  LiveLoop live(kFloor);
  const auto refused = live.editor->load("[device]\nmax_force = 20\n" + kFloor, "strong.toml");
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().find("[device]"), std::string::npos) << refused.error();
  EXPECT_TRUE(live.editor->load(kFloor + "[[surface]]\npoint = [0, 0, 0.05]\nnormal = [0, 0, -1]\nstiffness = 500\n",
                                "box.toml"));
}

TEST(LiveScene, AFullMailboxRefusesTheChangeAndKeepsTheDocumentAsTheLoopWillHaveIt) {
  LiveLoop live(kFloor);
  for (std::size_t i = 0; i < Mailbox::capacity(); ++i) {
    ASSERT_TRUE(live.editor->set("surface1", fmt::format("stiffness = {}", 1100 + 100 * i)));
  }
  const auto refused = live.editor->set("surface1", "stiffness = 5000");
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().find("try again"), std::string::npos) << refused.error();
  EXPECT_DOUBLE_EQ(live.editor->scene().of<RuntimeSurface>()[0].wall.stiffness_n_per_m, 1400.0);
  // One update a tick, in order.
  for (std::size_t i = 0; i < Mailbox::capacity(); ++i) {
    live.step();
    EXPECT_EQ(live.loop->updates_applied(), i + 1);
    EXPECT_DOUBLE_EQ(to_double(live.loop->scene().params<RuntimeSurface<double>>(0).wall.stiffness_n_per_m),
                     1100.0 + 100.0 * static_cast<double>(i));
  }
  EXPECT_TRUE(live.editor->set("surface1", "stiffness = 5000")) << "room again";
}

TEST(LiveScene, AnImpactOnDemandIsTheLawOfSection4FromItsFiringTick) {
  const std::string wall =
      "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\n"
      "[surface.impact]\nrecoil_gain = 300\noscillation_gain = 900\nduration = 0.1\nfrequency = 30\n"
      "sine = \"library\"\n";  // std::sin, as the law below computes it
  LiveLoop live(wall);
  live.position = {0.0, 0.0, 0.01};  // out of contact: the shake needs no touch
  for (int i = 0; i < 5; ++i) EXPECT_EQ(live.step().z, 0.0);
  ASSERT_TRUE(live.editor->fire("surface1", "impact", 0.3));
  const double vi = 0.3, d = 0.1, kr = 300.0, kosc = 900.0, f = 30.0;
  for (int i = 0; i < 100; ++i) {
    const double t = i * kPeriodS;
    const double law = vi * (d - t) * (kr + kosc * std::sin(2.0 * std::numbers::pi * f * t));
    EXPECT_NEAR(live.step().z, law, 1e-6) << "t = " << t;
  }
  for (int i = 0; i < 5; ++i) live.step();
  EXPECT_EQ(live.step().z, 0.0) << "over after d";
  EXPECT_FALSE(live.editor->fire("surface1", "impact", -1.0)) << "a speed must be positive";
  EXPECT_FALSE(live.editor->fire("surface1", "look_down", 0.0)) << "a surface cannot look down";
}

// Fire answered ok to speeds whose transient the loop's numbers cannot hold (5 m/s on
// Q16.16 with these gains; 1e300 in double), which the loop then turned into faults with zero
// force. The speed is refused, with the range for this table and scalar in the message.
TEST(LiveScene, AnImpactSpeedTheLoopCannotRepresentIsRefusedWithTheRange) {
  const std::string wall =
      "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\n"
      "[surface.impact]\nrecoil_gain = 300\noscillation_gain = 900\nduration = 0.1\nfrequency = 30\n";
  // Peak force v_i d (|k_r| + |k_osc|) = 120 N per m/s.
  LiveLoop live(wall);
  EXPECT_TRUE(live.editor->fire("surface1", "impact", 0.3));
  const auto huge = live.editor->fire("surface1", "impact", 1e300);
  ASSERT_FALSE(huge);
  EXPECT_NE(huge.error().find("on the double loop"), std::string::npos) << huge.error();
  auto mailbox = std::make_unique<SceneMailbox<RuntimeScene<Q16_16>>>();
  auto q = SceneEditor<Q16_16>::open(wall, "live.toml", *mailbox);
  ASSERT_TRUE(q) << q.error();
  EXPECT_TRUE(q.value().fire("surface1", "impact", 1.5)) << "180 N: within sqrt(32767) N";
  const auto fast = q.value().fire("surface1", "impact", 5.0);
  ASSERT_FALSE(fast);
  // 181.02 N / 120 N per m/s, from the table's gains as Q16.16 holds them.
  EXPECT_NE(fast.error().find("within [1.53e-05, 1.508"), std::string::npos) << fast.error();
  EXPECT_NE(fast.error().find("m/s on the q16.16 loop"), std::string::npos) << fast.error();
  EXPECT_FALSE(q.value().fire("surface1", "impact", 1e-6)) << "below Q16.16's resolution: no transient at all";
}

// The top of that range is a transient the Q16.16 loop renders: force, no fault.
TEST(LiveScene, TheFastestImpactAcceptedOnQ16IsRenderedWithoutAFault) {
  using QScene = RuntimeScene<Q16_16>;
  const std::string wall =
      "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\n"
      "[surface.impact]\nrecoil_gain = 300\noscillation_gain = 900\nduration = 0.1\nfrequency = 30\n";
  auto mailbox = std::make_unique<SceneMailbox<QScene>>();
  auto editor = SceneEditor<Q16_16>::open(wall, "live.toml", *mailbox);
  ASSERT_TRUE(editor) << editor.error();
  Vec3<double> position{0.0, 0.0, 0.01};
  ServoLoop<HeldDevice, QScene, NullPins, kLiveStages> loop(
      HeldDevice{&position}, make_runtime_scene<Q16_16>(editor.value().scene()), live_config());
  loop.listen(*mailbox);
  for (std::int64_t k = 0; k < 5; ++k) loop.tick(k);
  ASSERT_TRUE(editor.value().fire("surface1", "impact", 1.5));
  double peak = 0.0;
  for (std::int64_t k = 5; k < 120; ++k) {
    loop.tick(k);
    peak = std::max(peak, std::fabs(to_double(loop.scene_force().z)));
  }
  EXPECT_GT(peak, 100.0) << "the transient's force (1.5 m/s x 120 N per m/s at its start)";
  EXPECT_FALSE(static_cast<bool>(loop.latched())) << "no fault";
}

TEST(LiveScene, LookDownDropsTheCharacterOverTheGapAndNowhereElse) {
  const std::string cliff =
      "[[cliff]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\naxis = [1, 0, 0]\ngap_min = 0.0\ngap_max = 0.02\n"
      "stiffness = 1000\nspeed_threshold = 0.05\n";
  LiveLoop live(cliff);
  // Running over the gap fast enough (0.2 m/s > 0.05) keeps the character up: cartoon physics.
  live.position = {-0.03, 0.0, -0.001};
  const auto run_to = [&](double x) {
    while (live.position.x < x) {
      live.position.x += 0.2 * kPeriodS;
      live.step();
    }
  };
  run_to(-0.005);
  ASSERT_TRUE(live.editor->fire("cliff1", "look_down", 0.0));  // over the ledge: nothing happens
  run_to(0.005);
  EXPECT_NEAR(live.loop->scene_force().z, 1.0, 1e-6) << "still supported over the gap";
  ASSERT_TRUE(live.editor->fire("cliff1", "look_down", 0.0));
  live.position.x += 0.2 * kPeriodS;
  EXPECT_EQ(live.step().z, 0.0) << "it looked down over the gap: it falls";
  double values[2]{};
  live.loop->describe(values);
  EXPECT_EQ(values[0], 1.0) << "fallen";
}

TEST(LiveScene, RemovingAnEffectKeepsTheOthersStatesWithThem) {
  // Two surfaces with impacts; the second one's transient runs. Removing the first makes the
  // second the first: its transient goes on with it (and does not start over or stop).
  const std::string impact =
      "[surface.impact]\nrecoil_gain = 300\noscillation_gain = 0\nduration = 0.1\nfrequency = 30\n";
  const std::string two = "[[surface]]\npoint = [0, 0, -1]\nnormal = [0, 0, 1]\nstiffness = 1000\n" + impact +
                          "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\n" + impact;
  LiveLoop live(two, 0.0);
  live.position = {0.0, 0.0, 0.01};  // above both
  live.step();
  ASSERT_TRUE(live.editor->fire("surface2", "impact", 0.5));
  for (int i = 0; i < 20; ++i) live.step();  // t = 0.019 s at the last of these
  double values[4]{};
  live.loop->describe(values);
  ASSERT_TRUE(std::isnan(values[1])) << "surface1 runs no transient";
  ASSERT_NEAR(values[3], 0.019, 1e-12) << "surface2's runs";
  ASSERT_TRUE(live.editor->remove("surface1"));
  const double f = live.step().z;
  live.loop->describe(values);
  EXPECT_NEAR(values[1], 0.020, 1e-12) << "the transient went on with its surface";
  EXPECT_NEAR(f, 0.5 * (0.1 - 0.020) * 300.0, 1e-9) << "its law at t = 0.020 s";
}

TEST(LiveScene, SwitchingScenesStartsEveryStateFresh) {
  const std::string gap =
      "[[cliff]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\naxis = [1, 0, 0]\ngap_min = -0.01\ngap_max = 0.01\n"
      "stiffness = 1000\nspeed_threshold = 0.05\n";
  LiveLoop live(gap);
  live.position = {0.0, 0.0, 0.005};
  for (int i = 0; i < 5; ++i) live.step();
  double values[2]{};
  live.loop->describe(values);
  ASSERT_EQ(values[0], 1.0);
  ASSERT_TRUE(live.editor->load(gap, "same.toml"));  // the same scene again, loaded: fresh
  live.position = {0.05, 0.0, 0.005};                // (away from the gap so it stays up)
  live.step();
  live.loop->describe(values);
  EXPECT_EQ(values[0], 0.0) << "a loaded scene starts supported";
}

TEST(LiveScene, ATickThatAppliesAnUpdateAllocatesNothing) {
  LiveLoop live(kFloor);
  live.position = {0.0, 0.0, -0.002};
  live.step();
  ASSERT_TRUE(live.editor->add("surface", "point = [0, 0, 0.003]\nnormal = [0, 0, 1]\nstiffness = 1000\n"
                                          "[impact]\nrecoil_gain = 300\noscillation_gain = 900\nduration = 0.1\n"
                                          "frequency = 30"));
  ASSERT_TRUE(live.editor->fire("surface2", "impact", 0.2));
  test::AllocationScope scope;
  live.step();
  live.step();
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(live.loop->updates_applied(), 2U);
}

TEST(LiveScene, AnUpdateFromAnotherThreadIsSeenWholeByEveryTick) {
  // Three surfaces at once, always with one stiffness among them: a tick that saw half an
  // update would see two. Without a fade the force says which scene a tick had: 3 K delta.
  const std::string three = kFloor + kFloor + kFloor;
  LiveLoop live(three, 0.0);
  live.position = {0.0, 0.0, -0.001};
  std::atomic<bool> done{false};
  std::thread app([&] {
    int n = 0;
    while (!done.load()) {
      const double k = (n++ % 2 == 0) ? 3000.0 : 1000.0;
      const std::string all = fmt::format("[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = {}\n", k);
      static_cast<void>(live.editor->load(all + all + all, "flip.toml"));
    }
  });
  // Ticks until 50 updates were applied (the application parses each: slower than a tick);
  // a count, not a time, so a loaded machine only takes longer.
  int mixed = 0;
  std::int64_t ticks = 0;
  while (live.loop->updates_applied() < 50 && ticks < 100'000'000) {
    const double f = live.step().z;
    if (std::abs(f - 3.0) > 1e-9 && std::abs(f - 9.0) > 1e-9) ++mixed;
    ++ticks;
  }
  done = true;
  app.join();
  EXPECT_EQ(mixed, 0);
  EXPECT_EQ(live.loop->updates_applied(), 50U) << "over " << ticks << " ticks";
}

}  // namespace
}  // namespace toonforce
