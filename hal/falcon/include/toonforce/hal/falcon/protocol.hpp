// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The Novint Falcon's runtime protocol (Novint SDK / nVent firmware) and the FTDI framing
/// around it, as pure functions: the 16-byte command and status codec, the stripping of the
/// 2 FTDI status bytes at every 64-byte packet boundary, and a fixed-capacity assembler that
/// finds whole frames in a byte stream split or merged across USB packets.
/// Source of every constant: docs/FALCON.md §1 and §3. No I/O, no allocation.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace toonforce::falcon {

/// One frame in either direction: '<', 14 bytes of value + 0x41, '>' (FALCON.md §3).
inline constexpr std::size_t kFrameBytes = 16;
using Frame = std::array<std::uint8_t, kFrameBytes>;
inline constexpr std::uint8_t kFrameStart = 0x3C;  // '<'
inline constexpr std::uint8_t kFrameEnd = 0x3E;    // '>'
inline constexpr std::uint8_t kByteOffset = 0x41;  // 'A': every payload byte is value + 0x41

/// Command byte 13 bits (FALCON.md §3: the code enum and the boneyard header agree; the doc
/// comment's other table is treated as wrong).
inline constexpr std::uint8_t kHomingRequest = 0x01;
inline constexpr std::uint8_t kLedGreen = 0x02;
inline constexpr std::uint8_t kLedBlue = 0x04;
inline constexpr std::uint8_t kLedRed = 0x08;
inline constexpr std::uint8_t kCommandFlagsMask = 0x0F;

/// Status byte 13 bits (FALCON.md §3): grip buttons in bits 0-3, homed flags in bits 4-6.
inline constexpr std::uint8_t kButtonPlus = 0x01;     ///< far right ("plus")
inline constexpr std::uint8_t kButtonForward = 0x02;  ///< centre-forward
inline constexpr std::uint8_t kButtonCentre = 0x04;   ///< centre (circle)
inline constexpr std::uint8_t kButtonMinus = 0x08;    ///< far left ("minus")
inline constexpr std::uint8_t kButtonsMask = 0x0F;
inline constexpr std::uint8_t kHomedArm1 = 0x10;  ///< top axis
inline constexpr std::uint8_t kHomedArm2 = 0x20;  ///< right axis
inline constexpr std::uint8_t kHomedArm3 = 0x40;  ///< left axis
inline constexpr std::uint8_t kHomedAll = kHomedArm1 | kHomedArm2 | kHomedArm3;
inline constexpr std::uint8_t kStatusInfoMask = 0x7F;

/// Host -> device: three signed 16-bit motor words and the LED/homing flags.
struct Command {
  std::array<std::int16_t, 3> motor{};
  std::uint8_t flags = 0;   ///< kHomingRequest | kLed*
  std::uint8_t byte14 = 0;  ///< meaning unknown; libnifalcon always sends 0 (+0x41)
  friend constexpr bool operator==(const Command&, const Command&) noexcept = default;
};

/// Device -> host: three signed 16-bit encoder counts, buttons and homed flags.
struct Status {
  std::array<std::int16_t, 3> encoder{};
  std::uint8_t info = 0;    ///< byte 13 - 0x41: buttons (bits 0-3), homed (bits 4-6)
  std::uint8_t byte14 = 0;  ///< byte 14 - 0x41 (mod 256); meaning unknown
  constexpr std::uint8_t buttons() const noexcept { return info & kButtonsMask; }
  constexpr std::uint8_t homed_mask() const noexcept { return info & kHomedAll; }
  constexpr bool homed() const noexcept { return homed_mask() == kHomedAll; }
  friend constexpr bool operator==(const Status&, const Status&) noexcept = default;
};

namespace detail {
/// A 16-bit two's-complement word as 4 nibbles, least significant first, each + 0x41.
constexpr void put_word(Frame& f, std::size_t at, std::int16_t value) noexcept {
  const auto v = static_cast<std::uint16_t>(value);
  for (std::size_t i = 0; i < 4; ++i) {
    f[at + i] = static_cast<std::uint8_t>(kByteOffset + ((v >> (4 * i)) & 0xF));
  }
}
constexpr bool get_word(const Frame& f, std::size_t at, std::int16_t& value) noexcept {
  std::uint16_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    const std::uint8_t b = f[at + i];
    if (b < kByteOffset || b > kByteOffset + 0xF) return false;  // not 'A'..'P'
    v = static_cast<std::uint16_t>(v | ((b - kByteOffset) << (4 * i)));
  }
  value = static_cast<std::int16_t>(v);
  return true;
}
}  // namespace detail

constexpr Frame encode_command(const Command& c) noexcept {
  Frame f{};
  f[0] = kFrameStart;
  for (std::size_t m = 0; m < 3; ++m) detail::put_word(f, 1 + 4 * m, c.motor[m]);
  f[13] = static_cast<std::uint8_t>(kByteOffset + (c.flags & kCommandFlagsMask));
  f[14] = static_cast<std::uint8_t>(kByteOffset + c.byte14);
  f[15] = kFrameEnd;
  return f;
}

/// Strict: framing, nibble bytes 'A'..'P', byte 13 in 'A'..'P'. Used by the emulator.
constexpr bool decode_command(const Frame& f, Command& c) noexcept {
  if (f[0] != kFrameStart || f[15] != kFrameEnd) return false;
  Command out{};
  for (std::size_t m = 0; m < 3; ++m) {
    if (!detail::get_word(f, 1 + 4 * m, out.motor[m])) return false;
  }
  if (f[13] < kByteOffset || f[13] > kByteOffset + kCommandFlagsMask) return false;
  out.flags = static_cast<std::uint8_t>(f[13] - kByteOffset);
  out.byte14 = static_cast<std::uint8_t>(f[14] - kByteOffset);
  c = out;
  return true;
}

constexpr Frame encode_status(const Status& s) noexcept {
  Frame f{};
  f[0] = kFrameStart;
  for (std::size_t m = 0; m < 3; ++m) detail::put_word(f, 1 + 4 * m, s.encoder[m]);
  f[13] = static_cast<std::uint8_t>(kByteOffset + (s.info & kStatusInfoMask));
  f[14] = static_cast<std::uint8_t>(kByteOffset + s.byte14);
  f[15] = kFrameEnd;
  return f;
}

/// Byte 13 is decoded by subtracting 0x41, never by a table: with homed flags it exceeds 'P'
/// (up to 0xC0; FALCON.md §3). Byte 14's meaning is unknown, so any value is accepted: a
/// frame is rejected only for what we know must hold.
constexpr bool decode_status(const Frame& f, Status& s) noexcept {
  if (f[0] != kFrameStart || f[15] != kFrameEnd) return false;
  Status out{};
  for (std::size_t m = 0; m < 3; ++m) {
    if (!detail::get_word(f, 1 + 4 * m, out.encoder[m])) return false;
  }
  if (f[13] < kByteOffset || f[13] > kByteOffset + kStatusInfoMask) return false;
  out.info = static_cast<std::uint8_t>(f[13] - kByteOffset);
  out.byte14 = static_cast<std::uint8_t>(f[14] - kByteOffset);
  s = out;
  return true;
}

/// FTDI bulk-IN framing (FALCON.md §1): every packet of a bulk-IN transfer starts with 2
/// modem-status bytes, so each 64-byte packet carries at most 62 payload bytes.
inline constexpr std::size_t kUsbPacketBytes = 64;
inline constexpr std::size_t kFtdiStatusBytes = 2;
inline constexpr std::size_t kFtdiPayloadPerPacket = kUsbPacketBytes - kFtdiStatusBytes;

/// Copies the payload of a raw bulk-IN transfer into `payload`, dropping the 2 status bytes
/// at the start of every 64-byte packet (a transfer longer than one packet is the packets
/// back to back; only the last may be short). Returns the payload size; stops early if
/// `payload` is full. `modem_status` (optional) receives the last packet's 2 status bytes.
std::size_t strip_ftdi_status(std::span<const std::uint8_t> transfer, std::span<std::uint8_t> payload,
                              std::array<std::uint8_t, 2>* modem_status = nullptr) noexcept;

/// Finds whole frames in a byte stream (FTDI status bytes already stripped). Replies may be
/// split or merged across USB packets (FALCON.md §3), so bytes are kept between calls. Unlike
/// libnifalcon it resynchronises: bytes before a '<', or a '<' that does not start a valid
/// frame, are discarded and counted, so one garbled byte costs one frame, not the stream.
/// Fixed capacity: when full, the oldest bytes are discarded (and counted).
class FrameAssembler {
 public:
  static constexpr std::size_t kCapacity = 512;

  void push(std::span<const std::uint8_t> bytes) noexcept;

  /// Extracts the next frame that `decode` accepts (decode_status / decode_command).
  template <class Message>
  bool pop(Message& out, bool (*decode)(const Frame&, Message&) noexcept) noexcept {
    while (end_ > begin_) {
      if (buffer_[begin_] != kFrameStart) {
        discard(1);
        continue;
      }
      if (end_ - begin_ < kFrameBytes) return false;  // wait for the rest
      Frame f{};
      for (std::size_t i = 0; i < kFrameBytes; ++i) f[i] = buffer_[begin_ + i];
      if (decode(f, out)) {
        begin_ += kFrameBytes;
        return true;
      }
      discard(1);  // a '<' that does not start a frame: resync on the next '<'
    }
    return false;
  }
  bool pop_status(Status& out) noexcept { return pop(out, &decode_status); }
  bool pop_command(Command& out) noexcept { return pop(out, &decode_command); }

  std::size_t pending() const noexcept { return end_ - begin_; }
  /// Bytes thrown away as garbage since construction (or the last clear()).
  std::size_t discarded() const noexcept { return discarded_; }
  void clear() noexcept { begin_ = end_ = discarded_ = 0; }

 private:
  void discard(std::size_t n) noexcept {
    begin_ += n;
    discarded_ += n;
  }

  std::array<std::uint8_t, kCapacity> buffer_{};
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
  std::size_t discarded_ = 0;
};

}  // namespace toonforce::falcon
