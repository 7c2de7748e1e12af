// SPDX-License-Identifier: Apache-2.0
#include "toonforce/control/world_session.hpp"

#include <fmt/format.h>

namespace toonforce {

Result<std::unique_ptr<DeviceGroup>> DeviceGroup::create(const std::vector<DeviceDriver*>& devices,
                                                         const std::vector<std::string>& names) {
  if (devices.empty() || names.size() != devices.size()) return Error{"a world needs its devices, each named"};
  auto group = std::unique_ptr<DeviceGroup>(new DeviceGroup());
  group->info_ = devices.front()->info();
  group->info_.clocking = Clocking::kHostTimer;
  std::string name;
  for (std::size_t i = 0; i < devices.size(); ++i) {
    const DeviceInfo& info = devices[i]->info();
    if (info.clocking == Clocking::kDeviceThread) {
      return Error{fmt::format(
          "device '{}' ({}) is clocked by its own servo thread; a world ticks every device from one thread on the "
          "host's clock, and a device with its own clock cannot join one yet: run it on its own (a one-device scene)",
          names[i], info.name)};
    }
    name += fmt::format("{}{}: {}", i == 0 ? "" : "; ", names[i], info.name);
  }
  group->info_.name = std::move(name);
  group->devices_ = devices;
  return group;
}

}  // namespace toonforce
