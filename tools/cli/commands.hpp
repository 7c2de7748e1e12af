// SPDX-License-Identifier: Apache-2.0
#pragma once
// Subcommands of the toonforce command line. Each add_* registers a subcommand whose callback
// runs it and stores the process exit status.
#include <initializer_list>
#include <string>

#include <CLI/CLI.hpp>

#include "toonforce/sim/check.hpp"

namespace toonforce::cli {

void add_replay(CLI::App& app);
void add_run(CLI::App& app);
void add_doctor(CLI::App& app);
void add_sim(CLI::App& app);
void add_figures(CLI::App& app);
void add_devices(CLI::App& app);
void add_falcon(CLI::App& app);
void add_bringup(CLI::App& app);
#if TOONFORCE_STUDY
void add_study(CLI::App& app);
#endif
void add_check(CLI::App& app);
#if TOONFORCE_VIEWER
void add_view(CLI::App& app);
#endif

/// Numeric option checks. CLI11's print their bounds with %f (the largest double in 309
/// digits) and take "inf" for a positive number; these say the range with %g and
/// want a finite number, so a bad value is one short line.
CLI::Validator number_in(double lo, double hi);
CLI::Validator positive_number();
CLI::Validator non_negative_number();
/// --max-output after CLI::AsSizeValue: 0 .. 4 EiB (it let -1 and 2^64 through, refusing 16E).
CLI::Validator max_output_range();

/// The input among `inputs` that writing `output` would overwrite, or "" if none: the same
/// device and inode (a link, another spelling), or, for an output that does not exist yet, the
/// same path by name. Empty names are skipped.
std::string input_overwritten_by(const std::string& output, std::initializer_list<std::string> inputs);

/// "" or why `check` and `run --script` refuse a hand script lasting `length_s` (the sim
/// library's, shared with the Python module).
using toonforce::hand_script_length_problem;

/// The exit status the subcommand that ran asked for.
int exit_code();
void set_exit_code(int code);

/// Parses the command line into `app` (running the subcommand it names) and returns the exit
/// status, for toonforce and the lab's toonforce-lab alike (spec interfaces.md, exits.md): a bad
/// command line is 2, too little memory 2, any other error 1 with `program: what` on standard
/// error, and what went to standard output must have arrived.
int parse_and_finish(CLI::App& app, int argc, char** argv, const char* program);

}  // namespace toonforce::cli
