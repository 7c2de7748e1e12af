// SPDX-License-Identifier: Apache-2.0
// The servo loop's [device] keys in scene files (toonforce extensions, interfaces.md): values,
// defaults, range and type errors that name file, line and key; old scenes keep working.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/config/world_file.hpp"

namespace toonforce {
namespace {

const std::string kFloor = "[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 1000.0\n";

TEST(ServoSceneKeys, ReadsEverySafetyKey) {
  const auto scene =
      parse_scene("[device]\nmax_force = 6.0\nengage_force = 0.3\nsoft_start = 0.5\nmax_velocity = 0.8\n"
                  "workspace_min = [-0.05, -0.04, -0.03]\nworkspace_max = [0.05, 0.04, 0.03]\nwatchdog_periods = 50\n"
                  "device_timeout_periods = 4\ncontinuous_force = 2.5\nthermal_time_constant = 45.0\n"
                  "thermal_derate_start = 0.7\npassivity_controller = false\npassivity_budget = 0.2\n"
                  "passivity_max_damping = 5.0\n" +
                      kFloor,
                  "keys.toml");
  ASSERT_TRUE(scene) << scene.error();
  const ServoConfig c = servo_config(scene.value(), 1e-3);
  EXPECT_EQ(c.period_s, 1e-3);
  EXPECT_EQ(c.limits.max_force_n, 6.0);
  EXPECT_EQ(c.safety.engage_force_n, 0.3);
  EXPECT_EQ(c.safety.soft_start_s, 0.5);
  EXPECT_TRUE(c.safety.has_max_velocity);
  EXPECT_EQ(c.safety.max_velocity_m_per_s, 0.8);
  EXPECT_TRUE(c.safety.has_workspace);
  EXPECT_EQ(c.safety.workspace_min_m, (Vec3<double>{-0.05, -0.04, -0.03}));
  EXPECT_EQ(c.safety.workspace_max_m, (Vec3<double>{0.05, 0.04, 0.03}));
  EXPECT_EQ(c.safety.watchdog_periods, 50);
  EXPECT_EQ(c.safety.device_timeout_periods, 4);
  EXPECT_EQ(c.safety.thermal.continuous_force_n, 2.5);
  EXPECT_EQ(c.safety.thermal.time_constant_s, 45.0);
  EXPECT_EQ(c.safety.thermal.derate_start, 0.7);
  EXPECT_FALSE(c.safety.passivity.controller);
  EXPECT_EQ(c.safety.passivity.budget_j, 0.2);
  EXPECT_EQ(c.safety.passivity.max_damping_n_s_per_m, 5.0);
  EXPECT_EQ(check_servo_config(c), "");
}

TEST(ServoSceneKeys, DefaultsAreTheDocumentedOnesAndTheDeviceFillsTheRest) {
  const auto scene = parse_scene(kFloor, "defaults.toml");
  ASSERT_TRUE(scene) << scene.error();
  const ServoConfig c = servo_config(scene.value(), 1e-3);
  EXPECT_EQ(c.safety.engage_force_n, 0.2);
  EXPECT_EQ(c.safety.soft_start_s, 1.0);
  EXPECT_EQ(c.safety.max_velocity_m_per_s, 1.2);
  EXPECT_FALSE(c.safety.has_workspace);
  EXPECT_EQ(c.safety.watchdog_periods, 30);
  EXPECT_EQ(c.safety.device_timeout_periods, 10);
  EXPECT_EQ(c.safety.thermal.continuous_force_n, 0.0);
  EXPECT_EQ(c.safety.thermal.time_constant_s, 60.0);
  EXPECT_EQ(c.safety.thermal.derate_start, 0.8);
  EXPECT_TRUE(c.safety.passivity.controller);
  EXPECT_EQ(c.safety.passivity.budget_j, 0.5);
  EXPECT_EQ(c.safety.passivity.max_damping_n_s_per_m, 10.0);
}

struct BadKey {
  const char* name;
  std::string device;
  std::string message;
};
class ServoSceneKeyErrors : public ::testing::TestWithParam<BadKey> {};

TEST_P(ServoSceneKeyErrors, NameFileLineAndKey) {
  const auto scene = parse_scene("[device]\n" + GetParam().device + kFloor, "bad.toml");
  ASSERT_FALSE(scene) << GetParam().name;
  EXPECT_NE(scene.error().find(GetParam().message), std::string::npos) << scene.error();
}

const BadKey kBadKeys[] = {
    {"zero engage force", "engage_force = 0\n", "bad.toml:2: device.engage_force: must be > 0"},
    {"negative soft start", "soft_start = -1\n", "bad.toml:2: device.soft_start: must be >= 0"},
    {"half a workspace", "workspace_min = [-1, -1, -1]\n",
     "device.workspace_min: needs workspace_min and workspace_max together"},
    {"inverted workspace", "workspace_min = [0, 0, 0]\nworkspace_max = [1, -1, 1]\n",
     "bad.toml:3: device.workspace_max: must be greater than workspace_min on every axis"},
    {"fractional periods", "watchdog_periods = 2.5\n",
     "device.watchdog_periods: must be a whole number, not a fraction"},
    {"zero periods", "device_timeout_periods = 0\n", "device.device_timeout_periods: must be >= 1 (got 0)"},
    {"rated derate start", "thermal_derate_start = 1.0\n", "device.thermal_derate_start: must be below 1"},
    {"string switch", "passivity_controller = \"yes\"\n",
     "device.passivity_controller: must be true or false, not a string"},
    {"typo", "pasivity_budget = 0.1\n", "unknown key 'pasivity_budget' (did you mean 'passivity_budget'?)"},
};
INSTANTIATE_TEST_SUITE_P(ServoSceneKeys, ServoSceneKeyErrors, ::testing::ValuesIn(kBadKeys));

TEST(ServoSceneKeys, Q16ChecksApplyToQuantitiesButNotToCounts) {
  const auto counts = parse_scene("[device]\nwatchdog_periods = 100000\n" + kFloor, "q.toml", ScalarKind::kQ16_16);
  EXPECT_TRUE(counts) << counts.error();
  const auto tiny = parse_scene("[device]\nengage_force = 1e-6\n" + kFloor, "q.toml", ScalarKind::kQ16_16);
  ASSERT_FALSE(tiny);
  EXPECT_NE(tiny.error().find("device.engage_force: 1e-06 rounds to 0 in Q16.16"), std::string::npos) << tiny.error();
}

TEST(ServoSceneKeys, EveryBundledSceneLoadsAndMakesAUsableServoConfig) {
  int scenes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(TOONFORCE_SOURCE_DIR "/scenes")) {
    if (entry.path().extension() != ".toml") continue;
    if (is_world_file(entry.path().string())) {  // several devices, each with its own [device] keys
      const auto world = load_world_file(entry.path().string());
      ASSERT_TRUE(world) << world.error();
      for (const WorldDeviceEntry& d : world->devices) {
        EXPECT_EQ(check_servo_config(servo_config(d.settings, 1e-3)), "") << entry.path() << " " << d.name;
      }
      ++scenes;
      continue;
    }
    for (const ScalarKind kind : {ScalarKind::kDouble, ScalarKind::kQ16_16}) {
      const auto scene = load_scene_file(entry.path().string(), kind);
      ASSERT_TRUE(scene) << scene.error();
      EXPECT_EQ(check_servo_config(servo_config(scene.value(), 1e-3)), "") << entry.path();
    }
    ++scenes;
  }
  EXPECT_GE(scenes, 5);
}

}  // namespace
}  // namespace toonforce
