// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: scene files. Any bytes must give a scene or errors, never a crash, a
// sanitizer report or a hang; a scene that loads must build and run a few ticks.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"

namespace {

struct ScriptedDevice {
  const toonforce::Vec3<double>* position;
  toonforce::DeviceStatus read(toonforce::DeviceReading& r) noexcept {
    r.position_m = *position;
    return toonforce::DeviceStatus::kOk;
  }
  toonforce::DeviceStatus write(const toonforce::Vec3<double>&) noexcept { return toonforce::DeviceStatus::kOk; }
};

template <toonforce::Scalar S>
void run(const toonforce::SceneDescription& d) {
  const toonforce::ServoConfig config = toonforce::servo_config(d, 1e-3);
  if (!toonforce::check_servo_config(config).empty()) return;
  toonforce::Vec3<double> x{};
  toonforce::ServoLoop<ScriptedDevice, toonforce::RuntimeScene<S>> loop(ScriptedDevice{&x},
                                                                        toonforce::make_runtime_scene<S>(d), config);
  for (int k = 0; k < 50; ++k) {
    x = {0.001 * k - 0.02, 0.0, 0.01 - 0.0004 * k};
    static_cast<void>(loop.tick(k));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  using toonforce::ScalarKind;
  for (const ScalarKind kind : {ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16}) {
    const auto scene = toonforce::parse_scene(text, "fuzz.toml", kind);
    if (!scene) continue;
    if (kind == ScalarKind::kDouble) run<double>(scene.value());
    if (kind == ScalarKind::kFloat) run<float>(scene.value());
    if (kind == ScalarKind::kQ16_16) run<toonforce::Q16_16>(scene.value());
  }
  return 0;
}
