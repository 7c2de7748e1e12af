// SPDX-License-Identifier: Apache-2.0
// FTDI mode sequences (FALCON.md §1 "Open sequence", §2.1 steps 1-2 and 6).
#include "toonforce/hal/falcon/ftdi.hpp"

#include <initializer_list>
#include <utility>

namespace toonforce::falcon::ftdi {
namespace {

TransportStatus run(FalconTransport& t,
                    std::initializer_list<std::pair<std::uint8_t, std::uint16_t>> requests) noexcept {
  for (const auto& [request, value] : requests) {
    const TransportStatus s = t.control(request, value);
    if (s != TransportStatus::kOk) return s;
  }
  return TransportStatus::kOk;
}

}  // namespace

TransportStatus purge(FalconTransport& t) noexcept { return run(t, {{kReset, kPurgeRx}, {kReset, kPurgeTx}}); }

TransportStatus enter_normal_mode(FalconTransport& t) noexcept {
  return run(t, {{kLatencyTimer, kLatencyNormalMs},
                 {kBaudDivisor, kDivisorNormal},
                 {kDataFormat, k8N1},
                 {kFlowControl, kFlowNone},
                 {kReset, kPurgeRx},
                 {kReset, kPurgeTx}});
}

TransportStatus enter_firmware_mode(FalconTransport& t) noexcept {
  return run(t, {{kReset, kPurgeRx},
                 {kReset, kPurgeTx},
                 {kLatencyTimer, kLatencyFirmwareMs},
                 {kBaudDivisor, kDivisor9600},
                 {kDataFormat, k8N1},
                 {kFlowControl, kFlowNone},
                 {kModemControl, kRtsLow},
                 {kModemControl, kDtrLow},
                 {kModemControl, kDtrHigh}});
}

}  // namespace toonforce::falcon::ftdi
