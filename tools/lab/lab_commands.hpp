// SPDX-License-Identifier: Apache-2.0
#pragma once
// Subcommands of toonforce-lab, the lab's program: the project measuring itself. It shares the
// product's option checks and exit-status store (tools/cli/commands.hpp) but is never installed.
#include <CLI/CLI.hpp>

namespace toonforce::cli {

/// `report latency|precision|fixed-point|stability|mcu|all` (report_command.cpp).
void add_report(CLI::App& app);

}  // namespace toonforce::cli
