// SPDX-License-Identifier: Apache-2.0
#pragma once
/// An in-process FalconTransport over a FalconEmulator: the protocol, firmware loader and
/// driver logic run against the emulated device in microseconds, with no USB stack between.
/// (The real libusb path runs against the same emulator under umockdev: usbfs_emulator.hpp.)
/// Unplugging and stalled IN transfers come from the emulator's fault switches.

#include <string>

#include "toonforce/hal/falcon/emulator/falcon_emulator.hpp"
#include "toonforce/hal/falcon/transport.hpp"

namespace toonforce::falcon::emulator {

class EmulatorTransport final : public FalconTransport {
 public:
  explicit EmulatorTransport(FalconEmulator& emulator, std::string location = "emulated Falcon (in-process)")
      : emulator_(emulator), location_(std::move(location)) {}

  TransportStatus control(std::uint8_t request, std::uint16_t value) noexcept override {
    if (!emulator_.connected()) return TransportStatus::kNoDevice;
    ++controls_;
    return emulator_.vendor_request(request, value) ? TransportStatus::kOk : TransportStatus::kStall;
  }
  TransportStatus write(std::span<const std::uint8_t> data, std::size_t& written, std::uint32_t) noexcept override {
    written = 0;
    if (!emulator_.connected()) return TransportStatus::kNoDevice;
    emulator_.bulk_out(data);
    written = data.size();
    ++writes_;
    return TransportStatus::kOk;
  }
  TransportStatus read(std::span<std::uint8_t> data, std::size_t& received, std::uint32_t) noexcept override {
    received = 0;
    if (!emulator_.connected()) return TransportStatus::kNoDevice;
    ++reads_;
    if (emulator_.take_in_stall()) return TransportStatus::kTimeout;
    received = emulator_.bulk_in(data);
    return TransportStatus::kOk;
  }
  bool emergency_write(std::span<const std::uint8_t> data) noexcept override {
    if (!emulator_.connected()) return false;
    emulator_.bulk_out(data);
    ++emergency_writes_;
    return true;
  }
  std::string_view location() const noexcept override { return location_; }

  std::size_t reads() const noexcept { return reads_; }
  std::size_t writes() const noexcept { return writes_; }
  std::size_t controls() const noexcept { return controls_; }
  std::size_t emergency_writes() const noexcept { return emergency_writes_; }

 private:
  FalconEmulator& emulator_;
  std::string location_;
  std::size_t reads_ = 0;
  std::size_t writes_ = 0;
  std::size_t controls_ = 0;
  std::size_t emergency_writes_ = 0;
};

}  // namespace toonforce::falcon::emulator
