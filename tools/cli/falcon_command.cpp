// toonforce falcon firmware FILE [--serial S | --index N] [--attempts N] [--reload]
// toonforce falcon udev-rule
// Novint Falcon chores: load its firmware (from a file the user supplies: toonforce ships
// none, docs/FALCON.md), and print the udev rule that lets group plugdev open it.
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/hal/falcon/falcon.hpp"

namespace toonforce::cli {
namespace {

struct FirmwareArgs {
  std::string path;
  std::string serial;
  unsigned index = 0;
  int attempts = 5;
  bool reload = false;
};

void print_error(const std::string& message) {
  std::fputs(message.c_str(), stderr);
  if (message.empty() || message.back() != '\n') std::fputc('\n', stderr);
}

}  // namespace

void add_falcon(CLI::App& app) {
  CLI::App* falcon = app.add_subcommand("falcon", "Novint Falcon: load firmware, print the udev rule");
  falcon->require_subcommand(1);

  auto args = std::make_shared<FirmwareArgs>();
  CLI::App* firmware = falcon->add_subcommand(
      "firmware", "Load firmware from FILE (copied from a Novint or nVent driver install) into the Falcon");
  firmware->add_option("FILE", args->path, "Firmware image; only the known Novint/nVent images are accepted")
      ->required();
  firmware->add_option("--serial", args->serial, "The Falcon with this serial number (see `toonforce devices`)");
  firmware->add_option("--index", args->index, "The N-th Falcon (0 = first) when --serial is not given");
  firmware->add_option("--attempts", args->attempts, "Whole-load retries")->check(CLI::Range(1, 50));
  firmware->add_flag("--reload", args->reload, "Load even if firmware already runs");
  firmware->callback([args] {
    FalconOptions options;
    options.serial = args->serial;
    options.index = args->index;
    options.firmware.attempts = args->attempts;
    const bool tty = ::isatty(STDERR_FILENO) != 0;
    int last_percent = -1;
    options.firmware.progress = [tty, &last_percent](std::size_t done, std::size_t total, int attempt) {
      const int percent = total > 0 ? static_cast<int>(100 * done / total) : 0;
      if (tty) {
        std::fprintf(stderr, "\rloading firmware (try %d): %3d%%", attempt, percent);
        if (done == total) std::fputc('\n', stderr);
      } else if (percent / 25 != last_percent / 25 || done == 0) {
        std::fprintf(stderr, "loading firmware (try %d): %d%%\n", attempt, percent);
      }
      last_percent = percent;
    };
    const auto result = load_falcon_firmware(args->path, options, args->reload);
    if (!result) {
      print_error(result.error());
      set_exit_code(1);
      return;
    }
    std::fputs((result.value() + "\n").c_str(), stdout);
    set_exit_code(0);
  });

  CLI::App* udev = falcon->add_subcommand(
      "udev-rule", fmt::format("Print the udev rule ({}) that lets group plugdev open the Falcon", kFalconUdevRuleName));
  udev->callback([] {
    const std::string_view rule = falcon_udev_rule();
    std::fwrite(rule.data(), 1, rule.size(), stdout);
    set_exit_code(0);
  });
}

}  // namespace toonforce::cli
