// SPDX-License-Identifier: Apache-2.0
// toonforce doctor against faked /sys, /proc and /dev trees: each check finds what the tree
// says, fails or warns with a fix, and the exit status says whether the host is ready.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "toonforce/doctor/doctor.hpp"

namespace toonforce {
namespace {

namespace fs = std::filesystem;

/// A fake root of a well-configured real-time host; tests spoil one thing at a time.
class FakeHost : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / fmt::format("toonforce_doctor_{}_{}", ::getpid(),
                                                    ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    write("sys/kernel/realtime", "1\n");
    write("proc/sys/kernel/osrelease", "6.1.0-28-rt-amd64\n");
    write("proc/sys/kernel/version", "#1 SMP PREEMPT_RT Debian 6.1.119-1\n");
    write("proc/sys/kernel/sched_rt_runtime_us", "-1\n");
    write("sys/devices/system/cpu/isolated", "3\n");
    write("sys/devices/system/clocksource/clocksource0/current_clocksource", "tsc\n");
    for (int cpu = 0; cpu < 4; ++cpu)
      write(fmt::format("sys/devices/system/cpu/cpu{}/cpufreq/scaling_governor", cpu), "performance\n");
    node_gid_ = gid_of_new_files();
    status(1000, {node_gid_}, "0000000000000000");
    limits("95", "unlimited");
  }
  void TearDown() override { fs::remove_all(root_); }

  void write(const std::string& relative, const std::string& text) {
    fs::create_directories((root_ / relative).parent_path());
    std::ofstream(root_ / relative) << text;
  }
  std::uint32_t gid_of_new_files() {
    write("probe", "");
    struct stat st {};
    ::stat((root_ / "probe").c_str(), &st);
    return st.st_gid;
  }
  void status(std::uint32_t uid, std::vector<std::uint32_t> groups, const std::string& cap_eff) {
    std::string g;
    for (auto id : groups) g += fmt::format("{} ", id);
    write("proc/self/status",
          fmt::format("Name:\ttoonforce\nUid:\t{0}\t{0}\t{0}\t{0}\nGid:\t{1}\t{1}\t{1}\t{1}\nGroups:\t{2}\n"
                      "CapEff:\t{3}\n",
                      uid, 5000, g, cap_eff));
  }
  void limits(const std::string& rtprio, const std::string& memlock) {
    write("proc/self/limits",
          fmt::format("Limit                     Soft Limit           Hard Limit           Units     \n"
                      "Max locked memory         {0:<21}{0:<21}bytes     \n"
                      "Max realtime priority     {1:<21}{1:<21}\n",
                      memlock, rtprio));
  }
  void falcon(const std::string& usb_dir, int bus, int dev, fs::perms mode) {
    write(fmt::format("sys/bus/usb/devices/{}/idVendor", usb_dir), "0403\n");
    write(fmt::format("sys/bus/usb/devices/{}/idProduct", usb_dir), "cb48\n");
    write(fmt::format("sys/bus/usb/devices/{}/busnum", usb_dir), fmt::format("{}\n", bus));
    write(fmt::format("sys/bus/usb/devices/{}/devnum", usb_dir), fmt::format("{}\n", dev));
    const std::string node = fmt::format("dev/bus/usb/{:03}/{:03}", bus, dev);
    write(node, "");
    fs::permissions(root_ / node, mode);
  }
  /// A Touch (vendor 2988) with, optionally, a cdc_acm tty or a hidraw node under its interface.
  void touch(const std::string& usb_dir, int bus, int dev, const std::string& tty, const std::string& hidraw,
             fs::perms mode) {
    const std::string sys = fmt::format("sys/bus/usb/devices/{}", usb_dir);
    write(sys + "/idVendor", "2988\n");
    write(sys + "/idProduct", "0304\n");
    write(sys + "/busnum", fmt::format("{}\n", bus));
    write(sys + "/devnum", fmt::format("{}\n", dev));
    const std::string node = fmt::format("dev/bus/usb/{:03}/{:03}", bus, dev);
    write(node, "");
    fs::permissions(root_ / node, mode);
    const std::string interface = fmt::format("{}/{}:1.0", sys, usb_dir);
    if (!tty.empty()) {
      fs::create_directories(root_ / interface / "tty" / tty);
      write("dev/" + tty, "");
      fs::permissions(root_ / "dev" / tty, mode);
    }
    if (!hidraw.empty()) {
      fs::create_directories(root_ / interface / "0003:2988:0304.0001" / "hidraw" / hidraw);
      write("dev/" + hidraw, "");
      fs::permissions(root_ / "dev" / hidraw, mode);
    }
  }
  static constexpr fs::perms kGroupRw =
      fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::group_write;
  static constexpr fs::perms kRootOnly = fs::perms::owner_read | fs::perms::owner_write;

  std::vector<Finding> run(std::optional<std::string> gtdd_home = std::nullopt) {
    DoctorOptions o;
    o.root = root_.string();
    o.gtdd_home = std::move(gtdd_home);
    return run_doctor(o);
  }
  // By value: callers pass the temporary that run() returns.
  static Finding find(const std::vector<Finding>& all, const std::string& check, std::size_t nth = 0) {
    for (const auto& f : all) {
      if (f.check == check && nth-- == 0) return f;
    }
    return {"missing", Verdict::kFail, "no such check", ""};
  }

  fs::path root_;
  std::uint32_t node_gid_ = 0;
};

TEST_F(FakeHost, AWellConfiguredRealTimeHostIsReady) {
  falcon("1-1", 1, 5, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::group_write);
  const auto f = run();
  EXPECT_TRUE(host_ready(f)) << format_findings(f);
  EXPECT_EQ(find(f, "kernel").verdict, Verdict::kOk);
  EXPECT_NE(find(f, "SCHED_FIFO").finding.find("priority 95"), std::string::npos);
  EXPECT_EQ(find(f, "mlockall").verdict, Verdict::kOk);
  EXPECT_EQ(find(f, "CPU frequency").verdict, Verdict::kOk);
  EXPECT_NE(find(f, "isolated CPUs").finding.find("3"), std::string::npos);
  EXPECT_EQ(find(f, "Falcon USB").verdict, Verdict::kOk);
  EXPECT_NE(find(f, "Falcon USB").finding.find("/dev/bus/usb/001/005"), std::string::npos);
}

TEST_F(FakeHost, AKernelWithoutPreemptRtIsNotReady) {
  fs::remove(root_ / "sys/kernel/realtime");
  write("proc/sys/kernel/version", "#1 SMP PREEMPT_DYNAMIC Debian 6.1.119-1\n");
  const auto f = run();
  EXPECT_FALSE(host_ready(f));
  EXPECT_EQ(find(f, "kernel").verdict, Verdict::kFail);
  EXPECT_NE(find(f, "kernel").fix.find("linux-image-rt-amd64"), std::string::npos);
}

TEST_F(FakeHost, TheRtVersionStringAloneIsEnough) {
  fs::remove(root_ / "sys/kernel/realtime");  // older RT kernels lack the file
  EXPECT_EQ(find(run(), "kernel").verdict, Verdict::kOk);
}

TEST_F(FakeHost, NoRtprioAndNoCapabilityMeansNoSchedFifo) {
  limits("0", "unlimited");
  const auto f = run();
  EXPECT_FALSE(host_ready(f));
  EXPECT_EQ(find(f, "SCHED_FIFO").verdict, Verdict::kFail);
  EXPECT_NE(find(f, "SCHED_FIFO").fix.find("limits.d"), std::string::npos);
  EXPECT_NE(find(f, "SCHED_FIFO").fix.find("cap_sys_nice"), std::string::npos);
}

TEST_F(FakeHost, CapSysNiceGrantsSchedFifoWithoutRtprio) {
  limits("0", "unlimited");
  status(1000, {node_gid_}, fmt::format("{:016x}", 1ULL << 23));
  EXPECT_EQ(find(run(), "SCHED_FIFO").verdict, Verdict::kOk);
}

TEST_F(FakeHost, AnRtprioBelowTheLoopsPriorityWarns) {
  limits("50", "unlimited");
  const auto& fifo = find(run(), "SCHED_FIFO");
  EXPECT_EQ(fifo.verdict, Verdict::kWarn);
  EXPECT_NE(fifo.finding.find("50"), std::string::npos);
}

TEST_F(FakeHost, ASmallMemlockLimitFailsUnlessCapIpcLock) {
  limits("95", "8388608");
  EXPECT_EQ(find(run(), "mlockall").verdict, Verdict::kFail);
  status(1000, {node_gid_}, fmt::format("{:016x}", 1ULL << 14));
  EXPECT_EQ(find(run(), "mlockall").verdict, Verdict::kOk);
}

TEST_F(FakeHost, AScalingGovernorWarnsNamingTheCpu) {
  write("sys/devices/system/cpu/cpu2/cpufreq/scaling_governor", "powersave\n");
  const auto& g = find(run(), "CPU frequency");
  EXPECT_EQ(g.verdict, Verdict::kWarn);
  EXPECT_NE(g.finding.find("cpu2: powersave"), std::string::npos) << g.finding;
  EXPECT_NE(g.fix.find("performance"), std::string::npos);
}

TEST_F(FakeHost, NoIsolatedCpuWarns) {
  write("sys/devices/system/cpu/isolated", "\n");
  const auto& i = find(run(), "isolated CPUs");
  EXPECT_EQ(i.verdict, Verdict::kWarn);
  EXPECT_NE(i.fix.find("isolcpus"), std::string::npos);
}

// On a 2-CPU host doctor advised --cpu 3, a CPU the host does not have.
TEST_F(FakeHost, TheIsolationAdviceNamesTheLastCpuThisHostHas) {
  write("sys/devices/system/cpu/isolated", "\n");
  write("sys/devices/system/cpu/online", "0-1\n");
  const auto two = find(run(), "isolated CPUs").fix;
  EXPECT_NE(two.find("isolcpus=managed_irq,domain,1 "), std::string::npos) << two;
  EXPECT_NE(two.find("irqaffinity=0 "), std::string::npos) << two;
  EXPECT_NE(two.find("toonforce run --cpu 1 "), std::string::npos) << two;
  write("sys/devices/system/cpu/online", "0-7\n");
  const auto eight = find(run(), "isolated CPUs").fix;
  EXPECT_NE(eight.find("--cpu 7 "), std::string::npos) << eight;
  EXPECT_NE(eight.find("irqaffinity=0-6 "), std::string::npos) << eight;
}

TEST_F(FakeHost, AFalconThisUserCannotOpenFailsWithTheUdevFix) {
  // Owned by root, group not ours, world read-only: the default for an unknown USB device.
  falcon("1-2", 2, 7, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::others_read);
  status(1000, {}, "0000000000000000");
  const auto f = run();
  EXPECT_FALSE(host_ready(f));
  const auto& d = find(f, "Falcon USB");
  EXPECT_EQ(d.verdict, Verdict::kFail);
  EXPECT_NE(d.finding.find("/dev/bus/usb/002/007"), std::string::npos);
  EXPECT_NE(d.fix.find("plugdev"), std::string::npos);
  EXPECT_NE(d.fix.find("udev"), std::string::npos);
}

// ---- `doctor --scene WORLD.toml`: the host once, then each device of the world by its name ----

TEST_F(FakeHost, AWorldsFalconsAreCheckedEachByItsSerialAndName) {
  falcon("1-1", 1, 5, kGroupRw);
  write("sys/bus/usb/devices/1-1/serial", "FTLEFT01\n");
  falcon("1-2", 1, 6, fs::perms::owner_read | fs::perms::owner_write | fs::perms::others_read);
  write("sys/bus/usb/devices/1-2/serial", "FTRIGHT2\n");
  DoctorOptions o;
  o.root = root_.string();
  o.world = {{"left", "falcon", "FTLEFT01"}, {"right", "falcon", "FTRIGHT2"}, {"ghost", "sim", ""}};
  auto f = run_doctor(o);
  EXPECT_EQ(find(f, "Falcon USB").finding, "no such check") << "the world's Falcons replace the host-wide list";
  const Finding left = find(f, "left (falcon)");
  EXPECT_EQ(left.verdict, Verdict::kOk);
  EXPECT_EQ(left.finding, "/dev/bus/usb/001/005 (0403:cb48): this user may open it (serial FTLEFT01)");
  const Finding right = find(f, "right (falcon)");
  EXPECT_EQ(right.verdict, Verdict::kFail);
  EXPECT_NE(right.finding.find("/dev/bus/usb/001/006"), std::string::npos) << right.finding;
  EXPECT_NE(right.finding.find("serial FTRIGHT2"), std::string::npos) << right.finding;
  EXPECT_NE(right.fix.find("udev"), std::string::npos);
  EXPECT_EQ(find(f, "ghost (sim)").verdict, Verdict::kInfo);
  EXPECT_FALSE(host_ready(f));
  // The world's devices come after every host check.
  EXPECT_EQ(f[f.size() - 3].check, "left (falcon)");

  // Swapped selects: each device still finds its own, by serial, not by order.
  o.world = {{"left", "falcon", "FTRIGHT2"}, {"right", "falcon", "FTLEFT01"}};
  f = run_doctor(o);
  EXPECT_EQ(find(f, "left (falcon)").verdict, Verdict::kFail);
  EXPECT_EQ(find(f, "right (falcon)").verdict, Verdict::kOk);
}

TEST_F(FakeHost, AWorldsFalconThatIsMissingSharedOrUnselectedFailsListingTheSerials) {
  falcon("1-1", 1, 5, kGroupRw);
  write("sys/bus/usb/devices/1-1/serial", "FTLEFT01\n");
  falcon("1-2", 1, 6, kGroupRw);
  write("sys/bus/usb/devices/1-2/serial", "FTRIGHT2\n");
  DoctorOptions o;
  o.root = root_.string();
  o.world = {{"a", "falcon", "FTLEFT01"}, {"b", "falcon", "FTLEFT01"}, {"c", "falcon", "NOPE"}, {"d", "falcon", ""}};
  const auto f = run_doctor(o);
  EXPECT_FALSE(host_ready(f));
  EXPECT_EQ(find(f, "a (falcon)").verdict, Verdict::kOk);
  const std::string attached = "attached Falcons: FTLEFT01 (/dev/bus/usb/001/005), FTRIGHT2 (/dev/bus/usb/001/006)";
  const Finding b = find(f, "b (falcon)");
  EXPECT_EQ(b.verdict, Verdict::kFail);
  EXPECT_NE(b.finding.find("the same Falcon as device 'a' (FTLEFT01)"), std::string::npos) << b.finding;
  const Finding c = find(f, "c (falcon)");
  EXPECT_EQ(c.verdict, Verdict::kFail);
  EXPECT_NE(c.finding.find("the Falcon with serial NOPE not connected; attached Falcons: FTLEFT01"), std::string::npos)
      << c.finding;
  const Finding d = find(f, "d (falcon)");
  EXPECT_EQ(d.verdict, Verdict::kFail);
  EXPECT_NE(d.finding.find("no `select`, and the world has 4 Falcons; " + attached), std::string::npos) << d.finding;
  EXPECT_NE(d.fix.find("add select = \"<serial>\""), std::string::npos) << d.fix;
}

TEST_F(FakeHost, AWorldsOnlyFalconWithoutSelectIsTheFirstByBusAndAddress) {
  // sysfs names sort "1-10" before "1-9"; hal/falcon (and so `run`) takes the lower address.
  falcon("1-10", 1, 10, kRootOnly);
  write("sys/bus/usb/devices/1-10/serial", "FTHIGH10\n");
  falcon("1-9", 1, 9, kGroupRw);
  write("sys/bus/usb/devices/1-9/serial", "FTLOW009\n");
  DoctorOptions o;
  o.root = root_.string();
  o.world = {{"only", "falcon", ""}, {"ghost", "sim", ""}};
  const Finding only = find(run_doctor(o), "only (falcon)");
  EXPECT_EQ(only.verdict, Verdict::kOk) << only.finding;
  EXPECT_NE(only.finding.find("/dev/bus/usb/001/009 (0403:cb48): this user may open it (serial FTLOW009)"),
            std::string::npos)
      << only.finding;
}

TEST_F(FakeHost, TheCommandReadsTheWorldSceneAndRefusesAOneDeviceScene) {
  falcon("1-1", 1, 5, kGroupRw);
  write("sys/bus/usb/devices/1-1/serial", "FTLEFT01\n");
  const auto run_binary = [this](const std::string& scene, std::string& out) {
    const std::string cmd = fmt::format("'{}' doctor --root '{}' --scene '{}' 2>&1", TOONFORCE_BINARY, root_.string(),
                                        (root_ / scene).string());
    FILE* p = ::popen(cmd.c_str(), "r");
    char buf[4096];
    for (std::size_t n = 0; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
    const int status = ::pclose(p);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  write("world.toml", "[[device]]\nname = \"left\"\nbackend = \"falcon\"\nselect = \"FTLEFT01\"\n"
                      "[[device]]\nname = \"ghost\"\n");
  std::string out;
  EXPECT_EQ(run_binary("world.toml", out), 0) << out;
  EXPECT_NE(out.find("[ ok ] left (falcon)  /dev/bus/usb/001/005 (0403:cb48): this user may open it (serial "
                     "FTLEFT01)\n"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("[info] ghost (sim)    simulated"), std::string::npos) << out;
  write("world.toml", "[[device]]\nname = \"left\"\nbackend = \"falcon\"\nselect = \"FTOTHER9\"\n");
  out.clear();
  EXPECT_EQ(run_binary("world.toml", out), 1) << out;
  write("one.toml", "[device]\nmax_force = 2.0\n");
  out.clear();
  EXPECT_EQ(run_binary("one.toml", out), 2) << out;
  EXPECT_NE(out.find("one.toml:1: device: a one-device scene"), std::string::npos) << out;
  write("bad.toml", "[[device]]\nname = \"left\"\nbackend = \"falcn\"\n");
  out.clear();
  EXPECT_EQ(run_binary("bad.toml", out), 2) << out;
  EXPECT_NE(out.find("bad.toml:3: device[1].backend"), std::string::npos) << out;
}

TEST_F(FakeHost, GpioChipsAreCheckedOneByOne) {
  write("dev/gpiochip0", "");
  write("dev/gpiochip1", "");
  fs::permissions(root_ / "dev/gpiochip0",
                  fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::group_write);
  fs::permissions(root_ / "dev/gpiochip1", fs::perms::owner_read | fs::perms::owner_write);
  const auto f = run();
  EXPECT_EQ(find(f, "GPIO", 0).verdict, Verdict::kOk);
  EXPECT_EQ(find(f, "GPIO", 1).verdict, Verdict::kFail);
  EXPECT_NE(find(f, "GPIO", 1).finding.find("/dev/gpiochip1"), std::string::npos);
}

TEST_F(FakeHost, ASerialTouchIsCheckedOnItsPortWithTheDialoutFix) {
  // The USB-serial model: the vendor library opens /dev/ttyACM*, not the USB node.
  touch("1-3", 1, 9, "ttyACM0", "", kRootOnly);
  status(1000, {}, "0000000000000000");
  const auto f = run();
  EXPECT_FALSE(host_ready(f));
  const auto serial = find(f, "Touch serial");
  EXPECT_EQ(serial.verdict, Verdict::kFail);
  EXPECT_NE(serial.finding.find("/dev/ttyACM0"), std::string::npos) << serial.finding;
  EXPECT_NE(serial.fix.find("dialout"), std::string::npos);
  EXPECT_EQ(find(f, "Touch USB").check, "missing") << "the USB node is not what the serial model opens";
}

TEST_F(FakeHost, AHidTouchIsCheckedOnItsUsbNodeAndWarnsAboutItsHidraw) {
  touch("1-4", 1, 10, "", "hidraw0", kGroupRw);  // our group: may open both
  auto f = run();
  EXPECT_TRUE(host_ready(f)) << format_findings(f);
  EXPECT_EQ(find(f, "Touch USB").verdict, Verdict::kOk);
  EXPECT_NE(find(f, "Touch USB").finding.find("/dev/bus/usb/001/010 (2988:0304)"), std::string::npos);
  EXPECT_EQ(find(f, "Touch hidraw").verdict, Verdict::kOk);

  status(1000, {}, "0000000000000000");  // now in no group that owns them
  f = run();
  EXPECT_EQ(find(f, "Touch USB").verdict, Verdict::kFail);
  EXPECT_NE(find(f, "Touch USB").fix.find("2988"), std::string::npos);
  const auto hidraw = find(f, "Touch hidraw");
  EXPECT_EQ(hidraw.verdict, Verdict::kWarn);
  EXPECT_NE(hidraw.finding.find("/dev/hidraw0"), std::string::npos);
}

TEST_F(FakeHost, AFirewireOmniIsFoundByItsVendorOui) {
  write("sys/bus/firewire/devices/fw1/vendor", "0x000b99\n");
  write("sys/bus/firewire/devices/fw0/vendor", "0x001f11\n");  // the host's own controller
  write("dev/fw1", "");
  fs::permissions(root_ / "dev/fw1", kRootOnly);
  status(1000, {}, "0000000000000000");
  const auto f = run();
  const auto omni = find(f, "Omni FireWire");
  EXPECT_EQ(omni.verdict, Verdict::kFail);
  EXPECT_NE(omni.finding.find("/dev/fw1"), std::string::npos);
  EXPECT_NE(omni.fix.find("0x000b99"), std::string::npos);
  EXPECT_EQ(find(f, "Omni FireWire", 1).check, "missing") << "fw0 is not an Omni";
}

// ---- OpenHaptics installs (hal/omni install_check.hpp, the same checks as `devices`) ----

TEST_F(FakeHost, NoOpenHapticsInstalledAndNoDeviceMeansNoOpenHapticsFinding) {
  EXPECT_EQ(find(run(), "OpenHaptics").check, "missing");
}

TEST_F(FakeHost, OpenHapticsInLib64WithoutALoaderEntryFailsWithTheLdSoConfFix) {
  write("usr/lib64/libHD.so.3.0.0", "");
  write("usr/lib64/libPHANToMIO.so.4.3", "");
  write("usr/lib/x86_64-linux-gnu/libraw1394.so.8", "");
  write("etc/ld.so.conf", "include /etc/ld.so.conf.d/*.conf\n");
  write("etc/ld.so.conf.d/x86_64-linux-gnu.conf", "# Multiarch support\n/usr/local/lib/x86_64-linux-gnu\n");
  write("sys/bus/firewire/devices/fw1/vendor", "0x000b99\n");  // a FireWire Omni is plugged in
  write("dev/fw1", "");
  fs::permissions(root_ / "dev/fw1", kGroupRw);
  auto f = run();
  const Finding lib64 = find(f, "OpenHaptics");
  EXPECT_EQ(lib64.verdict, Verdict::kFail) << format_findings(f);
  EXPECT_NE(lib64.finding.find("/usr/lib64/libHD.so.3.0.0"), std::string::npos) << lib64.finding;
  EXPECT_NE(lib64.finding.find("does not search"), std::string::npos) << lib64.finding;
  EXPECT_NE(lib64.fix.find("echo /usr/lib64 | sudo tee /etc/ld.so.conf.d/openhaptics.conf && sudo ldconfig"),
            std::string::npos)
      << lib64.fix;
  EXPECT_FALSE(host_ready(f));

  write("etc/ld.so.conf.d/openhaptics.conf", "/usr/lib64/\n");  // the fix, as tee writes it
  f = run();
  EXPECT_EQ(find(f, "OpenHaptics").verdict, Verdict::kOk) << format_findings(f);
  EXPECT_TRUE(host_ready(f)) << format_findings(f);
}

TEST_F(FakeHost, WithoutTheDeviceAnOpenHapticsProblemOnlyWarns) {
  write("usr/lib64/libHD.so.3.0.0", "");
  const auto f = run();
  EXPECT_EQ(find(f, "OpenHaptics").verdict, Verdict::kWarn);
  EXPECT_TRUE(host_ready(f));
}

TEST_F(FakeHost, TheFirewireDriverNeedsLibraw1394So8AndTheFixLinksTheInstalledOne) {
  write("usr/lib/libPHANToMIO.so.4.3", "");
  write("usr/lib/x86_64-linux-gnu/libraw1394.so.11", "");
  write("sys/bus/firewire/devices/fw1/vendor", "0x000b99\n");
  write("dev/fw1", "");
  fs::permissions(root_ / "dev/fw1", kGroupRw);
  auto f = run();
  const Finding raw = find(f, "OpenHaptics");
  EXPECT_EQ(raw.verdict, Verdict::kFail) << format_findings(f);
  EXPECT_NE(raw.finding.find("libraw1394.so.8"), std::string::npos) << raw.finding;
  EXPECT_NE(raw.fix.find("sudo ln -s /usr/lib/x86_64-linux-gnu/libraw1394.so.11 "
                         "/usr/lib/x86_64-linux-gnu/libraw1394.so.8 && sudo ldconfig"),
            std::string::npos)
      << raw.fix;
  write("usr/lib/x86_64-linux-gnu/libraw1394.so.8", "");
  EXPECT_EQ(find(run(), "OpenHaptics").verdict, Verdict::kOk);
}

TEST_F(FakeHost, TheTouchDriverNeedsGtddHomeAndItsConfigDirectory) {
  write("usr/lib/libPhantomIOLib42.so", "");
  touch("1-4", 1, 10, "", "", kGroupRw);
  Finding g = find(run(), "OpenHaptics");
  EXPECT_EQ(g.verdict, Verdict::kFail);
  EXPECT_NE(g.finding.find("GTDD_HOME is not set"), std::string::npos) << g.finding;
  EXPECT_NE(g.fix.find("GTDD_HOME=\"/usr/share/3DSystems\" to /etc/environment"), std::string::npos) << g.fix;
  EXPECT_NE(g.fix.find("sudo mkdir -p /usr/share/3DSystems/config"), std::string::npos) << g.fix;

  g = find(run("/usr/share/3DSystems"), "OpenHaptics");
  EXPECT_EQ(g.verdict, Verdict::kFail);
  EXPECT_NE(g.finding.find("/usr/share/3DSystems/config does not exist"), std::string::npos) << g.finding;

  fs::create_directories(root_ / "usr/share/3DSystems/config");
  g = find(run("/usr/share/3DSystems"), "OpenHaptics");
  EXPECT_EQ(g.verdict, Verdict::kFail);
  EXPECT_NE(g.fix.find("Touch_Setup"), std::string::npos) << g.fix;

  write("usr/share/3DSystems/config/Default Device.config", "");
  g = find(run("/usr/share/3DSystems"), "OpenHaptics");
  EXPECT_EQ(g.verdict, Verdict::kOk) << g.finding;
  EXPECT_NE(g.finding.find("Default Device.config"), std::string::npos) << g.finding;
}

TEST_F(FakeHost, TheIsolatedCpusFindingSaysWhetherTheyAreTickless) {
  EXPECT_NE(find(run(), "isolated CPUs").finding.find("nohz_full): none"), std::string::npos);
  write("sys/devices/system/cpu/nohz_full", "3\n");
  EXPECT_NE(find(run(), "isolated CPUs").finding.find("nohz_full): 3"), std::string::npos);
}

TEST_F(FakeHost, TheCommandsExitStatusSaysWhetherTheHostIsReady) {
  const auto run_binary = [this] {
    const std::string cmd = fmt::format("'{}' doctor --root '{}' > /dev/null", TOONFORCE_BINARY, root_.string());
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  EXPECT_EQ(run_binary(), 0);
  write("proc/sys/kernel/version", "#1 SMP PREEMPT_DYNAMIC\n");
  fs::remove(root_ / "sys/kernel/realtime");
  EXPECT_EQ(run_binary(), 1);
}

}  // namespace
}  // namespace toonforce
