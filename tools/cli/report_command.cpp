// toonforce report latency|precision|stability|all: the project measuring itself (issue 8).
// Each prints Markdown; `all` regenerates docs/PERFORMANCE.md and docs/STABILITY.md and their
// plots (tools/report/include/toonforce/report/documents.hpp).
#include <cstdio>
#include <memory>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/report/latency.hpp"
#include "toonforce/report/paths.hpp"

namespace toonforce::cli {

namespace {

void progress(const std::string& line) { std::fprintf(stderr, "report: %s\n", line.c_str()); }

template <class T>
bool report_error(const Result<T>& r) {
  if (r) return false;
  std::fprintf(stderr, "toonforce report: %s\n", r.error().c_str());
  set_exit_code(1);
  return true;
}

void add_latency(CLI::App& report) {
  auto options = std::make_shared<report::LatencyOptions>();
  auto no_callgrind = std::make_shared<bool>(false);
  CLI::App* cmd = report.add_subcommand(
      "latency", "ns and instructions per tick of each effect, paper scene and Controller, per scalar type");
  cmd->add_option("--root", options->root, "Source tree holding scenes/ (default: . if it has scenes/, else the build's)");
  cmd->add_option("--ticks", options->ticks, "Timed ticks per row (default 10^7)")->check(CLI::PositiveNumber);
  cmd->add_option("--filter", options->filter, "Only rows whose id contains one of these comma-separated texts");
  cmd->add_option("--cpu", options->cpu, "Pin the timing thread to this CPU");
  cmd->add_flag("--no-callgrind", *no_callgrind, "Do not count instructions (no valgrind run)");
  cmd->add_option("--valgrind", options->valgrind, "The valgrind to run (default: valgrind from PATH)");
  cmd->add_option("--tick-count", options->tick_count, "toonforce_tick_count (default: beside this executable)");
  cmd->callback([options, no_callgrind] {
    options->callgrind = !*no_callgrind;
    options->root = report::source_root(options->root);
    const auto result = report::run_latency(*options, progress);
    if (report_error(result)) return;
    std::fputs(report::latency_markdown(result.value()).c_str(), stdout);
    set_exit_code(0);
  });
}

}  // namespace

void add_report(CLI::App& app) {
  CLI::App* report = app.add_subcommand("report", "Measure toonforce: latency, precision, stability (Markdown)");
  report->require_subcommand(1);
  add_latency(*report);
}

}  // namespace toonforce::cli
