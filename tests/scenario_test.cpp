// SPDX-License-Identifier: Apache-2.0
// The latency and precision reports time and compare the paper scenes on scripted scenarios
// (tools/report/src/scenario.cpp) that claim to drive every branch of each scene, the
// expensive ones included. These tests check the claim on the scene's own diagnostics and
// forces, one pass at 1 kHz after a pass of warm-up (the reports run the scenarios over and
// over), and that the paths are what they say (C1 and periodic).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/report/scenario.hpp"

namespace toonforce::report {
namespace {

constexpr double kRateHz = 1000.0;

/// What the scene's effects show after a tick (their values, read by name).
struct Shown {
  bool in_contact = false;
  double impact_time_s = std::numeric_limits<double>::quiet_NaN();
};

struct TickView {
  PathPoint p;
  Vec3<double> scene_force;
  Vec3<double> force;
  std::uint8_t limits = 0;
  Shown before;  ///< after the previous tick
  Shown after;
  bool fallen_before = false;
  bool fallen_after = false;
  bool impact_running_before = false;
};

/// Runs two passes of the scene's scenario (effects plus safety stage) and calls `look` on
/// each tick of the second.
template <class Look>
void run_scenario(std::string_view scene, Look look) {
  const auto desc = load_scene_file(paper_scene_path(TOONFORCE_SOURCE_DIR, scene));
  ASSERT_TRUE(desc) << desc.error();
  const RuntimeScene<double> rt = make_runtime_scene<double>(desc.value());
  RuntimeScene<double>::State state{};
  std::array<ActiveForce<double>, RuntimeScene<double>::kActiveCapacity> active{};
  std::array<double, RuntimeScene<double>::kValueCapacity> values{};
  ForceSafety<double> safety(desc->limits);
  const bool has_cliff = rt.count<CartoonCliff<double>>() > 0;
  const bool has_surface = rt.count<RuntimeSurface<double>>() > 0;
  const auto& cliffs = std::get<1>(state.effects);
  const auto& surfaces = std::get<0>(state.effects);
  const KeyframePath path = paper_scenario(scene);
  const auto ticks = static_cast<std::int64_t>(std::llround(path.period_s() * kRateHz));
  ASSERT_GT(ticks, 0);
  Shown previous{};
  for (std::int64_t k = 0; k < 2 * ticks; ++k) {
    TickView v;
    v.p = path.at(static_cast<double>(k % ticks) / kRateHz);
    TickInput<double> in{};
    in.position_m = v.p.position_m;
    in.velocity_m_per_s = v.p.velocity_m_per_s;
    in.rate_hz = kRateHz;
    in.now = Instant{k, 0};
    in.period_s = 1.0 / kRateHz;
    v.before = previous;
    v.fallen_before = has_cliff && cliffs[0].fallen;
    v.impact_running_before = has_surface && surfaces[0].impact.running;
    v.scene_force = rt.force(in, state, active.data());
    const auto out = safety.limit(v.scene_force, kRateHz);
    v.force = out.force_n;
    v.limits = out.limits;
    v.after.in_contact = rt.describe(state, in, values.data());
    v.after.impact_time_s = has_surface ? values[1] : std::numeric_limits<double>::quiet_NaN();  // surface1.impact_t
    v.fallen_after = has_cliff && cliffs[0].fallen;
    previous = v.after;
    if (k >= ticks) look(v);
  }
}

bool has_limit(const TickView& v, Limit l) { return (v.limits & static_cast<std::uint8_t>(l)) != 0; }

TEST(Scenario, PathsAreContinuousInPositionAndVelocityAndPeriodic) {
  for (const std::string_view scene : kPaperScenes) {
    const KeyframePath path = paper_scenario(scene);
    ASSERT_GE(path.keys().size(), 3U) << scene;
    const Keyframe& first = path.keys().front();
    const Keyframe& last = path.keys().back();
    EXPECT_EQ(first.t_s, 0.0) << scene;
    EXPECT_EQ(first.position_m, last.position_m) << scene;
    EXPECT_EQ(first.velocity_m_per_s, last.velocity_m_per_s) << scene;
    // The velocity is the position's derivative: compare with a central difference.
    constexpr double h = 1e-6;
    for (double t = 0.001; t < path.period_s() - 0.001; t += 0.0037) {
      const Vec3<double> slope = (path.at(t + h).position_m - path.at(t - h).position_m) * (0.5 / h);
      EXPECT_NEAR(norm(slope - path.at(t).velocity_m_per_s), 0.0, 1e-5) << scene << " at " << t;
    }
    // Keyframes are hit exactly, from both sides (C1 through them).
    for (const Keyframe& key : path.keys()) {
      if (key.t_s >= path.period_s()) continue;
      EXPECT_NEAR(norm(path.at(key.t_s).position_m - key.position_m), 0.0, 1e-15) << scene;
      EXPECT_NEAR(norm(path.at(key.t_s).velocity_m_per_s - key.velocity_m_per_s), 0.0, 1e-12) << scene;
    }
  }
}

TEST(Scenario, WallGoesInAndOutAndHitsTheRateLimitAndTheClamp) {
  int in = 0, out = 0, rate_limited = 0, clamped = 0;
  run_scenario("wall", [&](const TickView& v) {
    (v.after.in_contact ? in : out)++;
    if (has_limit(v, Limit::kRateLimited)) ++rate_limited;
    if (has_limit(v, Limit::kClamped)) ++clamped;
  });
  EXPECT_GT(in, 100);
  EXPECT_GT(out, 100);
  EXPECT_GT(rate_limited, 0);
  EXPECT_GT(clamped, 0);
}

TEST(Scenario, FrictionStrokesBelowAndAboveTheRegularisationSpeed) {
  int slow = 0, fast = 0, out = 0;
  run_scenario("realistic_friction", [&](const TickView& v) {
    const Vec3<double> vt = tangential_part(v.p.velocity_m_per_s, Vec3<double>{0, 0, 1});
    if (!v.after.in_contact) {
      ++out;
    } else if (norm(vt) < 0.02) {
      ++slow;
    } else {
      ++fast;
    }
  });
  EXPECT_GT(slow, 50);
  EXPECT_GT(fast, 50);
  EXPECT_GT(out, 50);
}

TEST(Scenario, SlipperyStrokesUnderAndOverItsCap) {
  int under = 0, capped = 0;
  run_scenario("slippery", [&](const TickView& v) {
    if (!v.after.in_contact) return;
    const Vec3<double> vt = tangential_part(v.p.velocity_m_per_s, Vec3<double>{0, 0, 1});
    if (4.0 * norm(vt) > 2.0) {
      ++capped;
      // Capped: the tangential force is exactly 2 N.
      EXPECT_NEAR(std::hypot(v.scene_force.x, v.scene_force.y), 2.0, 1e-9);
    } else if (norm(vt) > 0.01) {
      ++under;
    }
  });
  EXPECT_GT(under, 20);
  EXPECT_GT(capped, 20);
}

TEST(Scenario, CartoonWallTriggersRetriggersWhileRunningAndIgnoresASlowEntry) {
  int triggers = 0, retriggers = 0, running = 0, slow_entries = 0;
  run_scenario("cartoon_wall", [&](const TickView& v) {
    const bool triggered = v.after.impact_time_s == 0.0;
    if (triggered) {
      ++triggers;
      if (v.impact_running_before) ++retriggers;
    }
    if (v.after.impact_time_s > 0.0) ++running;
    const bool enters = !v.before.in_contact && v.after.in_contact;
    if (enters && !triggered) {
      EXPECT_LT(-v.p.velocity_m_per_s.z, 0.05);  // slower than min_impact_speed
      ++slow_entries;
    }
  });
  EXPECT_EQ(triggers, 2);
  EXPECT_EQ(retriggers, 1);
  EXPECT_GT(running, 150);
  EXPECT_EQ(slow_entries, 1);
}

TEST(Scenario, CartoonWallEvaluatesItsTransientAtEveryTickOfItsDurationInContact) {
  // At a fixed rate the transient's sine is taken only at t = k T, k < d / T (effects.md §4):
  // 150 arguments at 1 kHz for the bundled d = 0.15 s. A pass that has all of them in contact
  // counts every argument class of the sine, so its most expensive tick is the worst over the
  // sine's arguments by enumeration (docs/performance/tick.md, "What is worst by construction").
  const auto desc = load_scene_file(paper_scene_path(TOONFORCE_SOURCE_DIR, "cartoon_wall"));
  ASSERT_TRUE(desc) << desc.error();
  const double duration_s = desc->of<RuntimeSurface>().at(0).impact.law.duration_s;
  const auto transient_ticks = static_cast<std::size_t>(std::llround(duration_s * kRateHz));
  std::vector<bool> seen(transient_ticks, false);
  run_scenario("cartoon_wall", [&](const TickView& v) {
    if (!v.after.in_contact || !(v.after.impact_time_s >= 0.0)) return;
    const auto k = static_cast<std::size_t>(std::llround(v.after.impact_time_s * kRateHz));
    if (k < seen.size()) seen[k] = true;
  });
  ASSERT_EQ(transient_ticks, 150U);
  for (std::size_t k = 0; k < seen.size(); ++k) EXPECT_TRUE(seen[k]) << "transient tick " << k << " never in contact";
}

TEST(Scenario, CliffVisitsEveryStateAndBothLedgeFaces) {
  int ledge = 0, bridged = 0, falls = 0, fallen_in_gap = 0, face_plus = 0, face_minus = 0, resupported = 0;
  run_scenario("cliff", [&](const TickView& v) {
    const double x = v.p.position_m.x;
    const bool in_gap = x >= 0.0 && x <= 0.02;
    const bool below = v.p.position_m.z < 0.0;
    if (!v.fallen_after && below && !in_gap) ++ledge;
    if (!v.fallen_after && below && in_gap) ++bridged;
    if (!v.fallen_before && v.fallen_after) ++falls;
    if (v.fallen_after && in_gap) ++fallen_in_gap;
    if (v.fallen_after && below && !in_gap) {
      if (v.scene_force.x > 0.0) ++face_plus;
      if (v.scene_force.x < 0.0) ++face_minus;
    }
    if (v.fallen_before && !v.fallen_after) ++resupported;
  });
  EXPECT_GT(ledge, 50);
  EXPECT_GT(bridged, 20);
  EXPECT_GE(falls, 1);
  EXPECT_GT(fallen_in_gap, 50);
  EXPECT_GT(face_plus, 5);
  EXPECT_GT(face_minus, 5);
  EXPECT_GE(resupported, 1);
}

}  // namespace
}  // namespace toonforce::report
