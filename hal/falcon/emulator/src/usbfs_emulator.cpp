// SPDX-License-Identifier: Apache-2.0
// Emulated Falcons behind usbfs through umockdev (FALCON.md §9: an in-process
// UMockdevIoctlBase handle-ioctl handler, here with held IN URBs, DISCARDURB,
// USBDEVFS_BULK, DISCONNECT_CLAIM and ENODEV after unplugging).
#include "toonforce/hal/falcon/emulator/usbfs_emulator.hpp"

#include <linux/usbdevice_fs.h>
#include <sys/ioctl.h>
#include <umockdev.h>

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <deque>
#include <stdexcept>
#include <vector>

namespace toonforce::falcon::emulator {
namespace {

// Device (18) + configuration (9) + interface (9, vendor class as an FTDI's) + bulk OUT 0x02
// and bulk IN 0x81, 64-byte packets (FALCON.md §1). Strings: 1 manufacturer, 2 product, 3 serial.
constexpr const char* kDescriptors = "12010002000000400304"
                                     "48CB"
                                     "0001"
                                     "010203"
                                     "01"
                                     "09022000010100803209040000"
                                     "02FFFFFF00"
                                     "07050202400000"
                                     "07058102400000";
constexpr const char* kManufacturer = "Novint (emulated)";
constexpr const char* kProduct = "FALCON HAPTIC";  // the FTDI description string (FALCON.md §1)

std::string testbed_entry(int address, const std::string& serial, std::string& syspath, std::string& devnode) {
  char dev[64];
  std::snprintf(dev, sizeof dev, "bus/usb/001/%03d", address);
  devnode = std::string("/dev/") + dev;
  syspath = "/devices/pci0000:00/0000:00:14.0/usb1/1-" + std::to_string(address);
  const std::string desc = kDescriptors;
  std::string e;
  e += "P: " + syspath + "\n";
  e += "N: " + std::string(dev) + "=" + desc + "\n";
  e += "E: DEVNAME=" + devnode + "\nE: DEVTYPE=usb_device\nE: DRIVER=usb\nE: PRODUCT=403/cb48/100\n";
  e += "E: TYPE=0/0/0\nE: BUSNUM=001\n";
  char devnum[32];
  std::snprintf(devnum, sizeof devnum, "E: DEVNUM=%03d\n", address);
  e += devnum;
  e += "E: MAJOR=189\nE: MINOR=" + std::to_string(address - 1) + "\nE: SUBSYSTEM=usb\n";
  e += "E: ID_VENDOR_ID=0403\nE: ID_MODEL_ID=cb48\nE: ID_BUS=usb\nE: ID_SERIAL_SHORT=" + serial + "\n";
  e += "A: authorized=1\\n\nA: bConfigurationValue=1\\n\nA: bDeviceClass=00\\n\nA: bMaxPacketSize0=64\\n\n";
  e += "A: bNumConfigurations=1\\n\nA: bNumInterfaces= 1\\n\nA: bcdDevice=0100\\n\nA: busnum=1\\n\n";
  e += "H: descriptors=" + desc + "\n";
  e += "A: dev=189:" + std::to_string(address - 1) + "\\n\n";
  e += "A: devnum=" + std::to_string(address) + "\\n\nA: devpath=" + std::to_string(address) + "\\n\n";
  e += "A: idProduct=cb48\\n\nA: idVendor=0403\\n\n";
  e += std::string("A: manufacturer=") + kManufacturer + "\\n\nA: product=" + kProduct + "\\n\n";
  e += "A: serial=" + serial + "\\n\nA: speed=12\\n\nA: version= 2.00\\n\n\n";
  e += "P: " + syspath + "/1-" + std::to_string(address) + ":1.0\n";
  e += "E: DEVTYPE=usb_interface\nE: PRODUCT=403/cb48/100\nE: TYPE=0/0/0\nE: INTERFACE=255/255/255\n";
  e += "E: SUBSYSTEM=usb\nA: bAlternateSetting= 0\\n\nA: bInterfaceClass=ff\\n\nA: bInterfaceNumber=00\\n\n";
  e += "A: bInterfaceProtocol=ff\\n\nA: bInterfaceSubClass=ff\\n\nA: bNumEndpoints=02\\n\n";
  return e;
}

std::size_t put_string(std::uint8_t* dst, std::size_t max, const std::string& s) {
  std::uint8_t tmp[256];
  std::size_t n = 2;
  for (const char c : s) {
    if (n + 2 > sizeof tmp) break;
    tmp[n++] = static_cast<std::uint8_t>(c);
    tmp[n++] = 0;
  }
  tmp[0] = static_cast<std::uint8_t>(n);
  tmp[1] = 3;  // STRING descriptor
  const std::size_t out = std::min(n, max);
  std::memcpy(dst, tmp, out);
  return out;
}

}  // namespace

struct UsbfsEmulator::Device {
  struct Urb {
    UMockdevIoctlClient* client = nullptr;  // owned ref
    UMockdevIoctlData* urb = nullptr;       // owned ref
    UMockdevIoctlData* buffer = nullptr;    // owned ref, may be null
  };

  std::mutex* mutex = nullptr;
  FalconEmulator model;
  std::string serial;
  std::string syspath;
  std::string devnode;
  UMockdevIoctlBase* handler = nullptr;
  std::deque<Urb> done;  // completed, waiting to be reaped
  std::deque<Urb> held;  // stalled IN URBs, until discarded
  bool unplugged = false;
  std::size_t ioctls = 0;
  std::size_t discarded = 0;

  explicit Device(EmulatorOptions o) : model(std::move(o)) {}
  ~Device() {
    for (auto* q : {&done, &held}) {
      for (Urb& u : *q) release(u);
    }
    if (handler != nullptr) g_object_unref(handler);
  }
  static void release(Urb& u) {
    if (u.buffer != nullptr) g_object_unref(u.buffer);
    if (u.urb != nullptr) g_object_unref(u.urb);
    if (u.client != nullptr) g_object_unref(u.client);
    u = Urb{};
  }

  /// Runs one URB through the model; returns the usbfs status (0 or -errno). -EINPROGRESS
  /// means "hold it" (a stalled IN transfer).
  int process(usbdevfs_urb& u, std::uint8_t* data) {
    if (u.type == USBDEVFS_URB_TYPE_CONTROL) {
      if (data == nullptr || u.buffer_length < 8) return -EPIPE;
      const std::uint8_t type = data[0];
      const std::uint8_t request = data[1];
      const auto value = static_cast<std::uint16_t>(data[2] | (data[3] << 8));
      const auto length = static_cast<std::uint16_t>(data[6] | (data[7] << 8));
      std::uint8_t* payload = data + 8;
      if (type == 0x40) {  // FTDI vendor request, no data stage (FALCON.md §1)
        u.actual_length = 0;
        return model.vendor_request(request, value) ? 0 : -EPIPE;
      }
      if (type == 0x80 && request == 6 && (value >> 8) == 3) {  // GET_DESCRIPTOR(STRING)
        const unsigned index = value & 0xFF;
        std::size_t n = 0;
        if (index == 0) {
          const std::uint8_t langs[] = {4, 3, 0x09, 0x04};
          n = std::min<std::size_t>(sizeof langs, length);
          std::memcpy(payload, langs, n);
        } else {
          n = put_string(payload, length, index == 1 ? kManufacturer : index == 2 ? kProduct : serial);
        }
        u.actual_length = static_cast<int>(n);
        return 0;
      }
      return -EPIPE;
    }
    if (u.type == USBDEVFS_URB_TYPE_BULK && u.endpoint == 0x02) {
      model.bulk_out({data, static_cast<std::size_t>(u.buffer_length)});
      u.actual_length = u.buffer_length;
      return 0;
    }
    if (u.type == USBDEVFS_URB_TYPE_BULK && u.endpoint == 0x81) {
      if (model.take_in_stall()) return -EINPROGRESS;
      u.actual_length = static_cast<int>(model.bulk_in({data, static_cast<std::size_t>(u.buffer_length)}));
      return 0;
    }
    return -EPIPE;
  }

  static gboolean on_ioctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer self) {
    static_cast<Device*>(self)->handle(client);
    return TRUE;
  }

  void handle(UMockdevIoctlClient* client) {
    std::lock_guard lock(*mutex);
    ++ioctls;
    const gulong request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* arg = umockdev_ioctl_client_get_arg(client);
    if (unplugged) {
      umockdev_ioctl_client_complete(client, -1, ENODEV);
      return;
    }
    GError* error = nullptr;
    switch (request) {
      case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(std::uint32_t), &error);
        if (d == nullptr) break;
        const std::uint32_t caps = USBDEVFS_CAP_BULK_CONTINUATION | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                                   USBDEVFS_CAP_ZERO_PACKET | USBDEVFS_CAP_REAP_AFTER_DISCONNECT;
        std::memcpy(d->data, &caps, sizeof caps);
        umockdev_ioctl_client_complete(client, 0, 0);
        g_object_unref(d);
        return;
      }
      case USBDEVFS_CLAIMINTERFACE:
      case USBDEVFS_RELEASEINTERFACE:
      case USBDEVFS_SETINTERFACE:
      case USBDEVFS_SETCONFIGURATION:
      case USBDEVFS_CLEAR_HALT:
      case USBDEVFS_RESETEP:
      case USBDEVFS_DISCONNECT_CLAIM:  // libusb's auto-detach path: nothing bound, claimed
        umockdev_ioctl_client_complete(client, 0, 0);
        return;
      case USBDEVFS_SUBMITURB: {
        Urb u;
        u.urb = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_urb), &error);
        if (u.urb == nullptr) break;
        auto* urb = reinterpret_cast<usbdevfs_urb*>(u.urb->data);
        if (urb->buffer_length > 0) {
          u.buffer = umockdev_ioctl_data_resolve(u.urb, offsetof(usbdevfs_urb, buffer),
                                                 static_cast<gsize>(urb->buffer_length), &error);
          if (u.buffer == nullptr) {
            release(u);
            break;
          }
        }
        const int status = process(*urb, u.buffer != nullptr ? u.buffer->data : nullptr);
        u.client = static_cast<UMockdevIoctlClient*>(g_object_ref(client));
        if (status == -EINPROGRESS) {
          held.push_back(u);
        } else {
          urb->status = status;
          if (status != 0) urb->actual_length = 0;
          done.push_back(u);
        }
        umockdev_ioctl_client_complete(client, 0, 0);
        return;
      }
      case USBDEVFS_REAPURB:
      case USBDEVFS_REAPURBNDELAY: {
        const auto it = std::find_if(done.begin(), done.end(), [client](const Urb& u) { return u.client == client; });
        if (it == done.end()) {
          umockdev_ioctl_client_complete(client, -1, EAGAIN);
          return;
        }
        Urb u = *it;
        done.erase(it);
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(void*), &error);
        if (d == nullptr) {
          release(u);
          break;
        }
        umockdev_ioctl_data_set_ptr(d, 0, u.urb);
        umockdev_ioctl_client_complete(client, 0, 0);  // syncs the URB and its buffer back
        g_object_unref(d);
        release(u);
        return;
      }
      case USBDEVFS_DISCARDURB: {
        // The argument is the URB's address in the client, but umockdev does not pass the
        // value of an argument-less (_IO) request through (client_addr is 0). The backend
        // has at most one IN URB outstanding per handle, so the client's oldest held URB is
        // the one being cancelled.
        const auto it = std::find_if(held.begin(), held.end(), [&](const Urb& u) { return u.client == client; });
        if (it == held.end()) {
          umockdev_ioctl_client_complete(client, -1, EINVAL);  // already completed
          return;
        }
        Urb u = *it;
        held.erase(it);
        auto* urb = reinterpret_cast<usbdevfs_urb*>(u.urb->data);
        urb->status = -ENOENT;  // what usbfs reports for a killed URB
        urb->actual_length = 0;
        done.push_back(u);
        ++discarded;
        umockdev_ioctl_client_complete(client, 0, 0);
        return;
      }
      case USBDEVFS_BULK: {
        // The synchronous bulk ioctl (LibusbTransport::emergency_write).
        UMockdevIoctlData* d = umockdev_ioctl_data_resolve(arg, 0, sizeof(usbdevfs_bulktransfer), &error);
        if (d == nullptr) break;
        const auto* bulk = reinterpret_cast<const usbdevfs_bulktransfer*>(d->data);
        if (bulk->ep != 0x02 || bulk->len == 0) {
          g_object_unref(d);
          umockdev_ioctl_client_complete(client, -1, EINVAL);
          return;
        }
        UMockdevIoctlData* data =
            umockdev_ioctl_data_resolve(d, offsetof(usbdevfs_bulktransfer, data), bulk->len, &error);
        if (data == nullptr) {
          g_object_unref(d);
          break;
        }
        model.bulk_out({data->data, bulk->len});
        umockdev_ioctl_client_complete(client, static_cast<glong>(bulk->len), 0);
        g_object_unref(data);
        g_object_unref(d);
        return;
      }
      case USBDEVFS_IOCTL:  // driver queries: no kernel driver is bound
        umockdev_ioctl_client_complete(client, -1, ENODATA);
        return;
      default: umockdev_ioctl_client_complete(client, -1, ENOTTY); return;
    }
    if (error != nullptr) g_error_free(error);
    umockdev_ioctl_client_complete(client, -1, EFAULT);
  }
};

struct UsbfsEmulator::Impl {
  UMockdevTestbed* testbed = nullptr;
  std::vector<std::unique_ptr<Device>> devices;
};

bool UsbfsEmulator::available() noexcept {
  // umockdev_in_mock_environment() caches its first answer, and answers true only while a
  // testbed redirects /sys: ask once, with a testbed in place.
  static const bool in_mock = [] {
    UMockdevTestbed* probe = umockdev_testbed_new();
    const bool r = umockdev_in_mock_environment() != FALSE;
    g_object_unref(probe);
    return r;
  }();
  return in_mock;
}

UsbfsEmulator::UsbfsEmulator() : impl_(std::make_unique<Impl>()) { impl_->testbed = umockdev_testbed_new(); }

UsbfsEmulator::~UsbfsEmulator() {
  for (auto& d : impl_->devices) {
    umockdev_testbed_detach_ioctl(impl_->testbed, d->devnode.c_str(), nullptr);
  }
  {
    std::lock_guard lock(mutex_);
    impl_->devices.clear();
  }
  g_object_unref(impl_->testbed);
}

std::size_t UsbfsEmulator::add_falcon(EmulatorOptions options, std::string serial, int address) {
  auto device = std::make_unique<Device>(std::move(options));
  device->mutex = &mutex_;
  device->serial = std::move(serial);
  const std::string entry = testbed_entry(address, device->serial, device->syspath, device->devnode);
  GError* error = nullptr;
  if (!umockdev_testbed_add_from_string(impl_->testbed, entry.c_str(), &error)) {
    const std::string message = error != nullptr ? error->message : "?";
    if (error != nullptr) g_error_free(error);
    throw std::runtime_error("umockdev: cannot add the emulated Falcon: " + message);
  }
  device->handler = umockdev_ioctl_base_new();
  g_signal_connect_data(device->handler, "handle-ioctl", reinterpret_cast<GCallback>(&Device::on_ioctl), device.get(),
                        nullptr, GConnectFlags{});
  if (!umockdev_testbed_attach_ioctl(impl_->testbed, device->devnode.c_str(), device->handler, &error)) {
    const std::string message = error != nullptr ? error->message : "?";
    if (error != nullptr) g_error_free(error);
    throw std::runtime_error("umockdev: cannot attach the ioctl handler to " + device->devnode + ": " + message);
  }
  std::lock_guard lock(mutex_);
  impl_->devices.push_back(std::move(device));
  return impl_->devices.size() - 1;
}

FalconEmulator& UsbfsEmulator::model(std::size_t index) { return impl_->devices.at(index)->model; }

void UsbfsEmulator::unplug(std::size_t index) {
  std::lock_guard lock(mutex_);
  Device& d = *impl_->devices.at(index);
  d.unplugged = true;
  d.model.unplug();
}

std::string UsbfsEmulator::devnode(std::size_t index) const { return impl_->devices.at(index)->devnode; }

std::size_t UsbfsEmulator::ioctls(std::size_t index) const {
  std::lock_guard lock(mutex_);
  return impl_->devices.at(index)->ioctls;
}

std::size_t UsbfsEmulator::discarded_urbs(std::size_t index) const {
  std::lock_guard lock(mutex_);
  return impl_->devices.at(index)->discarded;
}

}  // namespace toonforce::falcon::emulator
