#include "toonforce/report/precision.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/report/scenario.hpp"
#include "toonforce/report/workloads.hpp"

namespace toonforce::report {

namespace {

struct Forces {
  std::vector<Vec3<double>> force_n;  ///< of the last pass, one per tick
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

/// The loop on `passes` passes of the scenario at `rate_hz`; the forces of the last.
template <Scalar S>
Forces run_passes(const SceneDescription& desc, std::string_view scene, double rate_hz,
                  std::optional<SineMethod> sine, int passes) {
  Vec3<double> x{};
  SpecLoop<S> loop(PlayedPositions{&x}, scene_with<S>(desc, sine), servo_config(desc, 1.0 / rate_hz));
  const KeyframePath path = paper_scenario(scene);
  const std::int64_t n = ticks_per_pass(path, rate_hz);
  Forces out;
  out.force_n.reserve(static_cast<std::size_t>(n));
  for (std::int64_t k = 0; k < passes * n; ++k) {
    // k % n / rate: the same double for the same instant at every rate dividing the other.
    x = path.at(static_cast<double>(k % n) / rate_hz).position_m;
    const TickStatus r = loop.tick(k);
    if (k >= (passes - 1) * n) {
      out.force_n.push_back(to_double(loop.force()));
      if (r.faults) ++out.fault_ticks;
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

/// The drift run: the loop at `rate_hz` for `hours`, every tick after the first pass
/// compared with the reference at the same phase.
template <Scalar S>
DriftSeries drift_run(const SceneDescription& desc, std::string_view scene, const std::vector<Vec3<double>>& reference,
                      std::int64_t reference_step, double rate_hz, double hours) {
  DriftSeries d;
  d.scene = std::string(scene);
  d.scalar = kIsFixed<S> ? ScalarKind::kQ16_16 : std::same_as<S, float> ? ScalarKind::kFloat : ScalarKind::kDouble;
  Vec3<double> x{};
  SpecLoop<S> loop(PlayedPositions{&x}, make_runtime_scene<S>(desc), servo_config(desc, 1.0 / rate_hz));
  const KeyframePath path = paper_scenario(scene);
  const std::int64_t n = ticks_per_pass(path, rate_hz);
  std::vector<Vec3<double>> samples(static_cast<std::size_t>(n));
  std::vector<Vec3<double>> expected(static_cast<std::size_t>(n));
  for (std::int64_t j = 0; j < n; ++j) {
    samples[static_cast<std::size_t>(j)] = path.at(static_cast<double>(j) / rate_hz).position_m;
    expected[static_cast<std::size_t>(j)] = reference[static_cast<std::size_t>(j * reference_step)];
  }
  const auto total = static_cast<std::int64_t>(std::llround(hours * 3600.0 * rate_hz));
  const auto per_hour = static_cast<std::int64_t>(std::llround(3600.0 * rate_hz));
  const double start = cpu_seconds();
  double bucket_max = 0.0;
  double bucket_sum = 0.0;
  std::int64_t bucket_n = 0;
  std::int64_t phase = 0;
  for (std::int64_t k = 0; k < total; ++k) {
    x = samples[static_cast<std::size_t>(phase)];
    static_cast<void>(loop.tick(k));
    if (k >= n) {  // after the first pass (start-up transient of the filters)
      const double e = norm(to_double(loop.force()) - expected[static_cast<std::size_t>(phase)]);
      bucket_max = std::max(bucket_max, e);
      bucket_sum += e * e;
      ++bucket_n;
    }
    if (++phase == n) phase = 0;
    if ((k + 1) % per_hour == 0 || k + 1 == total) {
      d.max_error_n.push_back(bucket_max);
      d.rms_error_n.push_back(bucket_n > 0 ? std::sqrt(bucket_sum / static_cast<double>(bucket_n)) : 0.0);
      bucket_max = bucket_sum = 0.0;
      bucket_n = 0;
    }
  }
  d.ticks = static_cast<std::uint64_t>(total);
  d.cpu_s = cpu_seconds() - start;
  return d;
}

bool scene_selected(std::string_view scene, const std::string& filter) {
  return selected(std::string(scene), filter);
}

std::string sci(double v) { return v == 0.0 ? "0" : fmt::format("{:.2e}", v); }

}  // namespace

Result<PrecisionReport> run_precision(const PrecisionOptions& options, const Progress& progress) {
  const auto say = [&progress](const std::string& line) {
    if (progress) progress(line);
  };
  PrecisionReport report;
  report.options = options;
  report.machine = machine_info();
  report.load_before = load_average();
  for (const double rate : options.rates_hz) {
    const double ratio = options.reference_rate_hz / rate;
    if (!(rate > 0.0) || std::abs(ratio - std::round(ratio)) > 1e-9) {
      return Error{fmt::format("rate {} Hz does not divide the reference rate {} Hz", rate, options.reference_rate_hz)};
    }
  }
  report.clock = calibrate();
  CycleHistogram histogram;
  for (const std::string_view scene : kPaperScenes) {
    if (!scene_selected(scene, options.filter)) continue;
    const std::string path = paper_scene_path(options.root, scene);
    auto reference_desc = load_scene_file(path, ScalarKind::kDouble);
    if (!reference_desc) return Error{reference_desc.error()};
    say(fmt::format("{}: reference (double, library sine, {:g} Hz)", scene, options.reference_rate_hz));
    const Forces reference =
        run_any(reference_desc.value(), scene, ScalarKind::kDouble, options.reference_rate_hz, SineMethod::kLibrary);
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
          const auto step = static_cast<std::size_t>(std::llround(options.reference_rate_hz / rate));
          const Forces test = run_any(desc.value(), scene, kind, rate, sine);
          double sum = 0.0;
          for (std::size_t j = 0; j < test.force_n.size(); ++j) {
            const double e = norm(test.force_n[j] - reference.force_n[j * step]);
            row.max_error_n = std::max(row.max_error_n, e);
            sum += e * e;
          }
          row.rms_error_n = std::sqrt(sum / static_cast<double>(test.force_n.size()));
          for (std::size_t j = 0; j < test.force_n.size(); ++j) {
            row.same_rate_max_error_n =
                std::max(row.same_rate_max_error_n, norm(test.force_n[j] - same_rate[r].force_n[j]));
          }
          double held_sum = 0.0;
          for (std::size_t i = 0; i < reference.force_n.size(); ++i) {
            const double e = norm(test.force_n[i / step] - reference.force_n[i]);
            row.held_max_error_n = std::max(row.held_max_error_n, e);
            held_sum += e * e;
          }
          row.held_rms_error_n = std::sqrt(held_sum / static_cast<double>(reference.force_n.size()));
          row.fault_ticks = test.fault_ticks;

          auto timed = make_spec_loop_case(options.root, scene, kind, rate, sine);
          if (!timed) return Error{timed.error()};
          say(fmt::format("timing {}", timed.value()->info().id));
          timed.value()->run(std::max<std::uint64_t>(timed.value()->info().ticks_per_pass, 10000));
          histogram = CycleHistogram();
          timed.value()->time(options.timing_ticks, histogram);
          const double overhead = report.clock.overhead_mean_cycles;
          row.mean_ns = std::max(0.0, histogram.mean_in_bins() - overhead) / report.clock.cycles_per_ns;
          const std::uint64_t median = histogram.percentile(0.5);
          row.median_ns = static_cast<double>(median > report.clock.overhead_cycles ? median - report.clock.overhead_cycles : 0) /
                          report.clock.cycles_per_ns;
          report.rows.push_back(row);
        }
      }
    }

    if (options.drift_hours > 0.0) {
      const double ratio = options.reference_rate_hz / options.drift_rate_hz;
      const auto step = static_cast<std::int64_t>(std::llround(ratio));
      for (const ScalarKind kind : {ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16}) {
        auto desc = load_scene_file(path, kind);
        if (!desc) return Error{desc.error()};
        say(fmt::format("{}: {} for {:g} simulated hours at {:g} Hz", scene, scalar_kind_name(kind),
                        options.drift_hours, options.drift_rate_hz));
        switch (kind) {
          case ScalarKind::kDouble:
            report.drift.push_back(drift_run<double>(desc.value(), scene, reference.force_n, step,
                                                     options.drift_rate_hz, options.drift_hours));
            break;
          case ScalarKind::kFloat:
            report.drift.push_back(drift_run<float>(desc.value(), scene, reference.force_n, step,
                                                    options.drift_rate_hz, options.drift_hours));
            break;
          case ScalarKind::kQ16_16:
            report.drift.push_back(drift_run<Q16_16>(desc.value(), scene, reference.force_n, step,
                                                     options.drift_rate_hz, options.drift_hours));
            break;
        }
      }
    }
  }
  report.load_after = load_average();
  return report;
}

std::string precision_csv(const PrecisionReport& r) {
  std::string csv =
      "scene,scalar,sine,rate_hz,max_error_n,rms_error_n,same_rate_max_error_n,held_max_error_n,held_rms_error_n,mean_ns,"
      "median_ns,fault_ticks\n";
  for (const auto& row : r.rows) {
    csv += fmt::format("{},{},{},{:g},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.2f},{:.1f},{}\n", row.scene,
                       scalar_kind_name(row.scalar), row.sine ? sine_method_name(*row.sine) : std::string_view("-"),
                       row.rate_hz, row.max_error_n, row.rms_error_n, row.same_rate_max_error_n, row.held_max_error_n,
                       row.held_rms_error_n,
                       row.mean_ns, row.median_ns, row.fault_ticks);
  }
  return csv;
}

std::string drift_csv(const PrecisionReport& r) {
  std::string csv = "scene,scalar,hour,max_error_n,rms_error_n\n";
  for (const auto& d : r.drift) {
    for (std::size_t h = 0; h < d.max_error_n.size(); ++h) {
      csv += fmt::format("{},{},{},{:.6e},{:.6e}\n", d.scene, scalar_kind_name(d.scalar), h + 1, d.max_error_n[h],
                         d.rms_error_n[h]);
    }
  }
  return csv;
}

std::string precision_markdown(const PrecisionReport& r, const std::string& plot_dir) {
  std::string md;
  md += fmt::format("Measured {} UTC on {}; load average {} before, {} after. Clock: {}.\n\n", r.machine.date_utc,
                    describe(r.machine), r.load_before, r.load_after, describe(r.clock));
  md += fmt::format(
      "Reference: replay's servo loop (effects.md §6 stages) in double with the library sine at {:g} Hz on the same scripted scenario, the "
      "velocity estimated from the positions (the scenes' 50 Hz cut-off) as on a Falcon; forces include the "
      "scenes' safety stage (2000 N/s, 8 N). Each run covers two passes of the periodic scenario and only the "
      "second is compared. Every rate divides {:g} Hz, so each of its ticks falls on a reference tick: "
      "**sampled** error = |F - F_ref| at the configuration's own ticks; **held** error = at every reference tick, "
      "the configuration's last force (zero-order hold: what the device renders) against the reference's. Cost: "
      "replay's servo loop tick of that configuration, each of {} ticks timed alone (mean; the median is in steps of "
      "the counter, 10 ns here). CPU per second = mean ns x rate. **Max vs double, same rate** = the sampled error "
      "against double with the library sine at the same rate: the scalar type's and the sine method's own share.\n\n",
      r.options.reference_rate_hz, r.options.reference_rate_hz, r.options.timing_ticks);
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
  const auto summary_row = [&](const char* label, auto pick, bool nanoseconds = false) {
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
  summary_row("double: RMS held error vs the 40 kHz reference [N]",
              [](const PrecisionRow& row) { return row.scalar == ScalarKind::kDouble ? row.held_rms_error_n : 0.0; });
  summary_row("double: max sampled error vs the reference [N]",
              [](const PrecisionRow& row) { return row.scalar == ScalarKind::kDouble ? row.max_error_n : 0.0; });
  summary_row("float: max error vs double at the same rate [N]",
              [](const PrecisionRow& row) { return row.scalar == ScalarKind::kFloat ? row.same_rate_max_error_n : 0.0; });
  summary_row("q16.16: max error vs double at the same rate [N]",
              [](const PrecisionRow& row) { return row.scalar == ScalarKind::kQ16_16 ? row.same_rate_max_error_n : 0.0; });
  summary_row("double: mean ns per tick",
              [](const PrecisionRow& row) { return row.scalar == ScalarKind::kDouble ? row.mean_ns : 0.0; }, true);
  summary_row("float: mean ns per tick",
              [](const PrecisionRow& row) { return row.scalar == ScalarKind::kFloat ? row.mean_ns : 0.0; }, true);
  summary_row("q16.16: mean ns per tick",
              [](const PrecisionRow& row) { return row.scalar == ScalarKind::kQ16_16 ? row.mean_ns : 0.0; }, true);
  md += "\n";
  std::string scene;
  for (const auto& row : r.rows) {
    if (row.scene != scene) {
      scene = row.scene;
      md += fmt::format("\n#### {}\n\n", scene);
      md += "| scalar | sine | rate | max error [N] | RMS error [N] | max vs double, same rate [N] | held max [N] | held "
            "RMS [N] | mean ns | median ns | CPU per second [us] | fault ticks |\n";
      md += "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    }
    md += fmt::format("| {} | {} | {:g} Hz | {} | {} | {} | {} | {} | {:.1f} | {:.0f} | {:.0f} | {} |\n",
                      scalar_kind_name(row.scalar), row.sine ? sine_method_name(*row.sine) : std::string_view("-"),
                      row.rate_hz, sci(row.max_error_n), sci(row.rms_error_n), sci(row.same_rate_max_error_n),
                      sci(row.held_max_error_n),
                      sci(row.held_rms_error_n), row.mean_ns, row.median_ns, row.mean_ns * row.rate_hz / 1000.0,
                      row.fault_ticks);
  }
  if (!r.drift.empty()) {
    md += fmt::format(
        "\n### Drift over {:g} simulated hours\n\n"
        "Replay's servo loop at {:g} Hz on the repeating scenario ({:g} ticks per run), every tick after the first pass "
        "compared with the reference at the same phase of the scenario (sampled error). Time inside the effects is "
        "integer ticks (spec effects.md §0), so nothing should accumulate: the error of the last hour should equal "
        "the first's. Spread = (largest hourly value / smallest) - 1.\n\n",
        r.options.drift_hours, r.options.drift_rate_hz, r.options.drift_hours * 3600.0 * r.options.drift_rate_hz);
    if (!plot_dir.empty()) md += fmt::format("![drift over simulated hours]({}/drift.png)\n\n", plot_dir);
    md += "| scene | scalar | max error, first hour [N] | max error, last hour [N] | RMS, first hour [N] | RMS, last "
          "hour [N] | spread of the hourly max | spread of the hourly RMS | CPU time [s] |\n";
    md += "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    // Spread: (largest / smallest over the hours) - 1; 0 means every hour alike to the last digit.
    const auto spread = [](const std::vector<double>& v) {
      const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
      return *lo > 0.0 ? fmt::format("{:.1e}", *hi / *lo - 1.0) : std::string("-");
    };
    for (const auto& d : r.drift) {
      if (d.max_error_n.empty()) continue;
      md += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {:.1f} |\n", d.scene, scalar_kind_name(d.scalar),
                        sci(d.max_error_n.front()), sci(d.max_error_n.back()), sci(d.rms_error_n.front()),
                        sci(d.rms_error_n.back()), spread(d.max_error_n), spread(d.rms_error_n), d.cpu_s);
    }
  }
  return md;
}

}  // namespace toonforce::report
