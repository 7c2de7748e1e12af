// SPDX-License-Identifier: Apache-2.0
// toonforce replay --scene S.toml --input motion.csv --output forces.csv [--scalar ...] [--sine ...]
#include <atomic>
#include <cctype>
#include <cstdio>
#include <map>
#include <memory>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/replay/replay.hpp"

namespace toonforce::cli {

void add_replay(CLI::App& app) {
  auto options = std::make_shared<ReplayOptions>();
  auto quiet = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("replay", "Forces for a given motion, open loop (one row = one servo tick)");
  cmd->add_option("--scene", options->scene_path, "Scene file (TOML)")->required();
  cmd->add_flag("--allow-empty", options->allow_empty, "A scene without surfaces or cliffs is not an error");
  cmd->add_option("--input", options->input_path, "Motion CSV: t,x,y,z[,vx,vy,vz]")->required();
  cmd->add_option("--output", options->output_path, "Forces CSV to write ('-' for standard output)")->required();
  // Words in, parsed in the callback: CLI11's CheckedTransformer on these uint8_t enumerations
  // printed their values as raw bytes in --help (NUL for polynomial) and took `--sine 1`.
  auto scalar = std::make_shared<std::string>("double");
  auto sine = std::make_shared<std::string>();
  cmd->add_option("--scalar", *scalar, "Scalar type of the computation (default double)")
      ->check(CLI::IsMember({"double", "float", "q16.16"}, CLI::ignore_case));
  cmd->add_option("--sine", *sine, "Sine method of impact transients (overrides the scene)")
      ->check(CLI::IsMember({"library", "polynomial", "table"}, CLI::ignore_case));
  cmd->add_flag("--quiet,-q", *quiet, "Print nothing but errors");
  cmd->callback([options, quiet, scalar, sine] {
    const auto lower = [](std::string text) {
      for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      return text;
    };
    options->scalar = parse_scalar_kind(lower(*scalar)).value_or(ScalarKind::kDouble);
    if (!sine->empty()) options->sine = parse_sine_method(lower(*sine));
    // Every stop signal ends the replay after its row under way: the output ends on a whole
    // row, the summary says how far it got, exit status 1 (docs/spec/exits.md).
    std::atomic<int> stop{0};
    options->stop = &stop;
    install_signal_handlers(stop, EmergencyZero{});
    const auto summary = run_replay(*options);
    restore_signals();
    if (!summary) {
      std::fputs(summary.error().c_str(), stderr);
      if (summary.error().empty() || summary.error().back() != '\n') std::fputc('\n', stderr);
      set_exit_code(1);
      return;
    }
    if (!summary->input_note.empty()) fmt::print(stderr, "warning: {}\n", summary->input_note);
    if (!*quiet)
      std::fputs(format_summary(summary.value(), *options).c_str(), options->output_path == "-" ? stderr : stdout);
    if (!summary->output_error.empty()) {
      fmt::print(stderr, "toonforce: the output is incomplete: {}\n", summary->output_error);
      set_exit_code(1);
      return;
    }
    if (summary->stop_signal != 0) {
      fmt::print(stderr, "toonforce: stopped by {} after {} of {} rows: {} ends on the last whole one\n",
                 signal_name(summary->stop_signal), summary->rows_done, summary->rows, options->output_path);
      set_exit_code(1);
      return;
    }
    set_exit_code(0);
  });
}

}  // namespace toonforce::cli
