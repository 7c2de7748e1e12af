// toonforce: the command line (spec interfaces.md). Each subcommand lives in its own file and
// registers itself here; this file only parses and dispatches.
#include <csignal>
#include <cstdio>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "commands.hpp"

int main(int argc, char** argv) {
  // A reader that went away (`toonforce ... --trace - | head`) is a write error every writer
  // reports, never a death: the servo loop must end by its own shut-down, not by SIGPIPE.
  std::signal(SIGPIPE, SIG_IGN);
  CLI::App app{"toonforce: expressive, cartoon-inspired haptic rendering (Haptics Symposium 2010)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "toonforce " TOONFORCE_VERSION);
  toonforce::cli::add_replay(app);
  toonforce::cli::add_run(app);
  toonforce::cli::add_doctor(app);
  toonforce::cli::add_sim(app);
  toonforce::cli::add_figures(app);
  toonforce::cli::add_devices(app);
  toonforce::cli::add_falcon(app);
  toonforce::cli::add_report(app);
  toonforce::cli::add_bringup(app);
  toonforce::cli::add_check(app);
#if TOONFORCE_VIEWER
  toonforce::cli::add_view(app);
#endif
  int code = 0;
  try {
    app.parse(argc, argv);
    code = toonforce::cli::exit_code();
  } catch (const CLI::ParseError& e) {
    // A bad command line (unknown flag, missing or out-of-range value) is "cannot start": 2
    // (interfaces.md), not CLI11's own codes (105, 106, 109, ...); --help and --version are 0.
    code = app.exit(e) == 0 ? 0 : 2;
  }
  // What went to standard output must have arrived (`falcon udev-rule > /dev/full`).
  if (std::fflush(stdout) != 0 || std::ferror(stdout) != 0) {
    std::fprintf(stderr, "toonforce: writing to standard output failed\n");
    if (code == 0) code = 1;
  }
  return code;
}
