// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/precision.hpp"

#include <time.h>

#include <algorithm>
#include <array>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/host_sim/sim_device.hpp"
#include "toonforce/host_sim/sim_driver.hpp"
#include "toonforce/report/scenario.hpp"
#include "toonforce/report/template.hpp"
#include "toonforce/report/templates.hpp"
#include "toonforce/report/tsc_clock.hpp"
#include "toonforce/report/workloads.hpp"
#include "toonforce/sim/closed_loop.hpp"

namespace toonforce::report {

namespace {

/// One tick of a compared pass: the force, and what the events are found from.
struct Forces {
  std::vector<Vec3<double>> force_n;  ///< of the last pass, one per tick
  std::vector<TickState> state;       ///< of the last pass, one per tick
  std::uint64_t fault_ticks = 0;      ///< in the last pass
};

std::int64_t ticks_per_pass(const KeyframePath& path, double rate_hz) {
  return static_cast<std::int64_t>(std::llround(path.period_s() * rate_hz));
}

/// Positions played to the loop as a device would give them (no velocity).
struct PlayedPositions {
  const Vec3<double>* position_m;
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = *position_m;
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>&) noexcept { return DeviceStatus::kOk; }
};

/// Replay's servo loop (effects.md §6 stages) at `rate_hz` on the scenario's positions.
template <Scalar S>
using SpecLoop = ServoLoop<PlayedPositions, RuntimeScene<S>, NullPins, kSpecStages>;

template <Scalar S>
RuntimeScene<S> scene_with(SceneDescription desc, std::optional<SineMethod> sine) {
  if (sine) override_sine(desc, *sine);
  return make_runtime_scene<S>(desc);
}

/// Where the events' values are in a scene's describe() output.
struct EventColumns {
  std::vector<std::size_t> impact_t;  ///< "surfaceN.impact_t"
  std::vector<std::size_t> cliff_state;
};
template <class SceneT>
EventColumns event_columns(const SceneT& scene) {
  EventColumns c;
  for (std::size_t i = 0; i < scene.effect_count(); ++i) {
    const EffectInfo info = scene.effect_info(i);
    for (std::size_t j = 0; j < info.values.size(); ++j) {
      if (info.values[j].name == "impact_t") c.impact_t.push_back(info.value_offset + j);
      if (info.key == "cliff" && info.values[j].name == "state") c.cliff_state.push_back(info.value_offset + j);
    }
  }
  return c;
}

/// The loop on `passes` passes of the scenario at `rate_hz`; the forces of the last.
template <Scalar S>
Forces run_passes(const SceneDescription& desc, std::string_view scene, double rate_hz, std::optional<SineMethod> sine,
                  int passes) {
  Vec3<double> x{};
  SpecLoop<S> loop(PlayedPositions{&x}, scene_with<S>(desc, sine), servo_config(desc, 1.0 / rate_hz));
  const EventColumns columns = event_columns(loop.scene());
  std::vector<double> values(loop.scene().value_count() + 1);
  const KeyframePath path = paper_scenario(scene);
  const std::int64_t n = ticks_per_pass(path, rate_hz);
  Forces out;
  out.force_n.reserve(static_cast<std::size_t>(n));
  out.state.reserve(static_cast<std::size_t>(n));
  for (std::int64_t k = 0; k < passes * n; ++k) {
    // k % n / rate: the same double for the same instant at every rate dividing the other.
    x = path.at(static_cast<double>(k % n) / rate_hz).position_m;
    const TickStatus r = loop.tick(k);
    if (k >= (passes - 1) * n) {
      out.force_n.push_back(to_double(loop.force()));
      if (r.faults) ++out.fault_ticks;
      TickState st;
      st.in_contact = loop.describe(values.data());
      for (const std::size_t i : columns.impact_t) {
        // The most recent trigger among the running impacts.
        if (!std::isnan(values[i]) && (std::isnan(st.impact_t_s) || values[i] < st.impact_t_s))
          st.impact_t_s = values[i];
      }
      for (const std::size_t i : columns.cliff_state) st.cliffs_fallen += values[i] > 0.5 ? 1 : 0;
      out.state.push_back(st);
    }
  }
  return out;
}

Forces run_any(const SceneDescription& desc, std::string_view scene, ScalarKind kind, double rate_hz,
               std::optional<SineMethod> sine, int passes = 2) {
  return with_scalar(
      kind, [&]<Scalar S>() { return run_passes<S>(desc, scene, rate_hz, sine, passes); },
      [](ScalarKind) { return Forces{}; });
}

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

/// Whether the tick at `t_s` of a run at `rate_hz` is away from the reference's events: outside
/// 2 of its ticks before and 2 ticks plus `settle_s` after each, and not while the reference's
/// impact transient runs (its timing shifts the whole transient by up to a tick).
struct Windows {
  const std::vector<Event>* events;
  const Forces* reference;
  double reference_rate_hz;
  double settle_s;
  bool away(double t_s, double rate_hz) const noexcept {
    const double tick = 1.0 / rate_hz;
    if (near_event(*events, t_s, 2.0 * tick, 2.0 * tick + settle_s)) return false;
    const auto i = static_cast<std::size_t>(std::llround(t_s * reference_rate_hz));
    return i >= reference->state.size() || std::isnan(reference->state[i].impact_t_s);
  }
};

/// |a - b| of two runs of one scene, `a` at rate_a, `b` at a multiple of it, compared at a's ticks.
struct Difference {
  double max_n = 0.0, rms_n = 0.0, away_max_n = 0.0, away_rms_n = 0.0;
};
Difference difference(const Forces& a, double rate_a, const Forces& b, double rate_b, const Windows& w) {
  Difference d;
  const auto step = static_cast<std::size_t>(std::llround(rate_b / rate_a));
  double sum = 0.0, away_sum = 0.0;
  std::size_t away_n = 0;
  for (std::size_t j = 0; j < a.force_n.size() && j * step < b.force_n.size(); ++j) {
    const double e = norm(a.force_n[j] - b.force_n[j * step]);
    d.max_n = std::max(d.max_n, e);
    sum += e * e;
    if (w.away(static_cast<double>(j) / rate_a, rate_a)) {
      d.away_max_n = std::max(d.away_max_n, e);
      away_sum += e * e;
      ++away_n;
    }
  }
  d.rms_n = a.force_n.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(a.force_n.size()));
  d.away_rms_n = away_n > 0 ? std::sqrt(away_sum / static_cast<double>(away_n)) : 0.0;
  return d;
}

std::vector<EventTiming> timing_of(const std::vector<Event>& reference, const Forces& run, double rate_hz) {
  std::vector<EventTiming> out;
  // Matched from one of the run's ticks early (to show an early event, which theory rules out
  // for contact) to 20 ms late: far more than any tick compared here, far less than the
  // scenarios' spacing of events of one kind.
  for (const Lateness& l : event_lateness(reference, find_events(run.state, 0.0, rate_hz), 1.0 / rate_hz, 0.02)) {
    out.push_back({l.kind, l.matched, l.unmatched, l.max_late_s, l.min_late_s, l.mean_late_s});
  }
  return out;
}

/// The analytic wall at `rate_hz` in scalar S: the wall scene's loop (spec stages), the handle
/// at x = 10 mm, z(t); two periods, the second compared with the closed form.
template <Scalar S>
AnalyticRow analytic_run(const SceneDescription& desc, const AnalyticWall& wall, double rate_hz) {
  Vec3<double> x{};
  SpecLoop<S> loop(PlayedPositions{&x}, make_runtime_scene<S>(desc), servo_config(desc, 1.0 / rate_hz));
  const auto n = static_cast<std::int64_t>(std::llround(wall.period_s() * rate_hz));
  std::vector<double> fz;
  fz.reserve(static_cast<std::size_t>(n));
  AnalyticRow row;
  row.rate_hz = rate_hz;
  for (std::int64_t k = 0; k < 2 * n; ++k) {
    const double t = static_cast<double>(k) / rate_hz;
    x = {0.01, 0.0, wall.height_m(t)};
    static_cast<void>(loop.tick(k));
    if (k >= n) {
      const Vec3<double> f = to_double(loop.force());
      // The wall's normal is +z: any x or y force is an error too.
      row.sampled_max_error_n = std::max(row.sampled_max_error_n, norm(f - Vec3<double>{0.0, 0.0, wall.force_n(t)}));
      fz.push_back(f.z + std::hypot(f.x, f.y));
    }
  }
  const double t0 = static_cast<double>(n) / rate_hz;
  const HeldError held = held_error(fz, t0, rate_hz, [&wall](double t) { return wall.force_n(t); });
  row.held_max_error_n = held.max_n;
  row.held_rms_error_n = held.rms_n;
  // The hold's error on a smooth force: F(t) - F(t_k) ~ F'(t_k)(t - t_k), whose RMS over a
  // tick is |F'| T / sqrt(3); over the period, T rms(F') / sqrt(3).
  double sum = 0.0;
  const int m = 100000;
  for (int i = 0; i < m; ++i) {
    const double r = wall.force_rate_n_per_s((i + 0.5) / m * wall.period_s());
    sum += r * r;
  }
  row.held_rms_theory_n = std::sqrt(sum / m) / rate_hz / std::sqrt(3.0);
  return row;
}

bool scene_selected(std::string_view scene, const std::string& filter) { return selected(std::string(scene), filter); }

std::string sci(double v) { return v == 0.0 ? "0" : fmt::format("{:.2e}", v); }
std::string order_text(double p) { return std::isnan(p) ? std::string("-") : fmt::format("{:.2f}", p); }

/// The drift run of one scene: double, float and Q16.16 closed loops in lock-step on the same
/// seeded hand, each difference fitted against time.
Result<std::vector<DriftSeries>> drift_run(const std::string& path, std::string_view scene, const PrecisionOptions& o) {
  const double duration_s = o.drift_hours * 3600.0;
  HandScriptFile hand;
  hand.script = random_hand_script(o.drift_seed, duration_s + 1.0);
  host_sim::PlanError plan_error;
  auto intent = host_sim::HandIntent::plan(hand.script, plan_error);
  if (!intent)
    return Error{fmt::format("drift hand: segment {}: {}: {}", plan_error.segment, plan_error.key, plan_error.problem)};
  hand.intent = std::move(*intent);

  constexpr std::array<ScalarKind, 3> kKinds{ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16};
  std::vector<SimSession> sessions;
  for (const ScalarKind kind : kKinds) {
    auto desc = load_scene_file(path, kind);
    if (!desc) return Error{desc.error()};
    SimConfig config;
    config.scalar = kind;
    config.seed = o.drift_seed;
    config.plant.period_s = 1.0 / o.drift_rate_hz;
    auto session = SimSession::create(desc.value(), hand, config);
    if (!session) return Error{session.error()};
    sessions.push_back(std::move(session.value()));
  }
  const std::int64_t total = sessions[0].ticks_for(duration_s);
  constexpr std::size_t kBuckets = 12;
  const std::int64_t per_bucket = std::max<std::int64_t>(
      1, (total + static_cast<std::int64_t>(kBuckets) - 1) / static_cast<std::int64_t>(kBuckets));
  // Series: 0-2 observer against port work per scalar; 3-4 E_obs of float, Q16 against double;
  // 5-6 force of float, Q16 against double.
  std::vector<DriftSeries> series;
  const auto add_series = [&series](ScalarKind kind, const char* quantity, const char* unit) {
    DriftSeries d;
    d.scalar = kind;
    d.quantity = std::string(quantity);
    d.unit = std::string(unit);
    series.push_back(std::move(d));
  };
  for (const ScalarKind kind : kKinds) add_series(kind, "observer - port work", "J");
  add_series(ScalarKind::kFloat, "observer vs double", "J");
  add_series(ScalarKind::kQ16_16, "observer vs double", "J");
  add_series(ScalarKind::kFloat, "force vs double", "N");
  add_series(ScalarKind::kQ16_16, "force vs double", "N");
  std::vector<LineFit> fits(series.size());
  std::vector<double> bucket(series.size(), 0.0);
  std::array<double, 3> port_absorbed_j{};  // -sum F . dx of the true motion
  double exchanged_j = 0.0;                 // sum |F . dx| of the double run
  std::array<Vec3<double>, 3> last_x{};
  std::array<Vec3<double>, 3> last_f{};
  std::array<bool, 3> started{};
  const double start = cpu_seconds();
  const double period = 1.0 / o.drift_rate_hz;
  for (std::int64_t k = 0; k < total; ++k) {
    std::array<SimRecord, 3> rec;
    for (std::size_t i = 0; i < 3; ++i) {
      rec[i] = sessions[i].step();
      // The force the device applied over the last tick, held (zero-order), times the handle's
      // true displacement over it: exactly the integral of F . v over that tick.
      if (started[i]) {
        const double work = dot(last_f[i], rec[i].true_position_m - last_x[i]);
        port_absorbed_j[i] -= work;
        if (i == 0) exchanged_j += std::abs(work);
      }
      last_x[i] = rec[i].true_position_m;
      last_f[i] = rec[i].device_force_n;
      started[i] = true;
    }
    const double t_h = static_cast<double>(k + 1) * period / 3600.0;
    std::array<double, 7> signed_d{};
    for (std::size_t i = 0; i < 3; ++i) signed_d[i] = rec[i].frame.observed_energy_j - port_absorbed_j[i];
    for (std::size_t i = 0; i < 2; ++i) {
      signed_d[3 + i] = rec[1 + i].frame.observed_energy_j - rec[0].frame.observed_energy_j;
      signed_d[5 + i] = norm(rec[1 + i].frame.force_n - rec[0].frame.force_n);
    }
    for (std::size_t i = 0; i < 7; ++i) {
      const double d = std::abs(signed_d[i]);
      fits[i].add(t_h, d);
      bucket[i] = std::max(bucket[i], d);
      series[i].final_abs = d;
      series[i].final_signed = signed_d[i];
    }
    if ((k + 1) % per_bucket == 0 || k + 1 == total) {
      for (std::size_t i = 0; i < 7; ++i) {
        series[i].bucket_end_h.push_back(t_h);
        series[i].max_abs.push_back(bucket[i]);
        bucket[i] = 0.0;
      }
    }
  }
  const double cpu = cpu_seconds() - start;
  for (std::size_t i = 0; i < 7; ++i) {
    series[i].scene = std::string(scene);
    series[i].slope_per_h = fits[i].slope();
    series[i].intercept = fits[i].intercept();
    series[i].r_squared = fits[i].r_squared();
    series[i].ticks = static_cast<std::uint64_t>(total);
    series[i].cpu_s = cpu;
    series[i].exchanged_j = exchanged_j;
  }
  return series;
}

/// The simulated device split at the servo loop's tick, so that a counter pair can hold the
/// loop's tick alone: the loop reads the reading the device gave before the tick and leaves its
/// force here; the plant steps with it after the tick (SimDevice::write), outside the timed
/// region. Its I/O is then a copy each way, as cheap as the scripted device's the latency
/// report times. SimDevice's read and write always succeed, so the loop sees what it would see
/// on the SimDevice itself: the same run, tick for tick (test
/// Precision.TheTimedClosedLoopIsTheSimulationsClosedLoop).
struct HeldIo {
  DeviceReading reading;
  DeviceStatus read_status = DeviceStatus::kOk;
  Vec3<double> force_n;
};
struct HeldDevice {
  HeldIo* io;
  DeviceStatus read(DeviceReading& r) noexcept {
    r = io->reading;
    return io->read_status;
  }
  DeviceStatus write(const Vec3<double>& force_n) noexcept {
    io->force_n = force_n;
    return DeviceStatus::kOk;
  }
};
template <Scalar S>
using HeldLoop = ServoLoop<HeldDevice, RuntimeScene<S>>;

/// One tick of the loop between the counter reads, as the latency report's cases time theirs
/// (flattened: the tick's code inlined here, the reads around nothing else). Not inlined into
/// the run, so the plant's code stays out of it.
template <Scalar S>
[[gnu::noinline, gnu::flatten]] std::uint64_t timed_tick(HeldLoop<S>& loop, std::int64_t k) noexcept {
  const std::uint64_t start = tsc_begin();
  const TickStatus status = loop.tick(k);
  keep(status);
  const std::uint64_t end = tsc_end();
  return end - start;
}

template <Scalar S>
ClosedLoopRun closed_run_of(const SceneDescription& desc, const HandScriptFile& hand, const SimConfig& config,
                            double duration_s, CycleHistogram* cycles) {
  ClosedLoopRun run;
  auto device = host_sim::SimDevice::create(config.device, hand.intent, config.plant, config.seed);
  if (!device) {
    run.refused = device.error();
    return run;
  }
  // SimSession's configuration: the scene's, the device's figures filling the gaps.
  const ServoConfig servo = with_device(servo_config(desc, config.plant.period_s),
                                        host_sim::device_info(config.device, config.plant.period_s));
  if (const std::string problems = check_servo_config(servo); !problems.empty()) {
    run.refused = fmt::format("{}: the servo configuration does not work:\n{}", desc.source, problems);
    return run;
  }
  host_sim::SimDevice& sim = device.value();
  HeldIo io;
  HeldLoop<S> loop(HeldDevice{&io}, make_runtime_scene<S>(desc), servo);
  const std::int64_t n = std::llround(duration_s / config.plant.period_s);  // SimSession::ticks_for
  run.force_n.reserve(static_cast<std::size_t>(n));
  run.position_m.reserve(static_cast<std::size_t>(n));
  for (std::int64_t k = 0; k < n; ++k) {
    const std::int64_t tick = sim.tick();
    run.position_m.push_back(sim.plant().position_m());
    io.read_status = sim.read(io.reading);
    const std::uint64_t c = timed_tick<S>(loop, tick);
    if (cycles != nullptr) cycles->add(c);
    static_cast<void>(sim.write(io.force_n));
    run.force_n.push_back(sim.applied_force_n());
  }
  run.ticks = static_cast<std::uint64_t>(n);
  return run;
}

/// A closed-loop row's timed runs: the least disturbed (smallest mean) kept whole.
struct ClosedTiming {
  std::size_t row;
  SimConfig config;
  CycleHistogram best;
  int runs = 1;
  double min_mean_cycles = best.mean_in_bins();
  double max_mean_cycles = min_mean_cycles;
  void add(CycleHistogram cycles) {
    const double mean = cycles.mean_in_bins();
    ++runs;
    max_mean_cycles = std::max(max_mean_cycles, mean);
    if (mean < min_mean_cycles) {
      min_mean_cycles = mean;
      best = std::move(cycles);
    }
  }
};

/// Run `a` at rate_a against `b` at a multiple of it: the held force at every tick of b, the
/// position at a's ticks (RMS and max).
struct ClosedDifference {
  double force_rms_n = 0.0, force_max_n = 0.0, position_rms_m = 0.0, position_max_m = 0.0;
};
ClosedDifference closed_difference(const ClosedLoopRun& a, double rate_a, const ClosedLoopRun& b, double rate_b) {
  ClosedDifference d;
  const auto step = static_cast<std::size_t>(std::llround(rate_b / rate_a));
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < b.force_n.size() && i / step < a.force_n.size(); ++i) {
    const double e = norm(a.force_n[i / step] - b.force_n[i]);
    d.force_max_n = std::max(d.force_max_n, e);
    sum += e * e;
    ++n;
  }
  d.force_rms_n = n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
  sum = 0.0;
  n = 0;
  for (std::size_t j = 0; j < a.position_m.size() && j * step < b.position_m.size(); ++j) {
    const double e = norm(a.position_m[j] - b.position_m[j * step]);
    d.position_max_m = std::max(d.position_max_m, e);
    sum += e * e;
    ++n;
  }
  d.position_rms_m = n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
  return d;
}

}  // namespace

Result<std::vector<Vec3<double>>> scenario_forces(const std::string& root, std::string_view scene, double rate_hz) {
  auto desc = load_scene_file(paper_scene_path(root, scene), ScalarKind::kDouble);
  if (!desc) return Error{desc.error()};
  return run_any(desc.value(), scene, ScalarKind::kDouble, rate_hz, SineMethod::kLibrary).force_n;
}

SimConfig closed_loop_sim_config(ScalarKind kind, double rate_hz, std::uint64_t seed) {
  SimConfig config;
  config.scalar = kind;
  config.seed = seed;
  config.plant.period_s = 1.0 / rate_hz;
  // No encoder or DAC steps: they are the device's, the same for every scalar type and rate, and
  // they do not converge as the rate grows (a 20 um step differenced over a shorter tick is a
  // larger velocity spike), so a reference with them has no error of its own to state.
  config.device.encoder_step_m = 0.0;
  config.device.force_step_n = 0.0;
  return config;
}

ClosedLoopRun closed_loop_run(const std::string& scene_path, const HandScriptFile& hand, const SimConfig& config,
                              double duration_s, CycleHistogram* cycles) {
  auto desc = load_scene_file(scene_path, config.scalar);
  if (!desc) {
    ClosedLoopRun run;
    run.refused = desc.error();
    return run;
  }
  return with_scalar(
      config.scalar, [&]<Scalar S>() { return closed_run_of<S>(desc.value(), hand, config, duration_s, cycles); },
      [](ScalarKind kind) {
        ClosedLoopRun run;
        run.refused = fmt::format("this build has no servo loop in {}", scalar_kind_name(kind));
        return run;
      });
}

host_sim::HandScript random_hand_script(std::uint64_t seed, double duration_s) {
  SplitMix64 rng(seed);
  host_sim::HandScript script;
  script.name = fmt::format("random hand, seed {}", seed);
  script.start_m = {-0.03, 0.0, 0.005};
  Vec3<double> at = script.start_m;
  double t = 0.0;
  while (t < duration_s) {
    host_sim::HandSegment s;
    if (rng.uniform(0.0, 1.0) < 0.2) {
      // A hold, pressing down with up to 2 N (into the ground if the hand is on it).
      s.kind = host_sim::SegmentKind::kHold;
      s.duration_s = rng.uniform(0.05, 0.4);
      s.force_n = rng.uniform(0.0, 2.0);
      s.force_ramp_s = 0.02;
    } else {
      // A minimum-jerk move to a random point: across x (the cliff's gap is x in [0, 0.02]),
      // from 8 mm above the ground to 6 mm into it, at a mean speed of 1 cm/s to 30 cm/s, so
      // some entries are fast enough to trigger an impact (0.05 m/s) and some too slow.
      s.kind = host_sim::SegmentKind::kMove;
      s.to_m = {rng.uniform(-0.04, 0.045), rng.uniform(-0.01, 0.01), rng.uniform(-0.006, 0.008)};
      const double speed = rng.uniform(0.01, 0.3);
      s.duration_s = std::max(0.05, norm(s.to_m - at) / speed);
      if (rng.uniform(0.0, 1.0) < 0.25) {
        // A tap: up 3 to 8 mm above the ground (re-arming an impact), then straight down 4 to
        // 6 mm into it in 40 to 80 ms (entering at 0.1 m/s and more: over the cartoon wall's
        // 0.05 m/s impact threshold).
        host_sim::HandSegment lift;
        lift.kind = host_sim::SegmentKind::kMove;
        lift.to_m = {at.x, at.y, rng.uniform(0.003, 0.008)};
        lift.duration_s = rng.uniform(0.1, 0.2);
        t += *lift.duration_s;
        script.segments.push_back(lift);
        s.to_m = {at.x, at.y, rng.uniform(-0.006, -0.004)};
        s.duration_s = rng.uniform(0.04, 0.08);
      }
      at = s.to_m;
    }
    t += *s.duration_s;
    script.segments.push_back(s);
  }
  return script;
}

Result<PrecisionReport> run_precision(const PrecisionOptions& options, const Progress& progress) {
  const auto say = [&progress](const std::string& line) {
    if (progress) progress(line);
  };
  PrecisionReport report;
  report.options = options;
  report.machine = machine_info();
  report.load_before = load_average();
  if (options.reference_rates_hz.empty()) return Error{"no reference rate"};
  const double reference_rate = options.reference_rates_hz.back();
  const auto divides = [&](double rate) {
    const double ratio = reference_rate / rate;
    return rate > 0.0 && std::abs(ratio - std::round(ratio)) <= 1e-9;
  };
  for (const double rate : options.rates_hz) {
    if (!divides(rate))
      return Error{fmt::format("rate {} Hz does not divide the reference rate {} Hz", rate, reference_rate)};
  }
  for (std::size_t i = 1; i < options.reference_rates_hz.size(); ++i) {
    if (options.reference_rates_hz[i] != 2.0 * options.reference_rates_hz[i - 1]) {
      return Error{"each reference rate must be twice the one before"};
    }
  }
  report.clock = calibrate();

  // The analytic wall: the wall scene's law against its closed form.
  if (scene_selected("wall", options.filter)) {
    auto desc = load_scene_file(paper_scene_path(options.root, "wall"), ScalarKind::kDouble);
    if (!desc) return Error{desc.error()};
    const auto& surfaces = desc->of<RuntimeSurface>();
    if (!surfaces.empty()) report.analytic_wall.stiffness_n_per_m = surfaces.front().wall.stiffness_n_per_m;
    std::vector<double> rates = options.rates_hz;
    rates.insert(rates.end(), options.reference_rates_hz.begin(), options.reference_rates_hz.end());
    for (const ScalarKind kind : {ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16}) {
      auto d = load_scene_file(paper_scene_path(options.root, "wall"), kind);
      if (!d) return Error{d.error()};
      say(fmt::format("analytic wall: {}", scalar_kind_name(kind)));
      for (std::size_t i = 0; i < rates.size(); ++i) {
        AnalyticRow row = with_scalar(
            kind, [&]<Scalar S>() { return analytic_run<S>(d.value(), report.analytic_wall, rates[i]); },
            [](ScalarKind) { return AnalyticRow{}; });
        row.scalar = kind;
        row.held_rms_order = i == 0 ? std::nan("")
                                    : observed_order(report.analytic.back().held_rms_error_n, row.held_rms_error_n) /
                                          std::log2(rates[i] / rates[i - 1]);
        report.analytic.push_back(row);
      }
    }
  }

  CycleHistogram histogram;
  // The servo loop with every stage on the scripted scenario: what the closed loop ticks.
  std::vector<std::unique_ptr<TickCase>> loop_cases;
  if (options.closed_loop_s > 0.0) {
    auto cases = make_cases(options.root);
    if (!cases) return Error{cases.error()};
    for (auto& c : cases.value()) {
      if (c->info().level == Level::kLoop && c->info().form == "runtime") loop_cases.push_back(std::move(c));
    }
  }
  for (const std::string_view scene : kPaperScenes) {
    if (!scene_selected(scene, options.filter)) continue;
    const std::string path = paper_scene_path(options.root, scene);
    auto reference_desc = load_scene_file(path, ScalarKind::kDouble);
    if (!reference_desc) return Error{reference_desc.error()};

    // The reference ladder, finest last: the reference.
    std::vector<Forces> ladder;
    for (const double rate : options.reference_rates_hz) {
      say(fmt::format("{}: reference ladder (double, library sine, {:g} Hz)", scene, rate));
      ladder.push_back(run_any(reference_desc.value(), scene, ScalarKind::kDouble, rate, SineMethod::kLibrary));
    }
    const Forces& reference = ladder.back();
    const std::vector<Event> events = find_events(reference.state, 0.0, reference_rate);
    const ServoConfig config = servo_config(reference_desc.value(), 1.0 / reference_rate);
    SceneConvergence conv;
    conv.scene = std::string(scene);
    // After an event the safety stage ramps the force at its rate limit: up to the clamp's
    // worth of ramp is event timing, not the step.
    conv.settle_s = config.limits.has_max_force && config.limits.has_max_force_rate
                        ? config.limits.max_force_n / config.limits.max_force_rate_n_per_s
                        : 0.0;
    const Windows windows{&events, &reference, reference_rate, conv.settle_s};
    for (const EventKind kind :
         {EventKind::kContactOnset, EventKind::kContactEnd, EventKind::kImpactTrigger, EventKind::kCliffFall}) {
      const auto c = static_cast<std::size_t>(
          std::count_if(events.begin(), events.end(), [kind](const Event& e) { return e.kind == kind; }));
      if (c > 0) conv.event_counts.emplace_back(kind, c);
    }
    for (std::size_t i = 0; i + 1 < ladder.size(); ++i) {
      const double rate = options.reference_rates_hz[i];
      const Difference d = difference(ladder[i], rate, ladder[i + 1], 2.0 * rate, windows);
      ConvergenceStep step{rate,         d.max_n,      d.rms_n,      d.away_max_n,
                           d.away_rms_n, std::nan(""), std::nan(""), std::nan("")};
      if (i > 0) {
        step.rms_order = observed_order(conv.steps.back().rms_diff_n, step.rms_diff_n);
        step.away_rms_order = observed_order(conv.steps.back().away_rms_diff_n, step.away_rms_diff_n);
        step.away_max_order = observed_order(conv.steps.back().away_max_diff_n, step.away_max_diff_n);
      }
      conv.steps.push_back(step);
    }
    if (!conv.steps.empty()) {
      const ConvergenceStep& last = conv.steps.back();
      const ConvergenceStep& before = conv.steps.size() > 1 ? conv.steps[conv.steps.size() - 2] : last;
      conv.reference_away_rms_error_n = ladder_error(last.away_rms_diff_n, before.away_rms_order, last.away_rms_order);
      conv.reference_away_max_error_n = ladder_error(last.away_max_diff_n, before.away_max_order, last.away_max_order);
      conv.reference_max_diff_n = last.max_diff_n;
      conv.reference_rms_error_n = ladder_error(last.rms_diff_n, before.rms_order, last.rms_order);
      conv.reference_max_error_n = last.max_diff_n;
    }
    if (options.reference_check_factor > 1.0) {
      // The ladder's last step can miss an event's error: at 160 and 320 kHz an event may land
      // alike (realistic_friction's contact end did), and the difference is then no bound. So
      // the reference is checked against a run at a multiple of its rate, and its error at the
      // ticks near events is bounded from how far it can have moved an event.
      const double factor = options.reference_check_factor;
      conv.check_rate_hz = reference_rate * factor;
      say(fmt::format("{}: reference check (double, library sine, {:g} Hz)", scene, conv.check_rate_hz));
      const Forces check =
          run_any(reference_desc.value(), scene, ScalarKind::kDouble, conv.check_rate_hz, SineMethod::kLibrary);
      const Difference d = difference(reference, reference_rate, check, conv.check_rate_hz, windows);
      conv.check = {reference_rate, d.max_n,      d.rms_n,      d.away_max_n,
                    d.away_rms_n,   std::nan(""), std::nan(""), std::nan("")};
      const double tick_s = 1.0 / reference_rate;
      for (const Lateness& l :
           event_lateness(find_events(check.state, 0.0, conv.check_rate_hz), events, 2.0 * tick_s, 0.02)) {
        conv.check_unmatched_events += l.unmatched;
        if (l.matched > 0) {
          conv.check_event_shift_s =
              std::max({conv.check_event_shift_s, std::abs(l.max_late_s), std::abs(l.min_late_s)});
        }
      }
      // The check run is itself late by up to its own share: first order, the reference's shift
      // is factor / (factor - 1) times the one between them; never less than one tick.
      conv.event_shift_bound_s = std::max(tick_s, conv.check_event_shift_s * factor / (factor - 1.0));
      const double shift_ticks = conv.event_shift_bound_s / tick_s;
      const auto whole_ticks = static_cast<std::size_t>(std::ceil(shift_ticks - 1e-9));
      double event_sum = 0.0;
      const std::size_t n = reference.force_n.size();
      for (std::size_t i = 0; i < n; ++i) {
        // The ticks the "away" norms leave out: near an event, or while an impact transient runs
        // (its trigger's timing shifts all of it).
        if (windows.away(static_cast<double>(i) * tick_s, reference_rate)) continue;
        // Moved by up to `shift_ticks` ticks either way, the force at tick i is off by at most
        // its change over that many ticks on either side: over the whole ticks that cover the
        // shift, in proportion (exact on a ramp at the rate limit, the case that matters).
        double change = 0.0;
        const std::size_t lo = i >= whole_ticks ? i - whole_ticks : 0;
        const std::size_t hi = std::min(n - 1, i + whole_ticks);
        for (std::size_t j = lo; j <= hi; ++j)
          change = std::max(change, norm(reference.force_n[j] - reference.force_n[i]));
        change *= shift_ticks / static_cast<double>(whole_ticks);
        conv.event_max_bound_n = std::max(conv.event_max_bound_n, change);
        event_sum += change * change;
      }
      conv.event_rms_bound_n = n > 0 ? std::sqrt(event_sum / static_cast<double>(n)) : 0.0;
      // Convergence of order p: the reference is off by f^p / (f^p - 1) times its difference to
      // a run f times finer. p is the ladder's observed order where its last two agree (as for
      // Richardson), else 1: events and the velocity estimate converge no faster.
      const auto scale_for = [factor](double previous_order, double order) {
        const double p = std::abs(order - previous_order) <= 0.5 && order > 1.0 ? order : 1.0;
        return std::pow(factor, p) / (std::pow(factor, p) - 1.0);
      };
      const double scale = factor / (factor - 1.0);
      if (!conv.steps.empty()) {
        const ConvergenceStep& last = conv.steps.back();
        const ConvergenceStep& before = conv.steps.size() > 1 ? conv.steps[conv.steps.size() - 2] : last;
        conv.reference_away_rms_error_n = std::max(
            conv.reference_away_rms_error_n, scale_for(before.away_rms_order, last.away_rms_order) * d.away_rms_n);
        conv.reference_away_max_error_n = std::max(
            conv.reference_away_max_error_n, scale_for(before.away_max_order, last.away_max_order) * d.away_max_n);
      } else {
        conv.reference_away_rms_error_n = scale * d.away_rms_n;
        conv.reference_away_max_error_n = scale * d.away_max_n;
      }
      conv.reference_rms_error_n = std::max({conv.reference_rms_error_n, scale * d.rms_n,
                                             std::hypot(conv.reference_away_rms_error_n, conv.event_rms_bound_n)});
      conv.reference_max_error_n = std::max(
          {conv.reference_max_error_n, scale * d.max_n, conv.reference_away_max_error_n + conv.event_max_bound_n});
    }
    report.convergence.push_back(conv);

    // Double with the library sine at each rate: the baseline of the same-rate column.
    std::vector<Forces> same_rate;
    for (const double rate : options.rates_hz) {
      same_rate.push_back(run_any(reference_desc.value(), scene, ScalarKind::kDouble, rate, SineMethod::kLibrary));
    }
    const auto& surfaces = reference_desc->of<RuntimeSurface>();
    const bool has_impact =
        std::any_of(surfaces.begin(), surfaces.end(), [](const auto& s) { return s.impact.enabled; });

    for (const ScalarKind kind : {ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16}) {
      auto desc = load_scene_file(path, kind);
      if (!desc) return Error{desc.error()};
      std::vector<std::optional<SineMethod>> sines{std::nullopt};
      if (has_impact) {
        sines.clear();
        for (const SineMethod m : {SineMethod::kLibrary, SineMethod::kPolynomial, SineMethod::kTable}) {
          if (m == SineMethod::kLibrary && kind == ScalarKind::kQ16_16) continue;
          sines.emplace_back(m);
        }
      }
      for (const auto& sine : sines) {
        for (std::size_t r = 0; r < options.rates_hz.size(); ++r) {
          const double rate = options.rates_hz[r];
          PrecisionRow row;
          row.scene = std::string(scene);
          row.scalar = kind;
          row.rate_hz = rate;
          row.sine = sine;
          const auto step = static_cast<std::size_t>(std::llround(reference_rate / rate));
          const Forces test = run_any(desc.value(), scene, kind, rate, sine);
          const Difference d = difference(test, rate, reference, reference_rate, windows);
          row.max_error_n = d.max_n;
          row.rms_error_n = d.rms_n;
          row.away_max_error_n = d.away_max_n;
          row.away_rms_error_n = d.away_rms_n;
          for (std::size_t j = 0; j < test.force_n.size(); ++j) {
            row.same_rate_max_error_n =
                std::max(row.same_rate_max_error_n, norm(test.force_n[j] - same_rate[r].force_n[j]));
          }
          const HeldDifference held = held_difference(test.force_n, reference.force_n, step, [&](std::size_t i) {
            return windows.away(static_cast<double>(i) / reference_rate, rate);
          });
          row.held_max_error_n = held.max_n;
          row.held_rms_error_n = held.rms_n;
          row.held_away_rms_error_n = held.away_rms_n;
          row.fault_ticks = test.fault_ticks;
          row.events = timing_of(events, test, rate);
          if (kind != ScalarKind::kDouble || (sine && *sine != SineMethod::kLibrary)) {
            // Each of double's events against this run's nearest of the same kind (within 5
            // ticks): the ones on another tick.
            const std::vector<Event> own = find_events(test.state, 0.0, rate);
            const KeyframePath scenario = paper_scenario(scene);
            for (const Event& e : find_events(same_rate[r].state, 0.0, rate)) {
              double best = std::numeric_limits<double>::infinity();
              for (const Event& o : own) {
                if (o.kind == e.kind && std::abs(o.t_s - e.t_s) < std::abs(best)) best = o.t_s - e.t_s;
              }
              if (std::abs(best) > 0.5 / rate && std::abs(best) < 5.5 / rate) {
                row.same_rate_event_shifts.push_back({e.kind, e.t_s, best, scenario.at(e.t_s + best).position_m});
              }
            }
          }

          auto timed = make_spec_loop_case(options.root, scene, kind, rate, sine);
          if (!timed) return Error{timed.error()};
          say(fmt::format("timing {}", timed.value()->info().id));
          timed.value()->run(std::max<std::uint64_t>(timed.value()->info().ticks_per_pass, 10000));
          histogram = CycleHistogram();
          timed.value()->time(options.timing_ticks, histogram);
          const double overhead = report.clock.overhead_mean_cycles;
          row.mean_ns = std::max(0.0, histogram.mean_in_bins() - overhead) / report.clock.cycles_per_ns;
          const std::uint64_t median = histogram.percentile(0.5);
          row.median_ns =
              static_cast<double>(median > report.clock.overhead_cycles ? median - report.clock.overhead_cycles : 0) /
              report.clock.cycles_per_ns;
          report.rows.push_back(row);
        }
      }
    }

    if (options.closed_loop_s > 0.0 && !options.closed_loop_reference_rates_hz.empty()) {
      HandScriptFile hand;
      hand.script = random_hand_script(options.drift_seed, options.closed_loop_s + 1.0);
      host_sim::PlanError plan_error;
      auto intent = host_sim::HandIntent::plan(hand.script, plan_error);
      if (!intent) return Error{fmt::format("closed-loop hand: {}: {}", plan_error.key, plan_error.problem)};
      hand.intent = std::move(*intent);
      const auto& ladder_rates = options.closed_loop_reference_rates_hz;
      std::vector<ClosedLoopRun> cl_ladder;
      for (const double rate : ladder_rates) {
        say(fmt::format("{}: closed loop, double reference cl_ladder at {:g} Hz", scene, rate));
        cl_ladder.push_back(closed_loop_run(
            path, hand, closed_loop_sim_config(ScalarKind::kDouble, rate, options.drift_seed), options.closed_loop_s));
        if (!cl_ladder.back().refused.empty()) return Error{cl_ladder.back().refused};
      }
      ClosedLoopConvergence cl_conv;
      cl_conv.scene = std::string(scene);
      for (std::size_t i = 0; i + 1 < cl_ladder.size(); ++i) {
        const ClosedDifference d =
            closed_difference(cl_ladder[i], ladder_rates[i], cl_ladder[i + 1], ladder_rates[i + 1]);
        ClosedLoopStep step{ladder_rates[i], d.force_rms_n, d.position_rms_m, std::nan(""), std::nan("")};
        if (i > 0) {
          step.force_order = observed_order(cl_conv.steps.back().force_rms_diff_n, step.force_rms_diff_n);
          step.position_order = observed_order(cl_conv.steps.back().position_rms_diff_m, step.position_rms_diff_m);
        }
        cl_conv.steps.push_back(step);
      }
      if (!cl_conv.steps.empty()) {
        // Two steps give one order: Richardson with it (ladder_error needs two; the closed loop's
        // ladder is shorter, each run being the whole simulation).
        cl_conv.reference_force_rms_error_n =
            richardson_error(cl_conv.steps.back().force_rms_diff_n, cl_conv.steps.back().force_order);
        cl_conv.reference_position_rms_error_m =
            richardson_error(cl_conv.steps.back().position_rms_diff_m, cl_conv.steps.back().position_order);
      }
      report.closed_loop_convergence.push_back(cl_conv);
      const double closed_reference_rate = ladder_rates.back();
      std::vector<ClosedTiming> timings;
      for (const ScalarKind kind : {ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16}) {
        // For comparison: the loop's tick with every stage timed alone on the scripted scenario
        // (what this table's cost was before it was measured inside the closed loop).
        double loop_ns = 0.0;
        const std::string id = fmt::format("loop/{}/{}/runtime", scene, scalar_kind_name(kind));
        for (const auto& c : loop_cases) {
          if (c->info().id != id) continue;
          say(fmt::format("timing {}", id));
          c->run(std::max<std::uint64_t>(c->info().ticks_per_pass, 10000));
          histogram = CycleHistogram();
          c->time(options.timing_ticks, histogram);
          loop_ns =
              std::max(0.0, histogram.mean_in_bins() - report.clock.overhead_mean_cycles) / report.clock.cycles_per_ns;
        }
        for (const double rate : options.rates_hz) {
          ClosedLoopRow row;
          row.scene = std::string(scene);
          row.scalar = kind;
          row.rate_hz = rate;
          row.scripted_mean_ns = loop_ns;
          const double ratio = closed_reference_rate / rate;
          if (std::abs(ratio - std::round(ratio)) > 1e-9) {
            row.refused = fmt::format("{:g} Hz does not divide the reference's {:g} Hz", rate, closed_reference_rate);
          } else {
            say(fmt::format("{}: closed loop, {} at {:g} Hz", scene, scalar_kind_name(kind), rate));
            const SimConfig sim_config = closed_loop_sim_config(kind, rate, options.drift_seed);
            CycleHistogram cycles;
            const ClosedLoopRun run = closed_loop_run(path, hand, sim_config, options.closed_loop_s, &cycles);
            row.refused = run.refused;
            if (run.refused.empty()) {
              if (kind == ScalarKind::kQ16_16) {
                for (const auto& [m3_scene, instructions] : options.m3_loop_instructions_per_tick) {
                  if (m3_scene == scene) row.m3_instructions_per_s = instructions * rate;
                }
              }
              const ClosedDifference d = closed_difference(run, rate, cl_ladder.back(), closed_reference_rate);
              row.force_rms_error_n = d.force_rms_n;
              row.force_max_error_n = d.force_max_n;
              row.position_rms_error_m = d.position_rms_m;
              row.position_max_error_m = d.position_max_m;
              timings.push_back({report.closed_loop.size(), sim_config, std::move(cycles)});
            }
          }
          report.closed_loop.push_back(row);
        }
      }
      // The same runs again, only for their time (deterministic: the same ticks and branches),
      // in rounds over the scene's configurations so that a slow spell of the VM falls on
      // different ones; each row keeps its least disturbed run (the smallest mean).
      for (int round = 1; round < options.closed_loop_timing_runs; ++round) {
        say(fmt::format("{}: closed loop, timing round {} of {}", scene, round + 1, options.closed_loop_timing_runs));
        for (auto& t : timings) {
          CycleHistogram cycles;
          static_cast<void>(closed_loop_run(path, hand, t.config, options.closed_loop_s, &cycles));
          t.add(std::move(cycles));
        }
      }
      for (auto& t : timings) {
        const auto mean_ns = [&report](double mean_cycles) {
          return std::max(0.0, mean_cycles - report.clock.overhead_mean_cycles) / report.clock.cycles_per_ns;
        };
        // The empty measurement's cost off each tick: its mean from the mean, its median from
        // the percentiles (as the latency report does).
        const auto net_ns = [&report](std::uint64_t cycles) {
          const std::uint64_t overhead = report.clock.overhead_cycles;
          return static_cast<double>(cycles > overhead ? cycles - overhead : 0) / report.clock.cycles_per_ns;
        };
        ClosedLoopRow& row = report.closed_loop[t.row];
        row.loop_runs = t.runs;
        row.loop_mean_min_ns = mean_ns(t.min_mean_cycles);
        row.loop_mean_max_ns = mean_ns(t.max_mean_cycles);
        row.loop_ticks = t.best.count();
        row.loop_ticks_left_out = t.best.overflow();
        row.loop_mean_ns = mean_ns(t.best.mean_in_bins());
        row.loop_median_ns = net_ns(t.best.percentile(0.5));
        row.loop_p99_ns = net_ns(t.best.percentile(0.99));
        // Every tick of the run at the mean (the preemptions left out), over its simulated time.
        row.loop_cpu_us_per_s = row.loop_mean_ns * static_cast<double>(row.loop_ticks) / options.closed_loop_s / 1e3;
      }
    }

    if (options.drift_hours > 0.0) {
      say(fmt::format("{}: closed loop, double, float and q16.16, {:g} simulated hours at {:g} Hz", scene,
                      options.drift_hours, options.drift_rate_hz));
      auto drift = drift_run(path, scene, options);
      if (!drift) return Error{drift.error()};
      for (auto& d : drift.value()) report.drift.push_back(std::move(d));
    }
  }
  if (options.drift_hours > 0.0) {
    const host_sim::HandScript hand = random_hand_script(options.drift_seed, options.drift_hours * 3600.0);
    report.drift_segments_per_h = static_cast<double>(hand.segments.size()) / options.drift_hours;
  }
  report.load_after = load_average();
  return report;
}

std::string precision_csv(const PrecisionReport& r) {
  std::string csv =
      "scene,scalar,sine,rate_hz,max_error_n,rms_error_n,away_max_error_n,away_rms_error_n,same_rate_max_error_n,"
      "held_max_error_n,held_rms_error_n,held_away_rms_error_n,mean_ns,median_ns,fault_ticks,reference_away_rms_error_n\n";
  for (const auto& row : r.rows) {
    double reference_error = 0.0;
    for (const auto& c : r.convergence) {
      if (c.scene == row.scene) reference_error = c.reference_away_rms_error_n;
    }
    csv += fmt::format(
        "{},{},{},{:g},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.2f},{:.1f},{},{:.6e}\n", row.scene,
        scalar_kind_name(row.scalar), row.sine ? sine_method_name(*row.sine) : std::string_view("-"), row.rate_hz,
        row.max_error_n, row.rms_error_n, row.away_max_error_n, row.away_rms_error_n, row.same_rate_max_error_n,
        row.held_max_error_n, row.held_rms_error_n, row.held_away_rms_error_n, row.mean_ns, row.median_ns,
        row.fault_ticks, reference_error);
  }
  return csv;
}

std::string drift_csv(const PrecisionReport& r) {
  std::string csv = "scene,scalar,quantity,unit,t_h,max_abs,slope_per_h\n";
  for (const auto& d : r.drift) {
    for (std::size_t h = 0; h < d.max_abs.size(); ++h) {
      csv += fmt::format("{},{},{},{},{:.6f},{:.6e},{:.6e}\n", d.scene, scalar_kind_name(d.scalar), d.quantity, d.unit,
                         d.bucket_end_h[h], d.max_abs[h], d.slope_per_h);
    }
  }
  return csv;
}

std::string convergence_csv(const PrecisionReport& r) {
  std::string csv = "scene,rate_hz,next_rate_hz,max_diff_n,rms_diff_n,away_max_diff_n,away_rms_diff_n,away_rms_order\n";
  for (const auto& c : r.convergence) {
    for (const auto& s : c.steps) {
      csv +=
          fmt::format("{},{:g},{:g},{:.6e},{:.6e},{:.6e},{:.6e},{}\n", c.scene, s.rate_hz, 2.0 * s.rate_hz,
                      s.max_diff_n, s.rms_diff_n, s.away_max_diff_n, s.away_rms_diff_n, order_text(s.away_rms_order));
    }
    if (c.check_rate_hz > 0.0) {  // the check rung: the reference against a run a multiple of its rate
      const ConvergenceStep& s = c.check;
      csv += fmt::format("{},{:g},{:g},{:.6e},{:.6e},{:.6e},{:.6e},-\n", c.scene, s.rate_hz, c.check_rate_hz,
                         s.max_diff_n, s.rms_diff_n, s.away_max_diff_n, s.away_rms_diff_n);
    }
  }
  return csv;
}

std::string closed_loop_csv(const PrecisionReport& r) {
  std::string csv =
      "scene,scalar,rate_hz,force_rms_error_n,force_max_error_n,position_rms_error_m,position_max_error_m,loop_ticks,"
      "loop_ticks_left_out,loop_runs,loop_mean_min_ns,loop_mean_max_ns,loop_mean_ns,loop_median_ns,loop_p99_ns,cpu_us_per_s,scripted_mean_ns,scripted_cpu_us_per_s,"
      "m3_instructions_per_s,reference_force_rms_error_n,refused\n";
  for (const auto& row : r.closed_loop) {
    double reference_error = 0.0;
    for (const auto& c : r.closed_loop_convergence) {
      if (c.scene == row.scene) reference_error = c.reference_force_rms_error_n;
    }
    csv += fmt::format(
        "{},{},{:g},{:.6e},{:.6e},{:.6e},{:.6e},{},{},{},{:.2f},{:.2f},{:.2f},{:.2f},{:.2f},{:.2f},{:.2f},{:.2f},{},{:.6e},{}\n",
        row.scene, scalar_kind_name(row.scalar), row.rate_hz, row.force_rms_error_n, row.force_max_error_n,
        row.position_rms_error_m, row.position_max_error_m, row.loop_ticks, row.loop_ticks_left_out, row.loop_runs,
        row.loop_mean_min_ns, row.loop_mean_max_ns, row.loop_mean_ns, row.loop_median_ns, row.loop_p99_ns,
        row.loop_cpu_us_per_s, row.scripted_mean_ns, row.scripted_mean_ns * row.rate_hz / 1000.0,
        std::isnan(row.m3_instructions_per_s) ? std::string() : fmt::format("{:.0f}", row.m3_instructions_per_s),
        reference_error, row.refused.empty() ? "" : "refused");
  }
  return csv;
}

namespace {

std::string event_cell(const std::vector<EventTiming>& events, EventKind kind, double rate_hz) {
  for (const auto& e : events) {
    if (e.kind != kind) continue;
    // Ticks of the configuration and ms; the range min..max, and any event it missed.
    std::string cell = fmt::format("{:.2f}..{:.2f} ({:.3f}..{:.3f} ms)", e.min_late_s * rate_hz, e.max_late_s * rate_hz,
                                   e.min_late_s * 1e3, e.max_late_s * 1e3);
    if (e.unmatched > 0) cell += fmt::format(", {} missed", e.unmatched);
    return cell;
  }
  return "-";
}

// A figure as `{:g}` prints it, of its own type (a float prints differently from a double).
template <typename T>
std::string g(T value) {
  return fmt::format("{:g}", value);
}

}  // namespace

std::string precision_markdown(const PrecisionReport& r, const std::string& plot_dir) {
  std::string md;
  const double reference_rate = r.options.reference_rates_hz.back();
  md += fmt::format("Measured {} UTC on {}; load average {} before, {} after. Clock: {}.\n\n", r.machine.date_utc,
                    describe(r.machine), r.load_before, r.load_after, describe(r.clock));

  if (!r.analytic.empty()) {
    const AnalyticWall& w = r.analytic_wall;
    md += render_prose(templates::precision_analytic_wall_md,
                       {{"stiffness", g(w.stiffness_n_per_m)},
                        {"offset_mm", g(w.offset_m * 1e3)},
                        {"amplitude_mm", g(w.amplitude_m * 1e3)},
                        {"frequency", g(w.frequency_hz)},
                        {"peak_force", g(w.peak_force_n())},
                        {"peak_force_rate", fmt::format("{:.1f}", w.peak_force_rate_n_per_s())}});
    md += "| scalar | rate | sampled max [N] | held max [N] | held RMS [N] | theory, held RMS [N] | observed order |\n"
          "| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    for (const auto& a : r.analytic) {
      md += fmt::format("| {} | {:g} Hz | {} | {} | {} | {} | {} |\n", scalar_kind_name(a.scalar), a.rate_hz,
                        sci(a.sampled_max_error_n), sci(a.held_max_error_n), sci(a.held_rms_error_n),
                        sci(a.held_rms_theory_n), order_text(a.held_rms_order));
    }
    md += "\n";
  }

  md += render_prose(templates::precision_ladder_md,
                     {{"reference_rates", fmt::format("{}", fmt::join(r.options.reference_rates_hz, ", "))},
                      {"reference_rate", g(reference_rate)},
                      {"check_factor", g(r.options.reference_check_factor)},
                      {"check_khz", g(reference_rate * r.options.reference_check_factor / 1e3)},
                      {"check_factor_less_one", g(r.options.reference_check_factor - 1.0)}});
  md += "| scene | rates | max diff [N] | RMS diff [N] | order (RMS) | away: max diff [N] | away: RMS diff [N] | away: "
        "order (RMS) | away: order (max) |\n| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
  for (const auto& c : r.convergence) {
    for (const auto& s : c.steps) {
      md += fmt::format("| {} | {:g} / {:g} kHz | {} | {} | {} | {} | {} | {} | {} |\n", c.scene, s.rate_hz / 1e3,
                        2.0 * s.rate_hz / 1e3, sci(s.max_diff_n), sci(s.rms_diff_n), order_text(s.rms_order),
                        sci(s.away_max_diff_n), sci(s.away_rms_diff_n), order_text(s.away_rms_order),
                        order_text(s.away_max_order));
    }
    if (c.check_rate_hz > 0.0) {
      const ConvergenceStep& s = c.check;
      md += fmt::format("| {} | {:g} / {:g} kHz (check) | {} | {} | - | {} | {} | - | - |\n", c.scene, s.rate_hz / 1e3,
                        c.check_rate_hz / 1e3, sci(s.max_diff_n), sci(s.rms_diff_n), sci(s.away_max_diff_n),
                        sci(s.away_rms_diff_n));
    }
  }
  const double check_factor = r.options.reference_check_factor;
  md += render_prose(templates::precision_reference_error_md, {{"reference_rate", g(reference_rate)},
                                                               {"check_factor", g(check_factor)},
                                                               {"check_factor_less_one", g(check_factor - 1.0)}});
  md +=
      "| scene | away: RMS [N] | away: max [N] | every tick: RMS [N] | every tick: max [N] | event bound: max / RMS "
      "[N] | event shift: vs check / bound [ticks] | events in the compared pass |\n| --- | ---: | ---: | ---: | ---: | "
      "---: | ---: | --- |\n";
  for (const auto& c : r.convergence) {
    std::string counts;
    for (const auto& [kind, n] : c.event_counts) {
      counts += fmt::format("{}{} {}", counts.empty() ? "" : ", ", n, event_kind_name(kind));
    }
    if (c.check_unmatched_events > 0)
      counts += fmt::format("; {} not matched in the check run", c.check_unmatched_events);
    md +=
        fmt::format("| {} | {} | {} | {} | {} | {} / {} | {:.2f} / {:.2f} | {} |\n", c.scene,
                    sci(c.reference_away_rms_error_n), sci(c.reference_away_max_error_n), sci(c.reference_rms_error_n),
                    sci(c.reference_max_error_n), sci(c.event_max_bound_n), sci(c.event_rms_bound_n),
                    c.check_event_shift_s * reference_rate, c.event_shift_bound_s * reference_rate, counts);
  }

  md += render_prose(
      templates::precision_configurations_md,
      {{"reference_rate", g(reference_rate)}, {"timing_ticks", fmt::format("{}", r.options.timing_ticks)}});
  if (!plot_dir.empty()) {
    md += fmt::format("![work-precision diagram]({}/work_precision.png)\n\n", plot_dir);
  }
  // The summary: what the rate costs in error (double, held RMS, worst scene) against what the
  // scalar type costs (max vs double at the same rate, worst scene and sine method).
  md += "Summary, worst over the five scenes (and sine methods):\n\n| | ";
  for (const double rate : r.options.rates_hz) md += fmt::format("{:g} Hz | ", rate);
  md += "\n| --- |";
  for (std::size_t i = 0; i < r.options.rates_hz.size(); ++i) md += " ---: |";
  md += "\n";
  const auto summary_row = [&](const std::string& label, auto pick, bool nanoseconds = false) {
    md += fmt::format("| {} |", label);
    for (const double rate : r.options.rates_hz) {
      double worst = 0.0;
      for (const auto& row : r.rows) {
        if (row.rate_hz == rate) worst = std::max(worst, pick(row));
      }
      md += nanoseconds ? fmt::format(" {:.1f} |", worst) : fmt::format(" {} |", sci(worst));
    }
    md += "\n";
  };
  double worst_reference = 0.0;
  for (const auto& c : r.convergence) worst_reference = std::max(worst_reference, c.reference_away_rms_error_n);
  summary_row(
      fmt::format("double: RMS held error away from events vs the {:g} kHz reference (its own: {}) [N]",
                  reference_rate / 1e3, sci(worst_reference)),
      [](const PrecisionRow& row) { return row.scalar == ScalarKind::kDouble ? row.held_away_rms_error_n : 0.0; });
  summary_row("double: max sampled error away from events [N]",
              [](const PrecisionRow& row) { return row.scalar == ScalarKind::kDouble ? row.away_max_error_n : 0.0; });
  summary_row("double: max sampled error, every tick (events included) [N]",
              [](const PrecisionRow& row) { return row.scalar == ScalarKind::kDouble ? row.max_error_n : 0.0; });
  summary_row("float: max error vs double at the same rate [N]", [](const PrecisionRow& row) {
    return row.scalar == ScalarKind::kFloat ? row.same_rate_max_error_n : 0.0;
  });
  summary_row("q16.16: max error vs double at the same rate [N]", [](const PrecisionRow& row) {
    return row.scalar == ScalarKind::kQ16_16 ? row.same_rate_max_error_n : 0.0;
  });
  summary_row(
      "double: mean ns per tick",
      [](const PrecisionRow& row) { return row.scalar == ScalarKind::kDouble ? row.mean_ns : 0.0; }, true);
  summary_row(
      "float: mean ns per tick",
      [](const PrecisionRow& row) { return row.scalar == ScalarKind::kFloat ? row.mean_ns : 0.0; }, true);
  summary_row(
      "q16.16: mean ns per tick",
      [](const PrecisionRow& row) { return row.scalar == ScalarKind::kQ16_16 ? row.mean_ns : 0.0; }, true);
  md += "\n";

  // What makes a "vs double at the same rate" figure large: an event on another tick,
  // with the position that decided it and that position as Q16.16 holds it.
  // Listed for the rows whose figure stands out: more than 3 times the smallest of their scene,
  // scalar type and sine method (the law's floor, table "Error floor per law").
  std::string shifts;
  for (const auto& row : r.rows) {
    double floor_n = std::numeric_limits<double>::infinity();
    for (const auto& other : r.rows) {
      if (other.scene == row.scene && other.scalar == row.scalar && other.sine == row.sine) {
        floor_n = std::min(floor_n, other.same_rate_max_error_n);
      }
    }
    if (!(row.same_rate_max_error_n > 3.0 * floor_n)) continue;
    for (const auto& e : row.same_rate_event_shifts) {
      // + 0.0: no "-0.0" printed for a coordinate that rounds to zero from below.
      const auto q16 = [](double v) { return std::round(v * 65536.0) / 65536.0 + 0.0; };
      const double ticks = e.shift_s * row.rate_hz;
      shifts += fmt::format(
          "- {}, {}{}, {:g} Hz: {} {:.0f} tick{} {} than double (double: t = {:.4f} s); the handle at its tick: x = {:.1f} "
          "um, z = {:.1f} um{}; that row's max vs double: {} N\n",
          row.scene, scalar_kind_name(row.scalar),
          row.sine ? fmt::format(" ({} sine)", sine_method_name(*row.sine)) : "", row.rate_hz, event_kind_name(e.kind),
          std::abs(ticks), std::abs(ticks) > 1.5 ? "s" : "", ticks < 0.0 ? "earlier" : "later", e.double_t_s,
          e.position_m.x * 1e6, e.position_m.z * 1e6,
          row.scalar == ScalarKind::kQ16_16 ? fmt::format(" (as Q16.16 holds them: x = {:.1f} um, z = {:.1f} um)",
                                                          q16(e.position_m.x) * 1e6, q16(e.position_m.z) * 1e6)
                                            : std::string(),
          sci(row.same_rate_max_error_n));
    }
  }
  if (!shifts.empty()) {
    md += render_prose(templates::precision_event_shifts_md, {{"shifts", shifts}});
  }

  // Event lateness, double with the library sine (or no sine): the rate's own share.
  md += render_prose(
      templates::precision_event_lateness_md,
      {{"reference_rate", g(reference_rate)}, {"reference_tick_ms", fmt::format("{:.4f}", 1e3 / reference_rate)}});
  md +=
      "| scene | rate | contact onset | contact end | impact trigger | cliff fall |\n| --- | ---: | --- | --- | --- | --- |\n";
  for (const auto& row : r.rows) {
    if (row.scalar != ScalarKind::kDouble || (row.sine && *row.sine != SineMethod::kLibrary)) continue;
    md += fmt::format("| {} | {:g} Hz | {} | {} | {} | {} |\n", row.scene, row.rate_hz,
                      event_cell(row.events, EventKind::kContactOnset, row.rate_hz),
                      event_cell(row.events, EventKind::kContactEnd, row.rate_hz),
                      event_cell(row.events, EventKind::kImpactTrigger, row.rate_hz),
                      event_cell(row.events, EventKind::kCliffFall, row.rate_hz));
  }
  md += "\n";

  std::string scene;
  for (const auto& row : r.rows) {
    if (row.scene != scene) {
      scene = row.scene;
      double ref = 0.0, ref_all = 0.0, ref_max = 0.0;
      for (const auto& c : r.convergence) {
        if (c.scene == scene) {
          ref = c.reference_away_rms_error_n;
          ref_all = c.reference_rms_error_n;
          ref_max = c.reference_max_error_n;
        }
      }
      md += fmt::format(
          "\n#### {} (reference's own error, RMS: {} N away from events, {} N every tick; max: {} N every tick)\n\n",
          scene, sci(ref), sci(ref_all), sci(ref_max));
      md += "| scalar | sine | rate | max error [N] | RMS error [N] | away: max [N] | away: RMS [N] | max vs double, "
            "same rate [N] | held max [N] | held RMS [N] | held RMS, away [N] | mean ns | median ns | CPU per second "
            "[us] | fault ticks |\n";
      md +=
          "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    }
    md += fmt::format("| {} | {} | {:g} Hz | {} | {} | {} | {} | {} | {} | {} | {} | {:.1f} | {:.0f} | {:.0f} | {} |\n",
                      scalar_kind_name(row.scalar), row.sine ? sine_method_name(*row.sine) : std::string_view("-"),
                      row.rate_hz, sci(row.max_error_n), sci(row.rms_error_n), sci(row.away_max_error_n),
                      sci(row.away_rms_error_n), sci(row.same_rate_max_error_n), sci(row.held_max_error_n),
                      sci(row.held_rms_error_n), sci(row.held_away_rms_error_n), row.mean_ns, row.median_ns,
                      row.mean_ns * row.rate_hz / 1000.0, row.fault_ticks);
  }
  if (!r.closed_loop.empty()) {
    const double cl_reference = r.options.closed_loop_reference_rates_hz.back();
    std::uint64_t left_out = 0, timed = 0;
    for (const auto& row : r.closed_loop) {
      left_out += row.loop_ticks_left_out;
      timed += row.loop_ticks;
    }
    md += render_prose(
        templates::precision_closed_loop_md,
        {{"seed", fmt::format("{}", r.options.drift_seed)},
         {"duration_s", g(r.options.closed_loop_s)},
         {"reference_rates", fmt::format("{}", fmt::join(r.options.closed_loop_reference_rates_hz, ", "))},
         {"reference_rate", g(cl_reference)},
         {"slowest_ticks", g(r.options.rates_hz.front() * r.options.closed_loop_s)},
         {"fastest_ticks", g(r.options.rates_hz.back() * r.options.closed_loop_s)},
         {"ticks_left_out", fmt::format("{}", left_out)},
         {"ticks_timed", fmt::format("{}", timed)},
         {"counter_step_ns", fmt::format("{:.1f}", static_cast<double>(r.clock.step_cycles) / r.clock.cycles_per_ns)},
         {"timing_runs", fmt::format("{}", r.options.closed_loop_timing_runs)},
         {"timing_ticks", fmt::format("{}", r.options.timing_ticks)},
         {"cortex_m3_images", r.options.m3_loop_instructions_per_tick.empty()
                                  ? "The Cortex-M3 images were not built when this ran: \"not built\" below (`cmake "
                                    "--workflow --preset release && ctest --preset release -L mcu` builds them)."
                                  : "Here from the images as `report mcu` ran them just before this report."}});
    if (!plot_dir.empty())
      md +=
          fmt::format("![closed loop: force error against CPU per simulated second]({}/closed_loop.png)\n\n", plot_dir);
    md += "The reference ladder:\n\n| scene | rates | force: RMS diff [N] | order | position: RMS diff [m] | order |\n"
          "| --- | --- | ---: | ---: | ---: | ---: |\n";
    for (const auto& c : r.closed_loop_convergence) {
      for (const auto& s : c.steps) {
        md += fmt::format("| {} | {:g} / {:g} kHz | {} | {} | {} | {} |\n", c.scene, s.rate_hz / 1e3,
                          2.0 * s.rate_hz / 1e3, sci(s.force_rms_diff_n), order_text(s.force_order),
                          sci(s.position_rms_diff_m), order_text(s.position_order));
      }
    }
    md += "\n| scene | reference's own error: force RMS [N] | position RMS [m] |\n| --- | ---: | ---: |\n";
    for (const auto& c : r.closed_loop_convergence) {
      md += fmt::format("| {} | {} | {} |\n", c.scene, sci(c.reference_force_rms_error_n),
                        sci(c.reference_position_rms_error_m));
    }
    md +=
        "\n| scene | scalar | rate | force RMS error [N] | force max error [N] | position RMS error [m] | position max "
        "error [m] | ticks per run | loop tick: mean [ns] | median [ns] | p99 [ns] | runs' means, min..max [ns] | "
        "**loop CPU per simulated second [us]** | scripted pass: tick [ns] | scripted pass: CPU per simulated second "
        "[us] (computed: its tick x rate) | Cortex-M3: instructions per simulated second [10^6] (computed: 1 kHz mean per tick x rate) |\n"
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    for (const auto& row : r.closed_loop) {
      if (!row.refused.empty()) {
        md += fmt::format("| {} | {} | {:g} Hz | refused: {} | | | | | | | | | | | | |\n", row.scene,
                          scalar_kind_name(row.scalar), row.rate_hz, row.refused);
        continue;
      }
      const std::string m3 = row.scalar != ScalarKind::kQ16_16 ? std::string("-")
                             : std::isnan(row.m3_instructions_per_s)
                                 ? std::string("not built")
                                 : fmt::format("{:.2f}", row.m3_instructions_per_s / 1e6);
      md += fmt::format(
          "| {} | {} | {:g} Hz | {} | {} | {} | {} | {} | {:.1f} | {:.0f} | {:.0f} | {:.1f}..{:.1f} | **{:.0f}** | {:.1f} | {:.0f} | {} |\n",
          row.scene, scalar_kind_name(row.scalar), row.rate_hz, sci(row.force_rms_error_n), sci(row.force_max_error_n),
          sci(row.position_rms_error_m), sci(row.position_max_error_m), row.loop_ticks, row.loop_mean_ns,
          row.loop_median_ns, row.loop_p99_ns, row.loop_mean_min_ns, row.loop_mean_max_ns, row.loop_cpu_us_per_s,
          row.scripted_mean_ns, row.scripted_mean_ns * row.rate_hz / 1000.0, m3);
    }
  }
  if (!r.drift.empty()) {
    md += render_prose(templates::precision_drift_md,
                       {{"hours", g(r.options.drift_hours)},
                        {"rate", g(r.options.drift_rate_hz)},
                        {"ticks", g(r.options.drift_hours * 3600.0 * r.options.drift_rate_hz)},
                        {"seed", fmt::format("{}", r.options.drift_seed)},
                        {"segments_per_hour", fmt::format("{:.0f}", r.drift_segments_per_h)}});
    if (!plot_dir.empty()) md += fmt::format("![drift over simulated hours]({}/drift.png)\n\n", plot_dir);
    md +=
        "| scene | scalar | quantity | max over first bucket | max over last bucket | at the end (signed) | slope per "
        "hour | R^2 | energy through the port, sum abs(F . dx) [J] | CPU time, scene [s] |\n"
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    for (const auto& d : r.drift) {
      if (d.max_abs.empty()) continue;
      md += fmt::format("| {} | {} | {} [{}] | {} | {} | {} | {} | {:.2f} | {} | {:.1f} |\n", d.scene,
                        scalar_kind_name(d.scalar), d.quantity, d.unit, sci(d.max_abs.front()), sci(d.max_abs.back()),
                        sci(d.final_signed), sci(d.slope_per_h), d.r_squared, sci(d.exchanged_j), d.cpu_s);
    }
    md += fmt::format("\nBuckets: {} equal parts of the run.\n", r.drift.front().max_abs.size());
  }
  return md;
}

}  // namespace toonforce::report
