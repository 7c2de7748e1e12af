// SPDX-License-Identifier: Apache-2.0
// The Falcon backend's entry points: open_falcon, load_falcon_firmware, detect_falcons.
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <variant>

#include <fmt/format.h>

#include "libusb_transport.hpp"
#include "toonforce/hal/falcon/driver.hpp"
#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/falcon/firmware.hpp"
#include "toonforce/hal/falcon/ftdi.hpp"
#include "toonforce/hal/falcon/usb.hpp"
#include "udev_check.hpp"

namespace toonforce {
namespace {

using falcon::LibusbTransport;
using falcon::OpenFailure;
using falcon::TransportStatus;

constexpr const char* kFirmwareFix =
    "load it with `toonforce falcon firmware FILE`, where FILE comes from a Novint or nVent driver install "
    "(docs/FALCON.md, \"Firmware\")";

/// Frees a libusb device list when leaving scope (the opened handles keep their devices).
struct DeviceList {
  libusb_device** list = nullptr;
  ~DeviceList() {
    if (list != nullptr) libusb_free_device_list(list, 1);
  }
};

std::string not_found_message() {
  return "no Novint Falcon found on USB (vendor 0403, product cb48). Check that its power supply is plugged in "
         "and its USB cable is connected, directly rather than through a hub; `lsusb -d 0403:cb48` should list "
         "it. In a container or virtual machine, pass the USB device through.";
}

Result<std::unique_ptr<LibusbTransport>> open_transport(const FalconOptions& options) {
  std::string error;
  auto context = falcon::UsbContext::create(error);
  if (!context) return Error{error};
  DeviceList list;
  const auto falcons = falcon::find_falcons(context->get(), list.list);
  if (falcons.empty()) return Error{not_found_message()};

  if (!options.serial.empty()) {
    std::string seen;
    for (const auto& f : falcons) {
      auto opened = LibusbTransport::open(context, f);
      if (auto* failure = std::get_if<OpenFailure>(&opened)) {
        seen += "\n  " + f.location + ": cannot open (" + failure->problem + "; " + failure->fix + ")";
        continue;
      }
      auto& t = std::get<std::unique_ptr<LibusbTransport>>(opened);
      if (t->serial() == options.serial) return std::move(t);
      seen += "\n  " + f.location + ": serial " + (t->serial().empty() ? "(none)" : t->serial());
    }
    return Error{"no Novint Falcon with serial number " + options.serial + " among those found:" + seen};
  }
  if (options.index >= falcons.size()) {
    return Error{"Falcon number " + std::to_string(options.index) + " was asked for, but only " +
                 std::to_string(falcons.size()) + " Novint Falcon(s) are connected (numbered from 0)"};
  }
  auto opened = LibusbTransport::open(context, falcons[options.index]);
  if (auto* failure = std::get_if<OpenFailure>(&opened))
    return Error{failure->problem + ". To fix it: " + failure->fix + "."};
  return std::move(std::get<std::unique_ptr<LibusbTransport>>(opened));
}

std::string device_name(const LibusbTransport& t) {
  return "Novint Falcon (" + (t.serial().empty() ? std::string() : "serial " + t.serial() + ", ") +
         std::string(t.location()) + ")";
}

/// Normal mode and the firmware probe; an error message, or empty with `loaded` set.
std::string probe(LibusbTransport& t, bool& loaded) {
  const falcon::FirmwareProbe p = falcon::probe_firmware(t);
  loaded = p.loaded;
  if (p.transport != TransportStatus::kOk) {
    return "USB error (" + std::string(falcon::to_string(p.transport)) + ") while asking the Novint Falcon at " +
           std::string(t.location()) + " whether its firmware runs. Unplug and replug it, then try again.";
  }
  return {};
}

/// The serial number the kernel read from the USB device at bus/address (sysfs `serial`), or
/// "". libusb reads it only from an opened device; a Falcon this user may not open (or one held
/// by another program) is still named by it, so `devices --scene` and `bringup --serial` find it
/// and say what stops the opening rather than that no such Falcon is attached.
std::string sysfs_serial(unsigned bus, unsigned address) {
  namespace fs = std::filesystem;
  const auto word = [](const fs::path& file) {
    std::ifstream in(file);
    std::string w;
    in >> w;
    return w;
  };
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator("/sys/bus/usb/devices", ec)) {
    if (word(entry.path() / "idVendor") != "0403" || word(entry.path() / "idProduct") != "cb48") continue;
    if (std::atoi(word(entry.path() / "busnum").c_str()) != static_cast<int>(bus)) continue;
    if (std::atoi(word(entry.path() / "devnum").c_str()) != static_cast<int>(address)) continue;
    return word(entry.path() / "serial");
  }
  return "";
}

}  // namespace

Result<ResolvedFalconCalibration> resolve_falcon_calibration(const std::string& explicit_path, std::string_view serial,
                                                             falcon::CalibrationReader read_file) {
  ResolvedFalconCalibration out;
  std::string path = explicit_path;
  if (path.empty()) {
    const std::string fallback = falcon::default_falcon_calibration_path(serial);
    std::error_code ec;
    if (fallback.empty() || !std::filesystem::exists(fallback, ec)) {
      out.source = fmt::format("libnifalcon's uncalibrated {:.0f} words per N m (no calibration file{}{}; "
                               "`toonforce bringup falcon` measures it)",
                               falcon::kUncalibratedWordsPerNewtonMetre, fallback.empty() ? "" : " at ", fallback);
      return out;
    }
    path = fallback;
  }
  if (read_file == nullptr) {
    return Error{fmt::format("{}: this program reads no Falcon calibration files (FalconOptions::read_calibration "
                             "is not set)",
                             path)};
  }
  auto read = read_file(path);
  if (!read) return Error{read.error()};
  if (!read.value().serial.empty() && !serial.empty() && read.value().serial != serial) {
    return Error{fmt::format("{}: this calibration was measured on the Falcon with serial number {}, but the one "
                             "opened is {}: measure this one (`toonforce bringup falcon`) or give its own file",
                             path, read.value().serial, serial)};
  }
  out.calibration = std::move(read.value());
  out.from_file = true;
  out.source = fmt::format("{:.6g} words per N m from {}", out.calibration.words_per_n_m, path);
  return out;
}

Result<std::unique_ptr<DeviceDriver>> open_falcon(const FalconOptions& options) {
  // The firmware file is checked before the device is touched.
  std::optional<falcon::FirmwareImage> image;
  if (!options.firmware_path.empty()) {
    auto checked = falcon::read_firmware_file(options.firmware_path);
    if (!checked) return Error{checked.error()};
    image = std::move(checked.value());
  }
  auto opened = open_transport(options);
  if (!opened) return Error{opened.error()};
  std::unique_ptr<LibusbTransport> t = std::move(opened.value());
  bool loaded = false;
  if (auto e = probe(*t, loaded); !e.empty()) return Error{e};
  if (!loaded) {
    if (!image) {
      return Error{"the Novint Falcon at " + std::string(t->location()) +
                   " has no firmware running (it loses it at every power-up): " + kFirmwareFix + "."};
    }
    auto report = falcon::load_firmware(*t, *image, options.firmware);
    if (!report) return Error{report.error()};
  }
  auto calibration = resolve_falcon_calibration(options.calibration_path, t->serial(), options.read_calibration);
  if (!calibration) return Error{calibration.error()};
  FalconOptions calibrated = options;
  calibrated.motor.words_per_n_m = calibration.value().calibration.words_per_n_m;
  calibrated.calibration_source = calibration.value().source;
  std::string name = device_name(*t);
  return std::unique_ptr<DeviceDriver>(
      std::make_unique<falcon::FalconDriver>(std::move(t), calibrated, std::move(name)));
}

Result<std::string> load_falcon_firmware(const std::string& path, const FalconOptions& options, bool reload) {
  auto image = falcon::read_firmware_file(path);
  if (!image) return Error{image.error()};
  auto opened = open_transport(options);
  if (!opened) return Error{opened.error()};
  LibusbTransport& t = *opened.value();
  if (!reload) {
    bool loaded = false;
    if (auto e = probe(t, loaded); !e.empty()) return Error{e};
    if (loaded) {
      return "firmware is already running on the " + device_name(t) +
             "; nothing loaded (it stays until the Falcon loses power; --reload loads " + path + " anyway)";
    }
  }
  auto report = falcon::load_firmware(t, image.value(), options.firmware);
  if (!report) return Error{report.error()};
  const int tries = report.value().attempts;
  return "loaded " + image.value().name + " (SHA-256 " + falcon::to_hex(image.value().digest) + ") into the " +
         device_name(t) + " in " + std::to_string(tries) + (tries == 1 ? " try" : " tries") +
         "; it answers commands. Home it before use: pull the grip all the way out, then push it straight in.";
}

namespace falcon {

Result<std::unique_ptr<FalconTransport>> open_falcon_transport(const FalconOptions& options) {
  auto opened = open_transport(options);
  if (!opened) return Error{opened.error()};
  return std::unique_ptr<FalconTransport>(std::move(opened.value()));
}

}  // namespace falcon

FalconDetection detect_falcons(const FalconDetectOptions& options) {
  FalconDetection out;
  const bool root = ::geteuid() == 0;

  const falcon::UdevRuleCheck rule = falcon::check_udev_rule();
  Prerequisite udev{"udev rule for the Novint Falcon", rule.installed, {}, {}};
  if (rule.installed) {
    udev.detail = rule.path;
  } else {
    udev.detail = "no rules file for 0403:cb48 in /etc/udev/rules.d, /run/udev/rules.d, /usr/lib/udev/rules.d";
    udev.fix = "toonforce falcon udev-rule | sudo tee /etc/udev/rules.d/" + std::string(kFalconUdevRuleName) +
               " && sudo udevadm control --reload-rules && sudo udevadm trigger";
  }
  if (root) udev.detail += " (you are root and may open it anyway; other users need the rule)";
  out.prerequisites.push_back(udev);

  const falcon::GroupCheck group = falcon::check_group("plugdev");
  Prerequisite member{
      "membership of group plugdev (which the udev rule grants access)", group.in_session || root, {}, {}};
  if (root) {
    member.detail = "you are root";
  } else if (!group.exists) {
    member.detail = "group plugdev does not exist on this host";
    member.fix = "sudo groupadd plugdev && sudo usermod -aG plugdev $USER, then log out and in";
  } else if (group.in_session) {
    member.detail = "yes";
  } else if (group.listed) {
    member.detail = "added, but this login session predates it";
    member.fix = "log out and in (or run `newgrp plugdev`)";
  } else {
    member.detail = "no";
    member.fix = "sudo usermod -aG plugdev $USER, then log out and in";
  }
  out.prerequisites.push_back(member);

  std::string error;
  auto context = falcon::UsbContext::create(error);
  if (!context) {
    out.prerequisites.push_back({"libusb-1.0", false, error, "install libusb-1.0-0 (tools/setup-deps)"});
    return out;
  }
  DeviceList list;
  for (const auto& f : falcon::find_falcons(context->get(), list.list)) {
    DetectedDevice d;
    d.kind = "Novint Falcon";
    d.location = f.location;
    auto opened = LibusbTransport::open(context, f);
    if (auto* failure = std::get_if<OpenFailure>(&opened)) {
      d.serial = sysfs_serial(f.bus, f.address);
      d.can_open = false;
      d.problem = failure->problem;
      d.fix = failure->fix;
      out.devices.push_back(d);
      continue;
    }
    auto& t = std::get<std::unique_ptr<LibusbTransport>>(opened);
    d.serial = t->serial();
    d.can_open = true;
    out.devices.push_back(d);
    if (options.probe_firmware) {
      bool loaded = false;
      const std::string e = probe(*t, loaded);
      Prerequisite fw{"firmware of the Novint Falcon at " + f.location, loaded, {}, {}};
      if (!e.empty()) {
        fw.detail = e;
      } else if (loaded) {
        fw.detail = "running";
      } else {
        fw.detail = "not loaded (the Falcon loses it at every power-up)";
        fw.fix = kFirmwareFix;
      }
      out.prerequisites.push_back(fw);
    }
  }
  return out;
}

}  // namespace toonforce
