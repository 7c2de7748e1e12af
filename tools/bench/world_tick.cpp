// SPDX-License-Identifier: Apache-2.0
// The cost of a world's tick (control/world.hpp) with 1, 2 and 4 devices, against the plain
// servo loop: each device on the cartoon wall's scene (every safety stage on), moving through
// it, with a coupling between neighbouring devices and a ball all of them touch. A timed
// program, never a test.
//
//   toonforce_world_bench [Google Benchmark flags]      ns per tick, per device count
//   toonforce_world_bench --ticks N --devices D [--live] runs N world ticks of D devices (0: the
//                                                       plain loop) and exits: under callgrind,
//                                                       the difference of two N gives
//                                                       instructions per tick; --live: the
//                                                       world as `run` builds it (live stages,
//                                                       listening to an empty mailbox)
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/control/world.hpp"

namespace toonforce {
namespace {

/// A fixed path through the floor, computed once (the device's reading costs a copy, not the
/// path's trigonometry: what is counted is the tick).
const std::vector<Vec3<double>>& path() {
  static const std::vector<Vec3<double>> p = [] {
    std::vector<Vec3<double>> v(4096);
    for (std::size_t k = 0; k < v.size(); ++k) {
      const double t = static_cast<double>(k) * 1e-3;
      v[k] = {0.02 * std::sin(3.0 * t), 0.01 * std::cos(2.0 * t), 0.004 * std::sin(7.0 * t) - 0.001};
    }
    return v;
  }();
  return p;
}

/// A device whose handle follows the path, each device from its own place on it.
struct PathDevice {
  std::size_t k = 0;
  Vec3<double> written{};
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = path()[k & 4095U];
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>& f) noexcept {
    written = f;
    ++k;
    return DeviceStatus::kOk;
  }
};

struct Loaded {
  SceneDescription scene;
  ServoConfig config;
};

const Loaded& loaded() {
  static const Loaded l = [] {
    auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/cartoon_wall.toml");
    if (!scene) {
      std::fputs(scene.error().c_str(), stderr);
      std::exit(1);
    }
    ServoConfig c = servo_config(scene.value(), 1e-3);
    c.limits.has_max_force = true;
    c.limits.max_force_n = 8.0;
    return Loaded{scene.value(), c};
  }();
  return l;
}

template <std::size_t N, LoopStages kStages = kEveryStage>
struct Bench {
  using W = World<PathDevice, RuntimeScene<double>, N, kStages>;
  std::array<PathDevice, N> devices{};
  std::unique_ptr<W> world;
  /// A live world listens to an empty mailbox: what `run` pays when no change comes.
  std::unique_ptr<WorldMailbox<RuntimeScene<double>>> mailbox;
  Bench() {
    WorldConfig c;
    for (std::size_t i = 0; i + 1 < N && i < kMaxCouplings; ++i) {
      c.couplings[c.coupling_count++] = {i, i + 1, {150.0, 1.0, 0.0}};
    }
    c.has_ball = true;
    c.ball.start_m = {0.0, 0.0, 0.01};
    static_cast<void>(between::check_and_normalise(c.ball));
    const RuntimeScene<double> scene = make_runtime_scene<double>(loaded().scene);
    std::array<typename W::Member, N> members = [&]<std::size_t... I>(std::index_sequence<I...>) {
      return std::array<typename W::Member, N>{
          typename W::Member{&devices[I], scene, DeviceFrame::yaw(0.3 * I), loaded().config}...};
    }
    (std::make_index_sequence<N>{});
    for (std::size_t i = 0; i < N; ++i) devices[i].k = 700 * i;
    world = std::make_unique<W>(members, c);
    if constexpr (kStages.live) {
      mailbox = std::make_unique<WorldMailbox<RuntimeScene<double>>>();
      world->listen(*mailbox);
    }
  }
};

template <std::size_t N>
void world_tick(benchmark::State& state) {
  Bench<N> b;
  std::int64_t k = 0;
  for (auto _ : state) benchmark::DoNotOptimize(b.world->tick(k++));
  state.counters["devices"] = static_cast<double>(N);
}

void loop_tick(benchmark::State& state) {
  ServoLoop<PathDevice, RuntimeScene<double>> loop(PathDevice{}, make_runtime_scene<double>(loaded().scene),
                                                   loaded().config);
  std::int64_t k = 0;
  for (auto _ : state) benchmark::DoNotOptimize(loop.tick(k++));
}

BENCHMARK(loop_tick);
BENCHMARK(world_tick<1>);
BENCHMARK(world_tick<2>);
BENCHMARK(world_tick<4>);

template <std::size_t N, LoopStages kStages = kEveryStage>
std::uint64_t run_ticks(std::int64_t ticks) {
  Bench<N, kStages> b;
  std::uint64_t sum = 0;
  for (std::int64_t k = 0; k < ticks; ++k) sum += b.world->tick(k).devices[0].limits;
  return sum;
}

/// The plain servo loop on the same device and scene (the comparison).
std::uint64_t run_loop_ticks(std::int64_t ticks) {
  ServoLoop<PathDevice, RuntimeScene<double>> loop(PathDevice{}, make_runtime_scene<double>(loaded().scene),
                                                   loaded().config);
  std::uint64_t sum = 0;
  for (std::int64_t k = 0; k < ticks; ++k) sum += loop.tick(k).limits;
  return sum;
}

}  // namespace
}  // namespace toonforce

int main(int argc, char** argv) {
  const bool live = argc == 6 && std::strcmp(argv[5], "--live") == 0;
  if ((argc == 5 || live) && std::strcmp(argv[1], "--ticks") == 0 && std::strcmp(argv[3], "--devices") == 0) {
    using toonforce::kLiveStages;
    const std::int64_t ticks = std::atoll(argv[2]);
    const int devices = std::atoi(argv[4]);
    std::uint64_t sum = 0;
    switch (devices) {
      case 0: sum = toonforce::run_loop_ticks(ticks); break;  // no world: the loop alone
      case 1: sum = live ? toonforce::run_ticks<1, kLiveStages>(ticks) : toonforce::run_ticks<1>(ticks); break;
      case 2: sum = live ? toonforce::run_ticks<2, kLiveStages>(ticks) : toonforce::run_ticks<2>(ticks); break;
      case 4: sum = live ? toonforce::run_ticks<4, kLiveStages>(ticks) : toonforce::run_ticks<4>(ticks); break;
      default: std::fputs("--devices 0 (the loop alone), 1, 2 or 4 [--live]\n", stderr); return 2;
    }
    std::printf("%llu\n", static_cast<unsigned long long>(sum));
    return 0;
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
