// SPDX-License-Identifier: Apache-2.0
// toonforce-lab: the lab's program, built beside toonforce in a build tree and never installed.
// It holds what measures the project (`report`), so that the installed toonforce carries none
// of it (docs/ARCHITECTURE.md, "The lab"). Parsing and exit statuses are the product's
// (spec interfaces.md, exits.md).
#include <csignal>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "lab_commands.hpp"

int main(int argc, char** argv) {
  // As in toonforce: a reader that went away or a file-size limit is a write error the report
  // says, never a death (the report's stop handlers take the stop signals).
  std::signal(SIGPIPE, SIG_IGN);
  std::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{"toonforce-lab: the toonforce project measuring itself (reports for docs/); not installed"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "toonforce-lab " TOONFORCE_VERSION);
  toonforce::cli::add_report(app);
  return toonforce::cli::parse_and_finish(app, argc, argv, "toonforce-lab");
}
