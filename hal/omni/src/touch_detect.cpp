// SPDX-License-Identifier: Apache-2.0
// Finding Touch devices with libusb, hidapi and sysfs, and checking OpenHaptics; see
// touch_detect.hpp. No request is ever sent to a device.
#include "toonforce/hal/omni/touch_detect.hpp"

#include <fcntl.h>
#include <hidapi/hidapi.h>
#include <libusb.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "toonforce/hal/omni/hd_library.hpp"

namespace toonforce {
namespace {

namespace fs = std::filesystem;

constexpr int kClassCdcComm = 0x02;
constexpr int kClassHid = 0x03;
constexpr int kClassCdcData = 0x0A;

std::string read_attribute(const fs::path& path) {
  std::ifstream in(path);
  std::string value;
  std::getline(in, value);
  while (!value.empty() && (value.back() == '\n' || value.back() == ' ' || value.back() == '\r')) value.pop_back();
  return value;
}

/// What sysfs says about a USB device: its strings, interface classes and the tty and
/// hidraw nodes the kernel made for it.
struct SysfsDevice {
  std::string serial;
  std::string product;
  std::vector<int> interface_classes;
  std::vector<std::string> ttys;     // "/dev/ttyACM0"
  std::vector<std::string> hidraws;  // "/dev/hidraw0"
};

SysfsDevice read_sysfs(const std::string& sysname) {
  SysfsDevice d;
  const fs::path dir = fs::path("/sys/bus/usb/devices") / sysname;
  d.serial = read_attribute(dir / "serial");
  d.product = read_attribute(dir / "product");
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (!name.starts_with(sysname + ":")) continue;  // interfaces are "<device>:<config>.<n>"
    const std::string cls = read_attribute(entry.path() / "bInterfaceClass");
    if (!cls.empty()) d.interface_classes.push_back(static_cast<int>(std::strtol(cls.c_str(), nullptr, 16)));
    std::error_code tty_ec;
    for (const auto& tty : fs::directory_iterator(entry.path() / "tty", tty_ec)) {
      d.ttys.push_back("/dev/" + tty.path().filename().string());
    }
    std::error_code sub_ec;
    for (const auto& sub : fs::directory_iterator(entry.path(), sub_ec)) {
      std::error_code hid_ec;
      for (const auto& raw : fs::directory_iterator(sub.path() / "hidraw", hid_ec)) {
        d.hidraws.push_back("/dev/" + raw.path().filename().string());
      }
    }
  }
  std::sort(d.ttys.begin(), d.ttys.end());
  std::sort(d.hidraws.begin(), d.hidraws.end());
  return d;
}

/// 0 when the node opens read-write, else the errno.
int try_open(const std::string& node) {
  const int fd = ::open(node.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return errno;
  ::close(fd);
  return 0;
}

int errno_of(int libusb_error) {
  switch (libusb_error) {
    case LIBUSB_SUCCESS: return 0;
    case LIBUSB_ERROR_ACCESS: return EACCES;
    case LIBUSB_ERROR_NO_DEVICE:
    case LIBUSB_ERROR_NOT_FOUND: return ENOENT;
    case LIBUSB_ERROR_BUSY: return EBUSY;
    default: return EIO;
  }
}

bool known_product(std::uint16_t pid) {
  return std::find(std::begin(kTouchUsbProductIds), std::end(kTouchUsbProductIds), pid) !=
         std::end(kTouchUsbProductIds);
}

/// 3D Systems' vendor id; one public note lists "0301:2988", which looks byte-swapped
/// (OMNI.md §1.2): matched too, so such a device is not missed.
bool is_touch(std::uint16_t vid, std::uint16_t pid) {
  return vid == kTouchUsbVendorId || (vid == 0x0301 && pid == kTouchUsbVendorId);
}

std::string kind_of(std::uint16_t vid, std::uint16_t pid, const SysfsDevice& d) {
  const auto has_class = [&](int c) {
    return std::find(d.interface_classes.begin(), d.interface_classes.end(), c) != d.interface_classes.end();
  };
  const std::string ids = fmt::format("{:04x}:{:04x}", vid, pid);
  if (vid != kTouchUsbVendorId) return fmt::format("3D Systems Touch (USB {}, byte-swapped ids)", ids);
  if (!known_product(pid)) return fmt::format("3D Systems device (USB {}, not a known Touch product id)", ids);
  if (!d.ttys.empty() || has_class(kClassCdcComm) || has_class(kClassCdcData)) {
    return fmt::format("3D Systems Touch (USB serial, {})", ids);
  }
  if (!d.hidraws.empty() || has_class(kClassHid)) return fmt::format("3D Systems Touch (USB HID, {})", ids);
  return fmt::format("3D Systems Touch (USB {})", ids);
}

std::string join_nodes(const std::vector<std::string>& nodes) {
  std::string out;
  for (const auto& n : nodes) out += (out.empty() ? "" : ", ") + n;
  return out;
}

}  // namespace

OpenProblem describe_open_failure(std::string_view node, std::string_view kind, int error_number) {
  switch (error_number) {
    case EACCES:
    case EPERM: {
      const std::string problem = fmt::format("this user may not open {} (permission denied)", node);
      if (kind == "tty") {
        return {problem, "add yourself to the dialout group, which owns /dev/ttyACM* (`sudo usermod -aG dialout "
                         "$USER`), then log out and in again; chmod 777 on the port is not needed"};
      }
      const std::string_view subsystem = kind == "hidraw" ? "hidraw" : "usb";
      return {problem, fmt::format("allow it with a udev rule: put `SUBSYSTEM==\"{}\", ATTRS{{idVendor}}==\"2988\", "
                                   "MODE=\"0660\", GROUP=\"plugdev\"` in /etc/udev/rules.d/99-3dsystems-touch.rules "
                                   "(the Touch Device Driver's installer ships a similar 99-3dsystems.rules), run "
                                   "`sudo udevadm control --reload-rules && sudo udevadm trigger`, add yourself to "
                                   "plugdev (`sudo usermod -aG plugdev $USER`) and log in again",
                                   subsystem)};
    }
    case ENOENT:
    case ENODEV:
    case ENXIO:
      return {fmt::format("{} does not exist: the device went away, or no kernel driver made its node", node),
              kind == "tty" ? "replug the device and check `dmesg` for cdc_acm taking it (ttyACM)"
                            : "replug the device and check `dmesg`; udev must be running to create USB nodes"};
    case EBUSY:
      return {fmt::format("{} is in use by another program", node),
              "close the other program (another toonforce, or a vendor tool such as Touch_Diagnostic)"};
    default:
      return {fmt::format("{} cannot be opened: {}", node, std::strerror(error_number)),
              "replug the device and check `dmesg`"};
  }
}

std::vector<DetectedDevice> detect_touch_devices() {
  std::vector<DetectedDevice> found;
  std::vector<std::string> claimed_hidraws;  // hidraw nodes already reported with their USB device

  libusb_context* context = nullptr;
  if (libusb_init(&context) == 0) {
    libusb_device** list = nullptr;
    const ssize_t count = libusb_get_device_list(context, &list);
    for (ssize_t i = 0; i < count; ++i) {
      libusb_device* device = list[i];
      libusb_device_descriptor descriptor{};
      if (libusb_get_device_descriptor(device, &descriptor) != 0) continue;
      if (!is_touch(descriptor.idVendor, descriptor.idProduct)) continue;

      const unsigned bus = libusb_get_bus_number(device);
      const unsigned address = libusb_get_device_address(device);
      std::uint8_t ports[8] = {};
      const int depth = libusb_get_port_numbers(device, ports, static_cast<int>(sizeof ports));
      std::string sysname = std::to_string(bus);
      for (int p = 0; p < depth; ++p) sysname += (p == 0 ? "-" : ".") + std::to_string(ports[p]);
      const SysfsDevice sys = read_sysfs(sysname);
      const std::string usb_node = fmt::format("/dev/bus/usb/{:03}/{:03}", bus, address);

      DetectedDevice d;
      d.kind = kind_of(descriptor.idVendor, descriptor.idProduct, sys);
      d.location = fmt::format("usb {:03}/{:03} ({})", bus, address, usb_node);
      if (!sys.ttys.empty()) d.location += ", serial port " + join_nodes(sys.ttys);
      if (!sys.hidraws.empty()) d.location += ", hidraw " + join_nodes(sys.hidraws);
      d.serial = sys.serial;
      claimed_hidraws.insert(claimed_hidraws.end(), sys.hidraws.begin(), sys.hidraws.end());

      // The node the vendor driver opens: the serial port of the USB-serial model (termios on
      // /dev/ttyACM*), else the USB device itself (its "HIDConnection" uses libusb), §1.2.
      int error_number = 0;
      std::string node = usb_node;
      std::string node_kind = "usb";
      if (!sys.ttys.empty()) {
        node = sys.ttys.front();
        node_kind = "tty";
        error_number = try_open(node);
      } else {
        libusb_device_handle* handle = nullptr;
        error_number = errno_of(libusb_open(device, &handle));
        if (handle != nullptr) libusb_close(handle);
      }
      d.can_open = error_number == 0;
      if (!d.can_open) {
        OpenProblem p = describe_open_failure(node, node_kind, error_number);
        d.problem = std::move(p.problem);
        d.fix = std::move(p.fix);
      }
      found.push_back(std::move(d));
    }
    if (count >= 0) libusb_free_device_list(list, 1);
    libusb_exit(context);
  }

  // hidapi: hidraw nodes of 3D Systems devices libusb did not account for (no usbfs access,
  // or a device on a bus libusb does not see).
  if (hid_init() == 0) {
    hid_device_info* devices = hid_enumerate(kTouchUsbVendorId, 0);
    for (const hid_device_info* h = devices; h != nullptr; h = h->next) {
      const std::string path = h->path != nullptr ? h->path : "";
      if (path.empty() || std::find(claimed_hidraws.begin(), claimed_hidraws.end(), path) != claimed_hidraws.end()) {
        continue;
      }
      claimed_hidraws.push_back(path);
      DetectedDevice d;
      d.kind = known_product(h->product_id)
                   ? fmt::format("3D Systems Touch (USB HID, {:04x}:{:04x})", h->vendor_id, h->product_id)
                   : fmt::format("3D Systems device (USB {:04x}:{:04x}, not a known Touch product id)", h->vendor_id,
                                 h->product_id);
      d.location = "hidraw " + path;
      if (h->serial_number != nullptr) {
        for (const wchar_t* c = h->serial_number; *c != L'\0'; ++c) d.serial += static_cast<char>(*c & 0x7F);
      }
      const int error_number = try_open(path);
      d.can_open = error_number == 0;
      if (!d.can_open) {
        OpenProblem p = describe_open_failure(path, "hidraw", error_number);
        d.problem = std::move(p.problem);
        d.fix = std::move(p.fix);
      }
      found.push_back(std::move(d));
    }
    hid_free_enumeration(devices);
    hid_exit();
  }
  return found;
}

Prerequisite openhaptics_prerequisite(std::string_view library_path) {
  Prerequisite p;
  p.name = "OpenHaptics HD library (libHD)";
  const hd::LoadOutcome loaded = hd::load_library(library_path);
  if (loaded.library == nullptr) {
    p.detail = loaded.what;
    p.fix = loaded.fix;
    return p;
  }
  p.ok = true;
  const std::string& version = loaded.library->file_version();
  p.detail = fmt::format(
      "{} loads{}, with all {} HD functions toonforce uses", loaded.library->path(),
      version.empty() ? " (its HD version is checked when a device opens)" : fmt::format(" (version {})", version),
      hd::kFunctionCount);
  return p;
}

}  // namespace toonforce
