// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce-lab report precision`: force error against run time (spec effects.md §8; the
/// work-precision diagrams of DiffEqDevTools.jl's WorkPrecisionSet and of Hairer and Wanner,
/// "Solving Ordinary Differential Equations"), for each paper scene, scalar type, servo
/// rate and sine method.
///
/// References, each with its own error stated:
///   - the analytic wall: the wall's law along a sinusoidal penetration path, where the force is
///     known in closed form at every instant (precision_reference.hpp: AnalyticWall); its only
///     error is double rounding;
///   - the scripted scenario (report/scenario.hpp) of every paper scene: the servo loop with the
///     spec's stages in double with the library sine at 40, 80, 160 and 320 kHz (a convergence
///     ladder), velocity estimated from the positions as on a Falcon, two passes of the scenario
///     with only the second compared. The finest is the reference; its own error is the
///     Richardson estimate from the last doubling and the observed order, checked against a
///     run at 5 times its rate and bounded at events from how far it can have moved one
///     (two rungs can see an event alike by chance). Every compared rate
///     divides it, so each of their ticks falls on a reference tick:
///       - sampled error: |F(t_k) - F_ref(t_k)| at the configuration's own ticks, every tick and
///         away from events (a window of 2 ticks before and 2 ticks plus the force-rate ramp
///         after each contact onset or end, impact trigger or cliff fall, and the whole of a
///         running impact transient): the step's own error apart from event timing;
///       - held error: the configuration's force held over its tick (zero-order hold, what the
///         device renders) against the reference, linear between its ticks, integrated exactly
///         (precision_reference.hpp held_difference);
///       - event lateness: each kind of event's time in the configuration minus the reference's.
/// Cost: the mean and median ns of that configuration's loop tick (TSC, each tick alone).
///
/// Drift: hours of the closed loop (tools/sim SimSession: the servo loop with
/// every stage on the simulated device and hand) with a seeded, varied hand; per scalar type,
/// the passivity observer's energy against the plant's true port work, and float and Q16.16
/// against double, each difference fitted by a line against time.

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/toml_reader.hpp"
#include "toonforce/host_sim/hand_script.hpp"
#include "toonforce/math/sine.hpp"
#include "toonforce/report/latency.hpp"
#include "toonforce/report/machine.hpp"
#include "toonforce/report/precision_reference.hpp"
#include "toonforce/report/workloads.hpp"
#include "toonforce/sim/closed_loop.hpp"

namespace toonforce::report {

struct PrecisionOptions {
  std::string root;
  std::vector<double> rates_hz{500.0, 1000.0, 4000.0, 10000.0};
  /// The double reference's convergence ladder, each twice the last; the last is the
  /// reference every configuration is compared with, and each rate above divides it.
  std::vector<double> reference_rates_hz{40000.0, 80000.0, 160000.0, 320000.0};
  /// The reference's check rung: double at this multiple of the reference rate (0: none).
  double reference_check_factor = 5.0;
  std::uint64_t timing_ticks = 1'000'000;  ///< timed ticks per configuration
  double drift_hours = 1.0;                ///< closed-loop simulated hours per scene; 0: no drift run
  double drift_rate_hz = 1000.0;
  std::uint64_t drift_seed = 15;  ///< the hand's motion
  /// The closed-loop comparison: seconds of the seeded hand (0: none), and its double ladder
  /// (each twice the last; the last is the reference; each rate above divides it).
  double closed_loop_s = 3.0;
  std::vector<double> closed_loop_reference_rates_hz{40000.0, 80000.0, 160000.0};
  /// Times each closed-loop configuration runs (bit-identical runs) to time its loop: a
  /// shared VM's noise moved one run's mean by up to 2x; the least disturbed run is reported.
  int closed_loop_timing_runs = 7;
  std::string filter;  ///< only scenes whose name contains one of these
  /// The Cortex-M3's every-stage Q16.16 loop tick per scene, mean instructions over its 1 kHz
  /// motions (report mcu's table, mcu_loop_mean_instructions); empty when not built.
  std::vector<std::pair<std::string, double>> m3_loop_instructions_per_tick;
};

/// How late a configuration sees each kind of event, against the reference.
struct EventTiming {
  EventKind kind = EventKind::kContactOnset;
  std::size_t matched = 0;
  std::size_t unmatched = 0;
  double max_late_s = 0.0;
  double min_late_s = 0.0;
  double mean_late_s = 0.0;
};

struct PrecisionRow {
  std::string scene;
  ScalarKind scalar = ScalarKind::kDouble;
  double rate_hz = 0.0;
  std::optional<SineMethod> sine;  ///< set for scenes with an impact transient
  double max_error_n = 0.0;        ///< sampled, every tick
  double rms_error_n = 0.0;        ///< sampled, every tick
  /// Sampled, ticks away from events only (precision_reference.hpp: near_event): the step's own error.
  double away_max_error_n = 0.0;
  double away_rms_error_n = 0.0;
  /// Sampled, against double with the library sine at the same rate: the scalar type's and
  /// the sine method's own share of the error (0 for that configuration itself).
  double same_rate_max_error_n = 0.0;
  double held_max_error_n = 0.0;  ///< zero-order hold, at every reference tick
  double held_rms_error_n = 0.0;
  double held_away_rms_error_n = 0.0;  ///< the same, away from events
  double mean_ns = 0.0;
  double median_ns = 0.0;
  std::uint64_t fault_ticks = 0;    ///< ticks with a fault (Q16.16 saturation) in the compared pass
  std::vector<EventTiming> events;  ///< lateness per kind of event
  /// Events this configuration saw on another tick than double (library sine) at the same rate:
  /// what makes a "max vs double, same rate" figure large.
  struct EventShift {
    EventKind kind = EventKind::kContactOnset;
    double double_t_s = 0.0;  ///< when double saw it
    double shift_s = 0.0;     ///< this configuration's time minus double's
    Vec3<double> position_m;  ///< the scenario's position at this configuration's tick of it
  };
  std::vector<EventShift> same_rate_event_shifts;
};

/// One step of a scene's reference ladder: double at `rate_hz` against double at 2 x rate,
/// compared at the coarser run's ticks.
struct ConvergenceStep {
  double rate_hz = 0.0;
  double max_diff_n = 0.0;
  double rms_diff_n = 0.0;
  double away_max_diff_n = 0.0;
  double away_rms_diff_n = 0.0;
  double away_rms_order = 0.0;  ///< observed order against the previous step (NaN for the first)
  double away_max_order = 0.0;
  double rms_order = 0.0;  ///< every tick
};

struct SceneConvergence {
  std::string scene;
  std::vector<ConvergenceStep> steps;
  /// The check rung: the reference against double at `check_rate_hz` (a
  /// multiple of it, not a doubling: a rung that an event may land on differently than on the
  /// ladder's), compared at the reference's ticks; orders NaN. check_rate_hz 0: none.
  double check_rate_hz = 0.0;
  ConvergenceStep check;
  /// The largest |t_reference - t_check| of an event over the compared pass, and events of the
  /// reference the check run did not show within 20 ms.
  double check_event_shift_s = 0.0;
  std::size_t check_unmatched_events = 0;
  /// How far the reference may have moved an event from the true instant: one reference tick
  /// (it sees a position-decided event at its first tick at or after it), or, if the check run
  /// shows more, that shift scaled as first-order (x factor / (factor - 1)).
  double event_shift_bound_s = 0.0;
  /// What that shift can do to the force at the ticks near events (the windows of "away", a
  /// running impact transient included): at each, the force's change over the neighbouring
  /// reference ticks times the shift in ticks (the safety stage's rate limit caps that change
  /// at max_force_rate x T); the largest and the RMS over the compared pass (ticks away from
  /// events count 0).
  double event_max_bound_n = 0.0;
  double event_rms_bound_n = 0.0;
  /// The reference's own error (the last rate of the ladder), as stated: away from events, the
  /// Richardson estimate from the last step and its observed order (else the last difference),
  /// raised to the check rung's difference scaled as first-order convergence if that is larger.
  double reference_away_rms_error_n = 0.0;
  double reference_away_max_error_n = 0.0;
  double reference_max_diff_n = 0.0;  ///< the ladder's last difference, every tick, max
  /// Every tick, the bound stated: the largest of the ladder's estimate (Richardson or the last
  /// difference), the check rung's difference scaled as first-order, and the error away from
  /// events plus the event bound (max: summed; RMS: in quadrature).
  double reference_rms_error_n = 0.0;
  double reference_max_error_n = 0.0;
  std::vector<std::pair<EventKind, std::size_t>> event_counts;  ///< in the reference's compared pass
  double settle_s = 0.0;  ///< the part of the window after an event (force-rate ramp of the clamp)
};

/// The analytic wall (precision_reference.hpp): a configuration's force against the closed form.
struct AnalyticRow {
  ScalarKind scalar = ScalarKind::kDouble;
  double rate_hz = 0.0;
  double sampled_max_error_n = 0.0;  ///< at its own ticks: the arithmetic only
  double held_max_error_n = 0.0;     ///< zero-order hold against F(t), 64 points per tick
  double held_rms_error_n = 0.0;
  double held_rms_theory_n = 0.0;  ///< T rms(dF/dt) / sqrt(3): the hold's first-order error
  double held_rms_order = 0.0;     ///< observed, against the previous rate (NaN for the first)
};

/// One difference tracked over a closed-loop drift run.
struct DriftSeries {
  std::string scene;
  ScalarKind scalar = ScalarKind::kDouble;
  std::string quantity;  ///< what is compared (see precision_markdown)
  std::string unit;
  std::vector<double> bucket_end_h;  ///< simulated time at the end of each bucket
  std::vector<double> max_abs;       ///< the largest |difference| in each bucket
  double slope_per_h = 0.0;          ///< least-squares slope of |difference| against time
  double intercept = 0.0;
  double r_squared = 0.0;
  double final_abs = 0.0;     ///< |difference| at the last tick
  double final_signed = 0.0;  ///< the difference itself at the last tick (its sign)
  double exchanged_j = 0.0;   ///< sum |F . dx| of the double run: the energy that went through the port
  std::uint64_t ticks = 0;
  double cpu_s = 0.0;  ///< CPU time of the whole scene's run (all scalars)
};

/// The closed loop: one scalar type and rate against the converged double
/// closed loop, the same seeded hand, the same simulated device.
struct ClosedLoopRow {
  std::string scene;
  ScalarKind scalar = ScalarKind::kDouble;
  double rate_hz = 0.0;
  std::string refused;             ///< why the loop refused this configuration (else empty)
  double force_rms_error_n = 0.0;  ///< rendered force, held, at every reference tick
  double force_max_error_n = 0.0;
  double position_rms_error_m = 0.0;  ///< the handle's true position, at the configuration's ticks
  double position_max_error_m = 0.0;
  /// The servo loop's tick timed inside this run (ServoLoop::tick only: the plant, hand and
  /// the records step outside the counter reads), the empty measurement's cost subtracted.
  std::uint64_t loop_ticks = 0;   ///< ticks timed in one run: rate x duration
  int loop_runs = 0;              ///< runs timed; the figures below are the least disturbed one's (smallest mean)
  double loop_mean_min_ns = 0.0;  ///< the smallest and largest mean of the runs (the noise)
  double loop_mean_max_ns = 0.0;
  std::uint64_t loop_ticks_left_out = 0;  ///< of them, 2^17 cycles and more (preemptions): not in the mean
  double loop_mean_ns = 0.0;
  double loop_median_ns = 0.0;
  double loop_p99_ns = 0.0;
  double loop_cpu_us_per_s = 0.0;  ///< loop CPU per simulated second: mean x ticks / duration
  double scripted_mean_ns = 0.0;   ///< for comparison: the same loop's tick on the scripted scenario (timed alone)
  /// Q16.16 rows: the Cortex-M3's every-stage loop tick (report mcu, mean over the scene's
  /// 1 kHz motions) x the rate; NaN when the images were not built or for other scalars.
  double m3_instructions_per_s = std::nan("");
};

/// The closed loop's double ladder, one step: rate against 2 x rate.
struct ClosedLoopStep {
  double rate_hz = 0.0;
  double force_rms_diff_n = 0.0;
  double position_rms_diff_m = 0.0;
  double force_order = 0.0;  ///< observed, against the previous step (NaN for the first)
  double position_order = 0.0;
};

struct ClosedLoopConvergence {
  std::string scene;
  std::vector<ClosedLoopStep> steps;
  double reference_force_rms_error_n = 0.0;  ///< Richardson, from the last step
  double reference_position_rms_error_m = 0.0;
};

struct PrecisionReport {
  MachineInfo machine;
  std::string load_before;
  std::string load_after;
  TscCalibration clock;
  PrecisionOptions options;
  std::vector<PrecisionRow> rows;
  std::vector<SceneConvergence> convergence;
  std::vector<AnalyticRow> analytic;
  AnalyticWall analytic_wall;
  std::vector<DriftSeries> drift;
  std::vector<ClosedLoopRow> closed_loop;
  std::vector<ClosedLoopConvergence> closed_loop_convergence;
  double drift_segments_per_h = 0.0;  ///< hand-script segments per simulated hour
};

Result<PrecisionReport> run_precision(const PrecisionOptions& options, const Progress& progress = {});

std::string precision_markdown(const PrecisionReport& report, const std::string& plot_dir_in_docs = {});
/// One row per configuration (the work-precision plot's input).
std::string precision_csv(const PrecisionReport& report);
/// One row per scene, scalar, quantity and bucket.
std::string drift_csv(const PrecisionReport& report);
/// The reference ladder per scene.
std::string convergence_csv(const PrecisionReport& report);
/// One row per closed-loop configuration (the closed-loop plot's input).
std::string closed_loop_csv(const PrecisionReport& report);

/// The forces of a paper scene's scripted scenario, second pass, as the reference ladder runs
/// it: replay's servo loop (spec stages) in double with the library sine at `rate_hz`.
Result<std::vector<Vec3<double>>> scenario_forces(const std::string& root, std::string_view scene, double rate_hz);

/// One closed-loop run of the report: the rendered force (what the device applied over each
/// tick) and the handle's true position at each tick.
struct ClosedLoopRun {
  std::vector<Vec3<double>> force_n;
  std::vector<Vec3<double>> position_m;
  std::uint64_t ticks = 0;  ///< ServoLoop::tick calls made (and timed)
  std::string refused;      ///< why the scene or configuration was refused (else empty)
};
/// The closed-loop rows' simulated device: Falcon-class, without its encoder and DAC steps.
SimConfig closed_loop_sim_config(ScalarKind kind, double rate_hz, std::uint64_t seed);
/// The closed loop of SimSession (the servo loop with every stage on the simulated device and
/// hand), run by the report so that each ServoLoop::tick call, and nothing else, is timed with
/// the time-stamp counter into `cycles` (raw cycles, the empty measurement's cost included;
/// null: not kept). The same run as SimSession's, tick for tick.
ClosedLoopRun closed_loop_run(const std::string& scene_path, const HandScriptFile& hand, const SimConfig& config,
                              double duration_s, CycleHistogram* cycles = nullptr);

/// A seeded, varied hand for the drift run: `duration_s` of minimum-jerk moves between random
/// points above, on and under the scenes' ground (z = 0) across the cliff's gap, with holds
/// pressing down in between; never one pass repeated. Start-up code.
host_sim::HandScript random_hand_script(std::uint64_t seed, double duration_s);

}  // namespace toonforce::report
