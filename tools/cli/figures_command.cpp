// SPDX-License-Identifier: Apache-2.0
// toonforce figures [--out DIR] [--format png|svg] [--root DIR] [--no-plot]
#include <cstdio>
#include <memory>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/sim/figures.hpp"

namespace toonforce::cli {

void add_figures(CLI::App& app) {
  auto options = std::make_shared<FiguresOptions>();
  auto no_plot = std::make_shared<bool>(false);
  auto quiet = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("figures", "Regenerate the paper's figures 1-4 on the host simulation");
  cmd->add_option("--out", options->out_dir, "Directory for NAME.csv and NAME.png (default docs/figures)");
  cmd->add_option("--format", options->format, "Plot format (default png)")->check(CLI::IsMember({"png", "svg"}));
  cmd->add_option("--root", options->root,
                  "Directory holding scenes/ (default: the current one if it has scenes/hands, else an installed "
                  "toonforce's share/toonforce, else the source tree)");
  cmd->add_flag("--no-plot", *no_plot, "Write the traces only");
  cmd->add_flag("--quiet,-q", *quiet, "Print nothing but errors");
  cmd->callback([options, no_plot, quiet] {
    options->plot = !*no_plot;
    const auto lines = run_figures(*options);
    if (!lines) {
      std::fputs(lines.error().c_str(), stderr);
      if (lines.error().empty() || lines.error().back() != '\n') std::fputc('\n', stderr);
      set_exit_code(1);
      return;
    }
    if (!*quiet) {
      for (const auto& line : lines.value()) std::puts(line.c_str());
    }
    set_exit_code(0);
  });
}

}  // namespace toonforce::cli
