// SPDX-License-Identifier: Apache-2.0
#pragma once
/// One point of the virtual coupling's stability map (docs/performance/world.md, "The
/// coupling's stability map"): two simulated Falcon-class devices in one world, coupled by a
/// spring-damper of rest length 0, every safety stage of each loop on. Shared by the map program
/// (world_stability.cpp) and its test (tests/world_stability_test.cpp), so that what the test
/// checks is what the map prints.
///
/// The run: both hands hold their handles at the same point, so the coupling starts at zero
/// force and both loops engage; the soft start brings the coupling in. Hand a lets go of its
/// handle at 1.2 s (or keeps holding it: `a_releases`); hand b moves its handle 5 mm along x in
/// 50 ms at 1.5 s and holds it there. The run lasts `duration_s`; its last second is the steady
/// state.
///
/// Stable (exact and deterministic: the simulation is bit-reproducible): no device's safety
/// latched a fault (a safety stop is a failure of the coupling, not a rescue), and in the steady
/// state the handles are together and at rest relative to each other: |x_a - x_b| stays within
/// the excitation (kStepM) and |v_a - v_b| within kSteadySpeedM_per_s. A growing oscillation
/// ends in a limit cycle the 8 N clamp holds (fast), or with one handle thrown out of the
/// workspace (far); a decaying one, or a handle creeping against its Coulomb friction on a soft
/// spring (slow: a creep is not an oscillation), is stable.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/control/world.hpp"
#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/host_sim/hand_intent.hpp"
#include "toonforce/host_sim/sim_device.hpp"
#include "toonforce/host_sim/sim_driver.hpp"

namespace toonforce::bench {

inline constexpr double kStepM = 0.005;  ///< hand b's move
/// [m/s] the steady state's largest relative speed that is still at rest: half the Falcon's
/// 20 um encoder count a 1 ms tick (a limit cycle of a few counts at tens of Hz exceeds it; a
/// creep against the friction is a thousand times slower).
inline constexpr double kSteadySpeedMPerS = 0.01;
inline constexpr double kReleaseAtS = 1.2;
inline constexpr double kMoveAtS = 1.5;

struct PointSpec {
  double stiffness_n_per_m = 200.0;
  double damping_n_s_per_m = 0.0;
  int delay_a_ticks = 1;
  int delay_b_ticks = 1;
  bool controller = false;  ///< the passivity controller (the observer is always on)
  bool a_releases = true;   ///< false: hand a holds its handle throughout
  double duration_s = 4.0;
  double period_s = 1e-3;
  std::FILE* trace = nullptr;  ///< if set: a CSV line a tick (t, both handles, both forces)
};

struct PointResult {
  bool ok = false;  ///< the point ran (the scene parsed, the devices were made)
  std::string error;
  bool held = false;  ///< a device's safety latched a fault: the world held
  double held_at_s = -1.0;
  double least_energy_j = 0.0;      ///< the least passivity-observer energy at either port
  double least_sum_energy_j = 0.0;  ///< the least of the two ports' sum (the coupling as a two-port)
  /// The same sum from what the devices did: each applied force on its handle's true motion
  /// (the plant), where the observer has the reading, io_delay_ticks late.
  double least_true_sum_energy_j = 0.0;
  double steady_largest_speed_m_per_s = 0.0;  ///< max |v_a - v_b| in the steady state
  double steady_largest_gap_m = 0.0;          ///< max |x_a - x_b| in the steady state
  double peak_force_n = 0.0;                  ///< the largest force either device applied
  bool stable = false;
};

namespace detail {

inline host_sim::HandIntent hand(bool mover, bool releases) {
  host_sim::HandScript script;
  script.name = mover ? "step" : (releases ? "let go" : "hold");
  script.start_m = {};
  host_sim::HandSegment wait;
  wait.kind = host_sim::SegmentKind::kHold;
  wait.duration_s = mover ? kMoveAtS : kReleaseAtS;
  script.segments.push_back(wait);
  if (mover) {
    host_sim::HandSegment move;
    move.kind = host_sim::SegmentKind::kMove;
    move.to_m = {kStepM, 0.0, 0.0};
    move.duration_s = 0.05;
    script.segments.push_back(move);
    host_sim::HandSegment stay;
    stay.kind = host_sim::SegmentKind::kHold;
    script.segments.push_back(stay);
  } else {
    host_sim::HandSegment last;
    last.kind = releases ? host_sim::SegmentKind::kRelease : host_sim::SegmentKind::kHold;
    script.segments.push_back(last);
  }
  host_sim::PlanError error;
  return *host_sim::HandIntent::plan(script, error);  // a fixed, valid script
}

}  // namespace detail

inline PointResult run_point(const PointSpec& spec) {
  using SimWorld = World<host_sim::SimDevice, RuntimeScene<double>, 2>;
  PointResult r;
  // Nothing but the world's coupling acts: one plane a metre below, never touched.
  auto scene = parse_scene("[[surface]]\npoint = [0.0, 0.0, -1.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 1.0\n",
                           "coupling.toml", ScalarKind::kDouble);
  if (!scene.ok()) {
    r.error = scene.error();
    return r;
  }
  std::array<host_sim::DeviceParams, 2> params{host_sim::falcon_params(), host_sim::falcon_params()};
  params[0].io_delay_ticks = spec.delay_a_ticks;
  params[1].io_delay_ticks = spec.delay_b_ticks;
  const host_sim::PlantOptions plant{host_sim::Integrator::kRk4, 4, spec.period_s};
  auto a = host_sim::SimDevice::create(params[0], detail::hand(false, spec.a_releases), plant, 1);
  auto b = host_sim::SimDevice::create(params[1], detail::hand(true, false), plant, 2);
  if (!a.ok() || !b.ok()) {
    r.error = a.ok() ? b.error() : a.error();
    return r;
  }
  std::array<host_sim::SimDevice, 2> devices{std::move(a).value(), std::move(b).value()};
  std::array<ServoConfig, 2> configs;
  for (std::size_t i = 0; i < 2; ++i) {
    // Every stage, with the simulated device's own limits (as `toonforce sim` configures it).
    configs[i] =
        with_device(servo_config(scene.value(), spec.period_s), host_sim::device_info(params[i], spec.period_s));
    configs[i].safety.passivity.controller = spec.controller;
    if (const std::string bad = check_servo_config(configs[i]); !bad.empty()) {
      r.error = bad;
      return r;
    }
  }
  WorldConfig world_config;
  world_config.coupling_count = 1;
  world_config.couplings[0] = {0, 1, {spec.stiffness_n_per_m, spec.damping_n_s_per_m, 0.0}};
  if (const std::string bad = check(world_config, 2); !bad.empty()) {
    r.error = bad;
    return r;
  }
  const RuntimeScene<double> runtime = make_runtime_scene<double>(scene.value());
  auto world = std::make_unique<SimWorld>(
      std::array<SimWorld::Member, 2>{SimWorld::Member{&devices[0], runtime, DeviceFrame{}, configs[0]},
                                      SimWorld::Member{&devices[1], runtime, DeviceFrame{}, configs[1]}},
      world_config);

  const auto ticks = static_cast<std::int64_t>(std::llround(spec.duration_s / spec.period_s));
  const auto steady_from = ticks - static_cast<std::int64_t>(std::llround(1.0 / spec.period_s));
  std::array<Vec3<double>, 2> last_m{devices[0].plant().position_m(), devices[1].plant().position_m()};
  double true_sum_j = 0.0;
  for (std::int64_t k = 0; k < ticks; ++k) {
    const WorldStatus<2> s = world->tick(k);
    for (std::size_t i = 0; i < 2; ++i) {
      // The force applied over this tick moved the handle from last_m to where it is now.
      const Vec3<double> now = devices[i].plant().position_m();
      true_sum_j -= dot(devices[i].applied_force_n(), now - last_m[i]);
      last_m[i] = now;
    }
    r.least_true_sum_energy_j = std::min(r.least_true_sum_energy_j, true_sum_j);
    if (s.held && !r.held) {
      r.held = true;
      r.held_at_s = static_cast<double>(k) * spec.period_s;
    }
    const double e_a = world->loop(0).passivity().observer().energy().to_double();
    const double e_b = world->loop(1).passivity().observer().energy().to_double();
    r.least_sum_energy_j = std::min(r.least_sum_energy_j, e_a + e_b);
    for (std::size_t i = 0; i < 2; ++i) {
      r.least_energy_j = std::min(r.least_energy_j, world->loop(i).passivity().observer().energy().to_double());
      r.peak_force_n = std::max(r.peak_force_n, norm(devices[i].applied_force_n()));
    }
    if (spec.trace != nullptr) {
      const Vec3<double> xa = devices[0].plant().position_m();
      const Vec3<double> xb = devices[1].plant().position_m();
      const Vec3<double> fa = devices[0].applied_force_n();
      const Vec3<double> fb = devices[1].applied_force_n();
      std::fprintf(spec.trace, "%.3f,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.4g,%.4g,%.4g,%.4g,%.4g,%.4g,%.6g,%.6g\n",
                   static_cast<double>(k) * spec.period_s, xa.x, xa.y, xa.z, xb.x, xb.y, xb.z, fa.x, fa.y, fa.z, fb.x,
                   fb.y, fb.z, world->loop(0).passivity().observer().energy().to_double(),
                   world->loop(1).passivity().observer().energy().to_double());
    }
    if (k >= steady_from) {
      // The handles themselves (the plant), not the delayed, quantised readings.
      const Vec3<double> gap = devices[0].plant().position_m() - devices[1].plant().position_m();
      const Vec3<double> speed = devices[0].plant().velocity_m_per_s() - devices[1].plant().velocity_m_per_s();
      r.steady_largest_gap_m = std::max(r.steady_largest_gap_m, norm(gap));
      r.steady_largest_speed_m_per_s = std::max(r.steady_largest_speed_m_per_s, norm(speed));
    }
  }
  r.stable = !r.held && r.steady_largest_gap_m <= kStepM && r.steady_largest_speed_m_per_s <= kSteadySpeedMPerS;
  r.ok = true;
  return r;
}

}  // namespace toonforce::bench
