// SPDX-License-Identifier: Apache-2.0
// Embedding toonforce, 2 of 3: a scene from a TOML file, loaded and checked through the library
// (toonforce::config), run by the servo loop with the scene's own safety settings on the
// simulated Falcon, held by a simulated hand that follows a hand script file.
//
//   run_scene_file SCENE.toml HAND.toml [--realtime] [--no-mlock]
//
// By default the loop runs in simulated time, as fast as the machine goes, with the same
// result every time. --realtime runs the same loop as a servo session (toonforce::control_rt:
// SCHED_FIFO where permitted, memory locked unless --no-mlock, absolute 1 ms deadlines, the
// frames handed to this program on a thread of their own, SIGINT/SIGTERM stop it with the force
// zeroed first), as `toonforce run` does on a real device; the simulated device then advances
// one period per exchange.
//
// Prints where the handle first touched something, the peak force, and the highest point the
// handle reached after that contact (how far the scene threw it back: try scenes/wall.toml and
// scenes/cartoon_wall.toml with scenes/hands/strike.toml). Exit status 0 when the run ended
// without a latched safety fault, 1 when it did, 2 when the files or settings are wrong.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <string>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/control/servo_session.hpp"
#include "toonforce/host_sim/sim_driver.hpp"

namespace {

using Loop = toonforce::ServoLoop<toonforce::DriverRef, toonforce::RuntimeScene<double>>;
constexpr double kRateHz = 1000.0;

/// What the run did, from each tick's telemetry frame (outside the tick: the loop itself stays
/// allocation- and I/O-free). In real time the session hands the frames over on its writer
/// thread (a FrameConsumer); in simulated time this program gives them itself.
struct Watch final : toonforce::FrameConsumer {
  double first_contact_s = std::numeric_limits<double>::quiet_NaN();
  double contact_z_m = 0.0;
  double highest_after_m = -std::numeric_limits<double>::infinity();
  double peak_force_n = 0.0;

  void consume(const toonforce::TelemetryFrame& f) override {
    peak_force_n = std::max(peak_force_n, std::sqrt(dot(f.force_n, f.force_n)));
    if (std::isnan(first_contact_s)) {
      if (f.in_contact) {  // some effect of the scene says the handle touches it
        first_contact_s = f.t_s;
        contact_z_m = f.position_m.z;
      }
    } else {
      highest_after_m = std::max(highest_after_m, f.position_m.z);
    }
  }
};

}  // namespace

int main(int argc, char** argv) {
  bool realtime = false;
  bool lock_memory = true;
  const char* files[2] = {nullptr, nullptr};
  int file_count = 0;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--realtime") == 0) {
      realtime = true;
    } else if (std::strcmp(argv[i], "--no-mlock") == 0) {
      lock_memory = false;
    } else if (file_count < 2) {
      files[file_count++] = argv[i];
    } else {
      file_count = 3;
    }
  }
  if (file_count != 2) {
    std::fprintf(stderr, "usage: %s SCENE.toml HAND.toml [--realtime] [--no-mlock]\n", argv[0]);
    return 2;
  }

  // Start-up: everything that can fail, fails here with a message naming file, line and key.
  auto scene = toonforce::load_scene_file(files[0]);
  if (!scene) {
    std::fprintf(stderr, "%s\n", scene.error().c_str());
    return 2;
  }
  auto hand = toonforce::load_hand_script(files[1]);
  if (!hand) {
    std::fprintf(stderr, "%s\n", hand.error().c_str());
    return 2;
  }
  namespace hs = toonforce::host_sim;
  hs::PlantOptions plant;
  plant.period_s = 1.0 / kRateHz;
  auto driver = hs::SimDriver::create(hs::falcon_params(), hand.value().intent, plant);
  if (!driver) {
    std::fprintf(stderr, "simulated device: %s\n", driver.error().c_str());
    return 2;
  }
  hs::SimDriver& device = *driver.value();
  // The scene's [device] settings, completed by what the device says of itself (its maximum
  // force, workspace, continuous force), as `toonforce run` does.
  const toonforce::ServoConfig config =
      toonforce::with_device(toonforce::servo_config(scene.value(), plant.period_s), device.info());
  if (const std::string problems = toonforce::check_servo_config(config); !problems.empty()) {
    std::fprintf(stderr, "%s: %s", files[0], problems.c_str());
    return 2;
  }
  // The loop holds the scene in fixed capacity: allocate it once, here, not on the stack.
  auto loop = std::make_unique<Loop>(toonforce::DriverRef(device), toonforce::make_runtime_scene<double>(scene.value()),
                                     config);

  const double duration_s = hand.value().intent.duration_s() + 0.2;
  const auto ticks = static_cast<std::int64_t>(std::llround(duration_s * kRateHz));
  Watch watch;
  std::printf("scene '%s' (%zu surface(s), %zu cliff(s)), hand '%s', %.3f s on the %s\n", scene.value().name.c_str(),
              scene.value().of<toonforce::RuntimeSurface>().size(), scene.value().of<toonforce::CartoonCliff>().size(),
              hand.value().script.name.c_str(), static_cast<double>(ticks) / kRateHz, device.info().name.c_str());

  if (!realtime) {
    toonforce::TelemetryFrame frame;
    for (std::int64_t k = 0; k < ticks; ++k) {
      static_cast<void>(loop->tick(k));
      loop->fill_frame(frame);
      watch.consume(frame);
    }
    static_cast<void>(loop->shutdown(ticks));
  } else {
    toonforce::SessionOptions options;
    options.realtime.rate_hz = kRateHz;
    options.realtime.deadlines = ticks;
    options.realtime.allow_non_realtime = true;  // an example: run anyway, and say so
    options.realtime.lock_memory = lock_memory;
    options.realtime.watchdog_periods = config.safety.watchdog_periods;
    options.interactive = false;
    const auto report = toonforce::run_loop(*loop, device, watch, options);
    if (!report) {
      std::fprintf(stderr, "%s\n", report.error().c_str());
      return 2;
    }
    const toonforce::RunReport& r = report->report;
    const toonforce::LatencySummary wake = r.wake.summary();
    std::printf("real time: %s; %lld ticks, %lld deadlines missed; wake-up latency median %.1f us, "
                "p99 %.1f us, max %.1f us\n%s",
                r.setup.fifo ? "SCHED_FIFO" : "NOT real-time", static_cast<long long>(r.ticks),
                static_cast<long long>(r.missed), static_cast<double>(wake.median_ns) / 1e3,
                static_cast<double>(wake.p99_ns) / 1e3, static_cast<double>(wake.max_ns) / 1e3, r.setup.notes.c_str());
  }

  if (std::isnan(watch.first_contact_s)) {
    std::printf("no contact\n");
  } else {
    std::printf("first contact at t = %.3f s, z = %.2f mm\n", watch.first_contact_s, watch.contact_z_m * 1e3);
    std::printf("highest point after it: z = %.2f mm\n", watch.highest_after_m * 1e3);
  }
  std::printf("peak force %.2f N; latched safety faults: %s\n", watch.peak_force_n, loop->latched() ? "yes" : "none");
  return loop->latched() ? 1 : 0;
}
