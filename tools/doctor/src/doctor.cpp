// SPDX-License-Identifier: Apache-2.0
#include "toonforce/doctor/doctor.hpp"

#include <sys/stat.h>
#include <time.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include <string>
#include <utility>

#include <fmt/format.h>

#include "toonforce/hal/omni/install_check.hpp"

namespace toonforce {
namespace {

namespace fs = std::filesystem;

/// The memory mlockall must be allowed to lock: the whole process, generously.
constexpr std::uint64_t kMemlockNeeded = 256ULL << 20;
constexpr int kCapIpcLock = 14;  // linux/capability.h
constexpr int kCapSysNice = 23;

class Host {
 public:
  explicit Host(std::string root) : root_(std::move(root)) {}

  fs::path path(const std::string& absolute) const { return fs::path(root_) / absolute.substr(1); }

  std::optional<std::string> read(const std::string& absolute) const {
    std::ifstream in(path(absolute));
    if (!in) return std::nullopt;
    std::stringstream text;
    text << in.rdbuf();
    std::string s = text.str();
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    return s;
  }

  /// A "Name:\tvalue" line of /proc/self/status.
  std::optional<std::string> status_field(const std::string& name) const {
    const auto status = read("/proc/self/status");
    if (!status) return std::nullopt;
    std::istringstream lines(*status);
    std::string line;
    while (std::getline(lines, line)) {
      if (line.rfind(name + ":", 0) == 0) {
        std::string value = line.substr(name.size() + 1);
        value.erase(0, value.find_first_not_of(" \t"));
        return value;
      }
    }
    return std::nullopt;
  }

  bool has_capability(int bit) const {
    const auto eff = status_field("CapEff");
    if (!eff) return false;
    const std::uint64_t mask = std::stoull(*eff, nullptr, 16);
    return ((mask >> bit) & 1U) != 0;
  }

  std::uint32_t uid() const {
    const auto v = status_field("Uid");  // real, effective, saved, fs
    if (!v) return 0;
    std::istringstream fields(*v);
    std::uint32_t real = 0, effective = 0;
    fields >> real >> effective;
    return effective;
  }

  std::vector<std::uint32_t> groups() const {
    std::vector<std::uint32_t> out;
    if (const auto gid = status_field("Gid")) {
      std::istringstream fields(*gid);
      std::uint32_t real = 0, effective = 0;
      fields >> real >> effective;
      out.push_back(effective);
    }
    if (const auto g = status_field("Groups")) {
      std::istringstream fields(*g);
      std::uint32_t id = 0;
      while (fields >> id) out.push_back(id);
    }
    return out;
  }

  /// Soft limit of a /proc/self/limits row ("Max locked memory"); nullopt = unlimited.
  std::optional<std::optional<std::uint64_t>> soft_limit(const std::string& name) const {
    const auto limits = read("/proc/self/limits");
    if (!limits) return std::nullopt;
    std::istringstream lines(*limits);
    std::string line;
    while (std::getline(lines, line)) {
      if (line.rfind(name, 0) != 0) continue;
      std::istringstream fields(line.substr(name.size()));
      std::string soft;
      fields >> soft;
      if (soft == "unlimited") return std::optional<std::uint64_t>{};
      return std::optional<std::uint64_t>{std::stoull(soft)};
    }
    return std::nullopt;
  }

  /// Whether this process's user may read and write `node` (mode bits against uid and groups).
  bool may_read_write(const fs::path& node) const {
    struct stat st {};
    if (::stat(node.c_str(), &st) != 0) return false;
    const std::uint32_t me = uid();
    if (me == 0) return true;
    mode_t bits = 0;
    if (st.st_uid == me) {
      bits = (st.st_mode >> 6) & 7U;
    } else {
      const auto gs = groups();
      bits = std::find(gs.begin(), gs.end(), st.st_gid) != gs.end() ? (st.st_mode >> 3) & 7U : st.st_mode & 7U;
    }
    return (bits & 6U) == 6U;
  }

 private:
  std::string root_;
};

std::string cap_or_limit_fix(const std::string& what) {
  return fmt::format(
      "/etc/security/limits.d/toonforce.conf (rtprio 95, memlock unlimited for group realtime; the toonforce "
      "package installs it, from a source tree: sudo cp tools/deploy/toonforce-limits.conf "
      "/etc/security/limits.d/toonforce.conf), sudo groupadd -f realtime && sudo usermod -aG realtime $USER, log in "
      "again; or grant the binary {}; a service gets both from its unit (LimitRTPRIO, LimitMEMLOCK: "
      "toonforce@.service, docs/DEPLOY.md)",
      what);
}

Finding check_kernel(const Host& host) {
  Finding f{"kernel", Verdict::kOk, "", ""};
  const auto realtime = host.read("/sys/kernel/realtime");
  const std::string release = host.read("/proc/sys/kernel/osrelease").value_or("unknown");
  const std::string version = host.read("/proc/sys/kernel/version").value_or("");
  if ((realtime && *realtime == "1") || version.find("PREEMPT_RT") != std::string::npos) {
    f.finding = fmt::format("PREEMPT_RT ({}, \"{}\")", release, version);
    return f;
  }
  f.verdict = Verdict::kFail;
  f.finding = fmt::format("not PREEMPT_RT ({}, \"{}\"): wake-up latency has no bound; expect millisecond outliers",
                          release, version);
  f.fix = "install Debian's real-time kernel: sudo apt-get install linux-image-rt-amd64, then reboot into it "
          "(docs/DEPLOY.md)";
  return f;
}

Finding check_fifo(const Host& host, int priority) {
  Finding f{"SCHED_FIFO", Verdict::kOk, "", ""};
  if (host.uid() == 0) {
    f.finding = "permitted (running as root)";
    return f;
  }
  if (host.has_capability(kCapSysNice)) {
    f.finding = "permitted (CAP_SYS_NICE)";
    return f;
  }
  const auto limit = host.soft_limit("Max realtime priority");
  if (limit && (!*limit || **limit >= static_cast<std::uint64_t>(priority))) {
    f.finding =
        fmt::format("permitted up to priority {} (rtprio limit)", *limit ? std::to_string(**limit) : "unlimited");
    return f;
  }
  const std::uint64_t have = limit && *limit ? **limit : 0;
  f.verdict = have > 0 ? Verdict::kWarn : Verdict::kFail;
  f.finding =
      have > 0 ? fmt::format("only up to priority {} (rtprio limit), below the {} toonforce run uses", have, priority)
               : "not permitted: rtprio limit 0 and no CAP_SYS_NICE (the loop would run as an ordinary thread)";
  f.fix = cap_or_limit_fix("CAP_SYS_NICE: sudo setcap cap_sys_nice,cap_ipc_lock+ep $(command -v toonforce)");
  return f;
}

Finding check_memlock(const Host& host) {
  Finding f{"mlockall", Verdict::kOk, "", ""};
  if (host.uid() == 0 || host.has_capability(kCapIpcLock)) {
    f.finding = host.uid() == 0 ? "permitted (running as root)" : "permitted (CAP_IPC_LOCK)";
    return f;
  }
  const auto limit = host.soft_limit("Max locked memory");
  if (limit && (!*limit || **limit >= kMemlockNeeded)) {
    f.finding = fmt::format("memlock limit {}", *limit ? fmt::format("{} MiB", **limit >> 20) : "unlimited");
    return f;
  }
  f.verdict = Verdict::kFail;
  f.finding = fmt::format("memlock limit {} KiB: mlockall would fail and page faults could stall the loop",
                          limit && *limit ? **limit >> 10 : 0);
  f.fix = cap_or_limit_fix("CAP_IPC_LOCK: sudo setcap cap_sys_nice,cap_ipc_lock+ep $(command -v toonforce)");
  return f;
}

Finding check_throttling(const Host& host) {
  Finding f{"RT throttling", Verdict::kOk, "", ""};
  const auto runtime = host.read("/proc/sys/kernel/sched_rt_runtime_us");
  if (!runtime) {
    f.verdict = Verdict::kInfo;
    f.finding = "sched_rt_runtime_us not found";
    return f;
  }
  if (*runtime == "-1") {
    f.finding = "off (sched_rt_runtime_us = -1)";
    return f;
  }
  // The loop sleeps every period, so the 5% the kernel keeps for others never bites it; only a
  // spinning RT thread would be stopped for 50 ms each second.
  f.verdict = Verdict::kInfo;
  f.finding = fmt::format("on (sched_rt_runtime_us = {}): harmless to a loop that sleeps each period, as "
                          "toonforce's does",
                          *runtime);
  return f;
}

Finding check_governor(const Host& host) {
  Finding f{"CPU frequency", Verdict::kOk, "", ""};
  std::vector<std::string> slow;
  int cpus = 0;
  const fs::path dir = host.path("/sys/devices/system/cpu");
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("cpu", 0) != 0 || name.size() < 4 || !std::isdigit(static_cast<unsigned char>(name[3]))) continue;
    std::ifstream in(entry.path() / "cpufreq" / "scaling_governor");
    std::string governor;
    if (!(in >> governor)) continue;
    ++cpus;
    if (governor != "performance") slow.push_back(fmt::format("{}: {}", name, governor));
  }
  if (cpus == 0) {
    f.verdict = Verdict::kInfo;
    f.finding = "no frequency scaling exposed (fixed clock, or a virtual machine)";
    return f;
  }
  if (slow.empty()) {
    f.finding = fmt::format("governor 'performance' on all {} CPUs", cpus);
    return f;
  }
  std::sort(slow.begin(), slow.end());
  std::string list;
  for (const auto& s : slow) list += (list.empty() ? "" : ", ") + s;
  f.verdict = Verdict::kWarn;
  f.finding = fmt::format("frequency scaling can stretch a tick: {}", list);
  f.fix = "sudo cpupower frequency-set -g performance (Debian package linux-cpupower)";
  return f;
}

Finding check_isolation(const Host& host) {
  Finding f{"isolated CPUs", Verdict::kOk, "", ""};
  const std::string isolated = host.read("/sys/devices/system/cpu/isolated").value_or("");
  const std::string nohz_full = host.read("/sys/devices/system/cpu/nohz_full").value_or("");
  if (!isolated.empty()) {
    // nohz_full stops the scheduler tick on a CPU running one task: a few us less jitter.
    f.finding = fmt::format("{}; tickless (nohz_full): {} (run the loop there: toonforce run --cpu N)", isolated,
                            nohz_full.empty() || nohz_full == "(null)" ? "none" : nohz_full);
    return f;
  }
  f.verdict = Verdict::kWarn;
  f.finding = "none: the loop shares its CPU with everything else";
  // The last CPU this host has ("0-1" in /sys/devices/system/cpu/online: CPU 1), not a
  // made-up 3 (doctor advised --cpu 3 on a 2-CPU host).
  const std::string online = host.read("/sys/devices/system/cpu/online").value_or("");
  const std::size_t cut = online.find_last_of("-,");
  int last = -1;
  try {
    last = online.empty() ? -1 : std::stoi(online.substr(cut == std::string::npos ? 0 : cut + 1));
  } catch (...) {
    last = -1;
  }
  if (last == 0) {
    f.fix = "this host has one CPU: there is none to isolate for the loop; use a host with two or more";
  } else if (last < 0) {
    f.fix = "isolate one CPU for the loop, the last one, N: add isolcpus=managed_irq,domain,N nohz_full=N rcu_nocbs=N "
            "irqaffinity=0-(N-1) to GRUB_CMDLINE_LINUX_DEFAULT in /etc/default/grub, sudo update-grub, reboot, then "
            "toonforce run --cpu N (docs/DEPLOY.md)";
  } else {
    const std::string others = last == 1 ? "0" : fmt::format("0-{}", last - 1);
    f.fix = fmt::format("isolate one CPU for the loop (here the last of {}): add isolcpus=managed_irq,domain,{} "
                        "nohz_full={} rcu_nocbs={} irqaffinity={} to GRUB_CMDLINE_LINUX_DEFAULT in /etc/default/grub, "
                        "sudo update-grub, reboot, then toonforce run --cpu {} (docs/DEPLOY.md)",
                        last + 1, last, last, last, others, last);
  }
  return f;
}

Finding check_clock(const Host& host, bool check_resolution) {
  Finding f{"timer", Verdict::kOk, "", ""};
  const std::string source =
      host.read("/sys/devices/system/clocksource/clocksource0/current_clocksource").value_or("unknown");
  std::string resolution = "not checked";
  if (check_resolution) {
    timespec res{};
    ::clock_getres(CLOCK_MONOTONIC, &res);
    const long ns = res.tv_sec * 1000000000L + res.tv_nsec;
    resolution = fmt::format("{} ns", ns);
    if (ns > 1000) {
      f.verdict = Verdict::kFail;
      f.fix = "enable high-resolution timers (CONFIG_HIGH_RES_TIMERS; Debian's kernels have them)";
    }
  }
  if (source == "jiffies" || source == "acpi_pm") {
    f.verdict = std::max(f.verdict, Verdict::kWarn);
    f.fix =
        f.fix.empty() ? "prefer the TSC clock source (clocksource=tsc tsc=reliable on the kernel command line)" : f.fix;
  }
  f.finding = fmt::format("CLOCK_MONOTONIC resolution {}, clock source {}", resolution, source);
  return f;
}

/// A device node a backend opens, as sysfs describes it.
struct Node {
  std::string name;  ///< for the finding: "/dev/bus/usb/001/005 (0403:cb48)"
  fs::path path;     ///< under the host root
};

std::string read_word(const fs::path& file) {
  std::ifstream in(file);
  std::string v;
  in >> v;
  return v;
}

/// The usbfs node of a USB device directory of /sys/bus/usb/devices.
Node usb_node(const Host& host, const fs::path& device_dir) {
  const int bus = std::atoi(read_word(device_dir / "busnum").c_str());
  const int dev = std::atoi(read_word(device_dir / "devnum").c_str());
  const std::string node = fmt::format("/dev/bus/usb/{:03}/{:03}", bus, dev);
  return {fmt::format("{} ({}:{})", node, read_word(device_dir / "idVendor"), read_word(device_dir / "idProduct")),
          host.path(node)};
}

/// USB devices (their sysfs directories) with this vendor (and product, if not empty).
std::vector<fs::path> usb_devices(const Host& host, const std::string& vendor, const std::string& product) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(host.path("/sys/bus/usb/devices"), ec)) {
    const std::string v = read_word(entry.path() / "idVendor");
    const std::string p = read_word(entry.path() / "idProduct");
    // 3D Systems' id also appears byte-swapped as 0301:2988 in one public note (OMNI.md §1.2);
    // hal/omni matches it too, so the doctor does.
    const bool swapped = vendor == "2988" && v == "0301" && p == "2988";
    if ((v == vendor && (product.empty() || p == product)) || swapped) out.push_back(entry.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// The tty (cdc_acm: <interface>/tty/ttyACMn) and hidraw (<interface>/<hid device>/hidraw/
/// hidrawN) nodes the kernel made for a USB device's interfaces ("<device>:<config>.<n>").
void child_nodes(const Host& host, const fs::path& device_dir, std::vector<Node>& ttys, std::vector<Node>& hidraws) {
  const std::string device = device_dir.filename().string();
  std::error_code ec;
  for (const auto& interface : fs::directory_iterator(device_dir, ec)) {
    if (interface.path().filename().string().rfind(device + ":", 0) != 0) continue;
    std::error_code tty_ec;
    for (const auto& tty : fs::directory_iterator(interface.path() / "tty", tty_ec)) {
      const std::string node = "/dev/" + tty.path().filename().string();
      ttys.push_back({node, host.path(node)});
    }
    std::error_code sub_ec;
    for (const auto& sub : fs::directory_iterator(interface.path(), sub_ec)) {
      std::error_code raw_ec;
      for (const auto& raw : fs::directory_iterator(sub.path() / "hidraw", raw_ec)) {
        const std::string node = "/dev/" + raw.path().filename().string();
        hidraws.push_back({node, host.path(node)});
      }
    }
  }
  const auto by_name = [](const Node& a, const Node& b) { return a.name < b.name; };
  std::sort(ttys.begin(), ttys.end(), by_name);
  std::sort(hidraws.begin(), hidraws.end(), by_name);
}

/// One finding per node: ok when this user may read and write it, else `missing` with `fix`.
void check_node(const Host& host, const char* check, const Node& node, Verdict missing, const std::string& note,
                const std::string& fix, std::vector<Finding>& findings) {
  if (host.may_read_write(node.path)) {
    findings.push_back({check, Verdict::kOk, fmt::format("{}: this user may open it{}", node.name, note), ""});
  } else {
    findings.push_back(
        {check, missing, fmt::format("{}: no read/write permission for this user{}", node.name, note), fix});
  }
}

constexpr const char* kTouchUdevFix =
    "a udev rule giving group plugdev rw on vendor 2988: SUBSYSTEM==\"usb\", ATTRS{idVendor}==\"2988\", "
    "MODE=\"0660\", GROUP=\"plugdev\" (and the same with SUBSYSTEM==\"hidraw\") in "
    "/etc/udev/rules.d/99-3dsystems-touch.rules (the Touch Device Driver's installer ships a similar "
    "99-3dsystems.rules), sudo udevadm control --reload-rules && sudo udevadm trigger, sudo usermod -aG plugdev "
    "$USER, log in again (docs/OMNI.md)";

constexpr const char* kFalconUdevFix =
    "the udev rule: the toonforce package installs it (/usr/lib/udev/rules.d/60-novint-falcon.rules); "
    "otherwise toonforce falcon udev-rule | sudo tee /etc/udev/rules.d/60-novint-falcon.rules, "
    "sudo udevadm control --reload-rules && sudo udevadm trigger; then sudo usermod -aG plugdev $USER, "
    "log in again, replug (docs/FALCON.md)";

void check_falcons(const Host& host, std::vector<Finding>& findings) {
  const auto devices = usb_devices(host, "0403", "cb48");
  if (devices.empty()) findings.push_back({"Falcon USB", Verdict::kInfo, "none connected", ""});
  for (const auto& dir : devices) {
    check_node(host, "Falcon USB", usb_node(host, dir), Verdict::kFail, "", kFalconUdevFix, findings);
  }
}

/// A Touch is opened through OpenHaptics' I/O library, on the node of its model (OMNI.md §1.2,
/// as hal/omni's detection does): the USB-serial model's /dev/ttyACM*, else the USB device
/// itself (libusb). Its hidraw node is reported as a warning only: the library is documented to
/// use libusb, not hidraw, but one user report points at /dev/hidraw.
void check_touches(const Host& host, std::vector<Finding>& findings) {
  const auto devices = usb_devices(host, "2988", "");
  if (devices.empty()) findings.push_back({"Touch USB", Verdict::kInfo, "none connected", ""});
  for (const auto& dir : devices) {
    std::vector<Node> ttys;
    std::vector<Node> hidraws;
    child_nodes(host, dir, ttys, hidraws);
    if (!ttys.empty()) {
      for (const Node& tty : ttys) {
        check_node(host, "Touch serial", tty, Verdict::kFail, " (the USB-serial Touch's port)",
                   "add yourself to the dialout group, which owns /dev/ttyACM*: sudo usermod -aG dialout $USER, "
                   "log in again (docs/OMNI.md)",
                   findings);
      }
    } else {
      check_node(host, "Touch USB", usb_node(host, dir), Verdict::kFail, "", kTouchUdevFix, findings);
    }
    for (const Node& hidraw : hidraws) {
      check_node(host, "Touch hidraw", hidraw, Verdict::kWarn, " (used if the vendor library opens hidraw)",
                 kTouchUdevFix, findings);
    }
  }
}

/// The original Phantom Omni on FireWire: SensAble's vendor OUI 0x000b99 on a /dev/fwN node
/// (OMNI.md §1.1), opened by OpenHaptics AE 3.0's PHANToM I/O library.
void check_firewire_omnis(const Host& host, std::vector<Finding>& findings) {
  std::vector<Node> nodes;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(host.path("/sys/bus/firewire/devices"), ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("fw", 0) != 0 || read_word(entry.path() / "vendor") != "0x000b99") continue;
    nodes.push_back({"/dev/" + name + " (vendor 0x000b99)", host.path("/dev/" + name)});
  }
  std::sort(nodes.begin(), nodes.end(), [](const Node& a, const Node& b) { return a.name < b.name; });
  for (const Node& node : nodes) {
    check_node(host, "Omni FireWire", node, Verdict::kFail, "",
               "a udev rule giving group plugdev rw on the Omni: SUBSYSTEM==\"firewire\", ATTR{vendor}==\"0x000b99\", "
               "MODE=\"0660\", GROUP=\"plugdev\" in /etc/udev/rules.d/99-phantom-omni.rules, sudo udevadm control "
               "--reload-rules && sudo udevadm trigger, sudo usermod -aG plugdev $USER, log in again (docs/OMNI.md)",
               findings);
  }
}

void check_gpiochips(const Host& host, std::vector<Finding>& findings) {
  std::vector<Node> chips;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(host.path("/dev"), ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("gpiochip", 0) == 0) chips.push_back({"/dev/" + name, entry.path()});
  }
  std::sort(chips.begin(), chips.end(), [](const Node& a, const Node& b) { return a.name < b.name; });
  if (chips.empty())
    findings.push_back({"GPIO", Verdict::kInfo, "no /dev/gpiochip* (needed only for --*-pin options)", ""});
  for (const Node& chip : chips) {
    check_node(host, "GPIO", chip, Verdict::kFail, "",
               "add a udev rule giving group gpio rw on gpiochip nodes (SUBSYSTEM==\"gpio\", KERNEL==\"gpiochip*\", "
               "GROUP=\"gpio\", MODE=\"0660\"), sudo usermod -aG gpio $USER, log in again (docs/GPIO.md)",
               findings);
  }
}

/// The OpenHaptics install, as `toonforce devices` checks it: a problem fails the host when a
/// device it matters for is plugged in, and warns otherwise (the host may not be for an Omni).
void check_openhaptics(const DoctorOptions& options, std::vector<Finding>& findings) {
  OpenHapticsHost host;
  host.root = options.root;
  host.gtdd_home = options.gtdd_home;
  for (const auto& f : check_openhaptics_install(host)) {
    const Prerequisite& p = f.prerequisite;
    const Verdict problem = f.device_present ? Verdict::kFail : Verdict::kWarn;
    findings.push_back({"OpenHaptics", p.ok ? Verdict::kOk : problem, p.name + ": " + p.detail, p.ok ? "" : p.fix});
  }
}

/// The world's devices, each under its own name: a Falcon is the attached one whose sysfs
/// `serial` is its `select` (as `run --device scene` opens it by that serial number).
void check_world_devices(const Host& host, const std::vector<DoctorWorldDevice>& world,
                         std::vector<Finding>& findings) {
  struct Attached {
    fs::path dir;
    std::string serial;
  };
  std::vector<Attached> attached;
  for (const auto& dir : usb_devices(host, "0403", "cb48")) attached.push_back({dir, read_word(dir / "serial")});
  // In bus and address order, as hal/falcon numbers them (a world's only Falcon without `select`
  // is the first), not by sysfs name ("1-10" sorts before "1-9").
  const auto number = [](const Attached& a) {
    return std::pair{std::atoi(read_word(a.dir / "busnum").c_str()), std::atoi(read_word(a.dir / "devnum").c_str())};
  };
  std::stable_sort(attached.begin(), attached.end(),
                   [&](const Attached& a, const Attached& b) { return number(a) < number(b); });
  std::string list;
  for (const Attached& a : attached) {
    const std::string node = usb_node(host, a.dir).name;  // "/dev/bus/usb/001/005 (0403:cb48)"
    list += fmt::format("{}{} ({})", list.empty() ? "" : ", ", a.serial.empty() ? "(no serial)" : a.serial,
                        node.substr(0, node.find(' ')));
  }
  if (list.empty()) list = "none";
  std::size_t falcons = 0;
  for (const DoctorWorldDevice& d : world) falcons += d.backend == "falcon";
  std::vector<std::pair<std::string, const Attached*>> taken;  // device name, its Falcon
  for (const DoctorWorldDevice& d : world) {
    const std::string check = fmt::format("{} ({})", d.name, d.backend);
    if (d.backend == "sim") {
      findings.push_back({check, Verdict::kInfo, "simulated: nothing on this host to check", ""});
      continue;
    }
    if (d.backend == "omni") {
      findings.push_back(
          {check, Verdict::kInfo,
           fmt::format("OpenHaptics device {}: its node and the OpenHaptics install are checked above, for the "
                       "host; `toonforce run --device scene` runs it on OpenHaptics' servo thread, bridged to the "
                       "world's clock",
                       d.select.empty() ? "(the default)" : "\"" + d.select + "\""),
           ""});
      continue;
    }
    const Attached* found = nullptr;
    if (d.select.empty() && falcons > 1) {
      findings.push_back({check, Verdict::kFail,
                          fmt::format("no `select`, and the world has {} Falcons; attached Falcons: {}", falcons, list),
                          "add select = \"<serial>\" to its [[device]] table, one of the serials above"});
      continue;
    }
    if (d.select.empty()) {
      if (!attached.empty()) found = &attached.front();
    } else {
      for (const Attached& a : attached) {
        if (a.serial == d.select) found = &a;
      }
    }
    if (found == nullptr) {
      findings.push_back(
          {check, Verdict::kFail,
           fmt::format("{} not connected; attached Falcons: {}",
                       d.select.empty() ? "no Falcon" : "the Falcon with serial " + d.select, list),
           "plug it in (its power supply too; `lsusb -d 0403:cb48 -v | grep iSerial` lists the serials), or correct "
           "`select`"});
      continue;
    }
    const auto other = std::find_if(taken.begin(), taken.end(), [&](const auto& t) { return t.second == found; });
    if (other != taken.end()) {
      findings.push_back({check, Verdict::kFail,
                          fmt::format("the same Falcon as device '{}' ({}); attached Falcons: {}", other->first,
                                      found->serial.empty() ? "no serial" : found->serial, list),
                          "give each [[device]] its own `select` serial"});
      continue;
    }
    taken.emplace_back(d.name, found);
    const std::size_t before = findings.size();
    check_node(host, "", usb_node(host, found->dir), Verdict::kFail,
               found->serial.empty() ? "" : fmt::format(" (serial {})", found->serial), kFalconUdevFix, findings);
    findings[before].check = check;
  }
}

std::string_view label(Verdict v) {
  switch (v) {
    case Verdict::kOk: return "[ ok ]";
    case Verdict::kInfo: return "[info]";
    case Verdict::kWarn: return "[warn]";
    case Verdict::kFail: return "[FAIL]";
  }
  return "[ ?? ]";
}

}  // namespace

std::vector<Finding> run_doctor(const DoctorOptions& options) {
  const Host host(options.root);
  std::vector<Finding> findings;
  findings.push_back(check_kernel(host));
  findings.push_back(check_fifo(host, options.priority));
  findings.push_back(check_memlock(host));
  findings.push_back(check_throttling(host));
  findings.push_back(check_governor(host));
  findings.push_back(check_isolation(host));
  findings.push_back(check_clock(host, options.check_clock));
  // With a world, its Falcons are checked per device (after the host's other checks) rather than
  // every attached one: a Falcon on the bench that no table names is not this session's concern.
  if (options.world.empty()) check_falcons(host, findings);
  check_touches(host, findings);
  check_firewire_omnis(host, findings);
  check_gpiochips(host, findings);
  check_openhaptics(options, findings);
  if (!options.world.empty()) check_world_devices(host, options.world, findings);
  return findings;
}

bool host_ready(const std::vector<Finding>& findings) {
  return std::none_of(findings.begin(), findings.end(), [](const Finding& f) { return f.verdict == Verdict::kFail; });
}

std::string format_findings(const std::vector<Finding>& findings) {
  std::string out;
  int failures = 0;
  int warnings = 0;
  for (const Finding& f : findings) {
    out += fmt::format("{} {:<14} {}\n", label(f.verdict), f.check, f.finding);
    if (!f.fix.empty()) out += fmt::format("       {:<14} fix: {}\n", "", f.fix);
    failures += f.verdict == Verdict::kFail;
    warnings += f.verdict == Verdict::kWarn;
  }
  out += fmt::format("\n{}: {} failure(s), {} warning(s)\n",
                     failures == 0 ? "READY for a real-time haptic loop" : "NOT READY for a real-time haptic loop",
                     failures, warnings);
  return out;
}

}  // namespace toonforce
