// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: world scene files. Any bytes must give a world or errors, never a crash, a
// sanitizer report or a hang; a world that loads must build and run a few ticks of every
// device, the forces between them included.
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string_view>
#include <utility>

#include "toonforce/config/world_file.hpp"
#include "toonforce/control/world.hpp"

namespace {

struct ScriptedDevice {
  toonforce::Vec3<double> position;
  toonforce::DeviceStatus read(toonforce::DeviceReading& r) noexcept {
    r.position_m = position;
    return toonforce::DeviceStatus::kOk;
  }
  toonforce::DeviceStatus write(const toonforce::Vec3<double>&) noexcept { return toonforce::DeviceStatus::kOk; }
};

template <std::size_t N>
void run(const toonforce::WorldDescription& w) {
  using World = toonforce::World<ScriptedDevice, toonforce::RuntimeScene<double>, N>;
  std::array<ScriptedDevice, N> devices{};
  std::array<toonforce::ServoConfig, N> configs{};
  for (std::size_t i = 0; i < N; ++i) {
    configs[i] = toonforce::servo_config(w.devices[i].settings, 1e-3);
    if (!toonforce::check_servo_config(configs[i]).empty()) return;
  }
  toonforce::WorldConfig config = toonforce::world_config(w);
  if (!toonforce::check(config, N).empty()) return;
  const toonforce::RuntimeScene<double> scene = toonforce::make_runtime_scene<double>(w.scene);
  auto world = [&]<std::size_t... I>(std::index_sequence<I...>) {
    return std::make_unique<World>(std::array<typename World::Member, N>{typename World::Member{
                                       &devices[I], scene, w.devices[I].frame, configs[I]}...},
                                   config);
  }
  (std::make_index_sequence<N>{});
  for (int k = 0; k < 50; ++k) {
    for (std::size_t i = 0; i < N; ++i) {
      const double s = static_cast<double>(i) + 1.0;
      devices[i].position = {0.001 * k * s - 0.02, 0.0005 * s, 0.01 - 0.0004 * k};
    }
    static_cast<void>(world->tick(k));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  static_cast<void>(toonforce::is_world_text(text));
  const auto world = toonforce::parse_world(text, "fuzz.toml");
  if (!world) return 0;
  switch (world->devices.size()) {
    case 1: run<1>(world.value()); break;
    case 2: run<2>(world.value()); break;
    case 3: run<3>(world.value()); break;
    case 4: run<4>(world.value()); break;
    default: break;
  }
  return 0;
}
