// libFuzzer target: the tick (effects plus safety) fed arbitrary doubles as positions,
// velocities and periods, through every bundled scene in every scalar type. Whatever comes
// in, the force that goes out is finite, within max_force, and within the force-rate limit.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "toonforce/config/scene_file.hpp"

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

template <toonforce::Scalar S>
void run(const toonforce::SceneDescription& d, const double* v, std::size_t n) {
  toonforce::Controller ctl(toonforce::make_runtime_scene<S>(d), toonforce::controller_config(d, 0.0));
  const double max_force = d.limits.max_force_n;
  const double max_rate = d.limits.max_force_rate_n_per_s;
  double t = 0.0;
  toonforce::Vec3<double> previous{};
  for (std::size_t i = 0; i + 7 <= n; i += 7) {
    toonforce::Sample s;
    s.position_m = {v[i], v[i + 1], v[i + 2]};
    s.velocity_m_per_s = {v[i + 3], v[i + 4], v[i + 5]};
    s.has_velocity = std::signbit(v[i + 6]);
    // dt: any finite positive period a device could report, from 10 us to 1 s.
    const double dt = std::isfinite(v[i + 6]) ? std::fmin(1.0, std::fmax(1e-5, std::fabs(v[i + 6]))) : 1e-3;
    t += dt;
    s.now = toonforce::Instant{static_cast<std::int64_t>(i), t};
    s.dt_s = dt;
    const auto r = ctl.tick(s);
    const auto f = toonforce::to_double(r.force_n);
    require(std::isfinite(f.x) && std::isfinite(f.y) && std::isfinite(f.z));
    const double magnitude = std::sqrt(toonforce::dot(f, f));
    // Q16.16 rounds each component: allow a few LSB over the limits.
    const double slack = toonforce::kIsFixed<S> ? 1e-3 : (std::is_same_v<S, float> ? 1e-5 : 1e-9);
    require(magnitude <= max_force + slack);
    const auto step = f - previous;
    require(std::sqrt(toonforce::dot(step, step)) <= max_rate * dt + slack || r.faults);
    previous = f;
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
