// SPDX-License-Identifier: Apache-2.0
// The emulated Falcon (FALCON.md §8 "What a faithful emulator must reproduce").
#include "toonforce/hal/falcon/emulator/falcon_emulator.hpp"

#include <algorithm>
#include <cmath>

#include "toonforce/hal/falcon/ftdi.hpp"

namespace toonforce::falcon::emulator {
namespace {

constexpr std::size_t kBootHeaderWords = 11;                     // key, 8 reserved, 2 entry-point words
constexpr std::array<std::uint8_t, 2> kModemStatus{0x31, 0x60};  // typical idle (FALCON.md §1)

std::uint16_t word_at(const std::vector<std::uint8_t>& image, std::size_t word) {
  return static_cast<std::uint16_t>(image[2 * word] | (image[2 * word + 1] << 8));
}

}  // namespace

FalconEmulator::FalconEmulator(EmulatorOptions options)
    : options_(std::move(options)), grip_m_(options_.grip_start_m), target_m_(options_.grip_start_m) {
  // Sized up front so a test's servo loop over the in-process transport allocates nothing.
  to_host_.reserve(std::size_t{64} * 1024);
  held_.reserve(1024);
  command_log_.reserve(20000);
  reset_dsp();
  handshake_failures_left_ = options_.handshake_failures;
  if (options_.firmware_loaded) state_ = BootState::kRunning;
  dynamic_ = options_.hand_stiffness_n_per_m > 0.0;
  step_mechanics();
  // A dead encoder is stuck where it was at power-on (relative counts, as the host sees them).
  for (std::size_t i = 0; i < 3; ++i) {
    dead_counts_[i] = static_cast<std::int16_t>(last_counts_[i] + options_.power_on_offset_counts[i]);
  }
}

void FalconEmulator::set_hand_spring(double stiffness_n_per_m, double damping_n_s_per_m) noexcept {
  options_.hand_stiffness_n_per_m = stiffness_n_per_m;
  options_.hand_damping_n_s_per_m = damping_n_s_per_m;
  dynamic_ = true;
}

void FalconEmulator::power_cycle() {
  ftdi_ = FtdiState{};
  to_host_.clear();
  held_.clear();
  reset_dsp();
  handshake_failures_left_ = options_.handshake_failures;
}

void FalconEmulator::reset_dsp() {
  // Inference (FALCON.md §2.1): DTR drives the DSP's reset; its firmware is RAM-resident.
  state_ = BootState::kBootRom;
  image_.clear();
  next_block_word_ = kBootHeaderWords;
  rom_input_.clear();
  commands_in_.clear();
  homed_ = false;
  pulled_out_ = false;
}

bool FalconEmulator::take_in_stall() noexcept {
  if (stall_in_ <= 0) return false;
  --stall_in_;
  return true;
}

bool FalconEmulator::vendor_request(std::uint8_t request, std::uint16_t value) {
  ftdi_.log.emplace_back(request, value);
  switch (request) {
    case ftdi::kReset:
      if (value == ftdi::kPurgeRx) {
        to_host_.clear();
        held_.clear();
        ++ftdi_.purges_rx;
      } else if (value == ftdi::kPurgeTx) {
        ++ftdi_.purges_tx;
      }
      return true;
    case ftdi::kModemControl: {
      // High byte: which lines to change (0x01 DTR, 0x02 RTS); low byte: their levels.
      const unsigned mask = value >> 8;
      if (mask & 0x02) ftdi_.rts = (value & 0x02) != 0;
      if (mask & 0x01) {
        const bool dtr = (value & 0x01) != 0;
        if (dtr && !ftdi_.dtr) reset_dsp();  // rising edge: the DSP leaves reset into its ROM
        ftdi_.dtr = dtr;
      }
      return true;
    }
    case ftdi::kFlowControl: ftdi_.flow = value; return true;
    case ftdi::kBaudDivisor: ftdi_.divisor = value; return true;
    case ftdi::kDataFormat: ftdi_.data_format = value; return true;
    case ftdi::kLatencyTimer: ftdi_.latency_ms = value; return true;
    default: return true;  // other FTDI requests are accepted and logged
  }
}

void FalconEmulator::send(std::span<const std::uint8_t> bytes) {
  to_host_.insert(to_host_.end(), bytes.begin(), bytes.end());
}

void FalconEmulator::bulk_out(std::span<const std::uint8_t> bytes) {
  if (!connected_) return;
  const bool framing_ok = ftdi_.data_format == ftdi::k8N1;
  switch (state_) {
    case BootState::kBootRom:
    case BootState::kHandshaken:
      for (const std::uint8_t b : bytes) boot_rom_byte(b);
      return;
    case BootState::kLoading:
      for (const std::uint8_t b : bytes) {
        if (state_ != BootState::kLoading) {
          ++ignored_bytes_;
          continue;
        }
        // The wrong baud rate garbles every byte the DSP sees: it echoes nothing useful.
        if (ftdi_.divisor != ftdi::kDivisor140k || !framing_ok) {
          ++ignored_bytes_;
          continue;
        }
        loading_byte(b);
      }
      return;
    case BootState::kRejected: ignored_bytes_ += bytes.size(); return;
    case BootState::kRunning:
      if (ftdi_.divisor != ftdi::kDivisorNormal || !framing_ok) {
        ignored_bytes_ += bytes.size();
        return;
      }
      running_bytes(bytes);
      return;
  }
}

void FalconEmulator::boot_rom_byte(std::uint8_t b) {
  // The autobaud character: DTR low at ~140 kbaud (FALCON.md §2.1 step 4).
  if (state_ == BootState::kHandshaken && ftdi_.divisor == ftdi::kDivisor140k && !ftdi_.dtr) {
    if (b == 0x41) {
      send(std::array<std::uint8_t, 1>{options_.autobaud_echo});
      send(options_.autobaud_trailing_bytes);
      if (options_.autobaud_echo != 0x41) return;  // not locked: it waits for another 'A'
      state_ = BootState::kLoading;
      image_.clear();
      next_block_word_ = kBootHeaderWords;
    } else {
      ++ignored_bytes_;
    }
    return;
  }
  if (ftdi_.divisor != ftdi::kDivisor9600 || ftdi_.data_format != ftdi::k8N1) {
    ++ignored_bytes_;
    return;
  }
  rom_input_.push_back(b);
  if (rom_input_.size() > 16) rom_input_.erase(rom_input_.begin());
  const std::size_t n = rom_input_.size();
  if (n >= 3 && rom_input_[n - 3] == 0x0A && rom_input_[n - 2] == 0x43 && rom_input_[n - 1] == 0x0D) {
    rom_input_.clear();
    if (handshake_failures_left_ > 0) {
      --handshake_failures_left_;
      return;
    }
    if (options_.handshake_leading_zero) send(std::array<std::uint8_t, 1>{0x00});
    send(std::array<std::uint8_t, 4>{0x0A, 0x44, 0x2C, 0x0D});
    ++handshakes_answered_;
    state_ = BootState::kHandshaken;
  }
}

void FalconEmulator::loading_byte(std::uint8_t b) {
  const std::size_t offset = image_.size();
  image_.push_back(b);
  if (offset == 1 && word_at(image_, 0) != kBootTableKey) {
    state_ = BootState::kRejected;  // the ROM does not echo past a bad key
    return;
  }
  std::uint8_t echo = b;
  if (offset == corrupt_echo_at_) {
    echo = static_cast<std::uint8_t>(b ^ 0x5A);
    corrupt_echo_at_ = SIZE_MAX;
  }
  send(std::array<std::uint8_t, 1>{echo});
  // Walk the block headers as their bytes arrive; a zero length ends the table.
  while (image_.size() >= 2 * (next_block_word_ + 1)) {
    const std::uint16_t length = word_at(image_, next_block_word_);
    if (length == 0) {
      ++loads_completed_;
      const Sha256 digest = sha256(image_);
      const bool accepted = options_.accepted_images.empty() ||
                            std::find(options_.accepted_images.begin(), options_.accepted_images.end(), digest) !=
                                options_.accepted_images.end();
      state_ = accepted ? BootState::kRunning : BootState::kRejected;
      commands_in_.clear();
      return;
    }
    next_block_word_ += 3 + length;
  }
}

void FalconEmulator::running_bytes(std::span<const std::uint8_t> bytes) {
  commands_in_.push(bytes);
  Command c;
  while (commands_in_.pop_command(c)) handle_command(c);
  // Malformed input is ignored (FALCON.md §8, item 3); the assembler resynchronises on '<'.
}

void FalconEmulator::handle_command(const Command& c) {
  ++commands_;
  while (hand_script_next_ < options_.hand_script.size() &&
         options_.hand_script[hand_script_next_].at_command <= commands_) {
    set_grip_position(options_.hand_script[hand_script_next_++].target_m);
  }
  last_command_ = c;
  command_log_.push_back(c);
  if (c.flags & kHomingRequest) {
    if (!homed_) {
      if (grip_m_.z > options_.homing_out_z_m) pulled_out_ = true;
      if (pulled_out_ && grip_m_.z < options_.homing_in_z_m) homed_ = true;  // counts re-based
    }
  } else {
    if (homed_) ++homing_bit_dropped_;  // the bit must stay set to stay homed (FALCON.md §4)
    homed_ = false;
    pulled_out_ = false;
  }
  step_mechanics();

  Status s;
  s.encoder = encoder_counts();
  std::uint8_t homed_flags = 0;
  if (homed_) {
    for (std::size_t i = 0; i < 3; ++i) {
      if (!options_.axis_never_homes[i]) homed_flags = static_cast<std::uint8_t>(homed_flags | (kHomedArm1 << i));
    }
  }
  s.info = static_cast<std::uint8_t>(buttons_ | homed_flags);
  Frame f = encode_status(s);
  if (drop_ > 0) {
    --drop_;
    return;
  }
  if (garble_ > 0) {
    --garble_;
    f[5] = 0x5A;  // 'Z': not a nibble byte
  }
  if (delay_ > 0) {
    --delay_;
    held_.insert(held_.end(), f.begin(), f.end());
    return;
  }
  send(held_);
  held_.clear();
  send(f);
  ++replies_;
}

void FalconEmulator::set_grip_position(const Vec3<double>& falcon_m) {
  target_m_ = falcon_m;
  if (!dynamic_) {
    grip_m_ = falcon_m;
    velocity_m_per_s_ = {};
    step_mechanics();
  }
}

Vec3<double> FalconEmulator::motor_force_n() const noexcept {
  // tau = -word * k; the grip force F solves J^T F = tau (the inverse of the host's mapping).
  Mat3 j;
  if (!position_jacobian(geometry_, grip_m_, j)) return {};
  Mat3 jt;
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) jt(r, c) = j(c, r);
  }
  Mat3 jt_inv;
  if (!invert(jt, jt_inv)) return {};
  const double k = -options_.n_m_per_word;
  const auto torque = [&](std::size_t i) {
    const double t = k * last_command_.motor[i];
    return options_.motor_reversed[i] ? -t : t;  // a motor wired backwards
  };
  const double t0 = torque(0);
  const double t1 = torque(1);
  const double t2 = torque(2);
  return {jt_inv(0, 0) * t0 + jt_inv(0, 1) * t1 + jt_inv(0, 2) * t2,
          jt_inv(1, 0) * t0 + jt_inv(1, 1) * t1 + jt_inv(1, 2) * t2,
          jt_inv(2, 0) * t0 + jt_inv(2, 1) * t1 + jt_inv(2, 2) * t2};
}

void FalconEmulator::step_mechanics() {
  if (dynamic_ && state_ == BootState::kRunning) {
    const double dt = options_.seconds_per_command;
    constexpr double kGravity = 9.81;  // [m/s^2] along the Falcon's -y (y is up, FALCON.md §5)
    const Vec3<double> force = (target_m_ - grip_m_) * options_.hand_stiffness_n_per_m -
                               velocity_m_per_s_ * options_.hand_damping_n_s_per_m + motor_force_n() +
                               Vec3<double>{0.0, -kGravity * weight_kg_, 0.0};
    velocity_m_per_s_ += force * (dt / (options_.grip_mass_kg + weight_kg_));  // semi-implicit Euler
    const Vec3<double> next = grip_m_ + velocity_m_per_s_ * dt;
    Angles probe{};
    if (inverse_kinematics(geometry_, next, probe)) {
      grip_m_ = next;
    } else {
      velocity_m_per_s_ = {};  // an end stop: the linkage cannot go there
    }
  }
  Angles theta{};
  if (inverse_kinematics(geometry_, grip_m_, theta)) {
    for (std::size_t i = 0; i < 3; ++i) {
      const double counts = std::round(theta1_rad_to_encoder(theta[i]));
      last_counts_[i] = static_cast<std::int16_t>(std::clamp(counts, -32768.0, 32767.0));
    }
  }
}

std::array<std::int16_t, 3> FalconEmulator::encoder_counts() const noexcept {
  std::array<std::int16_t, 3> counts = last_counts_;
  for (std::size_t i = 0; i < 3; ++i) {
    if (!homed_) counts[i] = static_cast<std::int16_t>(counts[i] + options_.power_on_offset_counts[i]);
    if (options_.encoder_dead[i]) counts[i] = dead_counts_[i];
  }
  return counts;
}

std::size_t FalconEmulator::bulk_in(std::span<std::uint8_t> transfer) {
  std::size_t pos = 0;
  std::size_t budget = max_payload_ > 0 ? max_payload_ : SIZE_MAX;
  std::size_t taken = 0;
  while (transfer.size() - pos >= kFtdiStatusBytes) {
    transfer[pos] = kModemStatus[0];
    transfer[pos + 1] = kModemStatus[1];
    pos += kFtdiStatusBytes;
    const std::size_t n = std::min({kFtdiPayloadPerPacket, transfer.size() - pos, to_host_.size() - taken, budget});
    std::copy_n(to_host_.begin() + static_cast<std::ptrdiff_t>(taken), n,
                transfer.begin() + static_cast<std::ptrdiff_t>(pos));
    taken += n;
    pos += n;
    budget -= n;
    if (n < kFtdiPayloadPerPacket) break;  // a short packet ends the transfer
  }
  to_host_.erase(to_host_.begin(), to_host_.begin() + static_cast<std::ptrdiff_t>(taken));
  return pos;
}

}  // namespace toonforce::falcon::emulator
