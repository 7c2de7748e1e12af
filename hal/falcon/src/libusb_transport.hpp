// SPDX-License-Identifier: Apache-2.0
#pragma once
// FalconTransport over libusb-1.0 (private to the backend). Bulk transfers use two libusb
// transfer objects allocated at open and reused, driven to completion with
// libusb_handle_events_timeout_completed: our code allocates nothing per transfer. (libusb's
// Linux backend itself callocs the URB array of each submitted transfer; that is inside
// libusb and documented in docs/FALCON.md.) Control requests use the synchronous API: they
// run at start-up only.
#include <libusb.h>

#include <array>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "toonforce/hal/falcon/transport.hpp"

namespace toonforce::falcon {

/// One libusb context, shared by the transports opened from it.
class UsbContext {
 public:
  static std::shared_ptr<UsbContext> create(std::string& error);
  ~UsbContext();
  UsbContext(const UsbContext&) = delete;
  UsbContext& operator=(const UsbContext&) = delete;
  libusb_context* get() const noexcept { return ctx_; }

 private:
  explicit UsbContext(libusb_context* ctx) : ctx_(ctx) {}
  libusb_context* ctx_;
};

/// A Falcon on the bus, before opening.
struct UsbFalcon {
  libusb_device* device = nullptr;  ///< referenced by the list that produced it
  std::uint8_t bus = 0;
  std::uint8_t address = 0;
  std::string node;      ///< /dev/bus/usb/BBB/DDD
  std::string location;  ///< "usb BBB/DDD (/dev/bus/usb/BBB/DDD)"
};

/// Why a Falcon could not be opened, for a person.
struct OpenFailure {
  TransportStatus status = TransportStatus::kIoError;
  std::string problem;  ///< what went wrong, naming the device
  std::string fix;      ///< what to do
};

class LibusbTransport final : public FalconTransport {
 public:
  ~LibusbTransport() override;

  /// Opens `falcon`: libusb_open, auto-detach, claim interface 0, read the serial number,
  /// allocate the transfers.
  static std::variant<std::unique_ptr<LibusbTransport>, OpenFailure> open(std::shared_ptr<UsbContext> context,
                                                                          const UsbFalcon& falcon);

  TransportStatus control(std::uint8_t request, std::uint16_t value) noexcept override;
  TransportStatus write(std::span<const std::uint8_t> data, std::size_t& written,
                        std::uint32_t timeout_ms) noexcept override;
  TransportStatus read(std::span<std::uint8_t> data, std::size_t& received, std::uint32_t timeout_ms) noexcept override;
  /// One USBDEVFS_BULK ioctl on the device's usbfs descriptor: a single system call, no locks,
  /// no allocation (async-signal-safe), independent of libusb's event handling.
  bool emergency_write(std::span<const std::uint8_t> data) noexcept override;
  std::string_view location() const noexcept override { return location_; }
  std::string_view usbfs_node() const noexcept override { return node_; }

  const std::string& serial() const noexcept { return serial_; }

 private:
  LibusbTransport(std::shared_ptr<UsbContext> context, libusb_device_handle* handle, std::string location);
  TransportStatus run(libusb_transfer* transfer) noexcept;

  std::shared_ptr<UsbContext> context_;
  libusb_device_handle* handle_ = nullptr;
  libusb_transfer* out_ = nullptr;
  libusb_transfer* in_ = nullptr;
  std::array<std::uint8_t, 512> out_buffer_{};
  std::array<std::uint8_t, 512> in_buffer_{};
  int usbfs_fd_ = -1;
  bool broken_ = false;  ///< a transfer could not be reaped: never touch the buffers again
  std::string location_;
  std::string node_;
  std::string serial_;
};

TransportStatus from_libusb(int error) noexcept;

/// Every Falcon (VID 0403, PID cb48) on the bus. `list` keeps the devices referenced; free it
/// with libusb_free_device_list(list, 1) after opening.
std::vector<UsbFalcon> find_falcons(libusb_context* ctx, libusb_device**& list);

/// What to tell a user who may not open `node`: udev rule, group, session.
std::string permission_fix(const std::string& node);
/// "crw-rw-r-- root:plugdev" for a device node, or empty.
std::string describe_node(const std::string& node);

}  // namespace toonforce::falcon
