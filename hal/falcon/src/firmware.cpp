// SPDX-License-Identifier: Apache-2.0
// Firmware checks and loading (FALCON.md §2). See firmware.hpp for the contract.
//
// SHA-256 comes from Debian's libnettle (nettle-dev) rather than our own: nettle is a small C
// library with a three-call API (init/update/digest), no global initialisation (unlike
// gcrypt's gcry_check_version) and no deprecation churn (OpenSSL 3 deprecated SHA256_Init;
// its EVP API allocates), it is already on every Debian system as a GnuTLS dependency, and
// a hash we use as a gate for code loaded into a motor controller should come from audited
// code, not from a fresh reimplementation.
#include "toonforce/hal/falcon/firmware.hpp"

#include <nettle/sha2.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sys/stat.h>

#include "toonforce/hal/falcon/ftdi.hpp"
#include "toonforce/hal/falcon/protocol.hpp"

namespace toonforce::falcon {
namespace {

constexpr int hex_value(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

constexpr Sha256 digest_of(std::string_view hex) {
  Sha256 d{};
  for (std::size_t i = 0; i < d.size(); ++i) {
    d[i] = static_cast<std::uint8_t>(hex_value(hex[2 * i]) * 16 + hex_value(hex[2 * i + 1]));
  }
  return d;
}

// FALCON.md §2.2 (sizes and SHA-256 "Derived" there from the libnifalcon repository's files).
constexpr std::array<KnownFirmware, 4> kKnown{{
    {"nvent_firmware.bin", 8492, digest_of("1119e39c39fab1f37678ea62dfc715b23dd86ee7f13d78f88f707d9f09b896a1"),
     "the nVent driver release; libnifalcon recommends it"},
    {"test_firmware.bin", 7324, digest_of("b2700d5cd5ca217e48565fb4de5a502a636c53f6e01ebd0cad193e9f84856c6a"),
     "novint.bin from the Novint driver's TestUtilities"},
    {"novint_T0.bin", 7914, digest_of("ae838730af34b5822c9c3949859b446614af0410730b832cc17a6ad627ea64a4"),
     "Novint driver install (origin and purpose undocumented)"},
    {"novint_T2.bin", 7914, digest_of("e0ae3598670fa1c8d9277bd6943c99b3152b97c400c46c1c42c60de77ff4e816"),
     "Novint driver install (same layout as T0, different content)"},
}};

std::uint16_t word_at(std::span<const std::uint8_t> image, std::size_t word) noexcept {
  return static_cast<std::uint16_t>(image[2 * word] | (image[2 * word + 1] << 8));
}

std::string hex_word(std::uint32_t v, int digits) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%0*X", digits, v);
  return buf;
}

std::string sizes_of(std::span<const KnownFirmware> allowlist) {
  std::string out;
  for (const auto& k : allowlist) {
    if (!out.empty()) out += ", ";
    out += std::to_string(k.size_bytes) + " (" + std::string(k.name) + ")";
  }
  return out;
}

constexpr std::uint32_t kOneRead = 64;  // one full-speed packet: 2 status + 62 payload bytes

}  // namespace

Sha256 sha256(std::span<const std::uint8_t> bytes) noexcept {
  sha256_ctx ctx;
  sha256_init(&ctx);
  sha256_update(&ctx, bytes.size(), bytes.data());
  Sha256 out{};
  sha256_digest(&ctx, out.size(), out.data());
  return out;
}

std::string to_hex(const Sha256& digest) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  out.reserve(64);
  for (const std::uint8_t b : digest) {
    out += kDigits[b >> 4];
    out += kDigits[b & 0xF];
  }
  return out;
}

bool parse_sha256_hex(std::string_view hex, Sha256& out) noexcept {
  if (hex.size() != 64) return false;
  Sha256 d{};
  for (std::size_t i = 0; i < d.size(); ++i) {
    const int hi = hex_value(hex[2 * i]);
    const int lo = hex_value(hex[2 * i + 1]);
    if (hi < 0 || lo < 0) return false;
    d[i] = static_cast<std::uint8_t>(hi * 16 + lo);
  }
  out = d;
  return true;
}

std::span<const KnownFirmware> known_firmware_images() noexcept { return kKnown; }

Result<BootTable> parse_boot_table(std::span<const std::uint8_t> image) {
  constexpr std::size_t kHeaderWords = 1 + 8 + 2;  // key, 8 reserved, entry point
  if (image.size() % 2 != 0) {
    return Error{"its size (" + std::to_string(image.size()) +
                 " bytes) is odd; a C28x boot table is made of 16-bit words"};
  }
  const std::size_t words = image.size() / 2;
  if (words < kHeaderWords + 1) {
    return Error{"it is too short (" + std::to_string(image.size()) +
                 " bytes) for a boot table: key, 8 reserved words, entry point, terminator"};
  }
  if (word_at(image, 0) != kBootTableKey) {
    return Error{"byte 0: the boot table key is " + hex_word(word_at(image, 0), 4) +
                 "; a C28x boot table starts with 0x08AA (bytes AA 08)"};
  }
  BootTable table;
  // The entry point is stored high 16-bit word first, each word little-endian.
  table.entry_point = (static_cast<std::uint32_t>(word_at(image, 9)) << 16) | word_at(image, 10);
  if (table.entry_point != kFalconEntryPoint) {
    return Error{"byte 18: the entry point is " + hex_word(table.entry_point, 8) +
                 "; every known Falcon image starts at 0x003F8002"};
  }
  std::size_t at = kHeaderWords;
  while (at < words) {
    const std::size_t length = word_at(image, at);
    if (length == 0) {
      ++at;
      if (at != words) {
        return Error{"byte " + std::to_string(2 * at) + ": " + std::to_string(image.size() - 2 * at) +
                     " bytes follow the terminating zero-length block; a boot table ends there"};
      }
      return table;
    }
    if (at + 3 + length > words) {
      return Error{"byte " + std::to_string(2 * at) + ": block " + std::to_string(table.blocks + 1) + " claims " +
                   std::to_string(length) + " words but the file ends after " +
                   std::to_string(words - std::min(words, at + 3)) + " more"};
    }
    ++table.blocks;
    table.data_words += length;
    at += 3 + length;
  }
  return Error{"the file ends without the terminating zero-length block"};
}

Result<FirmwareImage> validate_firmware(std::vector<std::uint8_t> bytes, std::string_view source,
                                        std::span<const KnownFirmware> allowlist) {
  const std::string src(source);
  const bool size_known = std::any_of(allowlist.begin(), allowlist.end(),
                                      [&](const KnownFirmware& k) { return k.size_bytes == bytes.size(); });
  if (!size_known) {
    return Error{src + " is " + std::to_string(bytes.size()) +
                 " bytes, which is not the size of any known Falcon firmware image: " + sizes_of(allowlist) +
                 " bytes. Copy the firmware file from a Novint or nVent driver install (see docs/FALCON.md)."};
  }
  auto table = parse_boot_table(bytes);
  if (!table) {
    return Error{src + " is not a Falcon firmware image: " + table.error() +
                 ". Copy the firmware file from a Novint or nVent driver install (see docs/FALCON.md)."};
  }
  const Sha256 digest = sha256(bytes);
  const auto match =
      std::find_if(allowlist.begin(), allowlist.end(), [&](const KnownFirmware& k) { return k.sha256 == digest; });
  if (match == allowlist.end()) {
    std::string same_size;
    for (const auto& k : allowlist) {
      if (k.size_bytes == bytes.size()) same_size += std::string(same_size.empty() ? "" : ", ") + std::string(k.name);
    }
    return Error{src + " has SHA-256 " + to_hex(digest) + ", which matches no known Falcon firmware image. " +
                 "It has the size of " + same_size +
                 " but different contents: a damaged or modified copy. toonforce loads only the known images "
                 "into the device; copy the file again from a Novint or nVent driver install."};
  }
  FirmwareImage image;
  image.bytes = std::move(bytes);
  image.table = table.value();
  image.digest = digest;
  image.name = std::string(match->name);
  return image;
}

Result<FirmwareImage> read_firmware_file(const std::string& path, std::span<const KnownFirmware> allowlist) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    return Error{"cannot read firmware file " + path + ": it does not exist or is not accessible"};
  }
  if (!S_ISREG(st.st_mode)) return Error{"firmware file " + path + " is not a regular file"};
  if (static_cast<std::uint64_t>(st.st_size) > kMaxFirmwareBytes) {
    return Error{path + " is " + std::to_string(st.st_size) + " bytes; Falcon firmware images are under " +
                 std::to_string(kMaxFirmwareBytes / 1024) + " KiB (" + sizes_of(allowlist) + " bytes)"};
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{"cannot open firmware file " + path + " for reading"};
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(st.st_size));
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (in.gcount() != static_cast<std::streamsize>(bytes.size()))
    return Error{"error while reading firmware file " + path};
  return validate_firmware(std::move(bytes), path, allowlist);
}

FirmwareProbe probe_firmware(FalconTransport& transport, int max_reads, int resend_every,
                             std::uint32_t timeout_ms) noexcept {
  FirmwareProbe probe;
  if (const auto s = ftdi::enter_normal_mode(transport); s != TransportStatus::kOk) {
    probe.transport = s;
    return probe;
  }
  Command idle;
  idle.flags = kHomingRequest;  // the homing bit is held in every command (FALCON.md §4)
  const Frame frame = encode_command(idle);
  FrameAssembler assembler;
  std::array<std::uint8_t, kOneRead> raw{};
  std::array<std::uint8_t, kOneRead> payload{};
  for (int i = 0; i < max_reads; ++i) {
    if (resend_every > 0 && i % resend_every == 0) {
      std::size_t written = 0;
      const auto s = transport.write(frame, written, timeout_ms);
      if (s != TransportStatus::kOk) {
        probe.transport = s;
        return probe;
      }
    }
    std::size_t received = 0;
    const auto s = transport.read(raw, received, timeout_ms);
    if (s == TransportStatus::kTimeout) continue;
    if (s != TransportStatus::kOk) {
      probe.transport = s;
      return probe;
    }
    assembler.push(std::span(payload).first(strip_ftdi_status(std::span(raw).first(received), payload)));
    Status status;
    if (assembler.pop_status(status)) {
      probe.loaded = true;
      return probe;
    }
  }
  return probe;
}

namespace {

/// One firmware-load attempt; returns an empty string on success, else what failed.
class Loader {
 public:
  Loader(FalconTransport& t, const FirmwareImage& image, const FirmwareLoadOptions& o, int attempt)
      : t_(t), image_(image), o_(o), attempt_(attempt) {}

  std::string run() {
    if (auto s = ftdi::enter_firmware_mode(t_); s != TransportStatus::kOk) return usb("setting firmware mode", s);
    if (auto e = handshake(); !e.empty()) return e;
    if (auto e = autobaud(); !e.empty()) return e;
    if (auto e = stream(); !e.empty()) return e;
    // FALCON.md §2.1 step 6, then §2.4 to confirm the firmware runs.
    if (auto s = ftdi::enter_normal_mode(t_); s != TransportStatus::kOk) return usb("returning to normal mode", s);
    const FirmwareProbe probe = probe_firmware(t_);
    if (probe.transport != TransportStatus::kOk) return usb("checking the loaded firmware", probe.transport);
    if (!probe.loaded) return "the whole image was echoed, but the firmware does not answer commands";
    return {};
  }

  TransportStatus last_usb_error() const noexcept { return last_usb_; }

 private:
  std::string usb(const char* what, TransportStatus s) {
    last_usb_ = s;
    return std::string("USB error while ") + what + ": " + std::string(to_string(s));
  }

  /// Reads one packet's payload into out; returns its size, or -1 on a USB error (recorded).
  std::ptrdiff_t read_payload(std::span<std::uint8_t> out, std::string& error) {
    std::array<std::uint8_t, 512> raw{};  // libnifalcon reads up to 512 here (§2.1 step 3)
    std::size_t received = 0;
    const auto s = t_.read(std::span(raw).first(std::min<std::size_t>(raw.size(), 64 * ((out.size() + 61) / 62))),
                           received, o_.timeout_ms);
    if (s == TransportStatus::kTimeout) return 0;
    if (s != TransportStatus::kOk) {
      error = usb("reading", s);
      return -1;
    }
    return static_cast<std::ptrdiff_t>(strip_ftdi_status(std::span(raw).first(received), out));
  }

  TransportStatus write_all(std::span<const std::uint8_t> bytes) {
    std::size_t written = 0;
    const auto s = t_.write(bytes, written, o_.timeout_ms);
    if (s == TransportStatus::kOk && written != bytes.size()) return TransportStatus::kIoError;
    return s;
  }

  // FALCON.md §2.1 step 3: "\nC\r" until the boot ROM answers "\nD,\r" (Linux) or
  // "\0\nD,\r" (Apple). Both contain "\nD,\r"; it is accepted wherever it appears in this
  // try's payload, since at 9600 baud and a 16 ms latency a reply can trail into the next read.
  std::string handshake() {
    static constexpr std::array<std::uint8_t, 3> kHello{0x0A, 0x43, 0x0D};
    static constexpr std::array<std::uint8_t, 4> kAnswer{0x0A, 0x44, 0x2C, 0x0D};
    for (int attempt = 0; attempt < o_.handshake_tries; ++attempt) {
      if (auto s = write_all(kHello); s != TransportStatus::kOk) return usb("sending the boot handshake", s);
      std::array<std::uint8_t, 512> got{};
      std::size_t have = 0;
      for (int r = 0; r < 4 && have < got.size(); ++r) {  // a few latency periods per try
        std::string error;
        const auto n = read_payload(std::span(got).subspan(have), error);
        if (n < 0) return error;
        have += static_cast<std::size_t>(n);
        if (std::search(got.begin(), got.begin() + static_cast<std::ptrdiff_t>(have), kAnswer.begin(), kAnswer.end()) !=
            got.begin() + static_cast<std::ptrdiff_t>(have)) {
          return {};
        }
      }
    }
    return "the boot loader did not answer the handshake (\"\\nC\\r\" -> \"\\nD,\\r\") in " +
           std::to_string(o_.handshake_tries) + " tries";
  }

  // FALCON.md §2.1 step 4: DTR low, ~140 kbaud, 'A' echoed (the C28x SCI autobaud). The echo is
  // the first byte of the answer, after one leading 0x13 that an FTD2XX comment reports ("0x13
  // 0x41"). Bytes after the echo answer nothing we sent (nothing else is on the line yet): they
  // are dropped with this read, so they can never be taken for the image's echo.
  std::string autobaud() {
    if (auto s = t_.control(ftdi::kModemControl, ftdi::kDtrLow); s != TransportStatus::kOk) return usb("DTR low", s);
    if (auto s = t_.control(ftdi::kBaudDivisor, ftdi::kDivisor140k); s != TransportStatus::kOk) {
      return usb("setting 140 kbaud", s);
    }
    // Late handshake answers must not be mistaken for the echo.
    if (auto s = t_.control(ftdi::kReset, ftdi::kPurgeRx); s != TransportStatus::kOk) return usb("purging", s);
    static constexpr std::uint8_t kEcho = 0x41;
    static constexpr std::uint8_t kLeading = 0x13;
    static constexpr std::array<std::uint8_t, 1> kAutobaud{kEcho};
    if (auto s = write_all(kAutobaud); s != TransportStatus::kOk) return usb("sending the autobaud 'A'", s);
    std::array<std::uint8_t, 8> got{};
    std::size_t have = 0;
    for (int r = 0; r < o_.echo_idle_reads && have < got.size(); ++r) {
      std::string error;
      const auto n = read_payload(std::span(got).subspan(have, got.size() - have), error);
      if (n < 0) return error;
      have += static_cast<std::size_t>(n);
      const std::size_t echo_at = have > 0 && got[0] == kLeading ? 1 : 0;
      if (have > echo_at) {
        if (got[echo_at] == kEcho) return {};
        break;
      }
    }
    if (have == 0) return "the boot loader did not echo the autobaud character 'A'";
    std::string answer;
    for (std::size_t i = 0; i < have; ++i) {
      if (i > 0) answer += ' ';
      answer += hex_word(got[i], 2);
    }
    return "the boot loader answered the autobaud 'A' with " + answer +
           " instead of echoing 0x41 (alone or after 0x13)";
  }

  // FALCON.md §2.1 step 5: 62-byte chunks, each echoed byte for byte before the next.
  std::string stream() {
    constexpr std::size_t kChunk = 62;
    const auto& bytes = image_.bytes;
    for (std::size_t at = 0; at < bytes.size(); at += kChunk) {
      const auto chunk = std::span(bytes).subspan(at, std::min(kChunk, bytes.size() - at));
      if (auto s = write_all(chunk); s != TransportStatus::kOk) {
        return usb(("sending image bytes " + std::to_string(at) + "..").c_str(), s);
      }
      std::size_t echoed = 0;
      int idle = 0;
      while (echoed < chunk.size()) {
        std::array<std::uint8_t, kChunk> got{};
        std::string error;
        const auto n = read_payload(std::span(got).first(chunk.size() - echoed), error);
        if (n < 0) return error;
        if (n == 0) {
          if (++idle >= o_.echo_idle_reads) {
            return "no echo from the boot loader after image byte " + std::to_string(at + echoed) + " of " +
                   std::to_string(bytes.size());
          }
          continue;
        }
        idle = 0;
        for (std::ptrdiff_t i = 0; i < n; ++i) {
          const std::size_t offset = at + echoed;
          if (got[static_cast<std::size_t>(i)] != bytes[offset]) {
            return "echo mismatch at image byte " + std::to_string(offset) + ": sent " + hex_word(bytes[offset], 2) +
                   ", the boot loader echoed " + hex_word(got[static_cast<std::size_t>(i)], 2);
          }
          ++echoed;
        }
      }
      if (o_.progress) o_.progress(at + chunk.size(), bytes.size(), attempt_);
    }
    return {};
  }

  FalconTransport& t_;
  const FirmwareImage& image_;
  const FirmwareLoadOptions& o_;
  int attempt_;
  TransportStatus last_usb_ = TransportStatus::kOk;
};

}  // namespace

Result<FirmwareLoadReport> load_firmware(FalconTransport& transport, const FirmwareImage& image,
                                         const FirmwareLoadOptions& options) {
  FirmwareLoadReport report;
  const int attempts = std::max(1, options.attempts);
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    report.attempts = attempt;
    if (options.progress) options.progress(0, image.bytes.size(), attempt);
    Loader loader(transport, image, options, attempt);
    const std::string failure = loader.run();
    if (failure.empty()) return report;
    report.failures.push_back(failure);
    const auto usb = loader.last_usb_error();
    if (usb == TransportStatus::kNoDevice || usb == TransportStatus::kAccessDenied) break;  // retrying cannot help
  }
  std::string message = "loading firmware " + image.name + " into the Novint Falcon at " +
                        std::string(transport.location()) + " failed after " + std::to_string(report.attempts) +
                        (report.attempts == 1 ? " try:\n" : " tries:\n");
  for (std::size_t i = 0; i < report.failures.size(); ++i) {
    message += "  try " + std::to_string(i + 1) + ": " + report.failures[i] + "\n";
  }
  message += "What to do: unplug the Falcon's power supply and USB cable, plug them back in (directly into the "
             "computer, not through a hub), wait two seconds and run `toonforce falcon firmware FILE` again. "
             "Loads often fail the first time on a real Falcon (docs/FALCON.md, \"Firmware\").";
  return Error{message};
}

}  // namespace toonforce::falcon
