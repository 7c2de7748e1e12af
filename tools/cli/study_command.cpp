// SPDX-License-Identifier: Apache-2.0
// toonforce study run|resume|analyze ...: perception studies (docs/STUDIES.md). The study runner
// is Python (scipy fits the psychometric functions, the participant's page is served by it, each
// interval is a toonforce run it drives through the control protocol), in the Python module's
// package toonforce.study; this command hands its arguments to `/usr/bin/python3 -m
// toonforce.study`, with the build tree's package on PYTHONPATH when this binary was built
// beside it (an installed toonforce finds the installed package in Debian's dist-packages).
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "commands.hpp"

namespace toonforce::cli {

void add_study(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand(
      "study", "Perception studies: run a session (a person at a device, or a simulated participant), resume it, "
               "analyze sessions (docs/STUDIES.md; `toonforce study --help` after `study` for its options)");
  cmd->prefix_command();  // everything after `study` is the study runner's, --help included
  cmd->set_help_flag();
  cmd->callback([cmd] {
    std::vector<std::string> argv{"/usr/bin/python3", "-m", "toonforce.study"};
    for (const auto& a : cmd->remaining()) argv.push_back(a);
    if (argv.size() == 3) argv.emplace_back("--help");
#ifdef TOONFORCE_PYTHON_FROM_BINDIR
    // The build tree's package, if this binary is still beside it: found from where the binary
    // is (bin/../python), so that no path of the build machine is compiled into the program.
    std::error_code ec;
    const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    const std::filesystem::path package_dir = (exe.parent_path() / TOONFORCE_PYTHON_FROM_BINDIR).lexically_normal();
    if (!ec && !exe.empty() && std::filesystem::is_directory(package_dir / "toonforce", ec)) {
      const char* old = std::getenv("PYTHONPATH");
      const std::string path = package_dir.string() + (old != nullptr && *old ? std::string(":") + old : "");
      setenv("PYTHONPATH", path.c_str(), 1);
    }
#endif
    // The study runner finds this program for its runs (toonforce.live) as TOONFORCE_BINARY.
    std::error_code ec2;
    const auto self = std::filesystem::read_symlink("/proc/self/exe", ec2);
    if (!ec2 && std::getenv("TOONFORCE_BINARY") == nullptr) setenv("TOONFORCE_BINARY", self.c_str(), 1);
    std::vector<char*> raw;
    for (auto& a : argv) raw.push_back(a.data());
    raw.push_back(nullptr);
    std::fflush(stdout);
    ::execv(raw[0], raw.data());
    fmt::print(stderr, "toonforce study: cannot start {}: {} (install python3: tools/setup-deps)\n", argv[0],
               std::strerror(errno));
    set_exit_code(2);
  });
}

}  // namespace toonforce::cli
