// SPDX-License-Identifier: Apache-2.0
#pragma once
// What the world tests (world_test.cpp, world_ball_test.cpp) share: two simulated Falcon-class
// devices in one world, each held by a scripted hand.
#include <gtest/gtest.h>

#include <utility>

#include "toonforce/control/world.hpp"
#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/host_sim/hand_intent.hpp"
#include "toonforce/host_sim/sim_device.hpp"

namespace toonforce::test {

using SimWorld2 = World<host_sim::SimDevice, RuntimeScene<double>, 2>;

/// A simulated device whose hand holds the handle at `start`, then moves it to `to` (from
/// 0.3 s, over `move_s`) and holds it there. 1 kHz, RK4 with 4 substeps.
inline host_sim::SimDevice sim_device(const Vec3<double>& start, const Vec3<double>& to, double move_s = 0.5) {
  host_sim::HandScript script;
  script.name = "reach";
  script.start_m = start;
  host_sim::HandSegment wait;
  wait.kind = host_sim::SegmentKind::kHold;
  wait.duration_s = 0.3;
  host_sim::HandSegment move;
  move.kind = host_sim::SegmentKind::kMove;
  move.to_m = to;
  move.duration_s = move_s;
  host_sim::HandSegment stay;
  stay.kind = host_sim::SegmentKind::kHold;
  script.segments = {wait, move, stay};
  host_sim::PlanError error;
  auto intent = host_sim::HandIntent::plan(script, error);
  EXPECT_TRUE(intent.has_value());
  auto d = host_sim::SimDevice::create(host_sim::falcon_params(), *intent, {host_sim::Integrator::kRk4, 4, 1e-3});
  EXPECT_TRUE(d) << d.error();
  d->set_state(start, {});
  return std::move(d).value();
}

}  // namespace toonforce::test
