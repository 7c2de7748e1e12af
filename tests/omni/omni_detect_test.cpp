// SPDX-License-Identifier: Apache-2.0
// Detection of 3D Systems Touch devices against devices emulated with umockdev
// (umockdev README; docs/FALCON.md §9): the real libusb, hidapi (hidraw) and sysfs code
// paths run against a testbed built in-process. CTest runs this binary under umockdev-wrapper
// (tests/support/run_under_umockdev); run directly, every test skips. The devices are emulated from the
// public facts (vendor 0x2988, product ids 0x0302 and 0x0304, CDC-ACM or HID): this proves the
// detection against those facts, not against a real Touch.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <umockdev.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "toonforce/hal/omni/touch_detect.hpp"

namespace toonforce {
namespace {

using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;

/// One emulated USB device, with an optional serial port (CDC-ACM) or hidraw node (HID).
struct UsbSpec {
  int bus = 1;
  int devnum = 5;
  int port = 1;
  std::uint16_t vid = 0x2988;
  std::uint16_t pid = 0x0304;
  int interface_class = 0x03;
  std::string serial = "TOUCH0001";
  std::string product = "Touch";
  bool node = true;    // the /dev/bus/usb node exists
  std::string tty;     // "ttyACM0"
  std::string hidraw;  // "hidraw0"
};

std::string hex(const std::vector<std::uint8_t>& bytes) {
  std::string out;
  for (const auto b : bytes) out += fmt::format("{:02X}", b);
  return out;
}

/// Device, configuration and one interface descriptor (USB 2.0 §9.6), as sysfs serves them.
std::vector<std::uint8_t> descriptors(const UsbSpec& u) {
  const auto lo = [](std::uint16_t v) { return static_cast<std::uint8_t>(v & 0xFF); };
  const auto hi = [](std::uint16_t v) { return static_cast<std::uint8_t>(v >> 8); };
  return {// device: bcdUSB 2.00, EP0 64 bytes, ids, bcdDevice 1.00, strings 1-3, 1 configuration
          18, 1, 0x00, 0x02, 0, 0, 0, 64, lo(u.vid), hi(u.vid), lo(u.pid), hi(u.pid), 0x00, 0x01, 1, 2, 3, 1,
          // configuration: 18 bytes in all, 1 interface, value 1, bus powered, 100 mA
          9, 2, 18, 0, 1, 1, 0, 0x80, 50,
          // interface 0: no endpoints, class as given
          9, 4, 0, 0, 0, static_cast<std::uint8_t>(u.interface_class), 0, 0, 0};
}

std::string testbed_description(const UsbSpec& u) {
  const std::string sys = fmt::format("/devices/pci0000:00/0000:00:14.0/usb{}/{}-{}", u.bus, u.bus, u.port);
  const std::string blob = hex(descriptors(u));
  const std::string dev = fmt::format("bus/usb/{:03}/{:03}", u.bus, u.devnum);
  std::string s;
  s += fmt::format("P: {}\n", sys);
  if (u.node) s += fmt::format("N: {}={}\n", dev, blob);
  s += fmt::format("E: DEVNAME=/dev/{}\nE: DEVTYPE=usb_device\nE: DRIVER=usb\n", dev);
  s += fmt::format("E: BUSNUM={:03}\nE: DEVNUM={:03}\nE: MAJOR=189\nE: MINOR={}\nE: SUBSYSTEM=usb\n", u.bus, u.devnum,
                   (u.bus - 1) * 128 + u.devnum - 1);
  s += fmt::format("E: PRODUCT={:x}/{:x}/100\n", u.vid, u.pid);
  s += "A: bConfigurationValue=1\\n\nA: bNumConfigurations=1\\n\nA: bNumInterfaces= 1\\n\n";
  s += fmt::format("A: busnum={}\\n\nA: devnum={}\\n\nA: devpath={}\\n\n", u.bus, u.devnum, u.port);
  s += fmt::format("A: dev=189:{}\\n\n", (u.bus - 1) * 128 + u.devnum - 1);
  s += fmt::format("A: idVendor={:04x}\\n\nA: idProduct={:04x}\\n\nA: speed=12\\n\n", u.vid, u.pid);
  s += fmt::format("A: manufacturer=3D Systems\\n\nA: product={}\\n\nA: serial={}\\n\n", u.product, u.serial);
  s += fmt::format("H: descriptors={}\n\n", blob);

  const std::string iface = fmt::format("{}/{}-{}:1.0", sys, u.bus, u.port);
  s += fmt::format("P: {}\nE: DEVTYPE=usb_interface\nE: SUBSYSTEM=usb\n", iface);
  s += fmt::format("E: DRIVER={}\n", u.interface_class == 0x03 ? "usbhid" : "cdc_acm");
  s += fmt::format("A: bInterfaceClass={:02x}\\n\nA: bInterfaceNumber=00\\n\nA: bNumEndpoints=00\\n\n\n",
                   u.interface_class);

  if (!u.tty.empty()) {
    s += fmt::format("P: {}/tty/{}\nN: {}\nE: DEVNAME=/dev/{}\nE: MAJOR=166\nE: MINOR=0\nE: SUBSYSTEM=tty\n"
                     "A: dev=166:0\\n\n\n",
                     iface, u.tty, u.tty, u.tty);
  }
  if (!u.hidraw.empty()) {
    const std::string hid = fmt::format("{}/0003:{:04X}:{:04X}.0001", iface, u.vid, u.pid);
    s += fmt::format("P: {}\nE: DRIVER=hid-generic\nE: HID_ID=0003:{:08X}:{:08X}\nE: HID_NAME=3D Systems {}\n"
                     "E: HID_UNIQ={}\nE: SUBSYSTEM=hid\n"
                     "H: report_descriptor=0600FF0901A1010920150026FF007508954081020921150026FF00750895409102C0\n\n",
                     hid, u.vid, u.pid, u.product, u.serial);
    s += fmt::format("P: {}/hidraw/{}\nN: {}\nE: DEVNAME=/dev/{}\nE: MAJOR=240\nE: MINOR=0\nE: SUBSYSTEM=hidraw\n"
                     "A: dev=240:0\\n\nL: device=../../../0003:{:04X}:{:04X}.0001\n\n",
                     hid, u.hidraw, u.hidraw, u.hidraw, u.vid, u.pid);
  }
  return s;
}

class TouchDetection : public ::testing::Test {
 protected:
  void SetUp() override {
    RecordProperty("proves", "detection with the real libusb, hidapi and sysfs code against devices emulated "
                             "with umockdev from the public facts; not against a real Touch");
    testbed = umockdev_testbed_new();
    if (!umockdev_in_mock_environment()) {
      // Under CTest the emulation is required: skipping there would pass without testing.
      if (std::getenv("TOONFORCE_REQUIRE_UMOCKDEV") != nullptr) FAIL() << "umockdev is not active";
      GTEST_SKIP() << "needs umockdev-wrapper (CTest runs this binary under it)";
    }
  }
  void TearDown() override {
    if (testbed != nullptr) g_object_unref(testbed);
  }
  void add(const UsbSpec& spec) {
    GError* error = nullptr;
    const std::string text = testbed_description(spec);
    ASSERT_TRUE(umockdev_testbed_add_from_string(testbed, text.c_str(), &error))
        << (error != nullptr ? error->message : "") << "\n"
        << text;
  }

  UMockdevTestbed* testbed = nullptr;
};

TEST_F(TouchDetection, NothingPluggedInFindsNothing) { EXPECT_THAT(detect_touch_devices(), IsEmpty()); }

TEST_F(TouchDetection, FindsATouchHidWithItsNodesAndSerial) {
  UsbSpec touch;
  touch.hidraw = "hidraw0";
  add(touch);
  const auto found = detect_touch_devices();
  ASSERT_EQ(found.size(), 1U);
  const DetectedDevice& d = found.front();
  EXPECT_EQ(d.kind, "3D Systems Touch (USB HID, 2988:0304)");
  EXPECT_EQ(d.location, "usb 001/005 (/dev/bus/usb/001/005), hidraw /dev/hidraw0");
  EXPECT_EQ(d.serial, "TOUCH0001");
  EXPECT_TRUE(d.can_open) << d.problem;
  EXPECT_THAT(d.problem, IsEmpty());
  EXPECT_THAT(d.fix, IsEmpty());
}

TEST_F(TouchDetection, FindsATouchOnAUsbSerialPortAndChecksThePort) {
  UsbSpec touch;
  touch.pid = 0x0302;
  touch.interface_class = 0x02;
  touch.serial = "SERIAL302";
  touch.tty = "ttyACM0";
  add(touch);
  const auto found = detect_touch_devices();
  ASSERT_EQ(found.size(), 1U);
  EXPECT_EQ(found[0].kind, "3D Systems Touch (USB serial, 2988:0302)");
  EXPECT_EQ(found[0].location, "usb 001/005 (/dev/bus/usb/001/005), serial port /dev/ttyACM0");
  EXPECT_EQ(found[0].serial, "SERIAL302");
  EXPECT_TRUE(found[0].can_open) << found[0].problem;
}

TEST_F(TouchDetection, OtherVendorsAreNotTouches) {
  UsbSpec falcon;  // a Novint Falcon (FTDI ids) on the same bus
  falcon.vid = 0x0403;
  falcon.pid = 0xcb48;
  falcon.interface_class = 0xFF;
  falcon.devnum = 4;
  falcon.port = 2;
  add(falcon);
  EXPECT_THAT(detect_touch_devices(), IsEmpty());
  UsbSpec touch;
  touch.hidraw = "hidraw0";
  add(touch);
  const auto found = detect_touch_devices();
  ASSERT_EQ(found.size(), 1U);
  EXPECT_THAT(found[0].kind, HasSubstr("2988:0304"));
}

TEST_F(TouchDetection, AnUnknownProductOfTheVendorIsReportedAsSuch) {
  UsbSpec other;
  other.pid = 0x0399;
  other.interface_class = 0xFF;
  add(other);
  const auto found = detect_touch_devices();
  ASSERT_EQ(found.size(), 1U);
  EXPECT_EQ(found[0].kind, "3D Systems device (USB 2988:0399, not a known Touch product id)");
}

TEST_F(TouchDetection, TwoTouchesAreTwoEntries) {
  UsbSpec a;
  a.hidraw = "hidraw0";
  UsbSpec b;
  b.devnum = 9;
  b.port = 3;
  b.serial = "TOUCH0002";
  b.pid = 0x0302;
  b.interface_class = 0x02;
  b.tty = "ttyACM0";
  add(a);
  add(b);
  const auto found = detect_touch_devices();
  ASSERT_EQ(found.size(), 2U);
  std::vector<std::string> serials{found[0].serial, found[1].serial};
  std::sort(serials.begin(), serials.end());
  EXPECT_EQ(serials, (std::vector<std::string>{"TOUCH0001", "TOUCH0002"}));
}

TEST_F(TouchDetection, ADeviceWhoseNodeIsMissingSaysWhatToDo) {
  UsbSpec touch;
  touch.node = false;  // in sysfs, but no /dev/bus/usb node
  add(touch);
  const auto found = detect_touch_devices();
  ASSERT_EQ(found.size(), 1U);
  EXPECT_FALSE(found[0].can_open);
  EXPECT_EQ(found[0].problem,
            "/dev/bus/usb/001/005 does not exist: the device went away, or no kernel driver made its node");
  EXPECT_THAT(found[0].fix, HasSubstr("replug"));
}

TEST_F(TouchDetection, ASerialPortThatWillNotOpenIsReportedWithTheDialoutFixOrReplug) {
  UsbSpec touch;
  touch.pid = 0x0302;
  touch.interface_class = 0x02;
  add(touch);
  // The kernel named ttyACM7 in sysfs, but no node exists for it.
  GError* error = nullptr;
  const std::string tty = "P: /devices/pci0000:00/0000:00:14.0/usb1/1-1/1-1:1.0/tty/ttyACM7\nE: DEVNAME=/dev/ttyACM7\n"
                          "E: MAJOR=166\nE: MINOR=7\nE: SUBSYSTEM=tty\nA: dev=166:7\\n\n";
  ASSERT_TRUE(umockdev_testbed_add_from_string(testbed, tty.c_str(), &error)) << error->message;
  const auto found = detect_touch_devices();
  ASSERT_EQ(found.size(), 1U);
  EXPECT_THAT(found[0].location, HasSubstr("serial port /dev/ttyACM7"));
  EXPECT_FALSE(found[0].can_open);
  EXPECT_THAT(found[0].problem, HasSubstr("/dev/ttyACM7 does not exist"));
  EXPECT_THAT(found[0].fix, HasSubstr("cdc_acm"));
  EXPECT_THAT(found[0].fix, Not(IsEmpty()));
}

}  // namespace
}  // namespace toonforce
