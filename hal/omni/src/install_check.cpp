// SPDX-License-Identifier: Apache-2.0
// Checks of an OpenHaptics install (see install_check.hpp).
#include "toonforce/hal/omni/install_check.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string_view>

#include <fmt/format.h>

namespace toonforce {
namespace {

namespace fs = std::filesystem;

/// Where the loader looks (Debian's multiarch directory, the classic ones) and where vendor
/// installers put libraries (/usr/lib64, /usr/local/lib).
constexpr const char* kLibraryDirs[] = {
    "/usr/lib/x86_64-linux-gnu", "/lib/x86_64-linux-gnu", "/usr/lib", "/lib", "/usr/lib64", "/usr/local/lib"};

class Tree {
 public:
  explicit Tree(std::string root) : root_(std::move(root)) {}
  fs::path at(std::string_view absolute) const { return fs::path(root_) / absolute.substr(1); }

  /// Files named `prefix`* in the library directories, as absolute paths of the host.
  std::vector<std::string> libraries(std::string_view prefix) const {
    std::vector<std::string> out;
    for (const char* dir : kLibraryDirs) {
      std::error_code ec;
      for (const auto& entry : fs::directory_iterator(at(dir), ec)) {
        const std::string name = entry.path().filename().string();
        if (name.rfind(prefix, 0) == 0) out.push_back(std::string(dir) + "/" + name);
      }
    }
    std::sort(out.begin(), out.end());
    return out;
  }

  std::string read_word(const fs::path& file) const {
    std::ifstream in(file);
    std::string v;
    in >> v;
    return v;
  }

  /// A USB device of 3D Systems (vendor 2988; also the byte-swapped 0301:2988 of one note).
  bool touch_present() const {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(at("/sys/bus/usb/devices"), ec)) {
      const std::string v = read_word(e.path() / "idVendor");
      const std::string p = read_word(e.path() / "idProduct");
      if (v == "2988" || (v == "0301" && p == "2988")) return true;
    }
    return false;
  }
  /// A FireWire node of SensAble's OUI 0x000b99 (OMNI.md §1.1).
  bool firewire_omni_present() const {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(at("/sys/bus/firewire/devices"), ec)) {
      if (read_word(e.path() / "vendor") == "0x000b99") return true;
    }
    return false;
  }

  /// Whether `dir` is a line of /etc/ld.so.conf or of a file in /etc/ld.so.conf.d.
  bool loader_searches(std::string_view dir) const {
    std::vector<fs::path> files{at("/etc/ld.so.conf")};
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(at("/etc/ld.so.conf.d"), ec)) {
      if (e.path().extension() == ".conf") files.push_back(e.path());
    }
    for (const auto& file : files) {
      std::ifstream in(file);
      std::string line;
      while (std::getline(in, line)) {
        line.erase(std::find(line.begin(), line.end(), '#'), line.end());
        const auto first = line.find_first_not_of(" \t");
        if (first == std::string::npos) continue;
        std::string entry = line.substr(first, line.find_last_not_of(" \t\r") - first + 1);
        while (entry.size() > 1 && entry.back() == '/') entry.pop_back();
        if (entry == dir) return true;
      }
    }
    return false;
  }

  bool is_directory(std::string_view absolute) const {
    std::error_code ec;
    return fs::is_directory(at(absolute), ec);
  }
  std::vector<std::string> files_in(std::string_view absolute, std::string_view extension) const {
    std::vector<std::string> out;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(at(absolute), ec)) {
      if (e.path().extension() == extension) out.push_back(e.path().filename().string());
    }
    std::sort(out.begin(), out.end());
    return out;
  }

 private:
  std::string root_;
};

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i > 0) out += ", ";
    out += items[i];
  }
  return out;
}

std::vector<std::string> only_in(const std::vector<std::string>& paths, std::string_view dir) {
  std::vector<std::string> out;
  for (const auto& p : paths) {
    if (p.rfind(std::string(dir) + "/", 0) == 0) out.push_back(p);
  }
  return out;
}

}  // namespace

OpenHapticsHost OpenHapticsHost::this_process() {
  OpenHapticsHost host;
  if (const char* g = std::getenv("GTDD_HOME"); g != nullptr) host.gtdd_home = std::string(g);
  return host;
}

std::vector<OpenHapticsInstallFinding> check_openhaptics_install(const OpenHapticsHost& host) {
  const Tree tree(host.root);
  std::vector<OpenHapticsInstallFinding> out;
  const bool touch = tree.touch_present();
  const bool firewire = tree.firewire_omni_present();

  // 1. /usr/lib64 on the loader's path.
  std::vector<std::string> in_lib64;
  for (const char* prefix : {"libHD.so", "libHL.so", "libPHANToMIO.so", "libPhantomIOLib42.so"}) {
    const auto found = only_in(tree.libraries(prefix), "/usr/lib64");
    in_lib64.insert(in_lib64.end(), found.begin(), found.end());
  }
  if (!in_lib64.empty()) {
    Prerequisite p{
        "dynamic loader path for /usr/lib64 (OpenHaptics' libraries)", tree.loader_searches("/usr/lib64"), {}, {}};
    if (p.ok) {
      p.detail = fmt::format("/usr/lib64 is listed in /etc/ld.so.conf(.d) ({})", join(in_lib64));
    } else {
      p.detail = fmt::format("{} installed in /usr/lib64, which the Debian/Ubuntu dynamic loader does not search, "
                             "so libHD cannot be loaded (or cannot load its driver)",
                             join(in_lib64));
      p.fix = kLib64LoaderFix;
    }
    out.push_back({p, touch || firewire});
  }

  // 2. libraw1394.so.8 for the FireWire driver.
  const auto phantomio = tree.libraries("libPHANToMIO.so");
  if (!phantomio.empty() || firewire) {
    const auto raw8 = tree.libraries("libraw1394.so.8");
    Prerequisite p{"libraw1394.so.8 (the FireWire Omni's driver, PDD 4.3, needs it)", !raw8.empty(), {}, {}};
    if (p.ok) {
      p.detail = join(raw8);
    } else {
      const auto raw11 = tree.libraries("libraw1394.so.11");
      p.detail = fmt::format("no libraw1394.so.8 in {}{}", join({std::begin(kLibraryDirs), std::end(kLibraryDirs)}),
                             raw11.empty() ? "" : fmt::format(" (there is {})", raw11.front()));
      if (raw11.empty()) {
        p.fix = "sudo apt-get install libraw1394-11, then sudo ln -s /usr/lib/x86_64-linux-gnu/libraw1394.so.11 "
                "/usr/lib/x86_64-linux-gnu/libraw1394.so.8 && sudo ldconfig (the driver was built against the "
                "older soname; docs/OMNI.md)";
      } else {
        const std::string dir = fs::path(raw11.front()).parent_path().string();
        p.fix = fmt::format("sudo ln -s {0}/libraw1394.so.11 {0}/libraw1394.so.8 && sudo ldconfig (the driver was "
                            "built against the older soname; docs/OMNI.md)",
                            dir);
      }
    }
    out.push_back({p, firewire});
  }

  // 3. The Touch driver's configuration directory.
  const auto touch_driver = tree.libraries("libPhantomIOLib42.so");
  if (!touch_driver.empty()) {
    constexpr const char* kDefaultHome = "/usr/share/3DSystems";
    Prerequisite p{"GTDD_HOME and its config directory (the Touch driver's configuration)", false, {}, {}};
    const std::string make_dir =
        fmt::format("sudo mkdir -p {0}/config && sudo chgrp plugdev {0}/config && sudo chmod 2775 {0}/config",
                    host.gtdd_home.value_or(kDefaultHome));
    if (!host.gtdd_home || host.gtdd_home->empty()) {
      p.detail =
          fmt::format("GTDD_HOME is not set in this environment; the Touch driver ({}) looks for its "
                      "configuration, calibration and motor-temperature files under $GTDD_HOME{}",
                      touch_driver.front(),
                      tree.is_directory("/usr/share/3DSystems/config") ? " (/usr/share/3DSystems/config exists)" : "");
      p.fix = fmt::format("add GTDD_HOME=\"{0}\" to /etc/environment and log in again (a systemd service needs "
                          "Environment=GTDD_HOME={0}; sudo drops it unless given -E); {1}; then run Touch_Setup",
                          kDefaultHome, make_dir);
    } else if (!tree.is_directory(*host.gtdd_home + "/config")) {
      p.detail = fmt::format("GTDD_HOME={} but {}/config does not exist", *host.gtdd_home, *host.gtdd_home);
      p.fix = make_dir + "; then run Touch_Setup, which writes the device's configuration there";
    } else if (const auto configs = tree.files_in(*host.gtdd_home + "/config", ".config"); configs.empty()) {
      p.detail =
          fmt::format("GTDD_HOME={}, but {}/config holds no device configuration", *host.gtdd_home, *host.gtdd_home);
      p.fix = "run Touch_Setup with the Touch plugged in; it writes \"Default Device.config\" there (its name is "
              "the device name `--omni-device` takes)";
    } else {
      p.ok = true;
      p.detail = fmt::format("GTDD_HOME={}, devices configured: {}", *host.gtdd_home, join(configs));
    }
    out.push_back({p, touch});
  }
  return out;
}

}  // namespace toonforce
