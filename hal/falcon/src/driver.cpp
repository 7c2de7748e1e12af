// SPDX-License-Identifier: Apache-2.0
// FalconDriver: the 1 kHz exchange (FALCON.md §3), homing (§4), kinematics (§5).
#include "toonforce/hal/falcon/driver.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace toonforce::falcon {
namespace {

/// The HDAL shim's workspace box in the Falcon frame [m] (FALCON.md §5 "Frame").
constexpr Vec3<double> kHdalBoxMin{-0.060, -0.060, 0.075};
constexpr Vec3<double> kHdalBoxMax{0.060, 0.060, 0.175};

/// A conservative guess for the thermal model until someone measures a real device: no source
/// gives the Falcon's motor ratings (FALCON.md §5 "Gaps").
constexpr double kContinuousForceGuessN = 4.0;

DeviceInfo make_info(std::string name, const FalconOptions& o) {
  DeviceInfo info;
  info.name = std::move(name);
  // What the motor words give in every direction at the workspace centre, from the kinematics,
  // the +-4095 word cap and the words-per-torque constant (calibrated or not): a force up to
  // this is delivered as asked there; toward the edges the envelope shrinks (docs/FALCON.md,
  // "Force envelope"), and a saturated write is flagged (DeviceReading::force_limited). The
  // often quoted ~9 N is unverified (FALCON.md §5 "Gaps").
  ForceEnvelope centre;
  info.max_force_n = force_envelope_at(FalconGeometry{}, o.workspace_centre_falcon_m, o.motor, centre)
                         ? centre.every_direction_n
                         : 0.0;
  info.max_continuous_force_n = std::min(kContinuousForceGuessN, info.max_force_n);
  const Vec3<double> a = falcon_to_scene(kHdalBoxMin, o.workspace_centre_falcon_m);
  const Vec3<double> b = falcon_to_scene(kHdalBoxMax, o.workspace_centre_falcon_m);
  info.workspace_min_m = {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
  info.workspace_max_m = {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
  info.nominal_rate_hz = 1000.0;  // the host paces the device (FALCON.md §3)
  info.clocking = Clocking::kHostTimer;
  return info;
}

}  // namespace

FalconDriver::FalconDriver(std::unique_ptr<FalconTransport> transport, const FalconOptions& options, std::string name)
    : transport_(std::move(transport)),
      options_(options),
      info_(make_info(std::move(name), options)),
      fk_(FalconGeometry{}, options.fk) {
  command_.flags = kHomingRequest | kLedRed;
  (void)send(command_);
}

FalconDriver::~FalconDriver() {
  // Leave the motors unpowered: a last zero-force command (the homing bit still held).
  if (!disconnected_) {
    Command zero;
    zero.flags = static_cast<std::uint8_t>(kHomingRequest | led());
    const Frame frame = encode_command(zero);
    std::size_t written = 0;
    (void)transport_->write(frame, written, options_.io_timeout_ms);
  }
}

DeviceStatus FalconDriver::map_usb(TransportStatus s) noexcept {
  switch (s) {
    case TransportStatus::kOk: return DeviceStatus::kOk;
    case TransportStatus::kNoDevice:
      disconnected_ = true;
      return fail(DeviceStatus::kDisconnected, FalconFault::kUnplugged, s);
    case TransportStatus::kTimeout: return fail(DeviceStatus::kTimeout, FalconFault::kUsbTimeout, s);
    default: return fail(DeviceStatus::kDeviceFault, FalconFault::kUsbError, s);
  }
}

DeviceStatus FalconDriver::fail(DeviceStatus status, FalconFault fault, TransportStatus usb) noexcept {
  if (fault_ == fault) {
    ++fault_streak_;
  } else {
    fault_streak_ = 1;
  }
  fault_ = fault;
  fault_usb_ = usb;
  last_read_ok_ = false;
  return status;
}

DeviceStatus FalconDriver::send(const Command& command) noexcept {
  const Frame frame = encode_command(command);
  std::size_t written = 0;
  const TransportStatus s = transport_->write(frame, written, options_.io_timeout_ms);
  if (s == TransportStatus::kOk && written != frame.size()) return map_usb(TransportStatus::kIoError);
  if (s != TransportStatus::kOk) return map_usb(s);
  ++in_flight_;
  ++stats_.commands_sent;
  return DeviceStatus::kOk;
}

DeviceStatus FalconDriver::read(DeviceReading& reading) noexcept {
  ++stats_.ticks;
  reading.force_limited = last_write_limited_;
  if (disconnected_) return fail(DeviceStatus::kDisconnected, FalconFault::kUnplugged, TransportStatus::kNoDevice);
  // Keep exactly one command in flight: if none is (a lost reply, two reads in a row), send one
  // so this read has a reply to wait for.
  // The repeated command carries zero force: whatever force was last asked for was computed
  // for a tick that has passed (and a loop that skips write() after a fault must not keep it).
  if (in_flight_ == 0) {
    Command idle;
    idle.flags = static_cast<std::uint8_t>(kHomingRequest | led());
    command_ = idle;
    if (const DeviceStatus s = send(command_); s != DeviceStatus::kOk) return s;
  }

  // An emergency_zero() command draws a reply too: collect it as well, or every later read
  // would take the previous tick's reply for this one's.
  in_flight_ += extra_replies_.exchange(0);

  const std::size_t garbage_before = assembler_.discarded();
  bool got = false;
  Status latest{};
  TransportStatus usb = TransportStatus::kOk;
  for (int i = 0; i < options_.max_reads_per_tick; ++i) {
    std::size_t received = 0;
    usb = transport_->read(raw_, received, options_.io_timeout_ms);
    ++stats_.usb_reads;
    if (usb != TransportStatus::kOk) break;  // a timed-out IN means the FTDI itself is silent
    const std::size_t n = strip_ftdi_status(std::span(raw_).first(received), payload_);
    assembler_.push(std::span(payload_).first(n));
    Status s;
    while (assembler_.pop_status(s)) {  // merged replies: keep the newest
      latest = s;
      got = true;
      ++stats_.replies;
      if (in_flight_ > 0) --in_flight_;
    }
    if (got && in_flight_ == 0) break;
  }
  const std::uint64_t garbled = assembler_.discarded() - garbage_before;
  stats_.garbled_bytes += garbled;

  if (usb == TransportStatus::kNoDevice) return map_usb(usb);
  if (!got) {
    in_flight_ = 0;  // the reply is lost; the next write() sends a fresh command
    if (usb != TransportStatus::kOk && usb != TransportStatus::kTimeout) return map_usb(usb);
    if (garbled > 0) {
      ++stats_.protocol_errors;
      fault_garbled_ = garbled;
      return fail(DeviceStatus::kProtocolError, FalconFault::kGarbled);
    }
    ++stats_.timeouts;
    if (usb == TransportStatus::kTimeout) return fail(DeviceStatus::kTimeout, FalconFault::kUsbTimeout, usb);
    return fail(DeviceStatus::kTimeout, FalconFault::kNoReply);
  }

  status_ = latest;
  reading.buttons = latest.buttons();
  reading.has_velocity = false;  // the servo loop's estimator differentiates positions
  if (!latest.homed()) {
    // Encoders are relative until homed; positions (and so forces) would be meaningless.
    homed_ = false;
    pose_valid_ = false;
    led_flags_.store(kLedRed);
    return fail(DeviceStatus::kNotReady, FalconFault::kNotHomed);
  }
  if (!homed_) {
    homed_ = true;
    fk_.reset();  // homing re-bases the counts: the old warm start is far away (FALCON.md §4)
    led_flags_.store(kLedGreen);
  }
  const Angles theta{encoder_to_theta1_rad(latest.encoder[0]), encoder_to_theta1_rad(latest.encoder[1]),
                     encoder_to_theta1_rad(latest.encoder[2])};
  const FkResult fk = fk_.solve(theta);
  stats_.max_fk_iterations = std::max(stats_.max_fk_iterations, fk.iterations);
  if (!fk.jacobian_valid || !(fk.residual_rad <= options_.fk_accept_residual_rad)) {
    pose_valid_ = false;
    fault_residual_rad_ = fk.residual_rad;
    return fail(DeviceStatus::kNotReady, FalconFault::kPoseNotConverged);
  }
  position_falcon_m_ = fk.position_m;
  jacobian_ = fk.dp_dtheta;
  pose_valid_ = true;
  reading.position_m = falcon_to_scene(fk.position_m, options_.workspace_centre_falcon_m);
  reading.velocity_m_per_s = {};
  last_read_ok_ = true;
  fault_ = FalconFault::kNone;
  fault_streak_ = 0;
  return DeviceStatus::kOk;
}

DeviceStatus FalconDriver::write(const Vec3<double>& force_n) noexcept {
  if (disconnected_) return fail(DeviceStatus::kDisconnected, FalconFault::kUnplugged, TransportStatus::kNoDevice);
  // Force only from a good reading of a homed device; anything else commands zero.
  const bool ready = last_read_ok_ && pose_valid_ && homed_;
  Command next;
  next.flags = static_cast<std::uint8_t>(kHomingRequest | led());
  bool zeroed = false;
  last_write_limited_ = false;
  if (ready && is_finite(force_n)) {
    const MotorWords words = force_to_motor_words(jacobian_, scene_force_to_falcon(force_n), options_.motor);
    next.motor = words.word;
    last_write_limited_ = words.saturated;
    if (words.saturated) ++stats_.saturated_writes;
  } else {
    zeroed = force_n != Vec3<double>{};
  }
  command_ = next;
  if (in_flight_ > 0) {
    // One command outstanding: this one is not sent (the next write() replaces it).
    ++stats_.deferred_writes;
    return zeroed ? DeviceStatus::kNotReady : DeviceStatus::kOk;
  }
  const DeviceStatus s = send(next);
  if (s != DeviceStatus::kOk) return s;
  return zeroed ? DeviceStatus::kNotReady : DeviceStatus::kOk;
}

std::uint8_t FalconDriver::led() const noexcept {
  const std::uint8_t forced = led_override_.load(std::memory_order_relaxed);
  return forced != 0 ? forced : led_flags_.load(std::memory_order_relaxed);
}

void FalconDriver::set_led(std::uint8_t flags) noexcept {
  led_override_.store(static_cast<std::uint8_t>(flags & (kLedRed | kLedGreen | kLedBlue)), std::memory_order_relaxed);
}

void FalconDriver::emergency_zero() noexcept {
  Command zero;
  zero.flags = static_cast<std::uint8_t>(kHomingRequest | led());
  const Frame frame = encode_command(zero);
  if (transport_->emergency_write(frame)) {
    extra_replies_.fetch_add(1);
    ++stats_.emergency_zeros;
  }
}

ExternalZero FalconDriver::external_zero() const noexcept {
  ExternalZero z;
  const std::string_view node = transport_->usbfs_node();
  if (node.empty() || node.size() >= sizeof z.usbfs_node) return z;
  z.kind = ExternalZero::Kind::kUsbBulk;
  node.copy(z.usbfs_node, node.size());
  z.interface = 0;  // the FTDI chip's only interface (libusb_transport.cpp kInterface)
  z.endpoint = kEndpointOut;
  Command zero;  // as emergency_zero(): no force, the LEDs as they are
  zero.flags = static_cast<std::uint8_t>(kHomingRequest | led());
  const Frame frame = encode_command(zero);
  static_assert(kFrameBytes <= sizeof z.frame);
  std::copy(frame.begin(), frame.end(), z.frame);
  z.frame_bytes = static_cast<std::uint8_t>(frame.size());
  return z;
}

std::string FalconDriver::last_error() const {
  const std::string who = info_.name;
  const std::string streak =
      fault_streak_ > 1 ? " (" + std::to_string(fault_streak_) + " ticks in a row)" : std::string();
  const std::string reload =
      "If it lost power, its firmware is gone too: run `toonforce falcon firmware FILE` after plugging it in.";
  switch (fault_) {
    case FalconFault::kNone: return {};
    case FalconFault::kNotHomed:
      return who + " is not homed yet (LED red): pull the grip all the way out toward you, then push it "
                   "straight in until the LED turns green. Forces stay off until all three axes report homed.";
    case FalconFault::kPoseNotConverged:
      return who + ": the position estimate did not converge (angle residual " + std::to_string(fault_residual_rad_) +
             " rad" + streak +
             "); forces are off for this tick. The grip may be at the edge of the "
             "workspace; move it toward the centre. If it persists, re-home (pull out, push in).";
    case FalconFault::kNoReply:
      return who + " did not answer the last command within " + std::to_string(options_.max_reads_per_tick) +
             " USB reads" + streak +
             "; forces are off. A single miss is harmless. If it repeats, check the USB "
             "cable (no hub) and the power supply; if the LED went dark the firmware stopped: power-cycle the "
             "Falcon and run `toonforce falcon firmware FILE`.";
    case FalconFault::kUsbTimeout:
      return who + ": a USB transfer timed out after " + std::to_string(options_.io_timeout_ms) + " ms" + streak +
             " (the FTDI USB bridge stopped answering); forces are off. Check the cable and power; if it "
             "persists, unplug and replug the Falcon and restart. " +
             reload;
    case FalconFault::kGarbled:
      return who + " sent " + std::to_string(fault_garbled_) +
             " bytes that did not form a valid 16-byte frame, "
             "and no valid reply" +
             streak +
             "; forces are off for this tick. Occasional garbling is survivable; "
             "if it persists check the cable and that no other program talks to the Falcon.";
    case FalconFault::kUnplugged:
      return who +
             " is gone: USB reported no device (LIBUSB_ERROR_NO_DEVICE: unplugged or powered off). "
             "Forces are off. Plug it back in and restart. " +
             reload;
    case FalconFault::kUsbError:
      return who + ": USB error (" + std::string(to_string(fault_usb_)) + ")" + streak +
             "; forces are off. Unplug and replug the Falcon; if it repeats, try another USB port.";
  }
  return {};
}

}  // namespace toonforce::falcon
