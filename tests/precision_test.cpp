// SPDX-License-Identifier: Apache-2.0
// The precision report's references and norms: the analytic wall
// equals the law's closed form, the hold's error is first order as theory says, the reference
// ladder converges at the order theory gives, events are seen within a tick, and the drift
// fit recovers a known slope. No timing is asserted (the report times, but nothing here reads it).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string_view>
#include <string>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/host_sim/hand_intent.hpp"
#include "toonforce/sim/closed_loop.hpp"
#include "toonforce/report/mcu.hpp"
#include "toonforce/report/precision.hpp"
#include "toonforce/report/precision_reference.hpp"
#include "toonforce/report/scenario.hpp"

namespace toonforce::report {
namespace {

/// The report on the two wall scenes (the filter "wall" selects wall and cartoon_wall), no
/// drift run, few timed ticks: computed once for the tests below.
const PrecisionReport& wall_report() {
  static const PrecisionReport report = [] {
    PrecisionOptions o;
    o.root = TOONFORCE_SOURCE_DIR;
    o.filter = "wall";
    o.timing_ticks = 1000;
    o.drift_hours = 0.0;
    auto r = run_precision(o);
    EXPECT_TRUE(r) << (r ? "" : r.error());
    return r ? r.value() : PrecisionReport{};
  }();
  return report;
}

TEST(Precision, TheAnalyticWallIsTheLawsClosedForm) {
  const AnalyticWall w;
  // F = K depth, depth = max(0, -z): at the deepest point, at the surface, above it.
  EXPECT_DOUBLE_EQ(w.force_n(0.25 / w.frequency_hz), w.stiffness_n_per_m * (w.amplitude_m - w.offset_m));
  EXPECT_EQ(w.force_n(0.0), 0.0);
  EXPECT_EQ(w.force_n(0.75 / w.frequency_hz), 0.0);
  // The loop in double at its own ticks gives the closed form to rounding: the reference is exact.
  const auto& rows = wall_report().analytic;
  ASSERT_FALSE(rows.empty());
  std::size_t checked = 0;
  for (const auto& a : rows) {
    if (a.scalar == ScalarKind::kDouble) {
      EXPECT_LE(a.sampled_max_error_n, 1e-12) << a.rate_hz;
      ++checked;
    } else if (a.scalar == ScalarKind::kFloat) {
      EXPECT_LE(a.sampled_max_error_n, 1e-5) << a.rate_hz;  // float's ulp at a few N
    }
  }
  EXPECT_EQ(checked, 8U);  // the four compared rates and the four of the ladder
}

TEST(Precision, TheHoldsErrorOnTheAnalyticWallIsFirstOrderAsTheoryGives) {
  // Zero-order hold: F(t) - F(t_k) ~ F'(t_k) (t - t_k), so RMS = T rms(F') / sqrt(3): order 1.
  for (const auto& a : wall_report().analytic) {
    if (a.scalar != ScalarKind::kDouble) continue;
    EXPECT_NEAR(a.held_rms_error_n / a.held_rms_theory_n, 1.0, 0.02) << a.rate_hz;
    if (!std::isnan(a.held_rms_order)) {
      EXPECT_NEAR(a.held_rms_order, 1.0, 0.05) << a.rate_hz;
    }
  }
}

TEST(Precision, TheWallsReferenceLadderConvergesAtSecondOrderAwayFromEvents) {
  // Away from events the wall is exact at its ticks except where the force-rate limit starts a
  // ramp: the discrete limiter leaves the target at a tick, not at the instant the target's slope
  // passes the limit, an offset of O(T^2) that the ramp carries along: second order.
  const SceneConvergence* wall = nullptr;
  for (const auto& c : wall_report().convergence) {
    if (c.scene == "wall") wall = &c;
  }
  ASSERT_NE(wall, nullptr);
  ASSERT_EQ(wall->steps.size(), 3U);
  for (std::size_t i = 1; i < wall->steps.size(); ++i) {
    EXPECT_NEAR(wall->steps[i].away_rms_order, 2.0, 0.2) << wall->steps[i].rate_hz;
  }
  // Its own error is the Richardson estimate: the last difference / (2^p - 1).
  const auto& last = wall->steps.back();
  // Or, if larger, the check rung's difference scaled as convergence of that order.
  const double richardson = last.away_rms_diff_n / (std::exp2(last.away_rms_order) - 1.0);
  const double f = PrecisionOptions{}.reference_check_factor;
  const double checked =
      wall->check.away_rms_diff_n * std::pow(f, last.away_rms_order) / (std::pow(f, last.away_rms_order) - 1.0);
  EXPECT_NEAR(wall->reference_away_rms_error_n, std::max(richardson, checked), 1e-15);
  EXPECT_GT(wall->reference_away_rms_error_n, 0.0);
}

TEST(Precision, TheHeldErrorOfARampIsTheHoldsExactFirstOrderError) {
  // A force ramp F = a t held over ticks of T is off by a s at s into a tick:
  // RMS a T / sqrt(3) and max a T (at the tick's end), exactly, whatever the reference's rate.
  // The reference here is the ramp at 32 times the rate (10 kHz against 320 kHz in the report);
  // reading the error at each reference tick's left end only gave 0.977 of that RMS.
  constexpr double kRateHz = 1000.0, kSlopeNPerS = 2.0;
  constexpr std::size_t kStep = 32, kTicks = 2000;
  std::vector<Vec3<double>> run(kTicks), reference(kTicks * kStep);
  for (std::size_t k = 0; k < run.size(); ++k) run[k] = {kSlopeNPerS * static_cast<double>(k) / kRateHz, 0.0, 0.0};
  for (std::size_t i = 0; i < reference.size(); ++i) {
    reference[i] = {kSlopeNPerS * static_cast<double>(i) / (kRateHz * kStep), 0.0, 0.0};
  }
  // "Away" here: every other tick of the run, whole (its reference ticks).
  const HeldDifference held = held_difference(run, reference, kStep, [](std::size_t i) { return i / kStep % 2 == 0; });
  const double theory_rms = kSlopeNPerS / kRateHz / std::sqrt(3.0);
  EXPECT_NEAR(held.rms_n / theory_rms, 1.0, 1e-4);
  EXPECT_NEAR(held.away_rms_n / theory_rms, 1.0, 1e-4);
  EXPECT_NEAR(held.max_n, kSlopeNPerS / kRateHz, 1e-12);
}

TEST(Precision, TheStatedReferenceErrorBoundsItsDifferenceToAFinerRunAtEventsToo) {
  // The reference (the ladder's finest run) must be within its stated error of
  // the truth at every tick, events included. The truth is taken as a run 8 times finer (not
  // the report's own check rung of 5: an event lands differently on it). realistic_friction's
  // contact end drops 0.27 N through the 2000 N/s rate limit, and at 160 and 320 kHz it landed
  // alike, so the ladder's last difference (2.8e-5 N) was stated while the reference is off
  // by about 5e-3 N there.
  const double reference_rate = PrecisionOptions{}.reference_rates_hz.back();
  for (const char* scene : {"realistic_friction", "wall", "slippery", "cartoon_wall", "cliff"}) {
    PrecisionOptions o;
    o.root = TOONFORCE_SOURCE_DIR;
    o.filter = scene;
    o.rates_hz = {1000.0};
    o.timing_ticks = 100;
    o.drift_hours = 0.0;
    o.closed_loop_s = 0.0;
    const auto r = run_precision(o);
    ASSERT_TRUE(r) << r.error();
    const SceneConvergence* c = nullptr;
    for (const auto& conv : r->convergence) {
      if (conv.scene == scene) c = &conv;
    }
    ASSERT_NE(c, nullptr) << scene;
    const auto reference = scenario_forces(TOONFORCE_SOURCE_DIR, scene, reference_rate);
    const auto finer = scenario_forces(TOONFORCE_SOURCE_DIR, scene, 8.0 * reference_rate);
    ASSERT_TRUE(reference && finer);
    const std::vector<Vec3<double>>& f_ref = reference.value();
    const std::vector<Vec3<double>>& f_fine = finer.value();
    ASSERT_EQ(f_fine.size(), 8U * f_ref.size());
    double max_n = 0.0, sum = 0.0;
    for (std::size_t i = 0; i < f_ref.size(); ++i) {
      const double e = norm(f_ref[i] - f_fine[8 * i]);
      max_n = std::max(max_n, e);
      sum += e * e;
    }
    const double rms_n = std::sqrt(sum / static_cast<double>(f_ref.size()));
    std::printf("%s: vs 8x: max %.3e RMS %.3e; stated max %.3e RMS %.3e\n", scene, max_n, rms_n,
                c->reference_max_error_n, c->reference_rms_error_n);
    EXPECT_LE(max_n, c->reference_max_error_n) << scene;
    EXPECT_LE(rms_n, c->reference_rms_error_n) << scene;
    if (std::string_view(scene) == "realistic_friction") {
      // A bound, not a blanket: the contact end's error is there to be bounded.
      EXPECT_LE(c->reference_max_error_n, 3.0 * max_n);
    }
  }
}

TEST(Precision, ContactAndImpactEventsAreSeenWithinOneTickOfTheReference) {
  // An event decided at a tick from the position (contact onset and end; an impact's trigger,
  // decided at the entering tick) is seen at the first tick at or after the reference sees it:
  // 0 <= lateness < 1 tick, give or take the reference's own tick.
  const double reference_tick = 1.0 / PrecisionOptions{}.reference_rates_hz.back();
  std::size_t checked = 0;
  for (const auto& row : wall_report().rows) {
    if (row.scalar != ScalarKind::kDouble) continue;
    for (const auto& e : row.events) {
      EXPECT_EQ(e.unmatched, 0U) << row.scene << " " << row.rate_hz << " " << event_kind_name(e.kind);
      EXPECT_GE(e.min_late_s, -reference_tick - 1e-12) << row.scene << " " << row.rate_hz;
      EXPECT_LE(e.max_late_s, 1.0 / row.rate_hz + reference_tick + 1e-12)
          << row.scene << " " << row.rate_hz << " " << event_kind_name(e.kind);
      ++checked;
    }
  }
  EXPECT_GE(checked, 20U);
}

TEST(Precision, TheClosedLoopsDoubleLadderConvergesAtFirstOrder) {
  // The closed loop holds its force over a tick and reads the handle one tick late: both
  // errors are O(T), so on the plain wall the force and the trajectory converge at first order.
  // The cartoon wall's impacts add event timing (an impact starting a tick apart), which at
  // these rates is not yet in its asymptotic regime: there, only convergence is asserted.
  const auto& all = wall_report().closed_loop_convergence;
  ASSERT_EQ(all.size(), 2U);  // wall and cartoon_wall
  for (const auto& c : all) {
    ASSERT_EQ(c.steps.size(), 2U);
    if (c.scene == "wall") {
      EXPECT_NEAR(c.steps.back().force_order, 1.0, 0.15) << c.scene;
      EXPECT_NEAR(c.steps.back().position_order, 1.0, 0.15) << c.scene;
    } else {
      EXPECT_GT(c.steps.back().force_order, 0.5) << c.scene;
      EXPECT_GT(c.steps.back().position_order, 0.5) << c.scene;
    }
    EXPECT_GT(c.reference_force_rms_error_n, 0.0);
  }
  // Every configuration ran, and double at 10 kHz is closer to the reference than at 500 Hz.
  double at_500 = 0.0, at_10k = 0.0;
  for (const auto& row : wall_report().closed_loop) {
    EXPECT_TRUE(row.refused.empty()) << row.scene << " " << row.rate_hz << ": " << row.refused;
    if (row.scene == "wall" && row.scalar == ScalarKind::kDouble && row.rate_hz == 500.0)
      at_500 = row.force_rms_error_n;
    if (row.scene == "wall" && row.scalar == ScalarKind::kDouble && row.rate_hz == 10000.0)
      at_10k = row.force_rms_error_n;
  }
  EXPECT_GT(at_500, 5.0 * at_10k);
}

TEST(Precision, OrderAndRichardsonOnKnownNumbers) {
  EXPECT_DOUBLE_EQ(observed_order(4e-3, 1e-3), 2.0);
  EXPECT_DOUBLE_EQ(observed_order(2e-3, 1e-3), 1.0);
  EXPECT_TRUE(std::isnan(observed_order(0.0, 1e-3)));
  EXPECT_DOUBLE_EQ(richardson_error(3e-3, 2.0), 1e-3);
  EXPECT_DOUBLE_EQ(richardson_error(3e-3, 1.0), 3e-3);
  EXPECT_DOUBLE_EQ(richardson_error(3e-3, std::nan("")), 3e-3);  // no order: the difference itself
  EXPECT_DOUBLE_EQ(ladder_error(3e-3, 1.9, 2.0), 1e-3);          // orders agree: Richardson
  EXPECT_DOUBLE_EQ(ladder_error(3e-3, 1.0, 4.0), 3e-3);          // they jump: the difference
  EXPECT_DOUBLE_EQ(ladder_error(3e-3, std::nan(""), 2.0), 3e-3);
}

TEST(Precision, EventsAreFoundAndWindowedWhereTheyHappen) {
  std::vector<TickState> ticks(10);
  for (std::size_t k = 3; k < 7; ++k) ticks[k].in_contact = true;
  ticks[3].impact_t_s = 0.0;
  ticks[4].impact_t_s = 0.001;
  ticks[5].impact_t_s = 0.0;  // re-triggered while running
  ticks[8].cliffs_fallen = 1;
  const auto events = find_events(ticks, 0.0, 1000.0);
  ASSERT_EQ(events.size(), 5U);
  EXPECT_EQ(events[0].kind, EventKind::kContactOnset);
  EXPECT_DOUBLE_EQ(events[0].t_s, 0.003);
  EXPECT_EQ(events[1].kind, EventKind::kImpactTrigger);
  EXPECT_EQ(events[2].kind, EventKind::kImpactTrigger);
  EXPECT_DOUBLE_EQ(events[2].t_s, 0.005);
  EXPECT_EQ(events[3].kind, EventKind::kContactEnd);
  EXPECT_DOUBLE_EQ(events[3].t_s, 0.007);
  EXPECT_EQ(events[4].kind, EventKind::kCliffFall);
  EXPECT_TRUE(near_event(events, 0.002, 0.0015, 0.0));
  EXPECT_FALSE(near_event(events, 0.001, 0.0015, 0.0));
  EXPECT_TRUE(near_event(events, 0.0085, 0.0, 0.001));
  EXPECT_FALSE(near_event(events, 0.0125, 0.0, 0.001));

  // A run one tick late on every event: lateness exactly one tick.
  std::vector<Event> late = events;
  for (auto& e : late) e.t_s += 0.001;
  for (const auto& l : event_lateness(events, late, 0.0005, 0.0015)) {
    EXPECT_EQ(l.unmatched, 0U);
    EXPECT_NEAR(l.max_late_s, 0.001, 1e-15);
    EXPECT_NEAR(l.min_late_s, 0.001, 1e-15);
  }
}

TEST(Precision, TheDriftFitRecoversAKnownSlope) {
  // |difference| = 0.3 + 2.5 t with deterministic noise of +-0.1 over 10 hours.
  SplitMix64 rng(7);
  LineFit line;
  LineFit flat;
  for (int i = 0; i < 100000; ++i) {
    const double t = 10.0 * i / 100000.0;
    const double noise = rng.uniform(-0.1, 0.1);
    line.add(t, 0.3 + 2.5 * t + noise);
    flat.add(t, 0.3 + noise);
  }
  EXPECT_NEAR(line.slope(), 2.5, 1e-3);
  EXPECT_NEAR(line.intercept(), 0.3, 1e-2);
  EXPECT_GT(line.r_squared(), 0.99);
  EXPECT_NEAR(flat.slope(), 0.0, 1e-3);
  EXPECT_LT(flat.r_squared(), 1e-3);
}

/// E_obs - (-sum F . dx of the true motion) after `seconds` of the wall with the drift hand.
double observer_minus_port_work(int io_delay_ticks, bool quantised, double seconds) {
  const auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/wall.toml");
  HandScriptFile hand;
  hand.script = random_hand_script(15, seconds + 1.0);
  host_sim::PlanError error;
  hand.intent = *host_sim::HandIntent::plan(hand.script, error);
  SimConfig config;
  config.device.io_delay_ticks = io_delay_ticks;
  if (!quantised) {
    config.device.encoder_step_m = 0.0;
    config.device.force_step_n = 0.0;
  }
  auto session = SimSession::create(scene.value(), hand, config);
  EXPECT_TRUE(session) << (session ? "" : session.error());
  if (!session) return 0.0;
  double absorbed = 0.0, observed = 0.0;
  SimRecord last = session->step();
  for (std::int64_t k = 1; k < session->ticks_for(seconds); ++k) {
    const SimRecord r = session->step();
    absorbed -= dot(last.device_force_n, r.true_position_m - last.true_position_m);
    observed = r.frame.observed_energy_j;
    last = r;
  }
  return observed - absorbed;
}

TEST(Precision, TheDriftRunsPortWorkIsWhatTheObserverSeesWithoutDelayOrQuantisation) {
  // The drift run's reference for the passivity observer: -sum F_k . (x_(k+1) - x_k) with the
  // force the device applied and the handle's true motion. With no I/O delay and no encoder or
  // DAC steps the observer reads exactly that motion, so the two agree to rounding; the
  // Falcon's one-tick delay pairs each force with the wrong tick's motion, and the observer
  // reports more absorbed energy than the plant absorbed, growing with the motion.
  EXPECT_NEAR(observer_minus_port_work(0, false, 20.0), 0.0, 1e-9);
  const double one_tick = observer_minus_port_work(1, false, 20.0);
  const double two_ticks = observer_minus_port_work(2, false, 20.0);
  EXPECT_GT(one_tick, 1e-3);
  EXPECT_GT(two_ticks, 1.5 * one_tick);
}

TEST(Precision, TheTimedClosedLoopIsTheSimulationsClosedLoop) {
  // The closed-loop rows time ServoLoop::tick alone by splitting the simulated device at the
  // tick (the plant steps after it): the run must still be SimSession's, bit for bit, or the
  // cost would be measured on another loop than the error. Every tick is timed exactly once.
  HandScriptFile hand;
  hand.script = random_hand_script(15, 3.0);
  host_sim::PlanError error;
  hand.intent = *host_sim::HandIntent::plan(hand.script, error);
  for (const char* scene : {"cartoon_wall", "cliff"}) {
    const std::string path = paper_scene_path(TOONFORCE_SOURCE_DIR, scene);
    for (const ScalarKind kind : {ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16}) {
      const SimConfig config = closed_loop_sim_config(kind, 1000.0, 15);
      CycleHistogram cycles;
      const ClosedLoopRun run = closed_loop_run(path, hand, config, 2.0, &cycles);
      ASSERT_TRUE(run.refused.empty()) << run.refused;
      EXPECT_EQ(run.ticks, 2000U);
      EXPECT_EQ(cycles.count(), run.ticks);
      ASSERT_EQ(run.force_n.size(), run.ticks);
      auto session = SimSession::create(load_scene_file(path, kind).value(), hand, config);
      ASSERT_TRUE(session) << session.error();
      std::size_t differing = 0;
      double largest_force_n = 0.0;
      for (std::size_t k = 0; k < run.force_n.size(); ++k) {
        const SimRecord r = session->step();
        if (!(r.device_force_n == run.force_n[k]) || !(r.true_position_m == run.position_m[k])) ++differing;
        largest_force_n = std::max(largest_force_n, norm(r.device_force_n));
      }
      EXPECT_EQ(differing, 0U) << scene << " " << scalar_kind_name(kind);
      EXPECT_GT(largest_force_n, 0.5) << "the hand never pressed: nothing compared";
    }
  }
}

TEST(Precision, EveryClosedLoopRowTimesEveryTickOfItsRun) {
  // Loop CPU per simulated second is the mean tick times the ticks the run made: rate x
  // duration of them, each timed once (a deterministic count, not a time).
  const PrecisionOptions defaults;
  std::size_t rows = 0;
  for (const auto& row : wall_report().closed_loop) {
    ASSERT_TRUE(row.refused.empty()) << row.refused;
    EXPECT_EQ(row.loop_ticks, static_cast<std::uint64_t>(std::llround(row.rate_hz * defaults.closed_loop_s)))
        << row.scene << " " << scalar_kind_name(row.scalar) << " " << row.rate_hz;
    EXPECT_LE(row.loop_ticks_left_out, row.loop_ticks);
    EXPECT_TRUE(std::isnan(row.m3_instructions_per_s)) << "no Cortex-M3 figures were given";
    ++rows;
  }
  EXPECT_EQ(rows, 2U * 3U * defaults.rates_hz.size());  // wall and cartoon_wall, three scalars
}

TEST(Precision, TheCortexM3LoopTickIsReadFromReportMcusTable) {
  // report mcu's instructions table, as its generator prints it (two scenes): the every-stage
  // loop's mean is the fifth column, not the replay loop's third.
  McuCore m3;
  m3.run_table =
      "| scene | ticks | replay's loop tick, mean | max | every-stage loop tick, mean | max | effects + safety, mean | "
      "max | stack per tick [B] | loop state, replay's / every stage [B] |\n"
      "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n"
      "| wall | 3901 | 863 | 1422 | 1146 | 1241 | 283 | 854 | 580 | 336 / 648 |\n"
      "| cliff | 3901 | 1751 | 2859 | 1713 | 2819 | 998 | 2098 | 688 | 416 / 696 |\n";
  const auto loop = mcu_loop_mean_instructions(m3);
  ASSERT_EQ(loop.size(), 2U);
  EXPECT_EQ(loop[0], (std::pair<std::string, double>{"wall", 1146.0}));
  EXPECT_EQ(loop[1], (std::pair<std::string, double>{"cliff", 1713.0}));
  m3.run_table = "| scene | ticks |\n| --- | ---: |\n| wall | 3901 |\n";
  EXPECT_TRUE(mcu_loop_mean_instructions(m3).empty());

  // Given those, each q16.16 closed-loop row's M3 cost is the 1 kHz mean times its rate; the
  // other scalar types have none (their M3 images are not built).
  PrecisionOptions o;
  o.root = TOONFORCE_SOURCE_DIR;
  o.filter = "cliff";
  o.timing_ticks = 100;
  o.drift_hours = 0.0;
  o.closed_loop_s = 0.5;
  o.closed_loop_timing_runs = 1;
  o.m3_loop_instructions_per_tick = {{"wall", 1146.0}, {"cliff", 1713.0}};
  const auto r = run_precision(o);
  ASSERT_TRUE(r) << r.error();
  std::size_t q16_rows = 0;
  for (const auto& row : r->closed_loop) {
    if (row.scalar == ScalarKind::kQ16_16) {
      EXPECT_DOUBLE_EQ(row.m3_instructions_per_s, 1713.0 * row.rate_hz);
      ++q16_rows;
    } else {
      EXPECT_TRUE(std::isnan(row.m3_instructions_per_s));
    }
  }
  EXPECT_EQ(q16_rows, o.rates_hz.size());
}

TEST(Precision, TheDriftHandIsSeededVariedAndPlannable) {
  const auto a = random_hand_script(15, 60.0);
  const auto b = random_hand_script(15, 60.0);
  const auto c = random_hand_script(16, 60.0);
  ASSERT_EQ(a.segments.size(), b.segments.size());
  EXPECT_EQ(a.segments[5].to_m.x, b.segments[5].to_m.x);  // the same seed, the same hand
  EXPECT_NE(a.segments[5].to_m.x, c.segments[5].to_m.x);
  host_sim::PlanError error;
  EXPECT_TRUE(host_sim::HandIntent::plan(a, error)) << error.key << ": " << error.problem;
}

}  // namespace
}  // namespace toonforce::report
