#pragma once
// Subcommands of the toonforce command line. Each add_* registers a subcommand whose callback
// runs it and stores the process exit status.
#include <CLI/CLI.hpp>

namespace toonforce::cli {

void add_replay(CLI::App& app);
void add_run(CLI::App& app);
void add_doctor(CLI::App& app);
void add_sim(CLI::App& app);
void add_figures(CLI::App& app);
void add_devices(CLI::App& app);
void add_falcon(CLI::App& app);
void add_report(CLI::App& app);
void add_bringup(CLI::App& app);
void add_check(CLI::App& app);
#if TOONFORCE_VIEWER
void add_view(CLI::App& app);
#endif

/// Numeric option checks. CLI11's print their bounds with %f (the largest double in 309
/// digits, issue 16) and take "inf" for a positive number; these say the range with %g and
/// want a finite number, so a bad value is one short line.
CLI::Validator number_in(double lo, double hi);
CLI::Validator positive_number();
CLI::Validator non_negative_number();

/// The exit status the subcommand that ran asked for.
int exit_code();
void set_exit_code(int code);

}  // namespace toonforce::cli
