// SPDX-License-Identifier: Apache-2.0
// toonforce doctor [--root DIR] [--priority P] [--scene WORLD.toml]: is this host ready for a
// real-time loop? With a world scene, the host's checks once, then each of its devices by name.
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "commands.hpp"
#include "toonforce/doctor/doctor.hpp"
#include "world_option.hpp"

namespace toonforce::cli {

void add_doctor(CLI::App& app) {
  auto options = std::make_shared<DoctorOptions>();
  auto scene = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "doctor", "Check what decides real-time behaviour on this host; exit status 0 when ready, 1 when not");
  cmd->add_option("--root", options->root, "Read /sys, /proc and /dev under this directory (for testing)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--priority", options->priority, "SCHED_FIFO priority the loop will ask for")
      ->check(number_in(1, 99));
  cmd->add_option("--scene", *scene,
                  "A world scene: after the host's checks, check each of its [[device]]s (its Falcon by serial, that "
                  "node's permission), each line naming the device");
  cmd->callback([options, scene] {
    if (!scene->empty()) {
      const auto world = load_world_option(*scene);
      if (!world) return set_exit_code(2);
      options->world.clear();
      for (const WorldDeviceEntry& d : world->devices) options->world.push_back({d.name, d.backend, d.select});
    }
    if (const char* g = std::getenv("GTDD_HOME"); g != nullptr) options->gtdd_home = std::string(g);
    const auto findings = run_doctor(*options);
    std::fputs(format_findings(findings).c_str(), stdout);
    set_exit_code(host_ready(findings) ? 0 : 1);
  });
}

}  // namespace toonforce::cli
