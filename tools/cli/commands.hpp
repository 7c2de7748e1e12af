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

/// The exit status the subcommand that ran asked for.
int exit_code();
void set_exit_code(int code);

}  // namespace toonforce::cli
