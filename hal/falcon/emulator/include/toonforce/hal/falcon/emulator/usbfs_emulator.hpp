// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Emulated Falcons at the usbfs boundary, for the real libusb backend: a umockdev testbed
/// (docs/FALCON.md §9) holds one sysfs device and /dev/bus/usb node per
/// Falcon, and an in-process UMockdevIoctlBase handler answers libusb's usbdevfs ioctls
/// (SUBMITURB/REAPURB[NDELAY]/DISCARDURB, USBDEVFS_BULK, claim/release, string descriptors,
/// the FTDI vendor requests) from a FalconEmulator. IN URBs complete at once, as an FTDI's do
/// within one latency period; a stalled IN URB is held until libusb's timeout discards it.
/// Works only inside umockdev (run the test binary under `umockdev-wrapper`; available()
/// says whether this process is). The handler runs on umockdev's thread: the models are
/// reached through with() under a lock. Tests only.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "toonforce/hal/falcon/emulator/falcon_emulator.hpp"

namespace toonforce::falcon::emulator {

class UsbfsEmulator {
 public:
  /// True inside umockdev-wrapper (umockdev's preload library is active).
  static bool available() noexcept;

  UsbfsEmulator();  ///< a fresh testbed with no devices
  ~UsbfsEmulator();
  UsbfsEmulator(const UsbfsEmulator&) = delete;
  UsbfsEmulator& operator=(const UsbfsEmulator&) = delete;

  /// Plugs in a Falcon at usb 001/`address` with this FTDI serial number; returns its index.
  std::size_t add_falcon(EmulatorOptions options = {}, std::string serial = "FTEMU0001", int address = 5);

  /// Runs `f(FalconEmulator&)` with the model of Falcon `index` locked.
  template <class F>
  decltype(auto) with(std::size_t index, F&& f) {
    std::lock_guard lock(mutex_);
    return f(model(index));
  }
  /// Unplugs Falcon `index`: every later ioctl on it fails with ENODEV, held URBs complete
  /// with -ENODEV (what usbfs does on disconnect).
  void unplug(std::size_t index);

  std::string devnode(std::size_t index) const;
  /// usbdevfs requests seen, for tests that check the path actually went through usbfs.
  std::size_t ioctls(std::size_t index) const;
  std::size_t discarded_urbs(std::size_t index) const;

  struct Device;  // opaque: GLib objects and queues (usbfs_emulator.cpp)

 private:
  FalconEmulator& model(std::size_t index);

  mutable std::mutex mutex_;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace toonforce::falcon::emulator
