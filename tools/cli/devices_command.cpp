// SPDX-License-Identifier: Apache-2.0
// toonforce devices [--no-probe] [--scene WORLD.toml]
// Lists the haptic devices on this host and, for each, whether this user may open it and what
// to do if not (spec interfaces.md "toonforce devices"), then the software prerequisites.
// Each device family contributes one detector to kDetectors, returning the structs of
// hal/detect.hpp; adding a family (the Touch / OpenHaptics backend) is one more entry.
// With --scene, each `[[device]]` of a world scene is then resolved to what is attached, as
// `toonforce run --device scene` would open it (tools/run world_run.cpp), so a lab learns
// before a session which table points at which physical device, and which points at none.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/hal/detect.hpp"
#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/omni/install_check.hpp"
#include "toonforce/hal/omni/touch_detect.hpp"
#include "world_option.hpp"

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

// The world resolution below reads kDetectors[kFalcons] and kDetectors[kTouches].
constexpr std::size_t kFalcons = 0;
constexpr std::size_t kTouches = 1;
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

// ---- a world's devices, resolved to what is attached ----

/// "usb 001/005" of "usb 001/005 (/dev/bus/usb/001/005)": short enough for a list.
std::string short_location(const std::string& location) { return location.substr(0, location.find(" (")); }

/// The attached Falcons, as a list a person picks a serial number from.
std::string attached_falcons(const std::vector<DetectedDevice>& falcons) {
  if (falcons.empty()) return "none (no Novint Falcon on USB: `lsusb -d 0403:cb48` should list it)";
  std::string out;
  for (const DetectedDevice& f : falcons) {
    out += out.empty() ? "" : ", ";
    // Neither an opened device (libusb) nor sysfs gave its serial number.
    out += f.serial.empty() ? fmt::format("one at {} whose serial cannot be read ({})", short_location(f.location),
                                          f.can_open ? "it reports none" : "this user may not open it")
                            : fmt::format("{} ({})", f.serial, short_location(f.location));
  }
  return out;
}

/// What one `[[device]]` resolved to: the lines to print, and whether it resolved.
struct Resolution {
  std::string text;
  bool resolved = false;
  const DetectedDevice* falcon = nullptr;  ///< the physical Falcon, when one was found
};

/// "; firmware: running" from the Falcon detector's prerequisite for this location (when probed).
std::string firmware_of(const DetectedDevice& f, const std::vector<Prerequisite>& prerequisites) {
  for (const Prerequisite& p : prerequisites) {
    if (p.name == "firmware of the Novint Falcon at " + f.location) {
      return fmt::format("; firmware: {}", p.ok ? "running" : p.detail + " (`toonforce falcon firmware FILE`)");
    }
  }
  return "";
}

Resolution resolve_falcon(const WorldDeviceEntry& d, std::size_t world_falcons, const DetectionReport& found) {
  Resolution r;
  const std::vector<DetectedDevice>& attached = found.devices;
  if (d.select.empty() && world_falcons > 1) {
    r.text = fmt::format(
        "ERROR: the world has {} Falcons, so each needs its own `select`: add select = \"<serial>\" to this "
        "[[device]] table; attached Falcons: {}",
        world_falcons, attached_falcons(attached));
    return r;
  }
  if (d.select.empty()) {
    // As `run --device scene` does: the world's only Falcon without `select` is the first one.
    if (attached.empty()) {
      r.text = "not found: attached Falcons: " + attached_falcons(attached);
      return r;
    }
    r.falcon = &attached.front();
    if (attached.size() > 1) {
      r.text = fmt::format("(no select: the first of the {} attached, as `run` opens it; add select = \"{}\" to be "
                           "sure which)\n      ",
                           attached.size(), r.falcon->serial.empty() ? "<serial>" : r.falcon->serial);
    }
  } else {
    for (const DetectedDevice& f : attached) {
      if (f.serial == d.select) r.falcon = &f;
    }
    if (r.falcon == nullptr) {
      r.text = fmt::format("not found: no Falcon with serial {} is attached; attached Falcons: {}", d.select,
                           attached_falcons(attached));
      return r;
    }
  }
  const DetectedDevice& f = *r.falcon;
  r.text += fmt::format("Novint Falcon at {}{}", f.location, f.serial.empty() ? "" : ", serial " + f.serial);
  if (f.can_open) {
    r.text += "; this user may open it: yes" + firmware_of(f, found.prerequisites);
    r.resolved = true;
  } else {
    r.text += fmt::format("; this user may open it: NO: {}", f.problem);
    if (!f.fix.empty()) r.text += fmt::format("\n      to fix: {}", f.fix);
  }
  return r;
}

Resolution resolve_omni(const WorldDeviceEntry& d, const DetectionReport& found) {
  Resolution r;
  std::string missing;
  for (const Prerequisite& p : found.prerequisites) {
    if (!p.ok) missing += (missing.empty() ? "" : ", ") + p.name;
  }
  r.resolved = missing.empty();
  r.text = fmt::format(
      "OpenHaptics device {}; OpenHaptics install checks: {}\n      note: `toonforce run --device scene` runs it on "
      "OpenHaptics' own servo thread, bridged to the world's clock",
      d.select.empty() ? "(the default device)" : "\"" + d.select + "\"",
      r.resolved ? "pass" : "FAIL (" + missing + ": see the prerequisites above)");
  return r;
}

/// The world section of `devices --scene`; `resolved` is whether every device resolved.
std::string resolve_world(const WorldDescription& world, const std::string& path, const DetectionReport& falcons,
                          const DetectionReport& touches, bool& all_resolved) {
  std::size_t world_falcons = 0;
  for (const WorldDeviceEntry& d : world.devices) world_falcons += d.backend == "falcon";
  std::string out =
      fmt::format("\nWorld scene {}: {} device{}\n", path, world.devices.size(), world.devices.size() == 1 ? "" : "s");
  std::vector<Resolution> done;
  std::vector<std::string> unresolved;
  for (std::size_t i = 0; i < world.devices.size(); ++i) {
    const WorldDeviceEntry& d = world.devices[i];
    out += fmt::format("  {} (line {}): backend {}{}\n", d.name, d.line, d.backend,
                       d.select.empty() ? "" : ", select \"" + d.select + "\"");
    Resolution r;
    if (d.backend == "falcon") {
      r = resolve_falcon(d, world_falcons, falcons);
    } else if (d.backend == "omni") {
      r = resolve_omni(d, touches);
    } else {
      r.text = "simulated (nothing to find on this host)";
      r.resolved = true;
    }
    // Two tables driving one physical device would each command it: never what a lab meant.
    for (std::size_t k = 0; k < done.size() && r.falcon != nullptr; ++k) {
      if (done[k].falcon == r.falcon) {
        r.text += fmt::format("\n      ERROR: the same Falcon as device '{}': each [[device]] needs its own; give "
                              "them different `select` serials (attached Falcons: {})",
                              world.devices[k].name, attached_falcons(falcons.devices));
        r.resolved = false;
        break;
      }
    }
    out += "    -> " + r.text + "\n";
    if (!r.resolved) unresolved.push_back(d.name);
    done.push_back(r);
  }
  all_resolved = unresolved.empty();
  if (all_resolved) {
    out += "every device of the world resolves\n";
  } else {
    std::string names;
    for (const auto& n : unresolved) names += (names.empty() ? "" : ", ") + n;
    out += fmt::format("{} of {} device(s) do not resolve: {}\n", unresolved.size(), world.devices.size(), names);
  }
  return out;
}

}  // namespace

void add_devices(CLI::App& app) {
  auto no_probe = std::make_shared<bool>(false);
  auto scene = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand("devices", "List haptic devices, whether you may open them, and how to fix it");
  cmd->add_flag("--no-probe", *no_probe, "Do not open devices to check their state (firmware)");
  cmd->add_option("--scene", *scene,
                  "A world scene: resolve each of its [[device]] tables to an attached device (exit status 1 if one "
                  "does not resolve)");
  cmd->callback([no_probe, scene] {
    // The file first: a typo in it is said before any device is touched.
    std::optional<WorldDescription> world;
    if (!scene->empty()) {
      world = load_world_option(*scene);
      if (!world) return set_exit_code(2);
    }
    DetectOptions options;
    options.probe = !*no_probe;
    std::vector<DetectionReport> reports;
    std::string out;
    for (const Detector& d : kDetectors) {
      reports.push_back(d.detect(options));
      out += format_family(d, reports.back());
    }
    bool all_resolved = true;
    if (world) out += resolve_world(*world, *scene, reports[kFalcons], reports[kTouches], all_resolved);
    std::fputs(out.c_str(), stdout);
    set_exit_code(all_resolved ? 0 : 1);
  });
}

}  // namespace toonforce::cli
