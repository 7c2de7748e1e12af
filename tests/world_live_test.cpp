// SPDX-License-Identifier: Apache-2.0
// Live scenes of a world (control/world_updates.hpp, config/world_editor.hpp): a change of an
// effect reaches every device it acts on at the same world tick and nowhere else; an update
// any of whose parts fails the loop's checks changes nothing on any device; the editor refuses
// what a running world keeps (devices, couplings, ball, which devices an effect acts on, the
// list of effects) with a message, and nothing reaches the world then.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <memory>
#include <string>

#include "servo_support.hpp"
#include "support/alloc_counter.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/config/world_editor.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/control/world.hpp"

namespace toonforce::test {
namespace {

using LiveWorld2 = World<FakeDevice, RuntimeScene<double>, 2, kLiveStages>;
using Mailbox = WorldEditor::Mailbox;

// Two devices, both in the world's frame. surface1, a floor at z = 0, acts on both; surface2,
// with an impact table, on "b" only.
constexpr const char* kWorld = R"(name = "live"
[[device]]
name = "a"
max_force = 8.0
soft_start = 0.0
max_velocity = 5.0
[[device]]
name = "b"
max_force = 8.0
soft_start = 0.0
max_velocity = 5.0
[[coupling]]
between = ["a", "b"]
stiffness = 10.0
rest_length = 0.02
[[surface]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
stiffness = 500.0
[[surface]]
devices = ["b"]
point = [0.0, 0.0, -0.5]
normal = [0.0, 0.0, 1.0]
stiffness = 100.0
  [surface.impact]
  recoil_gain = 200.0
  oscillation_gain = 400.0
  duration = 0.1
  frequency = 30.0
)";

struct Rig {
  WorldDescription world;
  std::array<FakeDeviceState, 2> dev{};
  std::array<FakeDevice, 2> fakes{FakeDevice{&dev[0]}, FakeDevice{&dev[1]}};
  std::unique_ptr<Mailbox> mailbox = std::make_unique<Mailbox>();
  std::unique_ptr<LiveWorld2> live;

  Rig() {
    auto w = parse_world(kWorld, "live.toml");
    EXPECT_TRUE(w) << w.error();
    world = std::move(w.value());
    std::array<LiveWorld2::Member, 2> members{
        LiveWorld2::Member{&fakes[0], make_runtime_scene<double>(world.scene_for(0)), world.devices[0].frame,
                           servo_config(world.devices[0].settings, kPeriodS)},
        LiveWorld2::Member{&fakes[1], make_runtime_scene<double>(world.scene_for(1)), world.devices[1].frame,
                           servo_config(world.devices[1].settings, kPeriodS)}};
    WorldConfig config = world_config(world);
    EXPECT_EQ(check(config, 2), "");
    live = std::make_unique<LiveWorld2>(members, config);
    live->listen(*mailbox);
  }
  /// Both handles `depth_m` into the floor (negative: above it), still.
  void place(double depth_m) {
    dev[0].position_m = {-0.01, 0.0, -depth_m};
    dev[1].position_m = {0.01, 0.0, -depth_m};
  }
};

TEST(WorldLive, ASetReachesEveryDeviceTheEffectActsOnOnTheSameTick) {
  Rig rig;
  auto editor = WorldEditor::open(kWorld, "live.toml", *rig.mailbox);
  ASSERT_TRUE(editor) << editor.error();
  std::int64_t k = 0;
  rig.place(-0.01);  // above the floor: both engage
  for (; k < 200; ++k) rig.live->tick(k);
  for (; k < 400; ++k) {  // down to 2 mm in, at 6 cm/s: 500 N/m gives 1 N up on each
    rig.place(-0.01 + 0.012 * std::min(1.0, static_cast<double>(k - 199) / 200.0));
    rig.live->tick(k);
  }
  for (; k < 500; ++k) rig.live->tick(k);  // still (the damped estimate settles)
  ASSERT_NEAR(rig.dev[0].last_written.z, 1.0, 1e-9);
  ASSERT_NEAR(rig.dev[1].last_written.z, 1.0, 1e-9);

  auto sent = editor->set("surface1", "stiffness = 1000.0");
  ASSERT_TRUE(sent) << sent.error();
  EXPECT_EQ(sent.value(), 1U);
  EXPECT_EQ(editor->applied(), 0U);
  {
    AllocationScope counter;
    rig.live->tick(k++);
    EXPECT_EQ(counter.count(), 0U);  // the update's copy, checks and application: no allocation
  }
  // Both devices took it on this one tick; the world says so once both have.
  EXPECT_EQ(rig.live->loop(0).updates_applied(), 1U);
  EXPECT_EQ(rig.live->loop(1).updates_applied(), 1U);
  EXPECT_EQ(editor->applied(), 1U);
  // Continuous at the update (the fade), then 2 N on each once the fade (0.25 s) is over.
  EXPECT_NEAR(rig.dev[0].last_written.z, 1.0, 0.01);
  for (int i = 0; i < 300; ++i) rig.live->tick(k++);
  EXPECT_NEAR(rig.dev[0].last_written.z, 2.0, 1e-9);
  EXPECT_NEAR(rig.dev[1].last_written.z, 2.0, 1e-9);
  EXPECT_EQ(rig.live->updates_refused(), 0U);
}

TEST(WorldLive, AFireGoesToTheDevicesTheEffectActsOnAtItsPlaceInEachScene) {
  Rig rig;
  auto editor = WorldEditor::open(kWorld, "live.toml", *rig.mailbox);
  ASSERT_TRUE(editor) << editor.error();
  ASSERT_TRUE(editor->fire("surface2", "impact", 0.3));
  WorldUpdate<RuntimeScene<double>> u;
  ASSERT_TRUE(rig.mailbox->copy_out<SceneUpdateCopy<WorldUpdate<RuntimeScene<double>>>>(0, u));
  EXPECT_EQ(u.device_count, 2U);
  EXPECT_EQ(u.devices[0].event_count, 0U);  // "a" does not have surface2
  ASSERT_EQ(u.devices[1].event_count, 1U);
  EXPECT_EQ(u.devices[1].events[0].effect, 1U);  // b's second effect
  EXPECT_DOUBLE_EQ(u.devices[1].events[0].value, 0.3);
  rig.live->tick(0);
  EXPECT_EQ(editor->applied(), 1U);
  EXPECT_EQ(rig.live->updates_refused(), 0U);
  // An event surface1 does not have, a speed its impact cannot carry.
  EXPECT_FALSE(editor->fire("surface1", "impact", 0.3));  // no impact table
  EXPECT_FALSE(editor->fire("surface2", "look_down", 0.0));
  EXPECT_FALSE(editor->fire("surface2", "impact", 1e300));
  EXPECT_EQ(rig.mailbox->pending(), 0U);
}

TEST(WorldLive, AnUpdateWithOneBadPartChangesNoDevice) {
  Rig rig;
  std::int64_t k = 0;
  rig.place(0.002);
  rig.live->tick(k++);
  using Update = WorldUpdate<RuntimeScene<double>>;
  const auto good = [&] {
    auto u = std::make_unique<Update>();
    u->device_count = 2;
    for (std::size_t i = 0; i < 2; ++i) {
      u->devices[i].scene = rig.live->loop(i).scene().inner();
      for (std::size_t e = 0; e < u->devices[i].continues.size(); ++e) {
        u->devices[i].continues[e] = e < u->devices[i].scene.effect_count() ? static_cast<std::int16_t>(0) : -1;
      }
    }
    u->devices[1].continues[1] = 1;  // b: surface1, surface2
    u->sequence = 7;
    return u;
  };
  // A whole one passes (the control case: the forgeries below differ from it in one field).
  ASSERT_TRUE(rig.mailbox->push(*good()));
  rig.live->tick(k++);
  ASSERT_EQ(rig.live->loop(0).updates_applied(), 1U);
  ASSERT_EQ(rig.mailbox->applied(), 7U);

  auto bad_continues = good();
  bad_continues->devices[1].continues[0] = 5;  // b has one surface1... no effect 5 to continue
  auto bad_count = good();
  bad_count->device_count = 3;
  auto bad_event = good();
  bad_event->devices[0].event_count = 1;
  bad_event->devices[0].events[0] = SceneEvent{1, 0, 0.3};  // a has one effect only
  auto bad_events = good();
  bad_events->devices[1].event_count = 200;  // past the events' array
  for (Update* u : {bad_continues.get(), bad_count.get(), bad_event.get(), bad_events.get()}) {
    ASSERT_TRUE(rig.mailbox->push(*u));
    rig.live->tick(k++);
  }
  EXPECT_EQ(rig.live->updates_refused(), 4U);
  EXPECT_EQ(rig.mailbox->refused(), 4U);
  EXPECT_EQ(rig.live->loop(0).updates_applied(), 1U);  // neither device took any of them
  EXPECT_EQ(rig.live->loop(1).updates_applied(), 1U);
  EXPECT_EQ(rig.mailbox->applied(), 7U);
}

TEST(WorldLive, TheEditorRefusesWhatARunningWorldKeepsAndSendsNothing) {
  Rig rig;
  auto editor = WorldEditor::open(kWorld, "live.toml", *rig.mailbox);
  ASSERT_TRUE(editor) << editor.error();
  const auto refused = [](const Result<std::uint64_t>& r, std::string_view says) {
    EXPECT_FALSE(r);
    if (!r) {
      EXPECT_NE(r.error().find(says), std::string::npos) << r.error();
    }
  };
  refused(editor->set("coupling1", "stiffness = 50.0"), "fixed while it runs");
  refused(editor->set("ball", "mass = 1.0"), "fixed while it runs");
  refused(editor->set("surface1", "devices = [\"a\"]"), "'devices' is fixed");
  refused(editor->set("surface1", "stiffnes = 800.0"), "stiffnes");  // the reader's message, the key named
  refused(editor->set("surface1", "stiffness = -1.0"), "stiffness");
  refused(editor->set("surface3", "stiffness = 1.0"), "2 surface");
  refused(editor->add("surface"), "list of effects is fixed");
  refused(editor->remove("surface1"), "list of effects is fixed");
  refused(editor->load("other.toml"), "keeps its devices");
  EXPECT_EQ(rig.mailbox->pending(), 0U);
  // A good change still goes, and the document is the world after it.
  ASSERT_TRUE(editor->set("surface2", "stiffness = 300.0"));
  EXPECT_DOUBLE_EQ(editor->world().scene.of<RuntimeSurface>()[1].wall.stiffness_n_per_m, 300.0);
  EXPECT_EQ(rig.mailbox->pending(), 1U);
}

}  // namespace
}  // namespace toonforce::test
