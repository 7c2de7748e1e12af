// SPDX-License-Identifier: Apache-2.0
// Scene files (spec interfaces.md): every bundled scene loads for every scalar type, and
// malformed files are rejected with the file, the line and the key in the message.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/config/toml_reader.hpp"

namespace toonforce {
namespace {

const std::string kScenes = std::string(TOONFORCE_SOURCE_DIR) + "/scenes/";

TEST(SceneFile, EveryBundledSceneLoadsForEveryScalar) {
  for (const char* name : {"wall", "realistic_friction", "slippery", "cartoon_wall", "cliff"}) {
    for (const ScalarKind kind : {ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16}) {
      const auto scene = load_scene_file(kScenes + name + ".toml", kind);
      EXPECT_TRUE(scene) << name << ": " << scene.error();
    }
  }
}

TEST(SceneFile, ReadsTheExampleOfTheSpecWithItsDefaults) {
  const auto scene = parse_scene(R"(name = "cartoon ice"
[device]
max_force = 8.0
[[surface]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 2.0]
stiffness = 1500
  [surface.slippery]
  mu = 4.0
  [surface.impact]
  recoil_gain = 300.0
  oscillation_gain = 600.0
  duration = 0.15
  frequency = 30.0
[[cliff]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
axis = [2.0, 0.0, 0.0]
gap_min = -0.01
gap_max = 0.01
stiffness = 1500.0
speed_threshold = 0.08
)",
                                 "example.toml");
  ASSERT_TRUE(scene) << scene.error();
  const SceneDescription& s = scene.value();
  EXPECT_EQ(s.name, "cartoon ice");
  EXPECT_TRUE(s.limits.has_max_force);
  EXPECT_FALSE(s.limits.has_max_force_rate);  // absent: no rate limit
  EXPECT_EQ(s.velocity_cutoff_hz, 50.0);
  const auto& surfaces = s.of<RuntimeSurface>();
  ASSERT_EQ(surfaces.size(), 1U);
  EXPECT_EQ(surfaces[0].plane.normal.z, 1.0);             // normalised
  EXPECT_EQ(surfaces[0].wall.stiffness_n_per_m, 1500.0);  // an integer is a number
  EXPECT_EQ(surfaces[0].wall.damping_n_s_per_m, 0.0);
  EXPECT_EQ(surfaces[0].tangential.kind, TangentialKind::kSlippery);
  EXPECT_EQ(surfaces[0].tangential.slippery.max_tangential_force_n, 2.0);  // the default
  EXPECT_TRUE(surfaces[0].impact.enabled);
  EXPECT_EQ(surfaces[0].impact.law.min_impact_speed_m_per_s, 0.05);
  EXPECT_EQ(surfaces[0].impact.law.rearm_distance_m, 0.001);
  EXPECT_EQ(surfaces[0].impact.law.sine, SineMethod::kAuto);  // not chosen: the scalar's own
  const auto& cliffs = s.of<CartoonCliff>();
  ASSERT_EQ(cliffs.size(), 1U);
  EXPECT_EQ(cliffs[0].axis.x, 1.0);
  EXPECT_EQ(cliffs[0].tau_s, 0.02);
  EXPECT_EQ(cliffs[0].rearm_height_m, 0.001);
  EXPECT_EQ(cliffs[0].fall_force_n, 0.0);
}

TEST(SceneFile, KeepsFileOrderAcrossSurfacesAndCliffs) {
  const auto scene = parse_scene(R"(
[[cliff]]
point = [0, 0, 0]
normal = [0, 0, 1]
axis = [1, 0, 0]
gap_min = 0.0
gap_max = 0.01
stiffness = 100
speed_threshold = 0.1
[[surface]]
point = [0, 0, 0.05]
normal = [0, 0, -1]
stiffness = 100
)",
                                 "order.toml");
  ASSERT_TRUE(scene) << scene.error();
  ASSERT_EQ(scene->order.size(), 2U);
  EXPECT_EQ(scene->order[0].kind, 1U);  // the cliff first, as written
  EXPECT_EQ(scene->order[0].line, 2U);
  EXPECT_EQ(scene->order[1].kind, 0U);
  // The run-time scene adds them in that order: cliff1's values come before surface1's.
  const RuntimeScene<double> runtime = make_runtime_scene<double>(scene.value());
  EXPECT_EQ(runtime.effect_info(0).key, "cliff");
  EXPECT_EQ(runtime.effect_info(1).key, "surface");
}

struct Malformed {
  const char* what;
  const char* text;
  const char* expected;  // must appear in the message, with "bad.toml:<line>:"
  int line;
};

constexpr const char* kSurface = "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1500\n";

class MalformedScene : public ::testing::TestWithParam<Malformed> {};

TEST_P(MalformedScene, IsRejectedNamingFileLineAndKey) {
  const Malformed& m = GetParam();
  const auto scene = parse_scene(m.text, "bad.toml");
  ASSERT_FALSE(scene) << m.what;
  const std::string& message = scene.error();
  EXPECT_NE(message.find(std::string("bad.toml:") + std::to_string(m.line) + ":"), std::string::npos)
      << m.what << ": " << message;
  EXPECT_NE(message.find(m.expected), std::string::npos) << m.what << ": " << message;
}

const Malformed kMalformed[] = {
    {"typo in a key", "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstifness = 1500\n",
     "unknown key 'stifness' (did you mean 'stiffness'?)", 4},
    {"missing required key", "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\n",
     "surface[1]: missing required key 'stiffness'", 1},
    {"wrong type", "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = \"stiff\"\n",
     "surface[1].stiffness: must be a number, not a string", 4},
    {"non-finite number", "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = inf\n",
     "surface[1].stiffness: must be a finite number", 4},
    {"zero normal", "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\nstiffness = 1500\n",
     "surface[1].normal: must not be a zero vector", 3},
    {"vector of two", "[[surface]]\npoint = [0, 0]\nnormal = [0, 0, 1]\nstiffness = 1500\n",
     "surface[1].point: must be an array of three numbers", 2},
    {"negative stiffness", "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = -5\n",
     "surface[1].stiffness: must be > 0 (got -5)", 4},
    {"friction and slippery together",
     "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1500\n[surface.friction]\ncoulomb = 0.3\n"
     "[surface.slippery]\nmu = 4.0\n",
     "contradict each other", 7},
    {"positive viscous friction",
     "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1500\n[surface.friction]\nviscous = 2.0\n",
     "surface[1].friction.viscous: must be <= 0 (got 2)", 6},
    {"unknown top-level table", "[[surfaces]]\npoint = [0, 0, 0]\n",
     "unknown effect [[surfaces]] (did you mean 'surface'?)", 1},
    {"an effect this program does not have", "[[magnet]]\ncentre = [0, 0, 0]\n",
     "unknown effect [[magnet]] (the effects this program reads: [[surface]], [[cliff]])", 1},
    {"surface written as a single table", "[surface]\npoint = [0, 0, 0]\n", "surface: must be an array of tables", 1},
    {"cliff axis along the normal",
     "[[cliff]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\naxis = [1, 0, 1]\ngap_min = 0\ngap_max = 0.02\n"
     "stiffness = 1500\nspeed_threshold = 0.08\n",
     "cliff[1].axis: must be perpendicular to the normal", 4},
    {"cliff gap the wrong way round",
     "[[cliff]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\naxis = [1, 0, 0]\ngap_min = 0.02\ngap_max = 0.0\n"
     "stiffness = 1500\nspeed_threshold = 0.08\n",
     "cliff[1].gap_max: must be greater than gap_min", 6},
    {"impact without duration",
     "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1500\n[surface.impact]\nrecoil_gain = 300\n"
     "oscillation_gain = 600\nfrequency = 30\n",
     "surface[1].impact: missing required key 'duration'", 5},
    {"unknown sine method",
     "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1500\n[surface.impact]\nrecoil_gain = 300\n"
     "oscillation_gain = 600\nduration = 0.1\nfrequency = 30\nsine = \"cordic\"\n",
     "surface[1].impact.sine: unknown sine 'cordic' (one of library, polynomial, table)", 10},
    {"device limit of zero", "[device]\nmax_force = 0\n", "device.max_force: must be > 0 (got 0)", 2},
    {"unknown key in device", "[device]\nmax_froce = 8\n",
     "device: unknown key 'max_froce' (did you mean 'max_force'?)", 2},
    {"TOML syntax error", "[[surface]]\npoint = [0, 0, 0\n", "TOML syntax", 2},
    {"boolean where a number goes", "[device]\nvelocity_cutoff = true\n", "must be a number, not a boolean", 2},
    // Found by tests/fuzz/scene_file_fuzz.cpp: toml++ 3.3 (Debian 12's) reaches undefined
    // behaviour on these (marzer/tomlplusplus#190 and #295); the loader rejects them first.
    {"non-ASCII outside comments and strings", "# \xc2\xa7 in a comment is fine\n[device]\nmax_force = 8 \xc2\xa7\n",
     "a non-ASCII character outside a comment or a string", 3},
    {"a combining mark at the top level (toml++ #295)", "name = \"ok\"\n\xcc\xaa\n",
     "a non-ASCII character outside a comment or a string", 2},
    {"invalid UTF-8, even in a comment", "name = \"ok\"\n# caf\xc3\x28\n", "invalid UTF-8 (byte 0xC3)", 2},
    {"non-ASCII after a line-ending backslash", "name = \"\"\"\\\n\xc2\xa7\"\"\"\n",
     "a non-ASCII character outside a comment or a string", 2},
};
INSTANTIATE_TEST_SUITE_P(SceneFile, MalformedScene, ::testing::ValuesIn(kMalformed));

// Stiffness = 1e308 loaded, and the force's square overflowed: the clamp scaled it to
// a silent 0 and the wall vanished.
TEST(SceneFile, AValueLargeEnoughToOverflowTheLawIsRefusedWithTheAllowedRange) {
  const auto scene = parse_scene("name = \"w\"\n[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n"
                                 "stiffness = 1e308\n",
                                 "huge.toml");
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.error().find("huge.toml:5"), std::string::npos) << scene.error();
  EXPECT_NE(scene.error().find("stiffness"), std::string::npos) << scene.error();
  EXPECT_NE(scene.error().find("allowed magnitudes are up to 1e+12"), std::string::npos) << scene.error();
}

TEST(SceneFile, AcceptsNonAsciiInCommentsAndStrings) {
  const auto scene = parse_scene("# ice \xe2\x9d\x84 (paper \xc2\xa7"
                                 "4.1)\nname = \"glace \xc3\xa0 la \xc2\xa7\"\n",
                                 "utf8.toml");
  ASSERT_TRUE(scene) << scene.error();
  EXPECT_EQ(scene->name, "glace \xc3\xa0 la \xc2\xa7");
}

TEST(SceneFile, ReportsEveryErrorOfAFileAtOnce) {
  const auto scene =
      parse_scene(std::string(kSurface) + "colour = \"red\"\n[[surface]]\npoint = [0, 0, 0]\n", "bad.toml");
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.error().find("bad.toml:5: surface[1]: unknown key 'colour'"), std::string::npos) << scene.error();
  EXPECT_NE(scene.error().find("bad.toml:6: surface[2]: missing required key 'normal'"), std::string::npos)
      << scene.error();
}

TEST(SceneFile, ErrorsAreListedByLineWhateverOrderTheyAreFoundIn) {
  // A table's unknown keys are found in the table's key order (alphabetical: 'foo', line 6,
  // before 'stifness', line 5), and the second surface's missing keys before its unknown
  // one: listed by line all the same.
  const std::string text = std::string(kSurface) + "stifness = 3\nfoo = 1\n[[surface]]\nbar = 1\n";
  const auto scene = parse_scene(text, "order.toml");
  ASSERT_FALSE(scene);
  std::vector<std::uint32_t> lines;
  std::istringstream in(scene.error());
  for (std::string row; std::getline(in, row);) {
    ASSERT_EQ(row.rfind("order.toml:", 0), 0U) << row;
    lines.push_back(static_cast<std::uint32_t>(std::stoul(row.substr(std::string("order.toml:").size()))));
  }
  ASSERT_GE(lines.size(), 4U) << scene.error();
  EXPECT_TRUE(std::is_sorted(lines.begin(), lines.end())) << scene.error();
}

TEST(SceneFile, ThousandsOfErrorsAreCappedAndCounted) {
  std::string text(kSurface);
  for (int i = 0; i < 5000; ++i) text += "bad" + std::to_string(i) + " = 1\n";
  const auto scene = parse_scene(text, "many.toml");
  ASSERT_FALSE(scene);
  const std::string& e = scene.error();
  EXPECT_EQ(static_cast<std::size_t>(std::count(e.begin(), e.end(), '\n')), ErrorList::kShown + 1) << e.substr(0, 2000);
  EXPECT_NE(e.find("many.toml: 4980 more error(s) not shown"), std::string::npos) << e.substr(e.size() - 300);
  EXPECT_NE(e.find("unknown key 'bad0'"), std::string::npos) << "the first by line come first";
}

TEST(SceneFile, AHugeUnknownKeyIsShortenedAndNotComparedInFull) {
  // A 2 MB key: the did-you-mean search skips keys whose length alone rules them out (a 20 MB
  // key took 8 s), and the message shows its start and its length.
  const std::string key(2'000'000, 'k');
  const auto scene = parse_scene(std::string(kSurface) + key + " = 1\n", "huge.toml");
  ASSERT_FALSE(scene);
  EXPECT_LT(scene.error().size(), 300U);
  EXPECT_NE(scene.error().find("unknown key '" + std::string(64, 'k') + "... (2000000 bytes)'"), std::string::npos)
      << scene.error();
}

TEST(SceneFile, ControlCharactersInAKeyAreShownNotSentAndRefusedInAName) {
  // A NUL cut the message short where it was printed as a C string; an escape sequence would
  // drive the terminal.
  const auto scene = parse_scene(std::string(kSurface) + "\"ab\\u0000cd\\u001b[31m\" = 1\n", "nul.toml");
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.error().find("unknown key 'ab\\x00cd\\x1B[31m'"), std::string::npos) << scene.error();
  EXPECT_EQ(scene.error().find('\0'), std::string::npos);
  EXPECT_EQ(scene.error().find('\x1b'), std::string::npos);
  const auto named = parse_scene("name = \"wall\\u0007\"\n" + std::string(kSurface), "bell.toml");
  ASSERT_FALSE(named);
  EXPECT_NE(named.error().find("bell.toml:1: name: 'wall\\x07' has a control character"), std::string::npos)
      << named.error();
}

TEST(SceneFile, AnEmptySceneIsAProblemToSayAndASceneWithAnEffectIsNot) {
  const auto empty = parse_scene("# only a comment\nname = \"nothing\"\n", "empty.toml");
  ASSERT_TRUE(empty) << empty.error();
  EXPECT_NE(
      empty_scene_problem(empty.value(), "empty.toml").find("empty.toml: the scene has no [[surface]] or [[cliff]]"),
      std::string::npos);
  const auto wall = parse_scene(kSurface, "wall.toml");
  ASSERT_TRUE(wall) << wall.error();
  EXPECT_EQ(empty_scene_problem(wall.value(), "wall.toml"), "");
}

TEST(SceneFile, RejectsValuesOutsideTheQ16Range) {
  const std::string text = "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 50000\n";
  EXPECT_TRUE(parse_scene(text, "big.toml", ScalarKind::kDouble));
  const auto q = parse_scene(text, "big.toml", ScalarKind::kQ16_16);
  ASSERT_FALSE(q);
  EXPECT_NE(q.error().find("big.toml:4: surface[1].stiffness: 50000 is outside the Q16.16 range"), std::string::npos)
      << q.error();
}

TEST(SceneFile, RejectsAPositiveValueThatRoundsToZeroInQ16) {
  const std::string text = std::string(kSurface) + "[surface.friction]\nregularization_speed = 1e-6\n";
  EXPECT_TRUE(parse_scene(text, "tiny.toml", ScalarKind::kDouble));
  const auto q = parse_scene(text, "tiny.toml", ScalarKind::kQ16_16);
  ASSERT_FALSE(q);
  EXPECT_NE(q.error().find("tiny.toml:6: surface[1].friction.regularization_speed: 1e-06 rounds to 0 in Q16.16"),
            std::string::npos)
      << q.error();
}

TEST(SceneFile, RejectsTheLibrarySineForQ16) {
  const std::string text = std::string(kSurface) +
                           "[surface.impact]\nrecoil_gain = 1\noscillation_gain = 1\nduration = 0.1\nfrequency = 30\n"
                           "sine = \"library\"\n";
  EXPECT_TRUE(parse_scene(text, "sine.toml", ScalarKind::kFloat));
  const auto q = parse_scene(text, "sine.toml", ScalarKind::kQ16_16);
  ASSERT_FALSE(q);
  EXPECT_NE(q.error().find("sine.toml:10: surface[1].impact.sine: 'library' needs a floating-point scalar"),
            std::string::npos)
      << q.error();
}

// ---- Q16.16: products that saturate in normal use, rates whose 1/dt does not fit -------------
// Normal use (scene_file.hpp fixed_point): the HIP anywhere in the workspace (the scene's, else
// the largest device's: z from -0.06 m) at up to [device] max_velocity (default 1.2 m/s).

/// A floor at z = 0 (normal +z): the deepest the default workspace lets the HIP in is 0.06 m.
std::string floor_with(const std::string& keys) {
  return "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\n" + keys;
}
constexpr double kDeepestM = 0.06;    // -kDefaultWorkspaceMinM.z
constexpr double kMaxForceN = 32767;  // fixed_point::kMaxProduct, one unit under Q16.16's largest

TEST(SceneFile, Q16RefusesAStiffnessWhoseWallForceSaturatesWithFileLineKeyAndTheRange) {
  // A stiffness fits Q16.16 on its own only below 32768 N/m, so k delta saturates only where the
  // workspace lets the HIP more than 1 m into the wall: a large device, here 2 m below the floor.
  const std::string big = "[device]\nworkspace_min = [-1, -1, -2]\nworkspace_max = [1, 1, 1]\n";
  const double deepest_m = 2.0;
  const double allowed = kMaxForceN / deepest_m;  // k delta <= 32767 N (effects.md §1)
  const std::string text = big + floor_with("stiffness = 20000\n");
  EXPECT_TRUE(parse_scene(text, "stiff.toml", ScalarKind::kDouble)) << "double holds it";
  EXPECT_TRUE(parse_scene(text, "stiff.toml", ScalarKind::kFloat)) << "float holds it";
  const auto q = parse_scene(text, "stiff.toml", ScalarKind::kQ16_16);
  ASSERT_FALSE(q);
  EXPECT_NE(q.error().find("stiff.toml:7: surface[1].stiffness: "), std::string::npos) << q.error();
  EXPECT_NE(q.error().find(fmt::format("stiffness up to {:.6g} N/m", allowed)), std::string::npos) << q.error();
  // Just under the bound it loads; in the devices' own workspaces (0.06 m deep) it is far under.
  const auto under =
      parse_scene(big + floor_with(fmt::format("stiffness = {}\n", allowed * 0.99)), "ok.toml", ScalarKind::kQ16_16);
  EXPECT_TRUE(under) << under.error();
  const auto small = parse_scene(floor_with("stiffness = 20000\n"), "small.toml", ScalarKind::kQ16_16);
  EXPECT_TRUE(small) << small.error();
}

TEST(SceneFile, Q16RefusesCoulombFrictionWhoseGainSaturatesOnAStiffWall) {
  // effects.md §2: below v_reg the Coulomb part is a damper mu_c N / v_reg, N the wall's force:
  // 30000 N/m x 0.06 m = 1800 N, so mu_c = 0.5 over 0.02 m/s is 45000 N s/m.
  const std::string text = floor_with("stiffness = 30000\n[surface.friction]\ncoulomb = 0.5\n");
  EXPECT_TRUE(parse_scene(text, "f.toml", ScalarKind::kDouble));
  const auto q = parse_scene(text, "f.toml", ScalarKind::kQ16_16);
  ASSERT_FALSE(q);
  EXPECT_NE(q.error().find("f.toml:6: surface[1].friction.coulomb: "), std::string::npos) << q.error();
  EXPECT_NE(q.error().find(fmt::format("coulomb up to {:.6g}", kMaxForceN * 0.02 / (30000 * kDeepestM))),
            std::string::npos)
      << q.error();
}

TEST(SceneFile, Q16RefusesDampingSlipperyGainAndImpactGainsThatSaturateAtTheTopSpeed) {
  const double v = 1.2;  // [device] max_velocity's default
  // b v (effects.md §1) with the spring's 1500 N/m x 0.06 m beside it.
  auto q = parse_scene(floor_with("stiffness = 1500\ndamping = 27250\n"), "b.toml", ScalarKind::kQ16_16);
  ASSERT_FALSE(q);
  EXPECT_NE(q.error().find("b.toml:5: surface[1].damping: "), std::string::npos) << q.error();
  EXPECT_NE(q.error().find(fmt::format("damping up to {:.6g} N s/m", (kMaxForceN - 1500 * kDeepestM) / v)),
            std::string::npos)
      << q.error();
  // mu v_t before the cap (effects.md §3).
  q = parse_scene(floor_with("stiffness = 1500\n[surface.slippery]\nmu = 28000\n"), "mu.toml", ScalarKind::kQ16_16);
  ASSERT_FALSE(q);
  EXPECT_NE(q.error().find("mu.toml:6: surface[1].slippery.mu: "), std::string::npos) << q.error();
  EXPECT_NE(q.error().find(fmt::format("mu up to {:.6g} N s/m", kMaxForceN / v)), std::string::npos) << q.error();
  // v_i d (k_r + k_osc) at t = 0 (effects.md §4): 1.2 m/s x 1 s x 30000 N/m = 36000 N.
  const std::string impact = floor_with(
      "stiffness = 1500\n[surface.impact]\nrecoil_gain = 10000\noscillation_gain = 20000\nduration = 1\nfrequency = 5\n");
  q = parse_scene(impact, "imp.toml", ScalarKind::kQ16_16);
  ASSERT_FALSE(q);
  EXPECT_NE(q.error().find("imp.toml:7: surface[1].impact.oscillation_gain: "), std::string::npos) << q.error();
  EXPECT_NE(q.error().find(fmt::format("up to {:.6g} N/m", kMaxForceN / v)), std::string::npos) << q.error();
  EXPECT_TRUE(parse_scene(impact, "imp.toml", ScalarKind::kDouble));
  // A lower max_velocity is a smaller top speed: the same transient fits.
  const auto slow = parse_scene("[device]\nmax_velocity = 1.0\n" + impact, "slow.toml", ScalarKind::kQ16_16);
  EXPECT_TRUE(slow) << "1.0 m/s x 1 s x 30000 N/m = 30000 N fits: " << slow.error();
}

TEST(SceneFile, Q16RateRuleIsOneOverDtAndTheCliffsFilter) {
  const auto wall = parse_scene(floor_with("stiffness = 1500\n"), "w.toml", ScalarKind::kQ16_16);
  ASSERT_TRUE(wall) << wall.error();
  // 1/dt must fit Q16.16 (largest value 32767.99998): whole rates up to 32767 Hz.
  EXPECT_EQ(fixed_point::check_rate(32767.0, ScalarKind::kQ16_16, wall.value()), "");
  const std::string refused = fixed_point::check_rate(32768.0, ScalarKind::kQ16_16, wall.value());
  EXPECT_NE(refused.find("up to 32767 Hz"), std::string::npos) << refused;
  EXPECT_EQ(fixed_point::check_rate(100000.0, ScalarKind::kDouble, wall.value()), "") << "only q16.16 has the rule";
  // The cliff's filter 1 + tau rate (effects.md §5): tau = 2 s allows (32767 - 1) / 2 Hz.
  const auto cliff = parse_scene(
      "[[cliff]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\naxis = [1, 0, 0]\ngap_min = -0.01\ngap_max = 0.01\n"
      "stiffness = 1500\nspeed_threshold = 0.08\ntau = 2\n",
      "c.toml", ScalarKind::kQ16_16);
  ASSERT_TRUE(cliff) << cliff.error();
  EXPECT_EQ(fixed_point::check_rate(16383.0, ScalarKind::kQ16_16, cliff.value()), "");
  const std::string slow = fixed_point::check_rate(16384.0, ScalarKind::kQ16_16, cliff.value());
  EXPECT_NE(slow.find("cliff[1]"), std::string::npos) << slow;
  EXPECT_NE(slow.find("up to 16383 Hz"), std::string::npos) << slow;
  // The velocity estimator's a = 1 / (1 + rate / (2 pi f_c)) (effects.md §0): a 0.1 Hz cut-off
  // allows (32767 - 1) x 2 pi x 0.1 Hz.
  const auto sluggish = parse_scene("[device]\nvelocity_cutoff = 0.1\n" + floor_with("stiffness = 1500\n"), "v.toml",
                                    ScalarKind::kQ16_16);
  ASSERT_TRUE(sluggish) << sluggish.error();
  const double allowed_hz = 32766.0 * 2.0 * 3.14159265358979323846 * 0.1;
  EXPECT_EQ(fixed_point::check_rate(std::floor(allowed_hz), ScalarKind::kQ16_16, sluggish.value()), "");
  const std::string estimator = fixed_point::check_rate(std::ceil(allowed_hz), ScalarKind::kQ16_16, sluggish.value());
  EXPECT_NE(estimator.find("velocity_cutoff"), std::string::npos) << estimator;
  EXPECT_NE(estimator.find(fmt::format("up to {:.6g} Hz", allowed_hz)), std::string::npos) << estimator;
}

TEST(SceneFile, SaysWhenTheFileIsMissing) {
  const auto scene = load_scene_file("/nonexistent/scene.toml");
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.error().find("/nonexistent/scene.toml: no such scene file"), std::string::npos) << scene.error();
}

TEST(SceneFile, AFileThatCannotBeReadSaysWhyWithoutALineZero) {
  // It said "DIR:0: cannot open the file for reading".
  const std::string dir = ::testing::TempDir() + "scene_dir.toml";
  std::filesystem::create_directories(dir);
  const auto scene = load_scene_file(dir);
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.error().find(dir + ": is a directory, not a TOML file"), std::string::npos) << scene.error();
  EXPECT_EQ(scene.error().find(":0:"), std::string::npos) << scene.error();
  std::filesystem::remove(dir);
}

TEST(SceneFile, RefusesMoreSurfacesThanASceneHolds) {
  std::string text;
  for (std::size_t i = 0; i <= RuntimeSurface<double>::kMaxPerScene; ++i) text += kSurface;
  const auto scene = parse_scene(text, "many.toml");
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.error().find("more than the 16 a scene holds"), std::string::npos) << scene.error();
}

// ---- depth and size before the parser -------------------------------------------------
// A dotted key ~40,000 deep crashed check, replay, sim and run inside toml++ (it recurses once
// per level), and a `load` message the same: the text is measured first, in one pass.

std::string repeated(std::string_view part, std::size_t n) {
  std::string out;
  out.reserve(part.size() * n);
  for (std::size_t i = 0; i < n; ++i) out += part;
  return out;
}

bool parses(std::string_view text, std::string* error = nullptr) {
  ErrorList errors("deep.toml");
  const bool ok = parse_toml_text(text, errors).has_value();
  if (error != nullptr) *error = errors.text();
  return ok;
}

struct DeepText {
  const char* what;
  std::string text;
  int line = 2;  ///< where the limit is passed
};

class DeepToml : public ::testing::TestWithParam<DeepText> {};

TEST_P(DeepToml, IsRefusedWithTheLimitAndItsLineBeforeTheParserRecurses) {
  std::string error;
  EXPECT_FALSE(parses(GetParam().text, &error)) << GetParam().what;
  EXPECT_NE(error.find(fmt::format("deep.toml:{}: nested deeper than {} levels", GetParam().line, kMaxTomlDepth)),
            std::string::npos)
      << GetParam().what << ": " << error.substr(0, 300);
}

const DeepText kDeep[] = {
    {"a dotted key 40,000 deep", "name = \"x\"\n" + repeated("a.", 40000) + "b = 1\n"},
    {"a table header 40,000 deep", "name = \"x\"\n[" + repeated("a.", 40000) + "b]\nc = 1\n"},
    {"an unclosed header 40,000 deep", "name = \"x\"\n[" + repeated("a.", 40000)},
    {"arrays 50,000 deep", "name = \"x\"\nk = " + repeated("[", 50000) + repeated("]", 50000) + "\n"},
    {"inline tables 30,000 deep", "name = \"x\"\nk = " + repeated("{a = ", 30000) + "1" + repeated("}", 30000) + "\n"},
    // Each part within the limit, together past it: 12 inline tables, each keyed 9 dots deep.
    {"dotted keys inside nested inline tables",
     "name = \"x\"\nk = " + repeated("{a.b.c.d.e.f.g.h.i.j = ", 12) + "1" + repeated("}", 12) + "\n"},
    {"a header's depth added to its keys'",
     "name = \"x\"\n[" + repeated("a.", 40) + "b]\n" + repeated("c.", 40) + "d = 1\n", 3},
};
INSTANTIATE_TEST_SUITE_P(SceneFile, DeepToml, ::testing::ValuesIn(kDeep), [](const auto& param_info) {
  std::string name;
  for (const char c : std::string_view(param_info.param.what))
    name += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return name;
});

TEST(SceneFile, NestingWithinTheLimitAndLongFlatArraysStillParse) {
  std::string error;
  // 40 levels of arrays, 5,000 numbers with a dot each on one line, a multi-line array of
  // arrays, dotted keys in an array of tables, dots inside strings and comments.
  EXPECT_TRUE(parses("k = " + repeated("[", 40) + repeated("]", 40) + "\n", &error)) << error;
  std::string flat = "k = [";
  for (int i = 0; i < 5000; ++i) flat += fmt::format("{}{}.5", i == 0 ? "" : ", ", i);
  EXPECT_TRUE(parses(flat + "]\n", &error)) << error;
  EXPECT_TRUE(parses("p = [\n  [1.0, 2.0, 3.0],\n  [4.0, 5.0, 6.0],\n]\n[[a.b.c]]\nd.e.f = 1.5\n"
                     "g = \"" +
                         repeated("x.", 500) + "\" # " + repeated("y.", 500) + "\n",
                     &error))
      << error;
  EXPECT_TRUE(parses("[" + repeated("a.", 20) + "b]\n" + repeated("c.", 20) + "d = 1\n", &error)) << error;
}

TEST(SceneFile, AFileLargerThanTheLimitIsRefusedAfterReadingNoMoreThanIt) {
  ErrorList errors("/dev/zero");
  EXPECT_FALSE(parse_toml_file("/dev/zero", errors));  // endless: read only to the limit
  EXPECT_NE(errors.text().find(fmt::format("larger than {} MiB", kMaxTomlBytes >> 20)), std::string::npos)
      << errors.text();
  std::string error;
  EXPECT_FALSE(parses(std::string(kMaxTomlBytes + 1, ' '), &error));
  EXPECT_NE(error.find("larger than"), std::string::npos) << error;
  EXPECT_TRUE(parses(std::string(1000, '\n') + "k = 1\n", &error)) << error;
}

TEST(SceneFile, ADeepSceneFileIsRefusedByTheLoaderWithFileAndLine) {
  const auto path = std::filesystem::temp_directory_path() / fmt::format("toonforce_deep_{}.toml", ::getpid());
  {
    std::ofstream out(path);
    out << "name = \"deep\"\n" << repeated("a.", 40000) << "b = 1\n";
  }
  const auto scene = load_scene_file(path.string());
  std::filesystem::remove(path);
  ASSERT_FALSE(scene);
  EXPECT_NE(scene.error().find(path.string() + ":2: nested deeper than"), std::string::npos)
      << scene.error().substr(0, 300);
}

}  // namespace
}  // namespace toonforce
