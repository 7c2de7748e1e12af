// SPDX-License-Identifier: Apache-2.0
// toonforce devices [--no-probe]
// Lists the haptic devices on this host and, for each, whether this user may open it and what
// to do if not (spec interfaces.md "toonforce devices"), then the software prerequisites.
// Each device family contributes one detector to kDetectors, returning the structs of
// hal/detect.hpp; adding a family (the Touch / OpenHaptics backend) is one more entry.
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/hal/detect.hpp"
#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/omni/install_check.hpp"
#include "toonforce/hal/omni/touch_detect.hpp"

namespace toonforce::cli {
namespace {

struct DetectOptions {
  bool probe = true;  ///< a detector may open devices to ask about their state (firmware)
};

/// What one detector found.
struct DetectionReport {
  std::vector<DetectedDevice> devices;
  std::vector<Prerequisite> prerequisites;
};

/// One device family's detector.
struct Detector {
  const char* family;     ///< "Novint Falcon"
  const char* when_none;  ///< what to check when none is found
  DetectionReport (*detect)(const DetectOptions&);
};

DetectionReport detect_falcon(const DetectOptions& options) {
  FalconDetectOptions o;
  o.probe_firmware = options.probe;
  FalconDetection found = detect_falcons(o);
  return {std::move(found.devices), std::move(found.prerequisites)};
}

DetectionReport detect_touch(const DetectOptions&) {
  // Loading the HD library to see whether it works is harmless (it is never unloaded). The
  // install checks explain what the loader cannot: /usr/lib64, libraw1394.so.8, GTDD_HOME.
  DetectionReport r{detect_touch_devices(), {openhaptics_prerequisite()}};
  for (const auto& f : check_openhaptics_install(OpenHapticsHost::this_process()))
    r.prerequisites.push_back(f.prerequisite);
  return r;
}

constexpr Detector kDetectors[] = {
    {"Novint Falcon",
     "check its power supply and USB cable (directly, not through a hub); `lsusb -d 0403:cb48` should list it",
     &detect_falcon},
    {"Phantom Omni / 3D Systems Touch",
     "check its power and USB cable; `lsusb -d 2988:` should list a Touch (a FireWire Phantom Omni is not "
     "listed there: see docs/OMNI.md)",
     &detect_touch},
};

std::string format_family(const Detector& d, const DetectionReport& r) {
  std::string out = fmt::format("{}: {} found\n", d.family, r.devices.size());
  if (r.devices.empty()) out += fmt::format("  none found: {}\n", d.when_none);
  for (const DetectedDevice& dev : r.devices) {
    out += fmt::format("  {}{}\n", dev.location, dev.serial.empty() ? "" : "  serial " + dev.serial);
    if (dev.can_open) {
      out += "    this user may open it: yes\n";
    } else {
      out += fmt::format("    this user may open it: NO: {}\n", dev.problem);
      if (!dev.fix.empty()) out += fmt::format("    to fix: {}\n", dev.fix);
    }
  }
  if (!r.prerequisites.empty()) out += "  prerequisites:\n";
  for (const Prerequisite& p : r.prerequisites) {
    out += fmt::format("    [{}] {}: {}\n", p.ok ? "ok" : "missing", p.name, p.detail);
    if (!p.ok && !p.fix.empty()) out += fmt::format("        to fix: {}\n", p.fix);
  }
  return out;
}

}  // namespace

void add_devices(CLI::App& app) {
  auto no_probe = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand("devices", "List haptic devices, whether you may open them, and how to fix it");
  cmd->add_flag("--no-probe", *no_probe, "Do not open devices to check their state (firmware)");
  cmd->callback([no_probe] {
    DetectOptions options;
    options.probe = !*no_probe;
    std::string out;
    for (const Detector& d : kDetectors) out += format_family(d, d.detect(options));
    std::fputs(out.c_str(), stdout);
    set_exit_code(0);
  });
}

}  // namespace toonforce::cli
