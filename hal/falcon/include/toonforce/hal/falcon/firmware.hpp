// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Falcon firmware: checking a file the user supplies and loading it into the DSP's RAM.
/// toonforce never ships firmware (Novint's licence forbids redistribution, FALCON.md §2.3):
/// the user gives the file from a Novint or nVent driver install, and it is loaded only if its
/// size, its C28x boot-table structure and its SHA-256 match a known image (FALCON.md §2.2).
/// The load follows libnifalcon's libusb sequence (FALCON.md §2.1) over a FalconTransport and
/// retries the whole sequence on failure; detection of loaded firmware follows §2.4.
/// Start-up code: allocates, may take seconds; never called from a tick.

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/hal/falcon/transport.hpp"

namespace toonforce::falcon {

using Sha256 = std::array<std::uint8_t, 32>;

/// SHA-256 through Debian's libnettle (see firmware.cpp for why not our own).
Sha256 sha256(std::span<const std::uint8_t> bytes) noexcept;
std::string to_hex(const Sha256& digest);
/// Parses 64 hex digits; false on anything else.
bool parse_sha256_hex(std::string_view hex, Sha256& out) noexcept;

/// An image the loader accepts.
struct KnownFirmware {
  std::string_view name;  ///< "nvent_firmware.bin"
  std::size_t size_bytes;
  Sha256 sha256;
  std::string_view origin;  ///< where users find it
};

/// The four images of FALCON.md §2.2 (sizes and SHA-256 only: no content is shipped).
std::span<const KnownFirmware> known_firmware_images() noexcept;

/// What the boot table holds (FALCON.md §2.1 "Derived": key 0x08AA, 8 reserved words, a
/// 32-bit entry point stored high word first, blocks of (length in words, 32-bit destination,
/// data), a zero-length block, no trailing bytes; all words little-endian).
struct BootTable {
  std::uint32_t entry_point = 0;
  std::size_t blocks = 0;      ///< data blocks, not counting the terminator
  std::size_t data_words = 0;  ///< 16-bit words over all blocks
};
inline constexpr std::uint16_t kBootTableKey = 0x08AA;
inline constexpr std::uint32_t kFalconEntryPoint = 0x003F8002;            ///< all four known images
inline constexpr std::size_t kMaxFirmwareBytes = std::size_t{64} * 1024;  ///< the known ones are < 9 KiB

/// Checks the boot-table structure; the error says which byte offset is wrong and why.
Result<BootTable> parse_boot_table(std::span<const std::uint8_t> image);

/// A firmware image that passed every check, ready to load.
struct FirmwareImage {
  std::vector<std::uint8_t> bytes;
  BootTable table;
  Sha256 digest{};
  std::string name;  ///< the matching known image's name
};

/// Size, then structure, then SHA-256 against `allowlist`, in that order (each error says what
/// was expected). `source` names the file in messages.
Result<FirmwareImage> validate_firmware(std::vector<std::uint8_t> bytes, std::string_view source,
                                        std::span<const KnownFirmware> allowlist = known_firmware_images());

/// Reads `path` (refusing anything above kMaxFirmwareBytes before reading it) and validates it.
Result<FirmwareImage> read_firmware_file(const std::string& path,
                                         std::span<const KnownFirmware> allowlist = known_firmware_images());

struct FirmwareLoadOptions {
  int attempts = 5;                 ///< whole-sequence tries (libnifalcon's callers use 10)
  int handshake_tries = 100;        ///< "\nC\r" probes per attempt (FALCON.md §2.1 step 3)
  std::uint32_t timeout_ms = 1000;  ///< per USB transfer (FALCON.md §2.1)
  int echo_idle_reads = 30;         ///< bulk reads without new echo bytes before giving up
  /// Called after each chunk with (bytes echoed, total) and on each new attempt; may be empty.
  std::function<void(std::size_t done, std::size_t total, int attempt)> progress;
};

struct FirmwareLoadReport {
  int attempts = 0;                   ///< tries used, including the successful one
  std::vector<std::string> failures;  ///< one line per failed try, oldest first
};

/// Loads `image` into the Falcon (FALCON.md §2.1): firmware mode, handshake, autobaud 'A',
/// 62-byte chunks each echoed byte for byte, then normal mode and the §2.4 probe to confirm the
/// firmware answers. Retries the whole sequence up to options.attempts times. The error lists
/// every try's failure and what to do.
Result<FirmwareLoadReport> load_firmware(FalconTransport& transport, const FirmwareImage& image,
                                         const FirmwareLoadOptions& options = {});

/// FALCON.md §2.4: in normal mode, sends an idle command (homing bit held, forces zero) and
/// waits for one well-formed 16-byte reply, re-sending every `resend_every` reads. Without
/// firmware nothing valid comes back. Leaves the FTDI in normal mode.
struct FirmwareProbe {
  bool loaded = false;
  TransportStatus transport = TransportStatus::kOk;  ///< first USB error, if any
};
FirmwareProbe probe_firmware(FalconTransport& transport, int max_reads = 60, int resend_every = 10,
                             std::uint32_t timeout_ms = 100) noexcept;

}  // namespace toonforce::falcon
