// toonforce: the command line (spec interfaces.md). Each subcommand lives in its own file and
// registers itself here; this file only parses and dispatches.
#include <cstdio>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "commands.hpp"

int main(int argc, char** argv) {
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
#if TOONFORCE_VIEWER
  toonforce::cli::add_view(app);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  return toonforce::cli::exit_code();
}
