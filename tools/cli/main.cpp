// SPDX-License-Identifier: Apache-2.0
// toonforce: the command line (spec interfaces.md). Each subcommand lives in its own file and
// registers itself here; this file only parses and dispatches.
#include <csignal>
#include <cstdio>
#include <string_view>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "toonforce/run/command_stop.hpp"

int main(int argc, char** argv) {
  // A reader that went away (`toonforce ... --trace - | head`) is a write error every writer
  // reports, never a death: the servo loop must end by its own shut-down, not by SIGPIPE.
  std::signal(SIGPIPE, SIG_IGN);
  // A file-size limit (`ulimit -f`) is a write error (EFBIG) the writers report as a full disk,
  // never a death with an empty statistics file (a SIGXFSZ sent with kill is a stop in the loop).
  std::signal(SIGXFSZ, SIG_IGN);
  // `run` handles every stop signal from here on: a signal that comes while the command line is
  // read, the guardian starts or the scene loads is a stop before the loop (exit status 2), never
  // a death by its default action (command_stop.hpp). After the line above: a SIGXFSZ sent with
  // kill is a stop like the others (the handler itself ignores the kernel's file-size one).
  if (argc > 1 && std::string_view(argv[1]) == "run") toonforce::install_command_stop_signals();
  // `report` measures the project, not a device: it is the lab's program (tools/lab), which a
  // build tree has beside this one and no install ships. Said in one line, whatever follows it.
  if (argc > 1 && std::string_view(argv[1]) == "report") {
    std::fputs("toonforce: `report` is not part of toonforce: it is the lab's `toonforce-lab report ...`, "
               "built beside toonforce in a build tree (bin/toonforce-lab) and never installed\n",
               stderr);
    return 2;
  }
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
  toonforce::cli::add_bringup(app);
#if TOONFORCE_STUDY
  toonforce::cli::add_study(app);
#endif
  toonforce::cli::add_check(app);
#if TOONFORCE_VIEWER
  toonforce::cli::add_view(app);
#endif
  return toonforce::cli::parse_and_finish(app, argc, argv, "toonforce");
}
