// SPDX-License-Identifier: Apache-2.0
#pragma once
/// FTDI set-up of the Falcon's USB-serial bridge through vendor requests (libftdi's request
/// numbers, the values libnifalcon's libusb path uses; FALCON.md §1 and §2.1). Two modes:
/// "normal" (1.5 Mbaud, 1 ms latency: the 1 kHz runtime link) and "firmware" (9600 baud,
/// 16 ms latency, DTR pulsed: the DSP's boot loader). Start-up code, not the tick.

#include <cstdint>

#include "toonforce/hal/falcon/transport.hpp"

namespace toonforce::falcon::ftdi {

// Request numbers (bRequest).
inline constexpr std::uint8_t kReset = 0;         ///< value: kPurgeRx / kPurgeTx
inline constexpr std::uint8_t kModemControl = 1;  ///< value: kDtr* / kRts*
inline constexpr std::uint8_t kFlowControl = 2;   ///< value: kFlowNone
inline constexpr std::uint8_t kBaudDivisor = 3;   ///< value: a divisor of the 3 MHz base
inline constexpr std::uint8_t kDataFormat = 4;    ///< value: k8N1
inline constexpr std::uint8_t kLatencyTimer = 9;  ///< value: milliseconds

inline constexpr std::uint16_t kPurgeRx = 1;
inline constexpr std::uint16_t kPurgeTx = 2;
inline constexpr std::uint16_t kDtrHigh = 0x0101;
inline constexpr std::uint16_t kDtrLow = 0x0100;
inline constexpr std::uint16_t kRtsHigh = 0x0202;
inline constexpr std::uint16_t kRtsLow = 0x0200;
inline constexpr std::uint16_t kFlowNone = 0;
inline constexpr std::uint16_t k8N1 = 0x0008;
/// Divisors (FALCON.md §1, Derived): 312.5 -> exactly 9600 baud; 21 -> ~142857 baud (the
/// boot loader's autobaud rate); 2 -> 1.5 Mbaud (normal mode).
inline constexpr std::uint16_t kDivisor9600 = 0x4138;
inline constexpr std::uint16_t kDivisor140k = 0x0015;
inline constexpr std::uint16_t kDivisorNormal = 0x0002;
inline constexpr std::uint16_t kLatencyNormalMs = 1;
inline constexpr std::uint16_t kLatencyFirmwareMs = 16;  ///< "firmware checks fail otherwise"

/// Purges the FTDI's receive and transmit buffers.
TransportStatus purge(FalconTransport& t) noexcept;

/// Normal mode: latency 1 ms, divisor 0x0002, 8N1, no flow control, purge RX and TX
/// (libnifalcon's setNormalMode plus 8N1/flow, which persist from firmware mode there but are
/// set explicitly here so a device left in any state comes up the same).
TransportStatus enter_normal_mode(FalconTransport& t) noexcept;

/// Firmware mode, FALCON.md §2.1 steps 1-2: purge, latency 16 ms, 9600 baud, 8N1, no flow
/// control, RTS low, DTR low, then DTR high (which, by inference, releases the DSP's reset).
TransportStatus enter_firmware_mode(FalconTransport& t) noexcept;

}  // namespace toonforce::falcon::ftdi
