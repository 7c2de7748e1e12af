// SPDX-License-Identifier: Apache-2.0
// World scene files (tools/config/world_file.hpp; spec interfaces.md "World scenes"): a full
// world read to its values and to the WorldConfig the world runs, every kind of mistake named
// by file, line and key (all of them at once), the one-device reader refusing a world, and the
// bundled example with its two hand scripts.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/world_file.hpp"

namespace toonforce {
namespace {

const std::string kScenes = std::string(TOONFORCE_SOURCE_DIR) + "/scenes/";

// Line numbers matter: the tests below name them.
constexpr const char* kFull = R"(name = "duel"
[[device]]
name = "left"
offset = [-0.04, 0.0, 0.01]
yaw = 0.0
max_force = 6.0
[[device]]
name = "right"
backend = "falcon"
select = "FTD1234"
offset = [0.04, 0.0, 0.0]
yaw = 180
scale = 2.0
max_force = 9.0
soft_start = 0.2
[[coupling]]
between = ["right", "left"]
stiffness = 150.0
damping = 1.5
rest_length = 0.08
[ball]
radius = 0.015
mass = 0.05
stiffness = 600
damping = 0.5
drag = 0.25
start = [0.0, 0.0, -0.015]
wall_point = [0.0, 0.0, -0.03]
wall_normal = [0.0, 0.0, 2.0]
wall_stiffness = 1000.0
wall_damping = 3.0
[world]
stop = "each"
[[surface]]
point = [0.0, 0.0, -0.03]
normal = [0.0, 0.0, 1.0]
stiffness = 1500.0
)";

TEST(WorldFile, ReadsAFullWorldToItsValues) {
  const auto world = parse_world(kFull, "w.toml");
  ASSERT_TRUE(world) << world.error();
  const WorldDescription& w = world.value();
  EXPECT_EQ(w.scene.name, "duel");
  EXPECT_EQ(w.scene.source, "w.toml");
  ASSERT_EQ(w.scene.of<RuntimeSurface>().size(), 1U);
  EXPECT_EQ(w.scene.of<RuntimeSurface>()[0].plane.point_m.z, -0.03);

  ASSERT_EQ(w.devices.size(), 2U);
  const WorldDeviceEntry& left = w.devices[0];
  EXPECT_EQ(left.name, "left");
  EXPECT_EQ(left.backend, "sim");  // the default
  EXPECT_EQ(left.select, "");
  EXPECT_EQ(left.line, 2U);
  EXPECT_EQ(left.frame.offset_m, (Vec3<double>{-0.04, 0.0, 0.01}));
  EXPECT_EQ(left.frame.scale, 1.0);
  EXPECT_TRUE(DeviceFrame::yaw(0.0, {-0.04, 0.0, 0.01}).rotation == left.frame.rotation);
  EXPECT_EQ(left.settings.name, "left");
  EXPECT_EQ(left.settings.source, "w.toml");
  EXPECT_TRUE(left.settings.limits.has_max_force);
  EXPECT_EQ(left.settings.limits.max_force_n, 6.0);
  EXPECT_EQ(left.settings.safety.soft_start_s, SceneSettings{}.safety.soft_start_s);  // its own: the default

  const WorldDeviceEntry& right = w.devices[1];
  EXPECT_EQ(right.name, "right");
  EXPECT_EQ(right.backend, "falcon");
  EXPECT_EQ(right.select, "FTD1234");
  EXPECT_EQ(right.line, 7U);
  EXPECT_EQ(right.frame.scale, 2.0);
  EXPECT_EQ(right.settings.limits.max_force_n, 9.0);
  EXPECT_EQ(right.settings.safety.soft_start_s, 0.2);
  // Half a turn, exactly: the device's +x is the world's -x, and its HIP at x = 3 cm (scaled
  // by 2) is 2 cm from the middle, as left's is on the other side.
  EXPECT_EQ(right.frame.rotation[0], (Vec3<double>{-1.0, 0.0, 0.0}));
  EXPECT_EQ(right.frame.rotation[1], (Vec3<double>{0.0, -1.0, 0.0}));
  EXPECT_EQ(right.frame.position_to_world(Vec3<double>{0.01, 0.0, 0.0}), (Vec3<double>{0.02, 0.0, 0.0}));
  EXPECT_EQ(check(right.frame), "");
  EXPECT_EQ(w.device_index("right"), 1U);
  EXPECT_EQ(w.device_index("left"), 0U);
  EXPECT_EQ(w.device_index("nobody"), 2U);

  ASSERT_EQ(w.couplings.size(), 1U);
  EXPECT_EQ(w.couplings[0].a, 1U);  // in the order written
  EXPECT_EQ(w.couplings[0].b, 0U);
  EXPECT_EQ(w.couplings[0].line, 16U);
  EXPECT_EQ(w.couplings[0].params.stiffness_n_per_m, 150.0);
  EXPECT_EQ(w.couplings[0].params.damping_n_s_per_m, 1.5);
  EXPECT_EQ(w.couplings[0].params.rest_length_m, 0.08);

  ASSERT_TRUE(w.ball.has_value());
  const between::BallParams& b = *w.ball;
  EXPECT_EQ(b.radius_m, 0.015);
  EXPECT_EQ(b.mass_kg, 0.05);
  EXPECT_EQ(b.stiffness_n_per_m, 600.0);
  EXPECT_EQ(b.damping_n_s_per_m, 0.5);
  EXPECT_EQ(b.drag_n_s_per_m, 0.25);
  EXPECT_EQ(b.start_m, (Vec3<double>{0.0, 0.0, -0.015}));
  EXPECT_TRUE(b.has_wall);
  EXPECT_EQ(b.wall_point_m, (Vec3<double>{0.0, 0.0, -0.03}));
  EXPECT_EQ(b.wall_normal, (Vec3<double>{0.0, 0.0, 1.0}));  // normalised
  EXPECT_EQ(b.wall_stiffness_n_per_m, 1000.0);
  EXPECT_EQ(b.wall_damping_n_s_per_m, 3.0);

  EXPECT_EQ(w.stop, StopPolicy::kEach);
}

TEST(WorldFile, WorldConfigIsTheFilesCouplingsBallAndStop) {
  const auto world = parse_world(kFull, "w.toml");
  ASSERT_TRUE(world) << world.error();
  WorldConfig c = world_config(world.value());
  EXPECT_EQ(c.stop, StopPolicy::kEach);
  ASSERT_EQ(c.coupling_count, 1U);
  EXPECT_EQ(c.couplings[0].a, 1U);
  EXPECT_EQ(c.couplings[0].b, 0U);
  EXPECT_EQ(c.couplings[0].params.stiffness_n_per_m, 150.0);
  EXPECT_EQ(c.couplings[0].params.damping_n_s_per_m, 1.5);
  EXPECT_EQ(c.couplings[0].params.rest_length_m, 0.08);
  EXPECT_TRUE(c.has_ball);
  EXPECT_EQ(c.ball.radius_m, 0.015);
  EXPECT_EQ(c.ball.mass_kg, 0.05);
  EXPECT_TRUE(c.ball.has_wall);
  EXPECT_EQ(c.ball.wall_normal, (Vec3<double>{0.0, 0.0, 1.0}));
  EXPECT_EQ(c.ball.wall_stiffness_n_per_m, 1000.0);
  EXPECT_EQ(check(c, world.value().devices.size()), "");  // what World's constructor is given
}

TEST(WorldFile, LeftOutKeysTakeTheirDefaults) {
  const auto world = parse_world(R"([[device]]
name = "solo"
[[device]]
name = "other"
[[coupling]]
between = ["solo", "other"]
[ball]
radius = 0.01
)",
                                 "defaults.toml");
  ASSERT_TRUE(world) << world.error();
  const WorldDescription& w = world.value();
  EXPECT_EQ(w.scene.name, "defaults");  // the file's stem
  EXPECT_TRUE(w.devices[0].frame.identity());
  EXPECT_EQ(w.devices[0].backend, "sim");
  EXPECT_FALSE(w.devices[0].settings.limits.has_max_force);
  EXPECT_EQ(w.devices[0].settings.velocity_cutoff_hz, SceneSettings{}.velocity_cutoff_hz);
  const between::CouplingParams coupling;
  EXPECT_EQ(w.couplings[0].params.stiffness_n_per_m, coupling.stiffness_n_per_m);
  EXPECT_EQ(w.couplings[0].params.damping_n_s_per_m, coupling.damping_n_s_per_m);
  EXPECT_EQ(w.couplings[0].params.rest_length_m, coupling.rest_length_m);
  const between::BallParams ball;
  ASSERT_TRUE(w.ball);
  EXPECT_EQ(w.ball->radius_m, 0.01);
  EXPECT_EQ(w.ball->mass_kg, ball.mass_kg);
  EXPECT_EQ(w.ball->stiffness_n_per_m, ball.stiffness_n_per_m);
  EXPECT_EQ(w.ball->drag_n_s_per_m, ball.drag_n_s_per_m);
  EXPECT_FALSE(w.ball->has_wall);      // no wall_* key: no wall
  EXPECT_FALSE(w.ball->has_slippery);  // no [ball.slippery], no [ball.impact]: a plain ball
  EXPECT_FALSE(w.ball->has_impact);
  EXPECT_EQ(w.stop, StopPolicy::kAll);
  EXPECT_TRUE(world_config(w).has_ball);
}

TEST(WorldFile, TheBallsSurfaceEffectsTakeTheSingleDeviceKeysAndDefaults) {
  const auto world = parse_world(R"([[device]]
name = "a"
[ball]
radius = 0.02
[ball.slippery]
mu = 4.0
[ball.impact]
recoil_gain = 400.0
oscillation_gain = 200.0
duration = 0.05
frequency = 30.0
)",
                                 "w.toml");
  ASSERT_TRUE(world) << world.error();
  ASSERT_TRUE(world.value().ball);
  const between::BallParams& b = *world.value().ball;
  EXPECT_TRUE(b.has_slippery);
  EXPECT_EQ(b.slippery.mu_n_s_per_m, 4.0);
  EXPECT_TRUE(b.has_impact);
  EXPECT_EQ(b.impact.recoil_gain_n_per_m, 400.0);
  EXPECT_EQ(b.impact.oscillation_gain_n_per_m, 200.0);
  EXPECT_EQ(b.impact.duration_s, 0.05);
  EXPECT_EQ(b.impact.frequency_hz, 30.0);
  // The keys left out take the single-device tables' defaults (spec effects.md §3-4), read
  // from the same schema as a [surface.slippery] or [surface.impact] table.
  const auto surface = parse_scene(R"([[surface]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
stiffness = 1000.0
[surface.slippery]
mu = 4.0
[surface.impact]
recoil_gain = 400.0
oscillation_gain = 200.0
duration = 0.05
frequency = 30.0
)",
                                   "s.toml");
  ASSERT_TRUE(surface) << surface.error();
  ASSERT_EQ(surface.value().of<RuntimeSurface>().size(), 1U);
  const auto& one = surface.value().of<RuntimeSurface>()[0];
  EXPECT_EQ(b.slippery.max_tangential_force_n, one.tangential.slippery.max_tangential_force_n);
  EXPECT_EQ(b.impact.min_impact_speed_m_per_s, one.impact.law.min_impact_speed_m_per_s);
  EXPECT_EQ(b.impact.rearm_distance_m, one.impact.law.rearm_distance_m);
  EXPECT_EQ(b.impact.sine, one.impact.law.sine);
  // The world's configuration carries them, and the world accepts it.
  WorldConfig c = world_config(world.value());
  EXPECT_TRUE(c.ball.has_slippery);
  EXPECT_TRUE(c.ball.has_impact);
  EXPECT_EQ(check(c, 1), "");
}

// ---- mistakes: each names the file, the line and the key ------------------------------------

struct Mistake {
  const char* what;
  const char* text;
  const char* expected;  // a line of the error text, from the file's name on
};

constexpr const char* kTwo = "[[device]]\nname = \"a\"\n[[device]]\nname = \"b\"\n";  // lines 1-4

const Mistake kMistakes[] = {
    {"duplicate_name", "[[device]]\nname = \"a\"\n[[device]]\nname = \"a\"\n",
     "w.toml:4: device[2].name: 'a' is already the name of device[1] (line 1): names must be unique"},
    {"missing_name", "[[device]]\nbackend = \"sim\"\n",
     "w.toml:1: device[1]: missing required key 'name' (traces and messages name the device by it)"},
    {"empty_name", "[[device]]\nname = \"\"\n",
     "w.toml:2: device[1].name: must not be empty: traces and messages name the device by it"},
    {"name_not_one_line", "[[device]]\nname = \"a\\nb\"\n",
     "w.toml:2: device[1].name: 'a\\x0Ab' has a control character: write it without"},
    {"unknown_device_in_between",
     "[[device]]\nname = \"a\"\n[[device]]\nname = \"b\"\n[[coupling]]\nbetween = [\"a\", \"c\"]\n",
     "w.toml:6: coupling[1].between: no [[device]] is named 'c' (the devices: 'a', 'b')"},
    {"coupled_to_itself",
     "[[device]]\nname = \"a\"\n[[device]]\nname = \"b\"\n[[coupling]]\nbetween = [\"b\", \"b\"]\n",
     "w.toml:6: coupling[1].between: couples 'b' with itself: name two different devices"},
    {"between_not_two_names", "[[device]]\nname = \"a\"\n[[device]]\nname = \"b\"\n[[coupling]]\nbetween = [\"a\"]\n",
     "w.toml:6: coupling[1].between: must be an array of two device names, like [\"left\", \"right\"]"},
    {"between_missing", "[[device]]\nname = \"a\"\n[[device]]\nname = \"b\"\n[[coupling]]\nstiffness = 1.0\n",
     "w.toml:5: coupling[1]: missing required key 'between'"},
    {"five_devices",
     "[[device]]\nname = \"a\"\n[[device]]\nname = \"b\"\n[[device]]\nname = \"c\"\n[[device]]\nname = \"d\"\n"
     "[[device]]\nname = \"e\"\n",
     "w.toml:9: device: 5 [[device]] tables, more than the 4 a world holds"},
    {"no_device", "[ball]\nradius = 0.01\n", "w.toml:1: device: a world needs at least one [[device]] table"},
    {"yaw_beyond_a_turn", "[[device]]\nname = \"a\"\nyaw = 400\n",
     "w.toml:3: device[1].yaw: must be in [-360, 360] degrees (got 400); it is in degrees, not radians"},
    {"yaw_not_a_number", "[[device]]\nname = \"a\"\nyaw = \"left\"\n",
     "w.toml:3: device[1].yaw: must be a number, not a string"},
    {"yaw_not_finite", "[[device]]\nname = \"a\"\nyaw = nan\n", "w.toml:3: device[1].yaw: must be a finite number"},
    {"scale_zero", "[[device]]\nname = \"a\"\nscale = 0\n",
     "w.toml:3: device[1].scale: must be > 0 (got 0); the factor from the device's metres to the world's"},
    {"offset_not_a_vector", "[[device]]\nname = \"a\"\noffset = 0.04\n",
     "w.toml:3: device[1].offset: must be an array of three numbers [m], like [0.0, 0.0, 1.0]"},
    {"bad_backend", "[[device]]\nname = \"a\"\nbackend = \"phantom\"\n",
     "w.toml:3: device[1].backend: unknown backend 'phantom' (one of sim, falcon, omni)"},
    {"device_key_out_of_range", "[[device]]\nname = \"a\"\nmax_force = -1.0\n",
     "w.toml:3: device[1].max_force: must be > 0 (got -1)"},
    {"device_box_half", "[[device]]\nname = \"a\"\nworkspace_min = [-0.1, -0.1, -0.1]\n",
     "w.toml:3: device[1].workspace_min: needs workspace_min and workspace_max together"},
    {"unknown_key_in_device", "[[device]]\nname = \"a\"\nmax_forse = 3.0\n",
     "w.toml:3: device[1]: unknown key 'max_forse' (did you mean 'max_force'? the keys of [[device]]: name, "
     "backend, select, offset, yaw, scale, max_force,"},
    {"unknown_key_in_coupling",
     "[[device]]\nname = \"a\"\n[[device]]\nname = \"b\"\n[[coupling]]\nbetween = [\"a\", \"b\"]\nspring = 3.0\n",
     "w.toml:7: coupling[1]: unknown key 'spring' (the keys of [[coupling]]: between, stiffness, damping, "
     "rest_length)"},
    {"negative_stiffness",
     "[[device]]\nname = \"a\"\n[[device]]\nname = \"b\"\n[[coupling]]\nbetween = [\"a\", \"b\"]\nstiffness = -150.0\n",
     "w.toml:7: coupling[1].stiffness: must be >= 0 (got -150); the spring's stiffness [N/m]"},
    {"negative_rest_length",
     "[[device]]\nname = \"a\"\n[[device]]\nname = \"b\"\n[[coupling]]\nbetween = [\"a\", \"b\"]\nrest_length = -0.1\n",
     "w.toml:7: coupling[1].rest_length: must be >= 0 (got -0.1); the spring's length at rest [m]"},
    {"unknown_key_in_ball", "[[device]]\nname = \"a\"\n[ball]\nradius = 0.01\nbounce = 0.5\n",
     "w.toml:5: ball: unknown key 'bounce' (the keys of [ball]: radius, mass, stiffness, damping, drag, start, "
     "gravity, wall_point, wall_normal, wall_stiffness, wall_damping, slippery, impact)"},
    // The ball's surface effects: the single-device tables' keys, ranges and messages.
    {"ball_slippery_without_mu", "[[device]]\nname = \"a\"\n[ball]\n[ball.slippery]\nmax_tangential_force = 1.0\n",
     "w.toml:4: ball.slippery: missing required key 'mu'"},
    {"ball_slippery_mu_negative", "[[device]]\nname = \"a\"\n[ball.slippery]\nmu = -4.0\n",
     "w.toml:4: ball.slippery.mu: must be > 0 (got -4)"},
    {"ball_slippery_cap_zero", "[[device]]\nname = \"a\"\n[ball.slippery]\nmu = 4.0\nmax_tangential_force = 0\n",
     "w.toml:5: ball.slippery.max_tangential_force: must be > 0 (got 0)"},
    {"ball_slippery_unknown_key", "[[device]]\nname = \"a\"\n[ball.slippery]\nmu = 4.0\nmu_max = 2.0\n",
     "w.toml:5: ball.slippery: unknown key 'mu_max'"},
    {"ball_impact_without_duration",
     "[[device]]\nname = \"a\"\n[ball.impact]\nrecoil_gain = 400.0\noscillation_gain = 200.0\nfrequency = 30.0\n",
     "w.toml:3: ball.impact: missing required key 'duration'"},
    {"ball_impact_duration_zero",
     "[[device]]\nname = \"a\"\n[ball.impact]\nrecoil_gain = 400.0\noscillation_gain = 200.0\nduration = 0\n"
     "frequency = 30.0\n",
     "w.toml:6: ball.impact.duration: must be > 0 (got 0)"},
    {"ball_impact_negative_min_speed",
     "[[device]]\nname = \"a\"\n[ball.impact]\nrecoil_gain = 400.0\noscillation_gain = 200.0\nduration = 0.05\n"
     "frequency = 30.0\nmin_impact_speed = -0.1\n",
     "w.toml:8: ball.impact.min_impact_speed: must be >= 0 (got -0.1)"},
    {"ball_impact_not_a_table", "[[device]]\nname = \"a\"\n[ball]\nimpact = 3\n",
     "w.toml:4: ball.impact: must be a table"},
    {"ball_radius_zero", "[[device]]\nname = \"a\"\n[ball]\nradius = 0\n",
     "w.toml:4: ball.radius: must be > 0 (got 0); the ball's radius [m]"},
    {"ball_mass_negative", "[[device]]\nname = \"a\"\n[ball]\nmass = -0.1\n",
     "w.toml:4: ball.mass: must be > 0 (got -0.1); the ball's mass [kg]"},
    {"wall_normal_zero",
     "[[device]]\nname = \"a\"\n[ball]\nwall_point = [0.0, 0.0, 0.0]\nwall_normal = [0.0, 0.0, 0.0]\n",
     "w.toml:5: ball.wall_normal: must not be a zero vector (it is normalised on load)"},
    {"wall_without_normal", "[[device]]\nname = \"a\"\n[ball]\nwall_stiffness = 100.0\n",
     "w.toml:3: ball: missing required key 'wall_normal': a wall_* key makes a wall"},
    {"negative_wall_damping", "[[device]]\nname = \"a\"\n[ball]\nwall_normal = [0, 0, 1]\nwall_damping = -1\n",
     "w.toml:5: ball.wall_damping: must be >= 0 (got -1); the ball-wall contact [N s/m]"},
    {"unknown_key_in_world", "[[device]]\nname = \"a\"\n[world]\nstop = \"all\"\npolicy = \"each\"\n",
     "w.toml:5: world: unknown key 'policy' (the keys of [world]: stop)"},
    {"unknown_stop", "[[device]]\nname = \"a\"\n[world]\nstop = \"some\"\n",
     "w.toml:4: world.stop: unknown stop 'some' (one of all:"},
    {"misspelt_world_key", "[[device]]\nname = \"a\"\n[[couplings]]\nbetween = [\"a\", \"a\"]\n",
     "w.toml:3: unknown key 'couplings' (did you mean 'coupling'?"},
    {"ball_not_a_table", "ball = 3\n[[device]]\nname = \"a\"\n",
     "w.toml:1: ball: must be a table ([ball]), not an integer"},
    {"world_not_a_table", "world = \"big\"\n[[device]]\nname = \"a\"\n",
     "w.toml:1: world: must be a table ([world]), not a string"},
    {"unknown_top_level_key", "colour = \"red\"\n[[device]]\nname = \"a\"\n", "w.toml:1: unknown key 'colour'"},
};

class WorldFileMistakes : public ::testing::TestWithParam<Mistake> {};

TEST_P(WorldFileMistakes, AreNamedByFileLineAndKey) {
  const Mistake& m = GetParam();
  const auto world = parse_world(m.text, "w.toml");
  ASSERT_FALSE(world) << "accepted:\n" << m.text;
  EXPECT_NE(world.error().find(m.expected), std::string::npos) << "expected: " << m.expected << "\ngot:\n"
                                                               << world.error();
  EXPECT_EQ(world.error().find(":0:"), std::string::npos) << world.error();  // every message has its line
}

INSTANTIATE_TEST_SUITE_P(WorldFile, WorldFileMistakes, ::testing::ValuesIn(kMistakes),
                         [](const auto& param_info) { return std::string(param_info.param.what); });

TEST(WorldFile, HoldsAtMostEightCouplings) {
  std::string text = kTwo;
  for (int n = 0; n < 9; ++n) text += "[[coupling]]\nbetween = [\"a\", \"b\"]\n";  // from line 5, two lines each
  const auto world = parse_world(text, "w.toml");
  ASSERT_FALSE(world);
  EXPECT_EQ(world.error(), "w.toml:21: coupling: 9 [[coupling]] tables, more than the 8 a world holds\n");
}

TEST(WorldFile, ReportsEveryMistakeAtOnceInLineOrder) {
  const auto world = parse_world(R"(name = "many"
[[device]]
name = "a"
yaw = 1000
[[device]]
name = "a"
backend = "omnii"
[[coupling]]
between = ["a", "z"]
damping = -1
[ball]
radius = -1
[world]
stop = "none"
[[surface]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
stiffness = -5.0
)",
                                 "w.toml");
  ASSERT_FALSE(world);
  const std::vector<std::string> expected{
      "w.toml:4: device[1].yaw:",       "w.toml:6: device[2].name:",        "w.toml:7: device[2].backend:",
      "w.toml:9: coupling[1].between:", "w.toml:10: coupling[1].damping:",  "w.toml:12: ball.radius:",
      "w.toml:14: world.stop:",         "w.toml:18: surface[1].stiffness:",
  };
  std::size_t at = 0;
  for (const std::string& e : expected) {
    const std::size_t found = world.error().find(e, at);
    EXPECT_NE(found, std::string::npos) << e << " (in order) in:\n" << world.error();
    if (found != std::string::npos) at = found;
  }
}

TEST(WorldFile, EffectsAreReadAsInAnySceneWithTheirLines) {
  // The effects stay in the root the scene reader reads; the world's tables are moved out of
  // it first. Effects before and after the world's tables keep their lines.
  const auto world = parse_world(R"([[surface]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 0.0]
stiffness = 1.0
[[device]]
name = "a"
[[cliff]]
point = [0.0, 0.0, 0.0]
)",
                                 "w.toml");
  ASSERT_FALSE(world);
  EXPECT_NE(world.error().find("w.toml:3: surface[1].normal: must not be a zero vector"), std::string::npos)
      << world.error();
  EXPECT_NE(world.error().find("w.toml:7: cliff[1]: missing required key"), std::string::npos) << world.error();
}

// ---- the one-device reader ------------------------------------------------------------------

TEST(WorldFile, TheOneDeviceReaderRefusesAWorldInOneLine) {
  const auto scene = parse_scene(kFull, "w.toml");
  ASSERT_FALSE(scene);
  EXPECT_EQ(scene.error(),
            "w.toml:2: device: [[device]] tables make this a world scene of 2 devices; `toonforce sim --scene FILE "
            "--script NAME=HAND_SCRIPT ...` and `toonforce run --device sim|scene --scene FILE ...` run a world\n");
  const auto one = parse_scene("[[device]]\nname = \"a\"\n", "one.toml");
  ASSERT_FALSE(one);
  EXPECT_NE(one.error().find("one.toml:1: device: [[device]] tables make this a world scene of 1 device; "),
            std::string::npos)
      << one.error();
  const auto file = load_scene_file(kScenes + "two_players.toml");
  ASSERT_FALSE(file);
  EXPECT_NE(file.error().find("two_players.toml:15: device: [[device]] tables make this a world scene of 2 devices"),
            std::string::npos)
      << file.error();
}

TEST(WorldFile, TellsAWorldFromAOneDeviceScene) {
  EXPECT_TRUE(is_world_text(kFull));
  EXPECT_TRUE(is_world_text(kTwo));
  EXPECT_FALSE(is_world_text("[device]\nmax_force = 3.0\n"));
  EXPECT_FALSE(is_world_text("name = \"no device\"\n"));
  EXPECT_FALSE(is_world_text("device = [1, 2]\n"));
  EXPECT_FALSE(is_world_text("[[device]\nname = \"a\"\n"));  // does not parse
  EXPECT_TRUE(is_world_file(kScenes + "two_players.toml"));
  EXPECT_FALSE(is_world_file(kScenes + "cartoon_wall.toml"));
  EXPECT_FALSE(is_world_file(kScenes + "no_such_scene.toml"));
  EXPECT_FALSE(is_world_file(kScenes));  // a directory
}

TEST(WorldFile, LoadingAFileThatIsNotThereSaysSo) {
  const auto world = load_world_file(kScenes + "no_such_scene.toml");
  ASSERT_FALSE(world);
  EXPECT_NE(world.error().find("no_such_scene.toml: no such scene file"), std::string::npos) << world.error();
  const auto dir = load_world_file(kScenes);
  ASSERT_FALSE(dir);
  EXPECT_NE(dir.error().find("is a directory"), std::string::npos) << dir.error();
}

// ---- the bundled example ----------------------------------------------------------------------

TEST(WorldFile, TheTwoPlayersExampleLoadsWithItsHandScripts) {
  const auto world = load_world_file(kScenes + "two_players.toml");
  ASSERT_TRUE(world) << world.error();
  const WorldDescription& w = world.value();
  ASSERT_EQ(w.devices.size(), 2U);
  const std::size_t left = w.device_index("left");
  const std::size_t right = w.device_index("right");
  ASSERT_LT(left, 2U);
  ASSERT_LT(right, 2U);
  for (const WorldDeviceEntry& d : w.devices) {
    EXPECT_EQ(d.backend, "sim");
    EXPECT_EQ(check_servo_config(servo_config(d.settings, 1e-3)), "") << d.name;
  }
  ASSERT_EQ(w.couplings.size(), 1U);
  EXPECT_EQ(w.couplings[0].params.stiffness_n_per_m, 40.0);
  EXPECT_EQ(w.couplings[0].params.damping_n_s_per_m, 1.0);
  ASSERT_TRUE(w.ball);
  EXPECT_EQ(w.ball->radius_m, 0.015);
  EXPECT_EQ(w.ball->mass_kg, 0.05);
  EXPECT_TRUE(w.ball->has_wall);
  ASSERT_EQ(w.scene.of<RuntimeSurface>().size(), 1U);
  EXPECT_TRUE(w.scene.of<RuntimeSurface>()[0].impact.enabled);
  WorldConfig config = world_config(w);
  EXPECT_EQ(check(config, w.devices.size()), "");

  // Each script starts at its device's x = 0 and reaches 3 cm toward the middle: the same
  // point of the world on either side (mirror images), 1 cm from the ball's centre.
  const auto left_script = load_hand_script(kScenes + "hands/left_push.toml");
  const auto right_script = load_hand_script(kScenes + "hands/right_push.toml");
  ASSERT_TRUE(left_script) << left_script.error();
  ASSERT_TRUE(right_script) << right_script.error();
  const Vec3<double> left_start = w.devices[left].frame.position_to_world(left_script->script.start_m);
  const Vec3<double> right_start = w.devices[right].frame.position_to_world(right_script->script.start_m);
  EXPECT_EQ(left_start, (Vec3<double>{-0.04, 0.0, -0.015}));
  EXPECT_EQ(right_start, (Vec3<double>{0.04, 0.0, -0.015}));
  const Vec3<double> reach{0.03, 0.0, -0.015};
  EXPECT_NEAR(w.devices[left].frame.position_to_world(reach).x, -0.01, 1e-15);
  EXPECT_NEAR(w.devices[right].frame.position_to_world(reach).x, 0.01, 1e-15);
}

TEST(WorldFile, TheSpecsExampleIsAWorldThatLoads) {
  std::ifstream in(std::string(TOONFORCE_SOURCE_DIR) + "/docs/spec/interfaces.md");
  std::stringstream text;
  text << in.rdbuf();
  const std::string spec = text.str();
  const std::size_t section = spec.find("\n## World scenes");
  ASSERT_NE(section, std::string::npos) << "docs/spec/interfaces.md has no World scenes section";
  const std::size_t begin = spec.find("```toml\n", section);
  ASSERT_NE(begin, std::string::npos);
  const std::size_t end = spec.find("```\n", begin + 8);
  ASSERT_NE(end, std::string::npos);
  const std::string example = spec.substr(begin + 8, end - begin - 8);
  EXPECT_TRUE(is_world_text(example));
  const auto world = parse_world(example, "interfaces.md");
  ASSERT_TRUE(world) << world.error();
  EXPECT_EQ(world->devices.size(), 2U);
  EXPECT_EQ(world->couplings.size(), 1U);
  EXPECT_TRUE(world->ball && world->ball->has_wall);
}

}  // namespace
}  // namespace toonforce

// ---- effects that name the devices they act on ------------------------------------------------

namespace toonforce {
namespace {

constexpr const char* kNamed = R"([[device]]
name = "left"
[[device]]
name = "right"
[[surface]]
point = [0.0, 0.0, -0.03]
normal = [0.0, 0.0, 1.0]
stiffness = 1500.0
devices = ["right"]
[[surface]]
point = [0.0, 0.0, -0.05]
normal = [0.0, 0.0, 1.0]
stiffness = 700.0
[[cliff]]
point = [0.0, 0.0, -0.02]
normal = [0.0, 0.0, 1.0]
axis = [1.0, 0.0, 0.0]
gap_min = 0.0
gap_max = 0.02
stiffness = 1500.0
speed_threshold = 0.08
tau = 0.02
devices = ["left", "right"]
[ball]
radius = 0.015
devices = ["left"]
)";

TEST(WorldFile, AnEffectThatNamesDevicesActsOnThemOnlyAndTheOthersOnEvery) {
  const auto world = parse_world(kNamed, "w.toml");
  ASSERT_TRUE(world) << world.error();
  const WorldDescription& w = world.value();
  ASSERT_EQ(w.scene.of<RuntimeSurface>().size(), 2U) << "the whole scene keeps every effect";
  const SceneDescription left = w.scene_for(0);
  const SceneDescription right = w.scene_for(1);
  ASSERT_EQ(left.of<RuntimeSurface>().size(), 1U);
  EXPECT_EQ(left.of<RuntimeSurface>()[0].plane.point_m.z, -0.05) << "left does not get right's surface";
  ASSERT_EQ(right.of<RuntimeSurface>().size(), 2U);
  EXPECT_EQ(right.of<RuntimeSurface>()[0].plane.point_m.z, -0.03);
  EXPECT_EQ(left.of<CartoonCliff>().size(), 1U);
  EXPECT_EQ(right.of<CartoonCliff>().size(), 1U);
  // The file order of what is left, renumbered within each kind: left has surface 0 then the cliff.
  ASSERT_EQ(left.order.size(), 2U);
  EXPECT_EQ(left.order[0].index, 0U);
  EXPECT_EQ(left.order[0].line, 10U);  // the second [[surface]]
  EXPECT_EQ(right.order.size(), 3U);
  EXPECT_EQ(w.ball_devices, 1U);
  EXPECT_EQ(world_config(w).ball_devices, 1U) << "only left touches the ball";
}

TEST(WorldFile, AnEffectsDevicesAreCheckedWithTheirLine) {
  std::string text = kNamed;
  const std::string right = "devices = [\"right\"]";
  text.replace(text.find(right), right.size(), "devices = [\"middle\"]");
  auto world = parse_world(text, "w.toml");
  ASSERT_FALSE(world);
  EXPECT_NE(world.error().find("w.toml:9: surface[1].devices: no [[device]] is named 'middle' (the devices: 'left', "
                               "'right')"),
            std::string::npos)
      << world.error();
  text = kNamed;
  const std::string both = "devices = [\"left\", \"right\"]";
  text.replace(text.find(both), both.size(), "devices = [\"left\", \"left\"]");
  world = parse_world(text, "w.toml");
  ASSERT_FALSE(world);
  EXPECT_NE(world.error().find("cliff[1].devices: names 'left' twice"), std::string::npos) << world.error();
  text = kNamed;
  const std::string left = "devices = [\"left\"]\n";
  text.replace(text.find(left), left.size(), "devices = []\n");
  world = parse_world(text, "w.toml");
  ASSERT_FALSE(world);
  EXPECT_NE(world.error().find("ball.devices: must be a non-empty array of device names"), std::string::npos)
      << world.error();
  // A one-device scene has no devices to name: the key is unknown there.
  const auto one = parse_scene("[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 100.0\n"
                               "devices = [\"a\"]\n",
                               "one.toml");
  ASSERT_FALSE(one);
  EXPECT_NE(one.error().find("devices"), std::string::npos) << one.error();
}

}  // namespace
}  // namespace toonforce
