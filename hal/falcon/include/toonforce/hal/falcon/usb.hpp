// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The Falcon's USB link alone, over libusb-1.0: found and claimed as open_falcon() does, but
/// without FTDI set-up or firmware checks. For tools and tests that drive the transport
/// directly (firmware loading against a test allowlist, bring-up). open_falcon() remains the
/// entry point for running a device.

#include <memory>

#include "toonforce/common/result.hpp"
#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/falcon/transport.hpp"

namespace toonforce::falcon {

/// Selects by options.serial, else options.index; errors say which device and how to fix it.
Result<std::unique_ptr<FalconTransport>> open_falcon_transport(const FalconOptions& options);

}  // namespace toonforce::falcon
