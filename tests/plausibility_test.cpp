// SPDX-License-Identifier: Apache-2.0
// The plausibility report: each finding is asserted against the bound and
// the limits it is computed from (control/passivity_bound.hpp, the device model), so the
// warnings move where the physics says they should: with the rate, the hand, the controller.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "toonforce/control/passivity_bound.hpp"
#include "toonforce/sim/plausibility.hpp"

namespace toonforce {
namespace {

SceneDescription scene_of(const std::string& text) {
  auto scene = parse_scene(text, "p.toml");
  EXPECT_TRUE(scene) << (scene ? "" : scene.error());
  return scene ? scene.value() : SceneDescription{};
}

std::string wall(double stiffness_n_per_m, const std::string& extra = "") {
  return "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = " + std::to_string(stiffness_n_per_m) + "\n" +
         extra;
}

bool any_has(const std::vector<std::string>& lines, const std::string& text) {
  return std::any_of(lines.begin(), lines.end(),
                     [&](const std::string& l) { return l.find(text) != std::string::npos; });
}

std::string all(const PlausibilityReport& r) {
  std::string out;
  for (const auto& l : r.notes) out += "note " + l + "\n";
  for (const auto& l : r.warnings) out += "warning " + l + "\n";
  return out;
}

TEST(Plausibility, TheHeldBoundIsColgateBrownWithTheDelayAndItMovesWithTheRate) {
  const host_sim::DeviceParams falcon = host_sim::falcon_params();
  // b + b_hand > (1 + 2 d) K T / 2: 2 (0.1 + 8) / (3 T).
  const double held_1khz =
      stiffest_passive_wall_n_per_m(falcon.damping_n_s_per_m + kHeldHandDampingNsPerM, 1e-3, falcon.io_delay_ticks);
  EXPECT_NEAR(held_1khz, 2.0 * 8.1 / (3.0 * 1e-3), 1e-9);
  const SceneDescription stiff = scene_of(wall(1.2 * held_1khz));
  const PlausibilityReport at_1khz = check_plausibility(stiff, "p.toml", falcon, 1000.0);
  ASSERT_EQ(at_1khz.warnings.size(), 1U) << all(at_1khz);
  EXPECT_NE(at_1khz.warnings[0].find("over the passive bound even when held (5400 N/m"), std::string::npos)
      << all(at_1khz);
  // Twice the rate, twice the bound: the same wall is then passive while held.
  const PlausibilityReport at_2khz = check_plausibility(stiff, "p.toml", falcon, 2000.0);
  EXPECT_TRUE(at_2khz.warnings.empty()) << all(at_2khz);
  EXPECT_TRUE(any_has(at_2khz.notes, "passive only while held (up to 1.08e+04 N/m")) << all(at_2khz);
  // Without the I/O delay the device alone holds three times as stiff a wall (d = 1 -> 0).
  host_sim::DeviceParams no_delay = falcon;
  no_delay.io_delay_ticks = 0;
  EXPECT_TRUE(any_has(check_plausibility(scene_of(wall(150.0)), "p.toml", no_delay, 1000.0).notes,
                      "passive on the device alone (up to 200 N/m)"));
  EXPECT_TRUE(
      any_has(check_plausibility(scene_of(wall(150.0)), "p.toml", falcon, 1000.0).notes, "passive only while held"));
}

TEST(Plausibility, VirtualDampingSpendsTheMargin) {
  const host_sim::DeviceParams falcon = host_sim::falcon_params();
  // 3000 N/m is within the held bound (5400) alone; with B = 4 N s/m it needs (3 K T / 2 + 4)
  // = 8.5 N s/m, more than 8.1.
  EXPECT_TRUE(check_plausibility(scene_of(wall(3000.0)), "p.toml", falcon, 1000.0).warnings.empty());
  const PlausibilityReport damped =
      check_plausibility(scene_of(wall(3000.0, "damping = 4.0\n")), "p.toml", falcon, 1000.0);
  ASSERT_EQ(damped.warnings.size(), 1U) << all(damped);
  EXPECT_NE(damped.warnings[0].find("K = 3000 N/m, B = 4 N s/m is over the passive bound even when held"),
            std::string::npos)
      << all(damped);
}

TEST(Plausibility, WithoutThePassivityControllerWhatIsOnlyPassiveWhenHeldIsAWarning) {
  const host_sim::DeviceParams falcon = host_sim::falcon_params();
  const std::string off = "[device]\npassivity_controller = false\n";
  EXPECT_TRUE(check_plausibility(scene_of(wall(1500.0)), "p.toml", falcon, 1000.0).warnings.empty());
  const PlausibilityReport r = check_plausibility(scene_of(off + wall(1500.0)), "p.toml", falcon, 1000.0);
  ASSERT_EQ(r.warnings.size(), 1U) << all(r);
  EXPECT_NE(r.warnings[0].find("passivity_controller = false: let go, nothing stops it buzzing"), std::string::npos);
  // The slippery surface's negative damping: passive only below the device's own b.
  const std::string slippery = wall(1000.0, "[surface.slippery]\nmu = 0.5\n");
  EXPECT_TRUE(any_has(check_plausibility(scene_of(slippery), "p.toml", falcon, 1000.0).notes,
                      "slippery mu = 0.5 N s/m is over the device's own damping b = 0.1 N s/m"));
  EXPECT_TRUE(any_has(check_plausibility(scene_of(off + slippery), "p.toml", falcon, 1000.0).warnings,
                      "nothing bounds the energy it gives"));
  EXPECT_TRUE(any_has(
      check_plausibility(scene_of(off + wall(1000.0, "[surface.slippery]\nmu = 0.05\n")), "p.toml", falcon, 1000.0)
          .notes,
      "slippery mu = 0.05 N s/m is within the device's own damping"));
}

TEST(Plausibility, GeometryOutsideTheWorkspaceAndAnAliasedImpactAreWarnings) {
  const host_sim::DeviceParams falcon = host_sim::falcon_params();  // workspace +-5 cm
  const auto far = check_plausibility(
      scene_of("[[surface]]\npoint = [0, 0, -0.2]\nnormal = [0, 0, 1]\nstiffness = 500\n"), "p.toml", falcon, 1000.0);
  EXPECT_TRUE(any_has(far.warnings, "lies 150 mm outside the device's workspace")) << all(far);
  const auto everywhere = check_plausibility(
      scene_of("[[surface]]\npoint = [0, 0, 0.2]\nnormal = [0, 0, 1]\nstiffness = 500\n"), "p.toml", falcon, 1000.0);
  EXPECT_TRUE(any_has(everywhere.warnings, "the whole workspace is inside it")) << all(everywhere);
  const std::string impact =
      "[surface.impact]\nrecoil_gain = 100\noscillation_gain = 100\nduration = 0.1\nfrequency = ";
  EXPECT_TRUE(any_has(check_plausibility(scene_of(wall(500.0, impact + "600\n")), "p.toml", falcon, 1000.0).warnings,
                      "impact frequency 600 Hz is at or over half the servo rate (500 Hz)"));
  EXPECT_TRUE(check_plausibility(scene_of(wall(500.0, impact + "600\n")), "p.toml", falcon, 2000.0).warnings.empty());
  const auto cliff = check_plausibility(
      scene_of("[[cliff]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\naxis = [1, 0, 0]\ngap_min = 0.3\ngap_max = 0.4\n"
               "stiffness = 800\nspeed_threshold = 0.05\n"),
      "p.toml", falcon, 1000.0);
  EXPECT_TRUE(any_has(cliff.warnings, "the gap [0.3, 0.4] m along its axis is outside the workspace")) << all(cliff);
}

TEST(Plausibility, AForceLimitOverTheDevicesAndAWallStifferThanOneEncoderCountAreWarnings) {
  const host_sim::DeviceParams falcon = host_sim::falcon_params();  // 8 N, 20 um
  const auto over =
      check_plausibility(scene_of("[device]\nmax_force = 12.0\n" + wall(500.0)), "p.toml", falcon, 1000.0);
  EXPECT_TRUE(any_has(over.warnings, "max_force = 12 N is over the device's peak of 8 N")) << all(over);
  // 8 N within less than 20 um: K > 400 000 N/m (also far over the bound; both are said).
  const auto hard = check_plausibility(scene_of(wall(500000.0)), "p.toml", falcon, 1000.0);
  EXPECT_TRUE(any_has(hard.warnings, "less than one encoder step (20 um)")) << all(hard);
}

TEST(Plausibility, TheBundledScenesAreWithinTheFalconsLimits) {
  for (const char* name : {"wall", "realistic_friction", "slippery", "cartoon_wall", "cliff"}) {
    const auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/" + name + ".toml");
    ASSERT_TRUE(scene) << scene.error();
    const auto r = check_plausibility(scene.value(), name, host_sim::falcon_params(), 1000.0);
    EXPECT_TRUE(r.warnings.empty()) << name << ":\n" << all(r);
  }
}

}  // namespace
}  // namespace toonforce
