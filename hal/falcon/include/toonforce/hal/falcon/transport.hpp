// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The Falcon's USB link as a small interface: FTDI vendor requests, bulk OUT to 0x02, bulk IN
/// from 0x81 (FALCON.md §1). Everything above it (FTDI set-up, firmware loading, the codec,
/// the 1 kHz exchange) is written against this interface, so it runs unchanged over libusb
/// (LibusbTransport, the real device or umockdev's emulated one) and over an in-process fake.
/// Every call is noexcept and returns a status; implementations allocate nothing per call.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "toonforce/hal/falcon/protocol.hpp"

namespace toonforce::falcon {

inline constexpr std::uint16_t kFalconVendorId = 0x0403;   // FTDI (FALCON.md §1)
inline constexpr std::uint16_t kFalconProductId = 0xCB48;  // Novint Falcon
inline constexpr std::uint8_t kEndpointOut = 0x02;
inline constexpr std::uint8_t kEndpointIn = 0x81;

enum class TransportStatus : std::uint8_t {
  kOk = 0,
  kTimeout,       ///< the transfer did not complete in time
  kNoDevice,      ///< unplugged (LIBUSB_ERROR_NO_DEVICE)
  kAccessDenied,  ///< no permission on the device node
  kBusy,          ///< another program holds the interface
  kStall,         ///< the device refused the request (endpoint stall)
  kIoError,       ///< anything else the USB stack reported
};

constexpr std::string_view to_string(TransportStatus s) noexcept {
  switch (s) {
    case TransportStatus::kOk: return "ok";
    case TransportStatus::kTimeout: return "timeout";
    case TransportStatus::kNoDevice: return "no device (unplugged)";
    case TransportStatus::kAccessDenied: return "access denied";
    case TransportStatus::kBusy: return "busy";
    case TransportStatus::kStall: return "stall";
    case TransportStatus::kIoError: return "I/O error";
  }
  return "?";
}

class FalconTransport {
 public:
  virtual ~FalconTransport() = default;
  FalconTransport() = default;
  FalconTransport(const FalconTransport&) = delete;
  FalconTransport& operator=(const FalconTransport&) = delete;

  /// An FTDI vendor request without data stage: bmRequestType 0x40, wIndex 0 (FALCON.md §1).
  virtual TransportStatus control(std::uint8_t request, std::uint16_t value) noexcept = 0;
  /// One bulk-OUT transfer; `written` receives the bytes the device accepted.
  virtual TransportStatus write(std::span<const std::uint8_t> data, std::size_t& written,
                                std::uint32_t timeout_ms) noexcept = 0;
  /// One bulk-IN transfer of at most data.size() bytes, raw: every 64-byte packet still starts
  /// with its 2 FTDI status bytes (strip them with strip_ftdi_status).
  virtual TransportStatus read(std::span<std::uint8_t> data, std::size_t& received,
                               std::uint32_t timeout_ms) noexcept = 0;
  /// Sends `data` (at most one frame) bypassing locks and allocation, for emergency_zero():
  /// safe from another thread and, where the implementation says so, from a signal handler.
  /// Returns false when nothing could be sent.
  virtual bool emergency_write(std::span<const std::uint8_t> data) noexcept = 0;
  /// Where the device is, for messages: "usb 001/005 (/dev/bus/usb/001/005)".
  virtual std::string_view location() const noexcept = 0;
  /// The usbfs node ("/dev/bus/usb/001/005") another process may open to reach the device;
  /// empty when there is none (an in-process emulator).
  virtual std::string_view usbfs_node() const noexcept { return {}; }
};

}  // namespace toonforce::falcon
