// SPDX-License-Identifier: Apache-2.0
// Firmware files (size, boot-table structure, SHA-256 against an allowlist) and the load
// sequence of FALCON.md §2.1 against the emulated Falcon over the in-process transport.
// Synthetic images only: the known-hash check runs on a test allowlist.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "synthetic_firmware.hpp"
#include "toonforce/hal/falcon/emulator/emulator_transport.hpp"
#include "toonforce/hal/falcon/emulator/falcon_emulator.hpp"
#include "toonforce/hal/falcon/firmware.hpp"
#include "toonforce/hal/falcon/ftdi.hpp"

namespace toonforce::falcon {
namespace {

using emulator::BootState;
using emulator::EmulatorOptions;
using emulator::EmulatorTransport;
using emulator::FalconEmulator;
using test::make_boot_image;
using test::TestAllowlist;

std::vector<std::uint8_t> bytes_of(const char* s) { return {s, s + std::char_traits<char>::length(s)}; }

FirmwareImage validated(const std::vector<std::uint8_t>& bytes) {
  const TestAllowlist allow({bytes});
  auto image = validate_firmware(bytes, "synthetic.bin", allow.entries);
  EXPECT_TRUE(image) << image.error();
  return image.value();
}

// ---- SHA-256 (nettle) ----

TEST(FalconFirmware, Sha256MatchesFips180Vectors) {
  EXPECT_EQ(to_hex(sha256({})), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(to_hex(sha256(bytes_of("abc"))), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(to_hex(sha256(bytes_of("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"))),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  Sha256 parsed{};
  ASSERT_TRUE(parse_sha256_hex("BA7816BF8F01CFEA414140DE5DAE2223B00361A396177A9CB410FF61F20015AD", parsed));
  EXPECT_EQ(parsed, sha256(bytes_of("abc")));
  EXPECT_FALSE(parse_sha256_hex("ba78", parsed));
}

TEST(FalconFirmware, KnownImagesAreTheFourOfTheReference) {
  const auto known = known_firmware_images();
  ASSERT_EQ(known.size(), 4u);
  EXPECT_EQ(known[0].name, "nvent_firmware.bin");
  EXPECT_EQ(known[0].size_bytes, 8492u);
  EXPECT_EQ(to_hex(known[0].sha256), "1119e39c39fab1f37678ea62dfc715b23dd86ee7f13d78f88f707d9f09b896a1");
  EXPECT_EQ(known[1].size_bytes, 7324u);
  EXPECT_EQ(known[2].size_bytes, 7914u);
  EXPECT_EQ(to_hex(known[3].sha256), "e0ae3598670fa1c8d9277bd6943c99b3152b97c400c46c1c42c60de77ff4e816");
}

// ---- boot-table structure ----

TEST(FalconFirmware, ParsesAValidBootTable) {
  const auto image = make_boot_image({100, 7, 250});
  auto table = parse_boot_table(image);
  ASSERT_TRUE(table) << table.error();
  EXPECT_EQ(table.value().entry_point, kFalconEntryPoint);
  EXPECT_EQ(table.value().blocks, 3u);
  EXPECT_EQ(table.value().data_words, 357u);
}

TEST(FalconFirmware, RejectsEachStructuralFault) {
  const auto good = make_boot_image({40, 12});
  auto bad_key = good;
  bad_key[0] = 0xAB;
  EXPECT_NE(parse_boot_table(bad_key).error().find("byte 0: the boot table key is 0x08AB"), std::string::npos);

  auto bad_entry = good;
  bad_entry[18] = 0x40;  // high word of the entry point: 0x0040 instead of 0x003F
  EXPECT_NE(parse_boot_table(bad_entry).error().find("entry point is 0x00408002"), std::string::npos);

  auto truncated = good;
  truncated.resize(good.size() - 10);
  EXPECT_NE(parse_boot_table(truncated).error().find("claims 12 words but the file ends"), std::string::npos);

  auto no_terminator = good;
  no_terminator.resize(good.size() - 2);
  EXPECT_NE(parse_boot_table(no_terminator).error().find("without the terminating zero-length block"),
            std::string::npos);

  auto trailing = good;
  trailing.push_back(0x12);
  trailing.push_back(0x34);
  EXPECT_NE(parse_boot_table(trailing).error().find("2 bytes follow the terminating"), std::string::npos);

  auto odd = good;
  odd.push_back(0);
  EXPECT_NE(parse_boot_table(odd).error().find("is odd"), std::string::npos);

  EXPECT_NE(parse_boot_table(std::vector<std::uint8_t>(10, 0)).error().find("too short"), std::string::npos);
}

// ---- validation order: size, structure, hash ----

TEST(FalconFirmware, AcceptsAnImageOnTheAllowlist) {
  const auto a = make_boot_image({300}, 1);
  const auto b = make_boot_image({200, 50}, 2);
  const TestAllowlist allow({a, b});
  auto image = validate_firmware(b, "b.bin", allow.entries);
  ASSERT_TRUE(image) << image.error();
  EXPECT_EQ(image.value().name, "synthetic_1.bin");
  EXPECT_EQ(image.value().bytes, b);
  EXPECT_EQ(image.value().table.blocks, 2u);
}

TEST(FalconFirmware, WrongSizeIsRejectedNamingTheKnownSizes) {
  const auto a = make_boot_image({300});
  const TestAllowlist allow({a});
  auto r = validate_firmware(make_boot_image({301}), "wrong.bin", allow.entries);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("wrong.bin is 632 bytes"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("630 (synthetic_0.bin)"), std::string::npos) << r.error();
}

TEST(FalconFirmware, WrongStructureWithAKnownSizeIsRejected) {
  const auto a = make_boot_image({300});
  const TestAllowlist allow({a});
  auto broken = a;
  broken[1] = 0x09;  // key 0x09AA
  auto r = validate_firmware(broken, "broken.bin", allow.entries);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("broken.bin is not a Falcon firmware image: byte 0"), std::string::npos) << r.error();
}

TEST(FalconFirmware, WrongHashWithValidStructureIsRejected) {
  const auto a = make_boot_image({300}, 1);
  const TestAllowlist allow({a});
  auto modified = a;
  modified[100] ^= 0x01;  // one bit in the data: structure intact
  ASSERT_TRUE(parse_boot_table(modified));
  auto r = validate_firmware(modified, "modified.bin", allow.entries);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("has SHA-256 " + to_hex(sha256(modified))), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("size of synthetic_0.bin but different contents"), std::string::npos) << r.error();
}

TEST(FalconFirmware, RealAllowlistRejectsASyntheticImageOfNventSize) {
  // One block of 4231 words makes exactly 8492 bytes, nvent_firmware.bin's size.
  const auto image = make_boot_image({4231});
  ASSERT_EQ(image.size(), 8492u);
  ASSERT_EQ(test::one_block_image_bytes(4231), 8492u);
  auto r = validate_firmware(image, "fake_nvent.bin");
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("matches no known Falcon firmware image"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("nvent_firmware.bin"), std::string::npos) << r.error();
}

TEST(FalconFirmware, ReadsFilesAndNamesThemInErrors) {
  const auto dir = std::filesystem::temp_directory_path() / ("toonforce_fw_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto image = make_boot_image({120});
  const TestAllowlist allow({image});
  const auto path = (dir / "fw.bin").string();
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(image.data()), static_cast<std::streamsize>(image.size()));
  }
  auto ok = read_firmware_file(path, allow.entries);
  ASSERT_TRUE(ok) << ok.error();
  EXPECT_EQ(ok.value().bytes, image);

  auto missing = read_firmware_file((dir / "nope.bin").string(), allow.entries);
  EXPECT_NE(missing.error().find("nope.bin: it does not exist"), std::string::npos) << missing.error();
  auto directory = read_firmware_file(dir.string(), allow.entries);
  EXPECT_NE(directory.error().find("not a regular file"), std::string::npos) << directory.error();
  const auto big = (dir / "big.bin").string();
  {
    std::ofstream out(big, std::ios::binary);
    const std::vector<char> zeros(kMaxFirmwareBytes + 1, 0);
    out.write(zeros.data(), static_cast<std::streamsize>(zeros.size()));
  }
  auto too_big = read_firmware_file(big, allow.entries);
  EXPECT_NE(too_big.error().find("big.bin is 65537 bytes"), std::string::npos) << too_big.error();
  std::filesystem::remove_all(dir);
}

// ---- loading into the emulated Falcon (FALCON.md §2.1) ----

TEST(FalconFirmwareLoad, LoadsAndTheFirmwareAnswers) {
  const FirmwareImage image = validated(make_boot_image({1000, 300, 17}, 3));
  FalconEmulator emu;
  EmulatorTransport t(emu);
  EXPECT_FALSE(probe_firmware(t).loaded) << "a fresh Falcon has no firmware";
  std::vector<std::size_t> progress;
  FirmwareLoadOptions options;
  options.progress = [&](std::size_t done, std::size_t, int) { progress.push_back(done); };
  auto report = load_firmware(t, image, options);
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report.value().attempts, 1);
  EXPECT_EQ(emu.state(), BootState::kRunning);
  EXPECT_EQ(emu.loaded_image(), image.bytes) << "every byte arrived, in order";
  EXPECT_EQ(emu.handshakes_answered(), 1u);
  ASSERT_FALSE(progress.empty());
  EXPECT_EQ(progress.back(), image.bytes.size());
  EXPECT_TRUE(std::is_sorted(progress.begin(), progress.end()));
  // Back in normal mode (FALCON.md §2.1 step 6).
  EXPECT_EQ(emu.ftdi().divisor, ftdi::kDivisorNormal);
  EXPECT_EQ(emu.ftdi().latency_ms, ftdi::kLatencyNormalMs);
  EXPECT_TRUE(probe_firmware(t).loaded);
}

TEST(FalconFirmwareLoad, SendsTheFtdiSequenceOfTheReference) {
  const FirmwareImage image = validated(make_boot_image({50}));
  FalconEmulator emu;
  EmulatorTransport t(emu);
  ASSERT_TRUE(load_firmware(t, image));
  using R = std::pair<std::uint8_t, std::uint16_t>;
  const std::vector<R> expected_prefix{{ftdi::kReset, ftdi::kPurgeRx},
                                       {ftdi::kReset, ftdi::kPurgeTx},
                                       {ftdi::kLatencyTimer, 16},
                                       {ftdi::kBaudDivisor, 0x4138},
                                       {ftdi::kDataFormat, 0x0008},
                                       {ftdi::kFlowControl, 0},
                                       {ftdi::kModemControl, ftdi::kRtsLow},
                                       {ftdi::kModemControl, ftdi::kDtrLow},
                                       {ftdi::kModemControl, ftdi::kDtrHigh},
                                       {ftdi::kModemControl, ftdi::kDtrLow},
                                       {ftdi::kBaudDivisor, 0x0015},
                                       {ftdi::kReset, ftdi::kPurgeRx},
                                       {ftdi::kLatencyTimer, 1},
                                       {ftdi::kBaudDivisor, 0x0002},
                                       {ftdi::kDataFormat, 0x0008},
                                       {ftdi::kFlowControl, 0},
                                       {ftdi::kReset, ftdi::kPurgeRx},
                                       {ftdi::kReset, ftdi::kPurgeTx}};
  const auto& log = emu.ftdi().log;
  ASSERT_GE(log.size(), expected_prefix.size());
  EXPECT_EQ(std::vector<R>(log.begin(), log.begin() + static_cast<std::ptrdiff_t>(expected_prefix.size())),
            expected_prefix);
}

TEST(FalconFirmwareLoad, AcceptsTheHandshakeWithALeadingZero) {
  const FirmwareImage image = validated(make_boot_image({64}));
  EmulatorOptions o;
  o.handshake_leading_zero = true;
  FalconEmulator emu(o);
  EmulatorTransport t(emu);
  auto report = load_firmware(t, image);
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(emu.state(), BootState::kRunning);
}

TEST(FalconFirmwareLoad, AStrayByteAfterTheAutobaudEchoIsNotAFailure) {
  // The 'A' came back, so the boot loader has locked its baud rate; a byte after it answers
  // nothing the host sent (FALCON.md §2.1 step 4) and must neither fail the try nor be taken
  // for the echo of the image's first byte.
  const FirmwareImage image = validated(make_boot_image({64}));
  EmulatorOptions o;
  o.autobaud_trailing_bytes = {0x7F};
  FalconEmulator emu(o);
  EmulatorTransport t(emu);
  auto report = load_firmware(t, image);
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report.value().attempts, 1) << report.value().failures.front();
  EXPECT_EQ(emu.state(), BootState::kRunning);
  EXPECT_EQ(emu.loaded_image(), image.bytes);
}

TEST(FalconFirmwareLoad, AWrongAutobaudAnswerNamesTheBytesReceived) {
  const FirmwareImage image = validated(make_boot_image({64}));
  EmulatorOptions o;
  o.autobaud_echo = 0x42;
  o.autobaud_trailing_bytes = {0x41};  // an 'A' after a wrong byte is still not the echo
  FalconEmulator emu(o);
  EmulatorTransport t(emu);
  FirmwareLoadOptions options;
  options.attempts = 1;
  auto report = load_firmware(t, image, options);
  ASSERT_FALSE(report);
  EXPECT_NE(report.error().find("answered the autobaud 'A' with 0x42 0x41 instead of echoing 0x41"), std::string::npos)
      << report.error();
  EXPECT_EQ(report.error().find("0x41 instead of 0x41"), std::string::npos) << report.error();
}

TEST(FalconFirmwareLoad, RetriesTheHandshakeWithinOneAttempt) {
  const FirmwareImage image = validated(make_boot_image({64}));
  EmulatorOptions o;
  o.handshake_failures = 7;
  FalconEmulator emu(o);
  EmulatorTransport t(emu);
  auto report = load_firmware(t, image);
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report.value().attempts, 1);
}

TEST(FalconFirmwareLoad, BadEchoFailsTheTryAndTheRetrySucceeds) {
  const FirmwareImage image = validated(make_boot_image({500}, 9));
  FalconEmulator emu;
  emu.corrupt_echo_at(321);  // the next load only
  EmulatorTransport t(emu);
  auto report = load_firmware(t, image);
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report.value().attempts, 2);
  ASSERT_EQ(report.value().failures.size(), 1u);
  EXPECT_NE(report.value().failures[0].find("echo mismatch at image byte 321"), std::string::npos)
      << report.value().failures[0];
  EXPECT_EQ(emu.state(), BootState::kRunning);
  EXPECT_EQ(emu.loaded_image(), image.bytes);
}

TEST(FalconFirmwareLoad, UnansweredHandshakeFailsATryAndTheNextSucceeds) {
  const FirmwareImage image = validated(make_boot_image({64}));
  EmulatorOptions o;
  o.handshake_failures = 12;
  FalconEmulator emu(o);
  EmulatorTransport t(emu);
  FirmwareLoadOptions options;
  options.handshake_tries = 10;
  auto report = load_firmware(t, image, options);
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report.value().attempts, 2);
  EXPECT_NE(report.value().failures[0].find("did not answer the handshake"), std::string::npos);
}

TEST(FalconFirmwareLoad, GivesUpAfterTheAttemptsAndListsEveryFailure) {
  const FirmwareImage image = validated(make_boot_image({64}, 4));
  EmulatorOptions o;
  o.accepted_images = {sha256(make_boot_image({64}, 5))};  // this DSP runs only another image
  FalconEmulator emu(o);
  EmulatorTransport t(emu);
  FirmwareLoadOptions options;
  options.attempts = 3;
  auto report = load_firmware(t, image, options);
  ASSERT_FALSE(report);
  EXPECT_EQ(emu.loads_completed(), 3u);
  for (const char* line :
       {"try 1: the whole image was echoed, but the firmware does not answer", "try 2: the whole image was echoed",
        "try 3: the whole image was echoed", "failed after 3 tries", "What to do: unplug the Falcon's power supply"}) {
    EXPECT_NE(report.error().find(line), std::string::npos) << line << "\n" << report.error();
  }
}

TEST(FalconFirmwareLoad, BootLoaderSilentOnABadKeySoTheLoadFails) {
  // The validator never lets such an image through; this checks the emulator and the echo check.
  FirmwareImage image = validated(make_boot_image({64}));
  image.bytes[0] = 0x00;
  FalconEmulator emu;
  EmulatorTransport t(emu);
  FirmwareLoadOptions options;
  options.attempts = 1;
  options.echo_idle_reads = 3;
  auto report = load_firmware(t, image, options);
  ASSERT_FALSE(report);
  EXPECT_NE(report.error().find("no echo from the boot loader after image byte 1"), std::string::npos)
      << report.error();
  EXPECT_EQ(emu.state(), BootState::kRejected);
}

TEST(FalconFirmwareLoad, UnpluggedStopsRetrying) {
  const FirmwareImage image = validated(make_boot_image({64}));
  FalconEmulator emu;
  emu.unplug();
  EmulatorTransport t(emu);
  auto report = load_firmware(t, image);
  ASSERT_FALSE(report);
  EXPECT_NE(report.error().find("failed after 1 try:"), std::string::npos) << report.error();
  EXPECT_NE(report.error().find("no device (unplugged)"), std::string::npos) << report.error();
}

TEST(FalconFirmwareProbe, DetectsFirmwareThatSurvivedAReconnect) {
  EmulatorOptions o;
  o.firmware_loaded = true;
  FalconEmulator emu(o);
  EmulatorTransport t(emu);
  const FirmwareProbe p = probe_firmware(t);
  EXPECT_TRUE(p.loaded);
  EXPECT_EQ(p.transport, TransportStatus::kOk);
  EXPECT_EQ(emu.ftdi().divisor, ftdi::kDivisorNormal) << "the probe runs in normal mode";
  ASSERT_GE(emu.commands_received(), 1u);
  EXPECT_TRUE(emu.last_command().flags & kHomingRequest);
  EXPECT_EQ(emu.last_command().motor, (std::array<std::int16_t, 3>{0, 0, 0}));
}

TEST(FalconFirmwareProbe, NoFirmwareMeansNoValidReplyAfterAllReads) {
  FalconEmulator emu;
  EmulatorTransport t(emu);
  const FirmwareProbe p = probe_firmware(t, 25, 5);
  EXPECT_FALSE(p.loaded);
  EXPECT_EQ(t.reads(), 25u);
  EXPECT_EQ(t.writes(), 5u) << "re-sent every 5 reads";
}

}  // namespace
}  // namespace toonforce::falcon
