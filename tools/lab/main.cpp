// SPDX-License-Identifier: Apache-2.0
// toonforce-lab: the lab's program, built beside toonforce in a build tree and never installed.
// It holds what measures the project (`report`), so that the installed toonforce carries none
// of it (docs/ARCHITECTURE.md, "The lab"). Parsing and exit statuses are the product's
// (spec interfaces.md, exits.md).
#include <csignal>
#include <cstdio>
#include <exception>
#include <new>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "lab_commands.hpp"

namespace toonforce::cli {

namespace {
int g_exit_code = 0;
}

int exit_code() { return g_exit_code; }
void set_exit_code(int code) { g_exit_code = code; }

}  // namespace toonforce::cli

int main(int argc, char** argv) {
  // As in toonforce: a reader that went away or a file-size limit is a write error the report
  // says, never a death (the report's stop handlers take the stop signals).
  std::signal(SIGPIPE, SIG_IGN);
  std::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{"toonforce-lab: the toonforce project measuring itself (reports for docs/); not installed"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "toonforce-lab " TOONFORCE_VERSION);
  toonforce::cli::add_report(app);
  int code = 0;
  try {
    app.parse(argc, argv);
    code = toonforce::cli::exit_code();
  } catch (const CLI::ParseError& e) {
    // A bad command line is "cannot start": 2, as in toonforce; --help and --version are 0.
    code = app.exit(e) == 0 ? 0 : 2;
  } catch (const std::bad_alloc&) {
    std::fputs("toonforce-lab: out of memory (is `ulimit -v` too small?)\n", stderr);
    code = 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "toonforce-lab: %s\n", e.what());
    code = 1;
  }
  if (std::fflush(stdout) != 0 || std::ferror(stdout) != 0) {
    std::fprintf(stderr, "toonforce-lab: writing to standard output failed\n");
    if (code == 0) code = 1;
  }
  return code;
}
