// SPDX-License-Identifier: Apache-2.0
#include "toonforce/host_sim/sim_driver.hpp"

#include <fmt/format.h>

namespace toonforce::host_sim {

DeviceInfo device_info(const DeviceParams& device, double period_s) {
  DeviceInfo info;
  info.name = fmt::format("{} (host simulation, {:g} Hz)", device.name, 1.0 / period_s);
  info.max_force_n = device.max_force_n;
  info.max_continuous_force_n = device.max_force_n;  // the simulation has no thermal limit
  info.workspace_min_m = device.workspace_min_m;
  info.workspace_max_m = device.workspace_max_m;
  info.nominal_rate_hz = 1.0 / period_s;
  info.clocking = Clocking::kHostTimer;
  return info;
}

Result<std::unique_ptr<SimDriver>> SimDriver::create(const DeviceParams& device, HandIntent intent,
                                                     const PlantOptions& options, std::uint64_t seed) {
  auto sim = SimDevice::create(device, std::move(intent), options, seed);
  if (!sim) return Error{sim.error()};
  return std::unique_ptr<SimDriver>(new SimDriver(std::move(sim).value(), device_info(device, options.period_s)));
}

}  // namespace toonforce::host_sim
