#include "toonforce/host_sim/sim_driver.hpp"

#include <fmt/format.h>

namespace toonforce::host_sim {

Result<std::unique_ptr<SimDriver>> SimDriver::create(const DeviceParams& device, HandIntent intent,
                                                     const PlantOptions& options, std::uint64_t seed) {
  auto sim = SimDevice::create(device, std::move(intent), options, seed);
  if (!sim) return Error{sim.error()};
  DeviceInfo info;
  info.name = fmt::format("{} (host simulation, {:g} Hz)", device.name, 1.0 / options.period_s);
  info.max_force_n = device.max_force_n;
  info.max_continuous_force_n = device.max_force_n;  // the simulation has no thermal limit
  info.workspace_min_m = device.workspace_min_m;
  info.workspace_max_m = device.workspace_max_m;
  info.nominal_rate_hz = 1.0 / options.period_s;
  info.self_clocked = false;
  return std::unique_ptr<SimDriver>(new SimDriver(std::move(sim).value(), std::move(info)));
}

}  // namespace toonforce::host_sim
