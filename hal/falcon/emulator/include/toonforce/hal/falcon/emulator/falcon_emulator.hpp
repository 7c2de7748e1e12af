// SPDX-License-Identifier: Apache-2.0
#pragma once
/// An emulated Novint Falcon behind its FTDI bridge, built from the public facts of
/// FALCON.md §8 "What a faithful emulator must reproduce": FTDI request state (divisor,
/// latency, format, flow, DTR/RTS, purges), 2 status bytes at the start of every 64-byte IN
/// packet and status-only packets when there is nothing to send, the boot ROM (handshake, 'A'
/// autobaud, byte echo while parsing the C28x boot table), the running firmware (one reply per
/// well-formed command, silence for anything else), delta mechanics with relative encoders
/// until homed, homing, and fault injection. It is a model, not a device: behaviour the
/// reference leaves open (what DTR does, the homing mechanism, a watchdog) is a documented
/// assumption here. Not thread-safe: UsbfsEmulator serialises access. Tests only.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "toonforce/hal/falcon/firmware.hpp"
#include "toonforce/hal/falcon/kinematics.hpp"
#include "toonforce/hal/falcon/protocol.hpp"

namespace toonforce::falcon::emulator {

enum class BootState : std::uint8_t {
  kBootRom,     ///< powered, no firmware: the DSP's ROM waits for the handshake
  kHandshaken,  ///< answered "\nC\r"; waits for the autobaud 'A' at ~140 kbaud with DTR low
  kLoading,     ///< echoing and parsing the boot table
  kRejected,    ///< a bad key or an unknown image: silent until reset (DTR rising edge)
  kRunning,     ///< firmware runs: one reply per command
};

struct EmulatorOptions {
  bool firmware_loaded = false;         ///< start in kRunning (firmware survives reconnects)
  int handshake_failures = 0;           ///< ignore this many handshakes after each reset
  bool handshake_leading_zero = false;  ///< answer "\0\nD,\r" (libnifalcon's "Apple" form)
  /// What the boot ROM answers the autobaud 'A' with: 0x41 once it has locked the baud rate.
  std::uint8_t autobaud_echo = 0x41;
  /// Bytes the boot ROM sends right after that answer, in the same packet (line noise): they
  /// answer nothing the host sent.
  std::vector<std::uint8_t> autobaud_trailing_bytes;
  /// When non-empty, an image whose SHA-256 is not listed is "rejected" (the DSP never runs).
  std::vector<Sha256> accepted_images;
  /// Encoders count from their power-on state until homed (FALCON.md §4): this offset is
  /// added to the absolute counts while not homed.
  std::array<std::int16_t, 3> power_on_offset_counts{137, -251, 73};
  Vec3<double> grip_start_m{0.0, 0.0, 0.110};  ///< Falcon frame
  /// Hand model. 0: the grip follows set_grip_position exactly (a scripted hand). > 0: the
  /// grip is a point mass held by a spring-damper toward the hand target and pushed by the
  /// motors, integrated once per received command (the host paces the device).
  double hand_stiffness_n_per_m = 0.0;
  double hand_damping_n_s_per_m = 5.0;
  double grip_mass_kg = 0.1;
  double seconds_per_command = 0.001;
  /// Joint torque per motor word (FALCON.md §8: 1e-4 N m matches libnifalcon's model;
  /// torque = -word * this, the inverse of the host's word = -10000 * torque).
  double n_m_per_word = 1e-4;
  /// Homing (an assumption; the mechanism is undocumented): with the homing bit held, the
  /// grip pulled beyond `homing_out_z_m` then pushed back inside `homing_in_z_m`.
  double homing_out_z_m = 0.170;
  double homing_in_z_m = 0.100;
  /// A scripted hand in the device's own time: once `at_command` commands have arrived, the
  /// hand's target becomes `target_m` (as set_grip_position would). A test that drives the
  /// host in another process homes the device this way rather than from a thread polling in
  /// wall time, which loses the race against the host's ticks on a loaded machine.
  struct HandMove {
    std::size_t at_command = 0;
    Vec3<double> target_m{};
  };
  std::vector<HandMove> hand_script;  ///< in order of at_command

  // ---- faults of the hardware itself: what `toonforce bringup falcon` must catch ----
  /// Motor i (arm i+1) wired backwards: its torque has the opposite sign of what its word asks.
  std::array<bool, 3> motor_reversed{};
  /// Encoder i is dead: it reports the count it had at power-on whatever the arm does.
  std::array<bool, 3> encoder_dead{};
  /// Axis i never reports homed (its flag in the status stays clear): homing never completes.
  std::array<bool, 3> axis_never_homes{};
  // A force constant off by a factor: set n_m_per_word to the device's true torque per word.
};

/// What the FTDI vendor requests have set.
struct FtdiState {
  std::uint16_t divisor = 0x4138;  ///< FTDI power-on default: 9600 baud
  std::uint16_t latency_ms = 16;
  std::uint16_t data_format = 0x0008;
  std::uint16_t flow = 0;
  bool dtr = false;
  bool rts = false;
  std::size_t purges_rx = 0;
  std::size_t purges_tx = 0;
  std::vector<std::pair<std::uint8_t, std::uint16_t>> log;  ///< every request, in order
};

class FalconEmulator {
 public:
  explicit FalconEmulator(EmulatorOptions options = {});

  // ---- the USB side (called by EmulatorTransport or UsbfsEmulator) ----
  /// A vendor OUT request (bmRequestType 0x40). Returns false to stall.
  bool vendor_request(std::uint8_t request, std::uint16_t value);
  /// Bytes the host wrote to bulk OUT 0x02 (one transfer).
  void bulk_out(std::span<const std::uint8_t> bytes);
  /// Fills one bulk-IN transfer of at most `transfer.size()` bytes as an FTDI does: packets of
  /// 2 status bytes + up to 62 payload bytes, back to back while full; a short packet ends the
  /// transfer; nothing to send gives a status-only packet (the latency timer expired).
  std::size_t bulk_in(std::span<std::uint8_t> transfer);

  // ---- the hand and the world ----
  void set_grip_position(const Vec3<double>& falcon_m);  ///< the hand's target (or the grip itself)
  Vec3<double> grip_position() const noexcept { return grip_m_; }
  void set_buttons(std::uint8_t buttons) noexcept { buttons_ = buttons & kButtonsMask; }
  /// The hand becomes a spring-damper toward its target (see EmulatorOptions), from now on;
  /// stiffness 0 is a hand that lets go: the grip moves under the motors (and a weight) alone.
  void set_hand_spring(double stiffness_n_per_m, double damping_n_s_per_m) noexcept;
  /// A weight of `mass_kg` hung from the grip (0 takes it off): gravity along the Falcon's -y
  /// and the weight's mass on the grip.
  void hang_weight(double mass_kg) noexcept { weight_kg_ = mass_kg; }
  /// The LED bits (kLedRed, kLedGreen, kLedBlue) of the last command: what a person sees.
  std::uint8_t led() const noexcept {
    return static_cast<std::uint8_t>(last_command_.flags & (kLedRed | kLedGreen | kLedBlue));
  }
  /// The force the motors apply at the grip [N, Falcon frame] for the last motor words.
  Vec3<double> motor_force_n() const noexcept;
  void power_cycle();  ///< firmware lost, not homed, FTDI back to defaults

  // ---- faults ----
  void drop_replies(int n) noexcept { drop_ += n; }      ///< commands received, no reply sent
  void garble_replies(int n) noexcept { garble_ += n; }  ///< replies with a corrupted byte
  void delay_replies(int n) noexcept { delay_ += n; }    ///< held, then sent with the next reply (merged)
  /// At most this many payload bytes per IN transfer (0: no limit): splits replies.
  void set_max_payload_per_transfer(std::size_t n) noexcept { max_payload_ = n; }
  void corrupt_echo_at(std::size_t image_offset) noexcept { corrupt_echo_at_ = image_offset; }  ///< next load only
  void stall_in_transfers(int n) noexcept { stall_in_ += n; }  ///< IN transfers that never complete
  void unplug() noexcept { connected_ = false; }
  bool connected() const noexcept { return connected_; }
  /// Consumes one pending IN stall (the transport then lets the transfer time out).
  bool take_in_stall() noexcept;

  // ---- observations ----
  BootState state() const noexcept { return state_; }
  const FtdiState& ftdi() const noexcept { return ftdi_; }
  const Command& last_command() const noexcept { return last_command_; }
  std::size_t commands_received() const noexcept { return commands_; }
  std::size_t replies_sent() const noexcept { return replies_; }
  std::size_t handshakes_answered() const noexcept { return handshakes_answered_; }
  std::size_t loads_completed() const noexcept { return loads_completed_; }
  std::size_t ignored_bytes() const noexcept { return ignored_bytes_; }
  /// Commands received after homing that lacked the homing bit (the host must hold it).
  std::size_t homing_bit_dropped() const noexcept { return homing_bit_dropped_; }
  bool homed() const noexcept { return homed_; }
  const std::vector<std::uint8_t>& loaded_image() const noexcept { return image_; }
  /// The encoder counts the device reports now.
  std::array<std::int16_t, 3> encoder_counts() const noexcept;
  /// Every command received in the running state, in order.
  const std::vector<Command>& command_log() const noexcept { return command_log_; }

 private:
  void reset_dsp();
  void boot_rom_byte(std::uint8_t b);
  void loading_byte(std::uint8_t b);
  void running_bytes(std::span<const std::uint8_t> bytes);
  void handle_command(const Command& c);
  void step_mechanics();
  void queue_reply(const Frame& f);
  void send(std::span<const std::uint8_t> bytes);

  EmulatorOptions options_;
  FalconGeometry geometry_{};
  FtdiState ftdi_;
  BootState state_ = BootState::kBootRom;
  bool connected_ = true;

  std::vector<std::uint8_t> to_host_;  ///< FTDI RX buffer (device -> host)
  std::vector<std::uint8_t> held_;     ///< delayed replies
  std::vector<std::uint8_t> rom_input_;
  int handshake_failures_left_ = 0;
  std::size_t handshakes_answered_ = 0;

  std::vector<std::uint8_t> image_;
  std::size_t next_block_word_ = 0;  ///< word index of the next block header while loading
  std::size_t corrupt_echo_at_ = SIZE_MAX;
  std::size_t loads_completed_ = 0;

  FrameAssembler commands_in_;
  Command last_command_{};
  std::vector<Command> command_log_;
  std::size_t commands_ = 0;
  std::size_t replies_ = 0;
  std::size_t ignored_bytes_ = 0;

  Vec3<double> grip_m_;
  Vec3<double> target_m_;
  Vec3<double> velocity_m_per_s_{};
  std::array<std::int16_t, 3> last_counts_{};
  std::array<std::int16_t, 3> dead_counts_{};  ///< what dead encoders report (power-on counts)
  bool dynamic_ = false;                       ///< the grip moves under forces (a hand spring), not by script
  double weight_kg_ = 0.0;
  std::uint8_t buttons_ = 0;
  bool homed_ = false;
  bool pulled_out_ = false;
  std::size_t hand_script_next_ = 0;  ///< the next move of options_.hand_script
  std::size_t homing_bit_dropped_ = 0;

  int drop_ = 0;
  int garble_ = 0;
  int delay_ = 0;
  int stall_in_ = 0;
  std::size_t max_payload_ = 0;
};

}  // namespace toonforce::falcon::emulator
