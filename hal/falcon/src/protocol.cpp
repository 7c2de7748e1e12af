// SPDX-License-Identifier: Apache-2.0
// FTDI status stripping and the frame assembler's buffer management (FALCON.md §1, §3).
#include "toonforce/hal/falcon/protocol.hpp"

#include <algorithm>
#include <cstring>

namespace toonforce::falcon {

std::size_t strip_ftdi_status(std::span<const std::uint8_t> transfer, std::span<std::uint8_t> payload,
                              std::array<std::uint8_t, 2>* modem_status) noexcept {
  std::size_t out = 0;
  for (std::size_t packet = 0; packet < transfer.size(); packet += kUsbPacketBytes) {
    const std::size_t packet_end = std::min(packet + kUsbPacketBytes, transfer.size());
    if (packet_end - packet < kFtdiStatusBytes) break;  // a truncated status header: no data
    if (modem_status != nullptr) *modem_status = {transfer[packet], transfer[packet + 1]};
    const std::size_t data = packet + kFtdiStatusBytes;
    const std::size_t n = std::min(packet_end - data, payload.size() - out);
    if (n > 0) std::memcpy(payload.data() + out, transfer.data() + data, n);
    out += n;
    if (out == payload.size()) break;
  }
  return out;
}

void FrameAssembler::push(std::span<const std::uint8_t> bytes) noexcept {
  // Keep only what can ever fit: the newest kCapacity bytes.
  if (bytes.size() > kCapacity) {
    discarded_ += pending() + bytes.size() - kCapacity;
    begin_ = end_ = 0;
    bytes = bytes.subspan(bytes.size() - kCapacity);
  }
  if (end_ + bytes.size() > kCapacity) {
    // Compact first; if still too full, drop the oldest bytes.
    const std::size_t keep = pending();
    if (begin_ > 0 && keep > 0) std::memmove(buffer_.data(), buffer_.data() + begin_, keep);
    begin_ = 0;
    end_ = keep;
    if (end_ + bytes.size() > kCapacity) {
      const std::size_t drop = end_ + bytes.size() - kCapacity;
      std::memmove(buffer_.data(), buffer_.data() + drop, end_ - drop);
      end_ -= drop;
      discarded_ += drop;
    }
  }
  if (!bytes.empty()) std::memcpy(buffer_.data() + end_, bytes.data(), bytes.size());
  end_ += bytes.size();
  if (begin_ == end_) begin_ = end_ = 0;
}

}  // namespace toonforce::falcon
