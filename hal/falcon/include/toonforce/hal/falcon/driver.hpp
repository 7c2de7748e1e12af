// SPDX-License-Identifier: Apache-2.0
#pragma once
/// FalconDriver: the Falcon's DeviceDriver over any FalconTransport. open_falcon() builds one
/// over libusb; tests build one over the in-process emulator. Protocol per tick (FALCON.md §3):
/// at most one command outstanding; read() collects the reply to the previous write() (whole
/// 16-byte frames from FTDI packets, split or merged), write() sends the next command. Every
/// command holds the homing bit; the LED is red until the Falcon reports all three axes homed,
/// green after (FALCON.md §4). Until homed, and on any fault, the force sent is zero. A force
/// beyond what the +-4095 motor words give at the pose is scaled down keeping its direction,
/// and the next read() sets DeviceReading::force_limited. info().max_force_n is the force
/// the words give in every direction at the workspace centre (force_envelope()).
/// Hot path: no allocation after construction, bounded reads, noexcept, status values.

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "toonforce/hal/device.hpp"
#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/falcon/frames.hpp"
#include "toonforce/hal/falcon/kinematics.hpp"
#include "toonforce/hal/falcon/protocol.hpp"
#include "toonforce/hal/falcon/transport.hpp"

namespace toonforce::falcon {

/// What the driver counts (for diagnostics and tests).
struct FalconStats {
  std::uint64_t ticks = 0;  ///< read() calls
  std::uint64_t commands_sent = 0;
  std::uint64_t replies = 0;          ///< valid status frames received
  std::uint64_t usb_reads = 0;        ///< bulk-IN transfers
  std::uint64_t timeouts = 0;         ///< ticks without a reply
  std::uint64_t protocol_errors = 0;  ///< ticks with garbled bytes and no valid reply
  std::uint64_t garbled_bytes = 0;
  std::uint64_t deferred_writes = 0;   ///< write() while a command was still outstanding
  std::uint64_t saturated_writes = 0;  ///< forces scaled down to the command range
  std::uint64_t emergency_zeros = 0;
  int max_fk_iterations = 0;
};

/// Why the last tick was not ok (formatted by last_error(), off the hot path).
enum class FalconFault : std::uint8_t {
  kNone,
  kNotHomed,
  kPoseNotConverged,
  kNoReply,     ///< reads returned no whole frame
  kUsbTimeout,  ///< a USB transfer itself timed out (the FTDI stopped answering)
  kGarbled,     ///< bytes that did not form a valid frame, and no valid reply
  kUnplugged,   ///< LIBUSB_ERROR_NO_DEVICE
  kUsbError,    ///< any other USB error
};

class FalconDriver final : public DeviceDriver {
 public:
  /// Takes the transport (FTDI already in normal mode, firmware running) and sends the first
  /// command (zero force, homing bit, red LED) so the first read() has a reply to collect.
  FalconDriver(std::unique_ptr<FalconTransport> transport, const FalconOptions& options, std::string name);
  ~FalconDriver() override;

  DeviceStatus read(DeviceReading& reading) noexcept override;
  DeviceStatus write(const Vec3<double>& force_n) noexcept override;
  /// Sends one zero-force command through FalconTransport::emergency_write (no locks, no
  /// allocation): callable from a watchdog thread. It does not latch: the next write() sends
  /// whatever it is given, so the caller stops the loop first.
  void emergency_zero() noexcept override;
  /// The zero-force frame emergency_zero() sends, on the transport's usbfs node.
  ExternalZero external_zero() const noexcept override;
  const DeviceInfo& info() const noexcept override { return info_; }
  std::string last_error() const override;

  const FalconStats& stats() const noexcept { return stats_; }
  FalconFault fault() const noexcept { return fault_; }
  bool homed() const noexcept { return homed_; }
  const Status& last_status() const noexcept { return status_; }
  /// Shows these LED bits (kLedRed | kLedGreen | kLedBlue) in every command from now on instead
  /// of red/green for the homing state; 0 returns to that (bring-up's LED check).
  void set_led(std::uint8_t flags) noexcept;
  const Command& last_command() const noexcept { return command_; }
  /// The last position estimate in the Falcon frame [m].
  Vec3<double> position_falcon_m() const noexcept { return position_falcon_m_; }
  FalconTransport& transport() noexcept { return *transport_; }
  /// Where the words-per-torque constant came from (FalconOptions::calibration_source).
  const std::string& calibration_source() const noexcept { return options_.calibration_source; }
  const falcon::MotorScale& motor_scale() const noexcept { return options_.motor; }

 private:
  DeviceStatus fail(DeviceStatus status, FalconFault fault, TransportStatus usb = TransportStatus::kOk) noexcept;
  DeviceStatus send(const Command& command) noexcept;
  DeviceStatus map_usb(TransportStatus s) noexcept;
  std::uint8_t led() const noexcept;

  std::unique_ptr<FalconTransport> transport_;
  FalconOptions options_;
  DeviceInfo info_;
  ForwardKinematics fk_;

  FrameAssembler assembler_;
  std::array<std::uint8_t, kUsbPacketBytes> raw_{};
  std::array<std::uint8_t, kUsbPacketBytes> payload_{};
  int in_flight_ = 0;                  ///< commands sent whose reply has not arrived (0 or 1 in normal flow)
  std::atomic<int> extra_replies_{0};  ///< replies emergency_zero() will cause, for read() to absorb

  Status status_{};
  Command command_{};
  std::atomic<std::uint8_t> led_flags_{kLedRed};  ///< red until homed, green after
  std::atomic<std::uint8_t> led_override_{0};     ///< set_led(); 0: led_flags_
  bool homed_ = false;
  bool pose_valid_ = false;
  bool last_read_ok_ = false;
  bool disconnected_ = false;
  bool last_write_limited_ = false;  ///< the last write() saturated the words (next read() says so)
  Vec3<double> position_falcon_m_{};
  Mat3 jacobian_{};

  FalconStats stats_;
  FalconFault fault_ = FalconFault::kNone;
  TransportStatus fault_usb_ = TransportStatus::kOk;
  std::uint64_t fault_garbled_ = 0;
  std::uint64_t fault_streak_ = 0;  ///< consecutive non-ok ticks
  double fault_residual_rad_ = 0;
};

}  // namespace toonforce::falcon
