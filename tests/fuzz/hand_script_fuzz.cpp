// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: hand scripts (docs/HAND_SCRIPTS.md). Any bytes must give a planned script or
// errors, never a crash, a sanitizer report or a hang; a script that loads must plan an intent
// that is finite at every instant and drive the simulated device for a few ticks.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/host_sim/sim_device.hpp"

namespace {

void require(bool ok) {
  if (!ok) std::abort();  // libFuzzer reports the input
}

bool finite(const toonforce::Vec3<double>& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto loaded = toonforce::parse_hand_script(text, "fuzz.toml");
  if (!loaded) {
    require(!loaded.error().empty());  // every refusal says why
    return 0;
  }
  const toonforce::host_sim::HandIntent& intent = loaded->intent;
  const double duration = intent.duration_s();
  require(std::isfinite(duration) && duration >= 0.0);
  // The intent at the start, through every segment and past the end.
  for (int i = 0; i <= 64; ++i) {
    const double t = duration * i / 64.0 + (i == 64 ? 1.0 : 0.0);
    const auto target = intent.at(t);
    require(finite(target.position_m) && finite(target.velocity_m_per_s) && finite(target.force_n));
  }
  // A few ticks of the simulated Falcon held by that hand: the plant must accept or refuse it.
  auto device = toonforce::host_sim::SimDevice::create(toonforce::host_sim::falcon_params(), intent,
                                                       {toonforce::host_sim::Integrator::kRk4, 4, 1e-3});
  if (!device) return 0;
  for (int k = 0; k < 20; ++k) {
    toonforce::DeviceReading reading;
    static_cast<void>(device->read(reading));
    static_cast<void>(device->write({0.0, 0.0, 0.5}));
  }
  return 0;
}
