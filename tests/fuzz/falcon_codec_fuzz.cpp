// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: the Novint Falcon codec (hal/falcon/protocol.hpp), the bytes a device or a
// garbled USB link can send. The first byte picks the property checked on the rest:
//   0: any 16 bytes as a status frame and as a command frame: if it decodes, encoding the
//      result gives the same bytes;
//   1: any status and command values encode into frames that decode back to them;
//   2: any bytes split into any USB transfers: the FTDI status bytes are stripped exactly, and
//      the assembler only ever returns frames that decode, and accounts for every byte
//      (returned in a frame, discarded as garbage, or still pending);
//   3: valid status frames with garbage between them (never a '<'), split into any chunks:
//      the assembler returns every frame, in order, and nothing else.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "toonforce/hal/falcon/protocol.hpp"

namespace {

using namespace toonforce::falcon;

void require(bool ok) {
  if (!ok) std::abort();  // libFuzzer reports the input
}

/// Reads the fuzzer's bytes in order, then zeros.
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::uint8_t next() { return at_ < size_ ? data_[at_++] : 0; }
  std::int16_t word() { return static_cast<std::int16_t>(next() | (next() << 8)); }
  bool empty() const { return at_ >= size_; }
  std::size_t left() const { return size_ - std::min(at_, size_); }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t at_ = 0;
};

Frame frame_from(Bytes& in) {
  Frame f{};
  for (auto& b : f) b = in.next();
  return f;
}

void frame_round_trip(Bytes& in) {
  while (in.left() >= kFrameBytes) {
    const Frame f = frame_from(in);
    Status s;
    if (decode_status(f, s)) require(encode_status(s) == f);
    Command c;
    if (decode_command(f, c)) require(encode_command(c) == f);
  }
}

void value_round_trip(Bytes& in) {
  while (!in.empty()) {
    Status s;
    for (auto& e : s.encoder) e = in.word();
    s.info = in.next() & kStatusInfoMask;
    s.byte14 = in.next();
    Status back;
    require(decode_status(encode_status(s), back) && back == s);
    Command c;
    for (auto& m : c.motor) m = in.word();
    c.flags = in.next() & kCommandFlagsMask;
    c.byte14 = in.next();
    Command c_back;
    require(decode_command(encode_command(c), c_back) && c_back == c);
  }
}

void stream_accounting(Bytes& in) {
  FrameAssembler assembler;
  std::size_t pushed = 0;
  std::size_t returned = 0;
  std::vector<std::uint8_t> transfer;
  std::vector<std::uint8_t> payload(4096);
  while (!in.empty()) {
    // One bulk-IN transfer of 0..255 bytes: FTDI status bytes at every 64-byte packet.
    transfer.resize(in.next());
    for (auto& b : transfer) b = in.next();
    const std::size_t n = strip_ftdi_status(transfer, payload);
    std::size_t expected = 0;
    for (std::size_t p = 0; p < transfer.size(); p += kUsbPacketBytes) {
      const std::size_t len = std::min(kUsbPacketBytes, transfer.size() - p);
      if (len < kFtdiStatusBytes) break;
      require(std::memcmp(payload.data() + expected, transfer.data() + p + kFtdiStatusBytes, len - kFtdiStatusBytes) ==
              0);
      expected += len - kFtdiStatusBytes;
    }
    require(n == expected);
    assembler.push({payload.data(), n});
    pushed += n;
    require(assembler.pending() <= FrameAssembler::kCapacity);
    Status s;
    while (assembler.pop_status(s)) {
      returned += kFrameBytes;
      Status again;
      require(decode_status(encode_status(s), again) && again == s);
    }
    require(returned + assembler.discarded() + assembler.pending() == pushed);
  }
}

void resynchronisation(Bytes& in) {
  std::vector<Status> sent;
  std::vector<std::uint8_t> stream;
  while (!in.empty() && sent.size() < 64) {
    for (std::uint8_t garbage = in.next() % 24; garbage > 0; --garbage) {
      const std::uint8_t b = in.next();
      stream.push_back(b == kFrameStart ? std::uint8_t{0} : b);
    }
    Status s;
    for (auto& e : s.encoder) e = in.word();
    s.info = in.next() & kStatusInfoMask;
    s.byte14 = in.next();
    const Frame f = encode_status(s);
    stream.insert(stream.end(), f.begin(), f.end());
    sent.push_back(s);
  }
  FrameAssembler assembler;
  std::vector<Status> received;
  std::size_t at = 0;
  std::uint8_t chunk_seed = static_cast<std::uint8_t>(sent.size());
  while (at < stream.size()) {
    chunk_seed = static_cast<std::uint8_t>(chunk_seed * 73 + 41);
    const std::size_t chunk = std::min<std::size_t>(1 + chunk_seed % 70, stream.size() - at);
    assembler.push({stream.data() + at, chunk});
    at += chunk;
    Status s;
    while (assembler.pop_status(s)) received.push_back(s);
  }
  require(received == sent);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  Bytes in(data + 1, size - 1);
  switch (data[0] % 4) {
    case 0: frame_round_trip(in); break;
    case 1: value_round_trip(in); break;
    case 2: stream_accounting(in); break;
    case 3: resynchronisation(in); break;
  }
  return 0;
}
