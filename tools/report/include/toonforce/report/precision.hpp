#pragma once
/// `toonforce report precision`: force error against run time (spec effects.md §8;
/// shared/reference/realtime-safety-stability.md §7), for each paper scene, scalar type, servo
/// rate and sine method.
///
/// Reference: the servo loop with the spec's stages (ServoLoop, kSpecStages) in double with the library sine at 40 kHz, on the same scripted
/// scenario (report/scenario.hpp), velocity estimated from the positions as on a Falcon; the
/// scenario runs twice and only the second pass is compared, so the filters and the effects'
/// states are in their periodic regime. Every compared rate divides 40 kHz, so each of their
/// ticks falls exactly on a reference tick:
///   - sampled error: |F(t_k) - F_ref(t_k)| at the configuration's own ticks (what its
///     arithmetic, its velocity estimate and its event timing get wrong);
///   - held error: at every reference tick, the configuration's force held since its last
///     tick (zero-order hold, what the device renders) against the reference's.
/// Cost: the mean and median ns of that configuration's loop tick (TSC, each tick alone).
///
/// Drift: the same loop at 1 kHz for `drift_hours` simulated hours on the repeating scenario,
/// each tick compared with the reference at the same phase; the maximum and RMS error per hour
/// must stay flat (time is integer ticks, so nothing accumulates).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/toml_reader.hpp"
#include "toonforce/math/sine.hpp"
#include "toonforce/report/latency.hpp"
#include "toonforce/report/machine.hpp"

namespace toonforce::report {

struct PrecisionOptions {
  std::string root;
  std::vector<double> rates_hz{500.0, 1000.0, 4000.0, 10000.0};
  double reference_rate_hz = 40000.0;
  std::uint64_t timing_ticks = 1'000'000;  ///< timed ticks per configuration
  double drift_hours = 24.0;               ///< 0: no drift run
  double drift_rate_hz = 1000.0;
  std::string filter;                      ///< only scenes whose name contains one of these
};

struct PrecisionRow {
  std::string scene;
  ScalarKind scalar = ScalarKind::kDouble;
  double rate_hz = 0.0;
  std::optional<SineMethod> sine;  ///< set for scenes with an impact transient
  double max_error_n = 0.0;        ///< sampled
  double rms_error_n = 0.0;        ///< sampled
  /// Sampled, against double with the library sine at the same rate: the scalar type's and
  /// the sine method's own share of the error (0 for that configuration itself).
  double same_rate_max_error_n = 0.0;
  double held_max_error_n = 0.0;   ///< zero-order hold, at every reference tick
  double held_rms_error_n = 0.0;
  double mean_ns = 0.0;
  double median_ns = 0.0;
  std::uint64_t fault_ticks = 0;   ///< ticks with a fault (Q16.16 saturation) in the compared pass
};

struct DriftSeries {
  std::string scene;
  ScalarKind scalar = ScalarKind::kDouble;
  std::vector<double> max_error_n;  ///< per simulated hour (the last one may be partial)
  std::vector<double> rms_error_n;
  std::uint64_t ticks = 0;
  double cpu_s = 0.0;               ///< CPU time the run took
};

struct PrecisionReport {
  MachineInfo machine;
  std::string load_before;
  std::string load_after;
  TscCalibration clock;
  PrecisionOptions options;
  std::vector<PrecisionRow> rows;
  std::vector<DriftSeries> drift;
};

Result<PrecisionReport> run_precision(const PrecisionOptions& options, const Progress& progress = {});

std::string precision_markdown(const PrecisionReport& report, const std::string& plot_dir_in_docs = {});
/// One row per configuration (the work-precision plot's input).
std::string precision_csv(const PrecisionReport& report);
/// One row per scene, scalar and hour.
std::string drift_csv(const PrecisionReport& report);

}  // namespace toonforce::report
