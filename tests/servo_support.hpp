// SPDX-License-Identifier: Apache-2.0
#pragma once
// Test doubles for the servo loop: a scripted device (position, statuses, what was written),
// GPIO pins whose levels the test sets, and scene/config helpers. None of them allocates in
// read/write/toggle/show, so the loop's no-allocation test can use them.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"

namespace toonforce::test {

struct FakeDeviceState {
  Vec3<double> position_m;
  Vec3<double> velocity_m_per_s;
  bool has_velocity = false;
  bool force_limited = false;  ///< the device says it could not give the last force in full
  DeviceStatus read_status = DeviceStatus::kOk;
  DeviceStatus write_status = DeviceStatus::kOk;
  Vec3<double> last_written{1e9, 1e9, 1e9};  // "nothing written yet"
  std::int64_t reads = 0;
  std::int64_t writes = 0;
};

/// A ServoDevice by value that reads and writes a FakeDeviceState the test owns.
struct FakeDevice {
  FakeDeviceState* state;
  DeviceStatus read(DeviceReading& r) noexcept {
    ++state->reads;
    r.position_m = state->position_m;
    r.velocity_m_per_s = state->velocity_m_per_s;
    r.has_velocity = state->has_velocity;
    r.force_limited = state->force_limited;
    return state->read_status;
  }
  DeviceStatus write(const Vec3<double>& f) noexcept {
    ++state->writes;
    state->last_written = f;
    return state->write_status;
  }
};
static_assert(ServoDevice<FakeDevice>);

struct PinState {
  PinLevel estop = PinLevel::kInactive;
  PinLevel enable = PinLevel::kActive;
  std::int64_t toggles = 0;
  LightState light = LightState::kIdle;
  std::int64_t light_changes = 0;
};
struct TestTickPin {
  PinState* s;
  void toggle() noexcept { ++s->toggles; }
};
struct TestEstop {
  PinState* s;
  PinLevel read() noexcept { return s->estop; }
};
struct TestEnable {
  PinState* s;
  PinLevel read() noexcept { return s->enable; }
};
struct TestLights {
  PinState* s;
  void show(LightState l) noexcept {
    s->light = l;
    ++s->light_changes;
  }
};
using TestPins = Pins<TestTickPin, TestEstop, TestEnable, TestLights>;
inline TestPins test_pins(PinState& s) { return TestPins{{&s}, {&s}, {&s}, {&s}}; }

constexpr double kPeriodS = 1e-3;

/// A floor at z = 0 (normal +z), stiffness [N/m]; extra TOML appended to the surface.
inline std::string floor_toml(double stiffness = 1000.0, const std::string& extra = "") {
  return "[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = " + std::to_string(stiffness) +
         "\n" + extra;
}

template <Scalar S>
RuntimeScene<S> scene_from(const std::string& toml) {
  constexpr ScalarKind kind = kIsFixed<S>              ? ScalarKind::kQ16_16
                              : std::same_as<S, float> ? ScalarKind::kFloat
                                                       : ScalarKind::kDouble;
  auto d = parse_scene(toml, "test.toml", kind);
  EXPECT_TRUE(d.ok()) << d.error();
  return make_runtime_scene<S>(d.value());
}

/// Everything off but the clamp at 8 N: each test turns on what it tests.
inline ServoConfig bare_config() {
  ServoConfig c;
  c.period_s = kPeriodS;
  c.limits.has_max_force = true;
  c.limits.max_force_n = 8.0;
  c.safety.soft_start_s = 0.0;
  c.safety.has_max_velocity = false;
  c.safety.has_workspace = false;
  c.safety.thermal.continuous_force_n = 0.0;
  c.safety.passivity.controller = false;
  return c;
}

/// A loop on a fake device with test pins, built in place (the loop is not movable).
template <Scalar S>
struct Rig {
  FakeDeviceState device;
  PinState pins;
  ServoLoop<FakeDevice, RuntimeScene<S>, TestPins> loop;
  std::int64_t k = 0;

  Rig(const std::string& toml, const ServoConfig& config)
      : loop(FakeDevice{&device}, scene_from<S>(toml), config, test_pins(pins)) {
    EXPECT_EQ(check_servo_config(config), "");
  }
  /// One tick at the next integer time with the HIP at `x`.
  TickStatus at(Vec3<double> x, std::int64_t step = 1) {
    device.position_m = x;
    const TickStatus s = loop.tick(k);
    k += step;
    return s;
  }
  Vec3<double> force() const { return device.last_written; }
};

/// Force tolerance [N]: Q16.16 positions are quantised to 2^-16 m (1.5e-5 m), which a
/// 1000 N/m wall turns into 0.015 N.
template <class S>
constexpr double kForceTol = kIsFixed<S> ? 0.02 : 1e-9;

using ServoScalars = ::testing::Types<double, Q16_16>;

}  // namespace toonforce::test
