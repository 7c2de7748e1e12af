// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: the servo loop's tick fed arbitrary doubles as positions, velocities and
// periods, through every bundled scene in every scalar type, as replay runs it (effects.md §6
// stages, stamped time) and as a device runs it (every stage, fixed period). Whatever comes in,
// the force that goes out is finite, within max_force, and within the force-rate limit unless
// the tick cut it to zero.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"

namespace {

using toonforce::ScalarKind;

struct Scenes {
  std::vector<toonforce::SceneDescription> d, f, q;
};

const Scenes& scenes() {
  static const Scenes all = [] {
    Scenes s;
    for (const char* name : {"wall", "realistic_friction", "slippery", "cartoon_wall", "cliff"}) {
      const std::string path = std::string(TOONFORCE_SOURCE_DIR) + "/scenes/" + name + ".toml";
      s.d.push_back(toonforce::load_scene_file(path, ScalarKind::kDouble).value());
      s.f.push_back(toonforce::load_scene_file(path, ScalarKind::kFloat).value());
      s.q.push_back(toonforce::load_scene_file(path, ScalarKind::kQ16_16).value());
    }
    return s;
  }();
  return all;
}

void require(bool ok) {
  if (!ok) std::abort();  // libFuzzer reports the input
}

/// A device that reports what the fuzzer gives it.
struct FuzzDevice {
  const toonforce::DeviceReading* reading;
  toonforce::DeviceStatus read(toonforce::DeviceReading& r) noexcept {
    r = *reading;
    return toonforce::DeviceStatus::kOk;
  }
  toonforce::DeviceStatus write(const toonforce::Vec3<double>&) noexcept { return toonforce::DeviceStatus::kOk; }
};

/// dt of the values' tick: any finite positive period a device could report, from 10 us to 1 s.
double dt_of(double v) { return std::isfinite(v) ? std::fmin(1.0, std::fmax(1e-5, std::fabs(v))) : 1e-3; }

template <class Loop>
void check(Loop& loop, const toonforce::TickStatus& status, double max_force, double max_rate, double dt,
           toonforce::Vec3<double>& previous) {
  using S = typename Loop::S;
  const auto f = toonforce::to_double(loop.force());
  require(std::isfinite(f.x) && std::isfinite(f.y) && std::isfinite(f.z));
  const double magnitude = std::sqrt(toonforce::dot(f, f));
  // Q16.16 rounds each component: allow a few LSB over the limits.
  const double slack = toonforce::kIsFixed<S> ? 1e-3 : (std::is_same_v<S, float> ? 1e-5 : 1e-9);
  require(magnitude <= max_force + slack);
  const auto step = f - previous;
  const bool cut = status.faults || f == toonforce::Vec3<double>{};  // a cut to zero bypasses the rate limit
  require(std::sqrt(toonforce::dot(step, step)) <= max_rate * dt + slack || cut);
  previous = f;
}

template <toonforce::Scalar S>
void run(const toonforce::SceneDescription& d, const double* v, std::size_t n) {
  if (n < 7) return;
  toonforce::DeviceReading reading;
  const toonforce::RuntimeScene<S> scene = toonforce::make_runtime_scene<S>(d);
  toonforce::ServoLoop<FuzzDevice, toonforce::RuntimeScene<S>, toonforce::NullPins, toonforce::kSpecStages> replayed(
      FuzzDevice{&reading}, scene,
      // The first tick's dt, like every other, to the nanosecond of the loop's stamps, as replay
      // takes it (the check below measures the rate limit against that dt).
      toonforce::replay_config(d, static_cast<double>(toonforce::ns_from_seconds(dt_of(v[6]))) / 1e9));
  toonforce::ServoConfig every = toonforce::servo_config(d, 1e-3);
  every.safety.soft_start_s = 0.0;  // the rate limit is what this checks, from the first tick
  toonforce::ServoLoop<FuzzDevice, toonforce::RuntimeScene<S>> device(FuzzDevice{&reading}, scene, every);
  const double max_force = d.limits.max_force_n;
  const double max_rate = d.limits.max_force_rate_n_per_s;
  std::int64_t t_ns = 0;  // the loop's stamps are whole nanoseconds
  toonforce::Vec3<double> previous_replayed{};
  toonforce::Vec3<double> previous_device{};
  for (std::size_t i = 0; i + 7 <= n; i += 7) {
    reading.position_m = {v[i], v[i + 1], v[i + 2]};
    reading.velocity_m_per_s = {v[i + 3], v[i + 4], v[i + 5]};
    reading.has_velocity = std::signbit(v[i + 6]);
    const std::int64_t dt_ns = toonforce::ns_from_seconds(dt_of(v[i + 6]));
    const double dt = static_cast<double>(dt_ns) / 1e9;
    if (i > 0) t_ns += dt_ns;
    const auto k = static_cast<std::int64_t>(i / 7);
    check(replayed, replayed.tick(toonforce::Instant{k, t_ns}), max_force, max_rate, dt, previous_replayed);
    check(device, device.tick(k), max_force, max_rate, 1e-3, previous_device);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const Scenes& s = scenes();
  const std::size_t scene = data[0] % s.d.size();
  const std::size_t kind = (data[0] / s.d.size()) % 3;
  std::vector<double> values((size - 1) / sizeof(double));
  if (values.empty()) return 0;
  std::memcpy(values.data(), data + 1, values.size() * sizeof(double));
  if (kind == 0) run<double>(s.d[scene], values.data(), values.size());
  if (kind == 1) run<float>(s.f[scene], values.data(), values.size());
  if (kind == 2) run<toonforce::Q16_16>(s.q[scene], values.data(), values.size());
  return 0;
}
