// SPDX-License-Identifier: Apache-2.0
// toonforce falcon firmware FILE [--serial S | --index N] [--attempts N] [--reload]
// toonforce falcon udev-rule
// toonforce falcon envelope [--calibration FILE] [--csv OUT] [--step MM]
// Novint Falcon chores: load its firmware (from a file the user supplies: toonforce ships
// none, docs/FALCON.md), and print the udev rule that lets group plugdev open it.
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/config/falcon_calibration_file.hpp"
#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/falcon/frames.hpp"
#include "toonforce/hal/falcon/kinematics.hpp"

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

struct EnvelopeArgs {
  std::string calibration;
  std::string csv;
  double step_mm = 5.0;
};

/// The force envelope (kinematics.hpp force_envelope) over the HDAL box of the driver's
/// workspace (FALCON.md §5), in the scene frame: x right, y away from the user, z up.
int run_envelope(const EnvelopeArgs& a) {
  falcon::MotorScale scale;
  std::string source = "libnifalcon's uncalibrated 10000 words per N m";
  if (!a.calibration.empty()) {
    auto c = falcon::read_falcon_calibration(a.calibration);
    if (!c) {
      print_error(c.error());
      return 1;
    }
    scale.words_per_n_m = c.value().words_per_n_m;
    source = fmt::format("{:.6g} words per N m from {}", scale.words_per_n_m, a.calibration);
  }
  const Vec3<double> centre{0.0, 0.0, 0.110};  // FalconOptions::workspace_centre_falcon_m
  // Scene axes in the Falcon frame (frames.hpp: scene = (x, -z, y)).
  const Vec3<double> along_x{1, 0, 0};
  const Vec3<double> along_y{0, 0, -1};
  const Vec3<double> along_z{0, 1, 0};
  std::FILE* csv = nullptr;
  // Rows go out with fputs, whose errors stay in the stream's error flag for the check at the
  // end (fmt::print threw them: `--csv /dev/full` aborted).
  const auto put = [&csv](const std::string& text) { std::fputs(text.c_str(), csv); };
  if (!a.csv.empty()) {
    csv = std::fopen(a.csv.c_str(), "w");
    if (csv == nullptr) {
      print_error(fmt::format("{}: cannot write: {}", a.csv, std::strerror(errno)));
      return 1;
    }
    put(fmt::format("# toonforce falcon envelope; {}\nx_m,y_m,z_m,along_x_n,along_y_n,along_z_n,every_direction_n\n",
                    source));
  }
  struct Least {
    double n = 1e9;
    Vec3<double> at{};
  };
  Least least[4];
  Least least_core[4];  // within kCoreMm of the centre along each axis: the ~10 cm cube
  constexpr double kCoreMm = 40.0;
  std::size_t core_points = 0;
  std::size_t core_below_4n = 0;
  std::size_t reached = 0;
  std::size_t points = 0;
  const auto steps = [&](double from_mm, double to_mm) {
    return static_cast<int>(std::lround((to_mm - from_mm) / a.step_mm));
  };
  // The HDAL box (driver.cpp): x, z in -60..60 mm, y (depth) in -65..35 mm about the centre.
  for (int ix = 0; ix <= steps(-60, 60); ++ix) {
    for (int iy = 0; iy <= steps(-65, 35); ++iy) {
      for (int iz = 0; iz <= steps(-60, 60); ++iz) {
        const Vec3<double> scene{(-60 + ix * a.step_mm) * 1e-3, (-65 + iy * a.step_mm) * 1e-3,
                                 (-60 + iz * a.step_mm) * 1e-3};
        ++points;
        falcon::Mat3 j;
        const bool ok = falcon::position_jacobian(falcon::FalconGeometry{}, falcon::scene_to_falcon(scene, centre), j);
        if (!ok) {
          if (csv != nullptr) put(fmt::format("{:.4f},{:.4f},{:.4f},,,,\n", scene.x, scene.y, scene.z));
          continue;
        }
        ++reached;
        const double f[4] = {falcon::max_force_along(j, along_x, scale), falcon::max_force_along(j, along_y, scale),
                             falcon::max_force_along(j, along_z, scale),
                             falcon::force_envelope(j, scale).every_direction_n};
        const bool core = std::abs(scene.x) <= kCoreMm * 1e-3 + 1e-9 && std::abs(scene.y) <= kCoreMm * 1e-3 + 1e-9 &&
                          std::abs(scene.z) <= kCoreMm * 1e-3 + 1e-9;
        for (int k = 0; k < 4; ++k) {
          if (f[k] < least[k].n) least[k] = {f[k], scene};
          if (core && f[k] < least_core[k].n) least_core[k] = {f[k], scene};
        }
        if (core) {
          ++core_points;
          core_below_4n += f[3] < 4.0 ? 1 : 0;
        }
        if (csv != nullptr) {
          put(fmt::format("{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f}\n", scene.x, scene.y, scene.z, f[0], f[1],
                          f[2], f[3]));
        }
      }
    }
  }
  if (csv != nullptr) {
    errno = 0;
    const bool flushed = std::fflush(csv) == 0 && std::ferror(csv) == 0;
    const int error = errno != 0 ? errno : EIO;
    if (std::fclose(csv) != 0 || !flushed) {
      print_error(fmt::format("{}: writing the grid failed: {}", a.csv, std::strerror(error)));
      return 1;
    }
  }
  falcon::ForceEnvelope at_centre;
  (void)falcon::force_envelope_at(falcon::FalconGeometry{}, centre, scale, at_centre);
  fmt::print("Force the Falcon's +-{} motor words allow ({}), scene frame (x right, y away, z up):\n", scale.max_word,
             source);
  fmt::print(
      "  at the workspace centre: along x {:.2f} N, along y {:.2f} N, along z {:.2f} N, in every direction {:.2f} N\n",
      at_centre.axis_n.x, at_centre.axis_n.z, at_centre.axis_n.y, at_centre.every_direction_n);
  fmt::print("  over the driver's workspace box (x, z -60..60 mm, y -65..35 mm, {} of {} grid points within reach):\n",
             reached, points);
  const char* names[4] = {"along x", "along y", "along z", "in every direction"};
  for (int k = 0; k < 4; ++k) {
    fmt::print("    least {:<19} {:6.2f} N at ({:.0f}, {:.0f}, {:.0f}) mm\n", names[k], least[k].n, least[k].at.x * 1e3,
               least[k].at.y * 1e3, least[k].at.z * 1e3);
  }
  fmt::print("  within {:.0f} mm of the centre along each axis (the ~10 cm cube; {} points, {} below 4 N in every "
             "direction):\n",
             kCoreMm, core_points, core_below_4n);
  for (int k = 0; k < 4; ++k) {
    fmt::print("    least {:<19} {:6.2f} N at ({:.0f}, {:.0f}, {:.0f}) mm\n", names[k], least_core[k].n,
               least_core[k].at.x * 1e3, least_core[k].at.y * 1e3, least_core[k].at.z * 1e3);
  }
  fmt::print("  (near the edges of the reach the kinematics approach a singularity and the envelope goes to zero)\n");
  if (!a.csv.empty()) fmt::print("  grid written to {}\n", a.csv);
  return 0;
}

}  // namespace

void add_falcon(CLI::App& app) {
  CLI::App* falcon =
      app.add_subcommand("falcon", "Novint Falcon: load firmware, print the udev rule, its force envelope");
  falcon->require_subcommand(1);

  auto args = std::make_shared<FirmwareArgs>();
  CLI::App* firmware = falcon->add_subcommand(
      "firmware", "Load firmware from FILE (copied from a Novint or nVent driver install) into the Falcon");
  firmware->add_option("FILE", args->path, "Firmware image; only the known Novint/nVent images are accepted")
      ->required();
  firmware->add_option("--serial", args->serial, "The Falcon with this serial number (see `toonforce devices`)");
  firmware->add_option("--index", args->index, "The N-th Falcon (0 = first) when --serial is not given");
  firmware->add_option("--attempts", args->attempts, "Whole-load retries")->check(number_in(1, 50));
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

  auto envelope = std::make_shared<EnvelopeArgs>();
  CLI::App* env = falcon->add_subcommand(
      "envelope", "The force the Falcon's motor words allow, per pose and direction, over its workspace");
  env->add_option("--calibration", envelope->calibration,
                  "A calibration file (default: libnifalcon's 10000 words per N m)")
      ->check(CLI::ExistingFile);
  env->add_option("--csv", envelope->csv,
                  "Write the grid: scene x,y,z [m], then the force [N] along x, y, z and "
                  "in every direction (empty where the kinematics do not reach)");
  env->add_option("--step", envelope->step_mm, "Grid step [mm]")->check(number_in(1.0, 20.0))->capture_default_str();
  env->callback([envelope] {
    // Refused before anything is opened: fopen("w") would empty the calibration it reads.
    if (const std::string input = input_overwritten_by(envelope->csv, {envelope->calibration}); !input.empty()) {
      print_error(fmt::format("--csv {} is the --calibration file {}: it would be overwritten; choose another file",
                              envelope->csv, input));
      return set_exit_code(2);
    }
    set_exit_code(run_envelope(*envelope));
  });

  CLI::App* udev = falcon->add_subcommand(
      "udev-rule",
      fmt::format("Print the udev rule ({}) that lets group plugdev open the Falcon", kFalconUdevRuleName));
  udev->callback([] {
    const std::string_view rule = falcon_udev_rule();
    std::fwrite(rule.data(), 1, rule.size(), stdout);
    set_exit_code(0);
  });
}

}  // namespace toonforce::cli
