// SPDX-License-Identifier: Apache-2.0
// The Falcon's 16-byte codec, FTDI status stripping and frame assembly, against the vectors of
// docs/FALCON.md §3 and our own (round trips, every flag bit, extremes).
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "toonforce/hal/falcon/protocol.hpp"

namespace toonforce::falcon {
namespace {

Frame frame_of(const char* text) {
  Frame f{};
  EXPECT_EQ(std::strlen(text), kFrameBytes) << text;
  std::memcpy(f.data(), text, kFrameBytes);
  return f;
}
Frame frame_of(std::initializer_list<int> bytes) {
  Frame f{};
  std::size_t i = 0;
  for (int b : bytes) f[i++] = static_cast<std::uint8_t>(b);
  EXPECT_EQ(i, kFrameBytes);
  return f;
}
std::string text_of(const Frame& f) { return std::string(f.begin(), f.end()); }

// ---- vectors from FALCON.md §3 "Test vectors" ----

TEST(FalconCodec, IdleCommandIsAllA) { EXPECT_EQ(text_of(encode_command(Command{})), "<AAAAAAAAAAAAAA>"); }

TEST(FalconCodec, HomingCommandSetsByte13ToB) {
  Command c;
  c.flags = kHomingRequest;
  EXPECT_EQ(text_of(encode_command(c)), "<AAAAAAAAAAAABA>");
}

TEST(FalconCodec, ReferenceCommandWithGreenAndHoming) {
  Command c{{1, -1, 4095}, kLedGreen | kHomingRequest, 0};
  EXPECT_EQ(encode_command(c),
            frame_of({0x3C, 0x42, 0x41, 0x41, 0x41, 0x50, 0x50, 0x50, 0x50, 0x50, 0x50, 0x50, 0x41, 0x44, 0x41, 0x3E}));
}

TEST(FalconCodec, ReferenceCommandWithExtremeWordsAndRed) {
  Command c{{-1447, 4660, -32768}, kLedRed, 0};
  EXPECT_EQ(text_of(encode_command(c)), "<JFKPEDCBAAAIIA>");
}

TEST(FalconCodec, ReferenceStatusEncodersNotHomed) {
  Status s;
  ASSERT_TRUE(decode_status(frame_of("<HKFAJFKPAAAAAA>"), s));
  EXPECT_EQ(s.encoder[0], 1447);
  EXPECT_EQ(s.encoder[1], -1447);
  EXPECT_EQ(s.encoder[2], 0);
  EXPECT_EQ(s.buttons(), 0);
  EXPECT_FALSE(s.homed());
}

TEST(FalconCodec, ReferenceStatusPlusButtonAllHomedHasByte13AboveP) {
  const Frame f =
      frame_of({0x3C, 0x4D, 0x50, 0x4E, 0x50, 0x4D, 0x50, 0x4E, 0x50, 0x4D, 0x50, 0x4E, 0x50, 0xB2, 0x41, 0x3E});
  Status s;
  ASSERT_TRUE(decode_status(f, s));
  EXPECT_EQ(s.encoder, (std::array<std::int16_t, 3>{-516, -516, -516}));
  EXPECT_EQ(s.buttons(), kButtonPlus);
  EXPECT_EQ(s.homed_mask(), kHomedAll);
  EXPECT_TRUE(s.homed());
  EXPECT_EQ(encode_status(s), f);
}

TEST(FalconCodec, HeaderDocExampleJfkpIsMinus1447) {
  // The doc claims "<JFBA..." decodes to 1447; its hex (JFKP) is -1447 (FALCON.md §3).
  Status s;
  ASSERT_TRUE(decode_status(frame_of("<JFKPAAAAAAAAAA>"), s));
  EXPECT_EQ(s.encoder[0], -1447);
}

TEST(FalconCodec, CapturedNovintPacketDecodes) {
  // util/translate_packet.py, F = (0, 0, -100): V = (4095, 3906, 4034), blue LED.
  const Frame f =
      frame_of({0x3C, 0x50, 0x50, 0x50, 0x41, 0x43, 0x45, 0x50, 0x41, 0x43, 0x4D, 0x50, 0x41, 0x45, 0x41, 0x3E});
  Command c;
  ASSERT_TRUE(decode_command(f, c));
  EXPECT_EQ(c.motor, (std::array<std::int16_t, 3>{4095, 3906, 4034}));
  EXPECT_EQ(c.flags, kLedBlue);
  EXPECT_EQ(encode_command(c), f);
}

// ---- our own ----

TEST(FalconCodec, EveryCommandFlagCombinationRoundTrips) {
  for (std::uint8_t flags = 0; flags <= kCommandFlagsMask; ++flags) {
    const Command c{{123, -456, 789}, flags, 0};
    const Frame f = encode_command(c);
    EXPECT_EQ(f[13], 0x41 + flags);
    Command back;
    ASSERT_TRUE(decode_command(f, back));
    EXPECT_EQ(back, c);
  }
}

TEST(FalconCodec, EveryStatusInfoValueRoundTripsAndSplitsIntoButtonsAndHomed) {
  for (unsigned info = 0; info <= kStatusInfoMask; ++info) {
    const Status s{{-1, 0, 1}, static_cast<std::uint8_t>(info), 0};
    const Frame f = encode_status(s);
    Status back;
    ASSERT_TRUE(decode_status(f, back)) << info;
    EXPECT_EQ(back, s);
    EXPECT_EQ(back.buttons(), info & 0x0F);
    EXPECT_EQ(back.homed_mask(), info & 0x70);
    EXPECT_EQ(back.homed(), (info & 0x70) == 0x70);
  }
}

TEST(FalconCodec, EachHomedBitAloneIsNotHomed) {
  for (std::uint8_t bit : {kHomedArm1, kHomedArm2, kHomedArm3}) {
    Status s;
    ASSERT_TRUE(decode_status(encode_status(Status{{}, bit, 0}), s));
    EXPECT_FALSE(s.homed());
    EXPECT_EQ(s.homed_mask(), bit);
  }
}

TEST(FalconCodec, ExtremeWordsRoundTripInEveryPosition) {
  const std::int16_t extremes[] = {-32768, -32767, -4096, -4095, -1, 0, 1, 15, 16, 255, 256, 4095, 4096, 32767};
  for (std::size_t m = 0; m < 3; ++m) {
    for (std::int16_t v : extremes) {
      Command c;
      c.motor[m] = v;
      Command back;
      ASSERT_TRUE(decode_command(encode_command(c), back));
      EXPECT_EQ(back.motor[m], v);
      Status s;
      s.encoder[m] = v;
      Status sback;
      ASSERT_TRUE(decode_status(encode_status(s), sback));
      EXPECT_EQ(sback.encoder[m], v);
    }
  }
}

TEST(FalconCodec, NibblesAreLeastSignificantFirst) {
  Command c;
  c.motor[0] = 0x1234;
  const Frame f = encode_command(c);
  EXPECT_EQ(f[1], 'A' + 4);
  EXPECT_EQ(f[2], 'A' + 3);
  EXPECT_EQ(f[3], 'A' + 2);
  EXPECT_EQ(f[4], 'A' + 1);
}

TEST(FalconCodec, RejectsBadFraming) {
  Status s;
  EXPECT_FALSE(decode_status(frame_of("[AAAAAAAAAAAAAA>"), s));
  EXPECT_FALSE(decode_status(frame_of("<AAAAAAAAAAAAAA]"), s));
  EXPECT_FALSE(decode_status(frame_of("<AAAAQAAAAAAAAA>"), s)) << "'Q' is not a nibble";
  EXPECT_FALSE(decode_status(frame_of("<AAAA@AAAAAAAAA>"), s)) << "'@' is below 'A'";
  Frame high = frame_of("<AAAAAAAAAAAAAA>");
  high[13] = 0xC1;  // 0x41 + 0x80: the 7-bit info field overflowed
  EXPECT_FALSE(decode_status(high, s));
  high[13] = 0xC0;
  EXPECT_TRUE(decode_status(high, s));
  Command c;
  EXPECT_FALSE(decode_command(frame_of("<AAAAAAAAAAAAQA>"), c)) << "command flags above 0x0F";
}

TEST(FalconCodec, StatusByte14IsAcceptedWhateverItHolds) {
  // Its meaning is unknown (FALCON.md §3): do not reject what is not understood.
  Frame f = frame_of("<AAAAAAAAAAAAAA>");
  f[14] = 0x20;
  Status s;
  ASSERT_TRUE(decode_status(f, s));
  EXPECT_EQ(s.byte14, static_cast<std::uint8_t>(0x20 - 0x41));
}

// ---- FTDI status bytes (FALCON.md §1) ----

TEST(FtdiStatus, StripsTwoBytesAtEvery64ByteBoundary) {
  std::vector<std::uint8_t> transfer;
  std::vector<std::uint8_t> expected;
  std::uint8_t next = 0;
  for (int packet = 0; packet < 3; ++packet) {
    transfer.push_back(0x31);
    transfer.push_back(static_cast<std::uint8_t>(0x60 + packet));
    const int n = packet < 2 ? 62 : 10;  // two full packets and a short one
    for (int i = 0; i < n; ++i) {
      transfer.push_back(next);
      expected.push_back(next);
      ++next;
    }
  }
  ASSERT_EQ(transfer.size(), 64u + 64u + 12u);
  std::vector<std::uint8_t> payload(200);
  std::array<std::uint8_t, 2> modem{};
  const std::size_t n = strip_ftdi_status(transfer, payload, &modem);
  ASSERT_EQ(n, expected.size());
  payload.resize(n);
  EXPECT_EQ(payload, expected);
  EXPECT_EQ(modem, (std::array<std::uint8_t, 2>{0x31, 0x62}));
}

TEST(FtdiStatus, StatusOnlyPacketCarriesNoData) {
  const std::uint8_t transfer[] = {0x31, 0x60};
  std::array<std::uint8_t, 64> payload{};
  EXPECT_EQ(strip_ftdi_status(transfer, payload), 0u);
  const std::uint8_t truncated[] = {0x31};
  EXPECT_EQ(strip_ftdi_status(truncated, payload), 0u);
  EXPECT_EQ(strip_ftdi_status({}, payload), 0u);
}

TEST(FtdiStatus, StopsWhenThePayloadBufferIsFull) {
  std::vector<std::uint8_t> transfer(64, 0x55);
  transfer[0] = 0x31;
  transfer[1] = 0x60;
  std::array<std::uint8_t, 10> payload{};
  EXPECT_EQ(strip_ftdi_status(transfer, payload), 10u);
}

// ---- frame assembly: split, merged, garbled (FALCON.md §3 "Rate and flow") ----

TEST(FrameAssembler, ReassemblesAFrameSplitByteByByte) {
  const Frame f = encode_status(Status{{10, -20, 30}, kHomedAll | kButtonCentre, 0});
  FrameAssembler a;
  Status s;
  for (std::size_t i = 0; i + 1 < f.size(); ++i) {
    a.push(std::span(f).subspan(i, 1));
    EXPECT_FALSE(a.pop_status(s)) << "complete after only " << i + 1 << " bytes";
  }
  a.push(std::span(f).subspan(f.size() - 1));
  ASSERT_TRUE(a.pop_status(s));
  EXPECT_EQ(s.encoder, (std::array<std::int16_t, 3>{10, -20, 30}));
  EXPECT_EQ(a.discarded(), 0u);
}

TEST(FrameAssembler, SplitsMergedFramesInOrder) {
  std::vector<std::uint8_t> bytes;
  for (std::int16_t k = 0; k < 3; ++k) {
    const Frame f = encode_status(Status{{k, k, k}, 0, 0});
    bytes.insert(bytes.end(), f.begin(), f.end());
  }
  const Frame tail = encode_status(Status{{99, 99, 99}, 0, 0});
  bytes.insert(bytes.end(), tail.begin(), tail.begin() + 7);  // and half of a fourth
  FrameAssembler a;
  a.push(bytes);
  Status s;
  for (std::int16_t k = 0; k < 3; ++k) {
    ASSERT_TRUE(a.pop_status(s));
    EXPECT_EQ(s.encoder[0], k);
  }
  EXPECT_FALSE(a.pop_status(s));
  EXPECT_EQ(a.pending(), 7u);
  a.push(std::span(tail).subspan(7));
  ASSERT_TRUE(a.pop_status(s));
  EXPECT_EQ(s.encoder[0], 99);
}

TEST(FrameAssembler, ResynchronisesAfterGarbageAndAGarbledFrame) {
  std::vector<std::uint8_t> bytes{'x', 'y', 0x00};
  Frame bad = encode_status(Status{{1, 1, 1}, 0, 0});
  bad[5] = 'Z';
  bytes.insert(bytes.end(), bad.begin(), bad.end());
  const Frame good = encode_status(Status{{2, 2, 2}, 0, 0});
  bytes.insert(bytes.end(), good.begin(), good.end());
  FrameAssembler a;
  a.push(bytes);
  Status s;
  ASSERT_TRUE(a.pop_status(s));
  EXPECT_EQ(s.encoder[0], 2);
  EXPECT_EQ(a.discarded(), 3u + kFrameBytes);
  EXPECT_EQ(a.pending(), 0u);
}

TEST(FrameAssembler, ALoneStartByteInsideGarbageDoesNotSwallowTheNextFrame) {
  // '<' followed by a valid frame that starts 5 bytes later.
  std::vector<std::uint8_t> bytes{'<', 'A', 'B', 'C', 'D'};
  const Frame good = encode_status(Status{{7, 8, 9}, 0, 0});
  bytes.insert(bytes.end(), good.begin(), good.end());
  FrameAssembler a;
  a.push(bytes);
  Status s;
  ASSERT_TRUE(a.pop_status(s));
  EXPECT_EQ(s.encoder, (std::array<std::int16_t, 3>{7, 8, 9}));
}

TEST(FrameAssembler, OverflowKeepsTheNewestBytes) {
  FrameAssembler a;
  const std::vector<std::uint8_t> junk(FrameAssembler::kCapacity - 3, 'A');
  a.push(junk);
  const Frame good = encode_status(Status{{5, 5, 5}, 0, 0});
  a.push(good);  // does not fit next to the junk: the oldest bytes go
  Status s;
  ASSERT_TRUE(a.pop_status(s));
  EXPECT_EQ(s.encoder[0], 5);
  EXPECT_EQ(a.discarded(), junk.size());
}

}  // namespace
}  // namespace toonforce::falcon
