// SPDX-License-Identifier: Apache-2.0
// toonforce-lab report latency|precision|fixed-point|stability|mcu|all: the project measuring
// itself (the lab's program, tools/lab; never installed).
// Each prints Markdown; `all` regenerates the generated blocks of docs/performance/ and
// docs/STABILITY.md and their plots (tools/report/include/toonforce/report/documents.hpp), and
// the microcontroller block when the Cortex-M3 images are built (mcu.hpp).
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "lab_commands.hpp"
#include "toonforce/report/staged_outputs.hpp"
#include "toonforce/report/documents.hpp"
#include "toonforce/report/latency.hpp"
#include "toonforce/report/paths.hpp"
#include "toonforce/report/fixed_point_map.hpp"
#include "toonforce/report/mcu.hpp"
#include "toonforce/report/precision.hpp"
#include "toonforce/report/stability.hpp"

namespace toonforce::cli {

namespace {

void progress(const std::string& line) { std::fprintf(stderr, "report: %s\n", line.c_str()); }

constexpr double kMaxTicks = 1e10;      // about an hour of timing at a few ns per tick
constexpr double kMaxDriftHours = 100;  // simulated hours per scene; 1e308 never ended
constexpr double kMaxCpu = 1023;        // CPU_SETSIZE - 1

/// What run_precision would refuse about the rates, said before anything runs; "" if nothing.
std::string rates_ladder_error(const report::PrecisionOptions& o) {
  if (o.reference_rates_hz.empty()) return "--reference-rates: none given";
  const double reference = o.reference_rates_hz.back();
  for (const double rate : o.rates_hz) {
    const double ratio = reference / rate;
    if (std::abs(ratio - std::round(ratio)) > 1e-9) {
      return fmt::format("--rates {:g}: does not divide the reference rate {:g} Hz (the last of --reference-rates)",
                         rate, reference);
    }
  }
  for (std::size_t i = 1; i < o.reference_rates_hz.size(); ++i) {
    if (o.reference_rates_hz[i] != 2.0 * o.reference_rates_hz[i - 1]) {
      return "--reference-rates: each must be twice the one before";
    }
  }
  return {};
}

template <class T>
bool report_error(const Result<T>& r) {
  if (r) return false;
  std::fprintf(stderr, "toonforce-lab report: %s\n", r.error().c_str());
  set_exit_code(1);
  return true;
}

void add_latency(CLI::App& report) {
  auto options = std::make_shared<report::LatencyOptions>();
  auto no_callgrind = std::make_shared<bool>(false);
  CLI::App* cmd = report.add_subcommand(
      "latency", "ns and instructions per tick of each effect, paper scene and servo loop, per scalar type");
  cmd->add_option("--root", options->root,
                  "Source tree holding scenes/ (default: . if it has scenes/, else the build's)");
  // Every numeric option's range is checked here, before anything runs (2^64-1 cold
  // ticks ran without end, 1e308 seconds aborted in llround).
  cmd->add_option("--ticks", options->ticks, "Timed ticks per row, 1..1e10 (default 10^7)")
      ->check(number_in(1, kMaxTicks));
  cmd->add_option("--cold-ticks", options->cold_ticks,
                  "Ticks per scene and loop row timed with the data caches cold, 0..1e6 (default 1000; 0: none)")
      ->check(number_in(0, 1e6));
  cmd->add_option("--filter", options->filter, "Only rows whose id contains one of these comma-separated texts");
  cmd->add_option("--cpu", options->cpu, "Pin the timing thread to this CPU")->check(number_in(0, kMaxCpu));
  cmd->add_flag("--no-callgrind", *no_callgrind, "Do not count instructions (no valgrind run)");
  cmd->add_option("--valgrind", options->valgrind, "The valgrind to run (default: valgrind from PATH)");
  cmd->add_option("--tick-count", options->tick_count, "toonforce_tick_count (default: beside this executable)");
  auto docs = std::make_shared<std::string>();
  cmd->add_option("--docs", *docs, "Regenerate the latency block of DIR/performance/tick.md instead of printing it");
  cmd->callback([options, no_callgrind, docs, cmd] {
    options->callgrind = !*no_callgrind;
    const bool root_given = !options->root.empty();
    options->root = report::source_root(options->root);
    const auto result = report::run_latency(*options, progress);
    if (report_error(result)) return;
    if (docs->empty()) {
      std::fputs(report::latency_markdown(result.value()).c_str(), stdout);
      set_exit_code(0);
      return;
    }
    // The line that made the block, for the block's header: the options given, no paths of this machine.
    std::string line = "toonforce-lab report latency --docs " + *docs;
    if (cmd->count("--ticks") > 0) line += fmt::format(" --ticks {}", options->ticks);
    if (cmd->count("--cold-ticks") > 0) line += fmt::format(" --cold-ticks {}", options->cold_ticks);
    if (cmd->count("--filter") > 0) line += fmt::format(" --filter {}", options->filter);
    if (cmd->count("--cpu") > 0) line += fmt::format(" --cpu {}", options->cpu);
    if (*no_callgrind) line += " --no-callgrind";
    if (root_given) line += " --root " + options->root;
    const auto written = report::write_latency_documents(result.value(), *docs, line);
    if (report_error(written)) return;
    for (const auto& path : written.value()) std::fprintf(stderr, "report: wrote %s\n", path.c_str());
    set_exit_code(0);
  });
}

void add_precision(CLI::App& report) {
  auto options = std::make_shared<report::PrecisionOptions>();
  CLI::App* cmd = report.add_subcommand(
      "precision",
      "Force error against references whose own error is known (closed form; a 40-320 kHz convergence ladder), event "
      "lateness, ns per tick; closed-loop drift over simulated hours");
  auto docs = std::make_shared<std::string>();
  cmd->add_option("--root", options->root, "Source tree holding scenes/");
  cmd->add_option("--rates", options->rates_hz, "Servo rates to compare [Hz], 10..1e6 (default 500 1000 4000 10000)")
      ->check(number_in(10, 1e6));
  cmd->add_option("--ticks", options->timing_ticks, "Timed ticks per configuration, 1..1e10 (default 10^6)")
      ->check(number_in(1, kMaxTicks));
  cmd->add_option("--reference-rates", options->reference_rates_hz,
                  "The double reference's ladder, each twice the last; the last is the reference [Hz], 10..1e7 "
                  "(default 40000 80000 160000 320000)")
      ->check(number_in(10, 1e7));
  cmd->add_option("--drift-hours", options->drift_hours,
                  "Simulated hours of closed loop per scene in the drift run, 0..100 (default 1; 0: none)")
      ->check(number_in(0, kMaxDriftHours));
  cmd->add_option("--drift-rate", options->drift_rate_hz,
                  "Servo rate of the drift run [Hz], 100..100000 (default 1000)")
      ->check(number_in(100, 100000));
  cmd->add_option("--drift-seed", options->drift_seed, "Seed of the drift run's hand motion (default 15)");
  cmd->add_option("--filter", options->filter, "Only scenes whose name contains one of these comma-separated texts");
  cmd->add_option("--docs", *docs,
                  "Also write the CSVs and plots into DIR/report/ and regenerate the precision block of "
                  "DIR/performance/precision.md");
  auto no_plot = std::make_shared<bool>(false);
  cmd->add_flag("--no-plot", *no_plot, "With --docs: no plots");
  auto mcu_images = std::make_shared<std::string>();
  cmd->add_option("--mcu-images", *mcu_images,
                  "The Cortex-M3 images whose loop tick gives the closed loop's M3 column (default: report mcu's; "
                  "not built: the column says so)");
  cmd->callback([options, docs, no_plot, mcu_images, cmd] {
    // The rates' ladder is checked before the slow parts (the Cortex-M3 run): a wrong one is a
    // bad command line, exit status 2, not a failure after minutes.
    if (const std::string bad = rates_ladder_error(*options); !bad.empty()) {
      std::fprintf(stderr, "%s\n", bad.c_str());
      return set_exit_code(2);
    }
    options->root = report::source_root(options->root);
    // The closed loop's second target: the Cortex-M3's loop tick, when its images are built
    // (seconds under QEMU); else the column says "not built".
    report::McuOptions mcu;
    mcu.root = options->root;
    mcu.images = *mcu_images;
    if (const std::string why = report::mcu_images_missing(mcu); !why.empty()) {
      std::fprintf(stderr, "closed loop, Cortex-M3 column: not built: %s\n", why.c_str());
    } else {
      const auto figures = report::run_mcu(mcu, progress);
      if (report_error(figures)) return;
      options->m3_loop_instructions_per_tick = report::mcu_loop_mean_instructions(figures.value().m3);
    }
    const auto result = report::run_precision(*options, progress);
    if (report_error(result)) return;
    if (!docs->empty()) {
      // The command as asked for, written beside the figures.
      std::string line = "toonforce-lab report precision --docs " + *docs;
      if (options->drift_hours != report::PrecisionOptions{}.drift_hours)
        line += fmt::format(" --drift-hours {:g}", options->drift_hours);
      if (!options->filter.empty()) line += " --filter " + options->filter;
      if (cmd->count("--ticks") > 0) line += fmt::format(" --ticks {}", options->timing_ticks);
      const auto written = report::write_precision_documents(result.value(), *docs, line, !*no_plot);
      if (report_error(written)) return;
      for (const auto& file : written.value()) std::printf("wrote %s\n", file.c_str());
    } else {
      std::fputs(report::precision_markdown(result.value()).c_str(), stdout);
    }
    set_exit_code(0);
  });
}

/// Where Q16.16 saturates: what the load-time guards accept (arithmetic only, nothing timed).
void add_fixed_point(CLI::App& report) {
  CLI::App* cmd = report.add_subcommand(
      "fixed-point", "Where Q16.16 saturates: the largest rate and scene values the q16.16 guards accept (no timing)");
  cmd->callback([] {
    std::fputs(report::fixed_point_map_markdown().c_str(), stdout);
    set_exit_code(0);
  });
}

void add_stability(CLI::App& report) {
  auto options = std::make_shared<report::StabilityOptions>();
  auto out = std::make_shared<std::string>();
  auto no_plot = std::make_shared<bool>(false);
  CLI::App* cmd = report.add_subcommand(
      "stability",
      "Sweeps of stiffness, damping, slippery gain, period and impact speed, classified by the loop's eigenvalues "
      "and by energy");
  cmd->add_option("--resolution", options->resolution, "Points per axis (default 24)")->check(number_in(2, 200));
  cmd->add_option("--duration", options->duration_s, "Simulated seconds per point, 0.01..1000 (default 4)")
      ->check(number_in(0.01, 1000));
  cmd->add_option("--longest-run", options->longest_run_s,
                  "Longest run [s] of a linear-map point whose eigenvalue predicts growth, 1..3600 (default 300)")
      ->check(number_in(1, 3600));
  cmd->add_option("--filter", options->filter, "Only maps whose name contains one of these comma-separated texts");
  cmd->add_option("--out", *out,
                  "Also write OUT/STABILITY.md and its CSVs and plots in OUT/report/ (not the performance pages)");
  cmd->add_flag("--no-plot", *no_plot, "With --out: the CSVs and STABILITY.md without plots");
  cmd->callback([options, out, no_plot] {
    if (!out->empty()) {
      report::DocumentsOptions documents;
      documents.out_dir = *out;
      documents.stability = *options;
      documents.plot = !*no_plot;
      documents.command_line = fmt::format(
          "toonforce-lab report stability --out {}{}{}{}", *out,
          options->resolution == 24 ? "" : fmt::format(" --resolution {}", options->resolution),
          options->duration_s == 4.0 ? "" : fmt::format(" --duration {:g}", options->duration_s),
          options->longest_run_s == 300.0 ? "" : fmt::format(" --longest-run {:g}", options->longest_run_s));
      const auto written = report::write_stability_documents(documents, progress);
      if (report_error(written)) return;
      for (const auto& file : written.value()) std::printf("wrote %s\n", file.c_str());
      set_exit_code(0);
      return;
    }
    const auto result = report::run_stability(*options, progress);
    if (report_error(result)) return;
    std::fputs(report::stability_markdown(result.value()).c_str(), stdout);
    set_exit_code(0);
  });
}

/// The microcontroller figures: the Cortex-M3 images (and the M4F ones beside them)
/// under QEMU, their tables; --docs regenerates their block of performance/mcu.md.
void add_mcu(CLI::App& report) {
  auto options = std::make_shared<report::McuOptions>();
  auto docs = std::make_shared<std::string>();
  CLI::App* cmd = report.add_subcommand(
      "mcu",
      "Microcontroller figures: each Cortex-M3 (and M4F) image's size and its exact instructions per tick under QEMU "
      "(needs the images, arm-none-eabi-size and qemu-system-arm)");
  cmd->add_option("--root", options->root, "Source tree the default directories are in");
  cmd->add_option("--images", options->images,
                  "The Cortex-M3 images (default: build/cortex-m3/tools/mcu/cortex-m3 if it has images, else "
                  "build/release/tools/mcu/cortex-m3)");
  cmd->add_option("--m4f-images", options->m4f_images,
                  "The Cortex-M4F images (default: cortex-m4f beside the M3 ones; if absent, the section says so)");
  cmd->add_option("--gen", options->gen, "toonforce_mcu_gen (default: in the M3 images' parent directory)");
  cmd->add_option("--docs", *docs,
                  "Regenerate the microcontroller block of DIR/performance/mcu.md instead of printing it");
  cmd->callback([options, docs] {
    // The command as asked for, written into the section.
    std::string line = "toonforce-lab report mcu";
    if (!docs->empty()) line += " --docs " + *docs;
    if (!options->root.empty()) line += " --root " + options->root;
    if (!options->images.empty()) line += " --images " + options->images;
    if (!options->m4f_images.empty()) line += " --m4f-images " + options->m4f_images;
    if (!options->gen.empty()) line += " --gen " + options->gen;
    options->command = line;
    options->root = report::source_root(options->root);
    const auto result = report::run_mcu(*options, progress);
    if (report_error(result)) return;
    if (!docs->empty()) {
      const auto written = report::write_mcu_documents(result.value(), *docs);
      if (report_error(written)) return;
      for (const auto& file : written.value()) std::printf("wrote %s\n", file.c_str());
    } else {
      std::fputs(report::mcu_markdown(result.value()).c_str(), stdout);
    }
    set_exit_code(0);
  });
}

void add_all(CLI::App& report) {
  auto options = std::make_shared<report::DocumentsOptions>();
  auto quick = std::make_shared<bool>(false);
  auto no_callgrind = std::make_shared<bool>(false);
  auto no_plot = std::make_shared<bool>(false);
  CLI::App* cmd = report.add_subcommand(
      "all", "Run every report; regenerate the blocks of OUT/performance/, OUT/STABILITY.md, OUT/report/");
  cmd->add_option("--out", options->out_dir, "Directory of the documents (default docs)");
  cmd->add_option("--root", options->root, "Source tree holding scenes/");
  cmd->add_option("--ticks", options->latency.ticks, "Timed ticks per latency row, 1..1e10 (default 10^7)")
      ->check(number_in(1, kMaxTicks));
  cmd->add_option("--drift-hours", options->precision.drift_hours,
                  "Simulated hours of closed loop per scene in the drift run, 0..100 (default 1)")
      ->check(number_in(0, kMaxDriftHours));
  cmd->add_option("--resolution", options->stability.resolution, "Stability points per axis (default 24)")
      ->check(number_in(2, 200));
  cmd->add_option("--cpu", options->latency.cpu, "Pin the timing thread to this CPU")->check(number_in(0, kMaxCpu));
  cmd->add_flag(
      "--quick", *quick,
      "A smoke run: 10^5 ticks (100 cold), 0.01 simulated hours of drift, 1 s of closed loop, 8 points per axis");
  cmd->add_flag("--no-callgrind", *no_callgrind, "Do not count instructions");
  cmd->add_flag("--no-plot", *no_plot, "Write the CSVs and documents without plots");
  cmd->callback([options, quick, no_callgrind, no_plot] {
    const std::string root_given = options->root;
    options->root = report::source_root(options->root);
    options->latency.callgrind = !*no_callgrind;
    options->plot = !*no_plot;
    if (*quick) {
      options->latency.ticks = 100'000;
      options->latency.cold_ticks = 100;
      options->precision.timing_ticks = 100'000;
      options->precision.drift_hours = 0.01;
      options->precision.closed_loop_s = 1.0;
      options->stability.resolution = 8;
    }
    options->command_line =
        fmt::format("toonforce-lab report all --out {}{}", options->out_dir, *quick ? " --quick" : "");
    // The microcontroller figures first (seconds; an image that fails stops here, before the
    // long reports): only with the Cortex-M3 images built, which needs the cross compiler.
    report::McuOptions mcu;
    mcu.root = options->root;
    mcu.command =
        "toonforce-lab report mcu --docs " + options->out_dir + (root_given.empty() ? "" : " --root " + root_given);
    if (const std::string why = report::mcu_images_missing(mcu); !why.empty()) {
      std::printf("not regenerated: the microcontroller block of %s/performance/mcu.md: %s\n", options->out_dir.c_str(),
                  why.c_str());
    } else {
      const auto figures = report::run_mcu(mcu, progress);
      if (report_error(figures)) return;
      options->precision.m3_loop_instructions_per_tick = report::mcu_loop_mean_instructions(figures.value().m3);
      const auto mcu_written = report::write_mcu_documents(figures.value(), options->out_dir);
      if (report_error(mcu_written)) return;
      for (const auto& file : mcu_written.value()) std::printf("wrote %s (microcontroller block)\n", file.c_str());
    }
    const auto written = report::write_documents(*options, progress);
    if (report_error(written)) return;
    for (const auto& file : written.value()) std::printf("wrote %s\n", file.c_str());
    set_exit_code(0);
  });
}

}  // namespace

void add_report(CLI::App& app) {
  CLI::App* report = app.add_subcommand(
      "report", "Measure toonforce: latency, precision, stability, microcontroller figures (Markdown)");
  report->require_subcommand(1);
  // A stop signal ends a report without a cut file (report/staged_outputs.hpp); from the start,
  // since every step runs for seconds to minutes.
  report->preparse_callback(
      [](std::size_t) { report::install_report_stop_handlers("toonforce-lab report", report::kReportLeaves); });
  add_latency(*report);
  add_precision(*report);
  add_fixed_point(*report);
  add_stability(*report);
  add_mcu(*report);
  add_all(*report);
}

}  // namespace toonforce::cli
