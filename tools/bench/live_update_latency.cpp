// SPDX-License-Identifier: Apache-2.0
// How long a live scene's change takes to reach the servo loop
// (docs/performance/live.md). A benchmark, never a test: it prints timings.
//
// The loop runs on the real-time runner (the one behind `toonforce run`) at --rate Hz with a
// live stage, on a device that holds the HIP 1 mm inside a floor. An application thread calls
// SceneEditor::set (retune the floor's stiffness) every --every-ms, and notes the time just
// before the call. The loop notes the time at the start of each tick; the tick that applies an
// update says which. Two times per update, on CLOCK_MONOTONIC (std::chrono::steady_clock):
//   check:  the call until it returns (parse, check with the scene files' reader, convert, push);
//   reach:  the call until the start of the tick that applied it.
// An update pushed between two ticks waits for the next one: the reference for `reach` is a
// wait spread evenly over one period (median T/2, p99 0.99 T) plus `check`.

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "toonforce/config/scene_editor.hpp"
#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/control/servo_loop.hpp"

namespace {

using namespace toonforce;
using Clock = std::chrono::steady_clock;

struct HeldDevice {
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = {0.0, 0.0, -0.001};
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>&) noexcept { return DeviceStatus::kOk; }
};

using FileScene = RuntimeScene<double>;
using Loop = ServoLoop<HeldDevice, FileScene, NullPins, kLiveStages>;
constexpr std::size_t kMaxUpdates = 100000;

/// The loop as the runner's task: notes when each tick starts and which update it applied.
class Task final : public PeriodicTask {
 public:
  Task(Loop& loop, std::vector<std::int64_t>& applied_ns) : loop_(loop), applied_ns_(applied_ns) {}
  void tick(std::int64_t k) noexcept override {
    start_ = Clock::now();
    const std::uint64_t before = loop_.updates_applied();
    loop_.tick(k);
    if (loop_.updates_applied() != before) {
      const std::size_t n = static_cast<std::size_t>(loop_.updates_applied());
      if (n <= applied_ns_.size()) applied_ns_[n - 1] = start_.time_since_epoch().count();
    }
  }
  void publish(std::int64_t, const TickTiming&) noexcept override {}
  void shutdown(std::int64_t k) noexcept override { static_cast<void>(loop_.shutdown(k)); }

 private:
  Loop& loop_;
  std::vector<std::int64_t>& applied_ns_;
  Clock::time_point start_{};
};

struct Stats {
  double median_us = 0.0, p99_us = 0.0, max_us = 0.0;
};
Stats stats_of(std::vector<double> us) {
  Stats s;
  if (us.empty()) return s;
  std::sort(us.begin(), us.end());
  const auto at = [&](double q) {
    return us[std::min(us.size() - 1, static_cast<std::size_t>(q * static_cast<double>(us.size())))];
  };
  s.median_us = at(0.5);
  s.p99_us = at(0.99);
  s.max_us = us.back();
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Latency of a live scene update: from SceneEditor::set to the servo tick that applies it"};
  double rate_hz = 1000.0;
  int updates = 1000;
  double every_ms = 7.3;  // not a multiple of the period: the calls fall at every phase of it
  bool allow_non_rt = true;
  app.add_option("--rate", rate_hz, "servo rate [Hz]")->check(CLI::Range(500.0, 10000.0));
  app.add_option("--updates", updates, "how many updates")->check(CLI::Range(10, static_cast<int>(kMaxUpdates)));
  app.add_option("--every-ms", every_ms, "the application's period [ms] (not a multiple of the servo period)")
      ->check(CLI::Range(0.5, 1000.0));
  app.add_flag("!--require-rt", allow_non_rt, "fail unless SCHED_FIFO is granted");
  CLI11_PARSE(app, argc, argv);

  const std::string floor = "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\n";
  auto mailbox = std::make_unique<SceneMailbox<FileScene>>();
  auto editor = SceneEditor<double>::open(floor, "floor.toml", *mailbox);
  if (!editor) {
    std::fputs(editor.error().c_str(), stderr);
    return 1;
  }
  ServoConfig config;
  config.period_s = 1.0 / rate_hz;
  config.safety.engage_force_n = 1e3;
  auto loop = std::make_unique<Loop>(HeldDevice{}, make_runtime_scene<double>(editor->scene()), config);
  loop->listen(*mailbox);

  const auto n = static_cast<std::size_t>(updates);
  std::vector<std::int64_t> called_ns(n), returned_ns(n), applied_ns(n, 0);
  std::atomic<int> stop{0};
  std::atomic<bool> refused{false};
  std::thread application([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the loop is running
    auto next = Clock::now();
    for (std::size_t i = 0; i < n && stop.load() == 0; ++i) {
      next += std::chrono::microseconds(static_cast<std::int64_t>(every_ms * 1000.0));
      std::this_thread::sleep_until(next);
      const std::string keys = fmt::format("stiffness = {}", 1000 + static_cast<int>(i % 2) * 500);
      called_ns[i] = Clock::now().time_since_epoch().count();
      const auto sent = editor->set("surface1", keys);
      returned_ns[i] = Clock::now().time_since_epoch().count();
      if (!sent) refused = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    stop = 1;
  });

  Task task(*loop, applied_ns);
  RealtimeOptions options;
  options.rate_hz = rate_hz;
  options.allow_non_realtime = allow_non_rt;
  options.lock_memory = false;
  auto report = run_realtime(task, options, EmergencyZero{}, stop);
  stop = 1;
  application.join();
  if (!report) {
    std::fputs(report.error().c_str(), stderr);
    return 1;
  }

  std::vector<double> check_us, reach_us;
  std::size_t lost = 0;
  for (std::size_t i = 0; i < n; ++i) {
    check_us.push_back(static_cast<double>(returned_ns[i] - called_ns[i]) * 1e-3);
    if (applied_ns[i] == 0) {
      ++lost;
      continue;
    }
    reach_us.push_back(static_cast<double>(applied_ns[i] - called_ns[i]) * 1e-3);
  }
  const Stats check = stats_of(check_us);
  const Stats reach = stats_of(reach_us);
  const double period_us = 1e6 / rate_hz;
  fmt::print("live scene updates: {} at {} Hz, one every {} ms; realtime {}; {} deadline(s) missed\n", n, rate_hz,
             every_ms,
             report->setup.fifo ? fmt::format("SCHED_FIFO {}", report->setup.priority) : "no (normal priority)",
             report->missed);
  fmt::print("[us]                               median      p99      max\n");
  fmt::print("check (set() call to return)     {:8.1f} {:8.1f} {:8.1f}\n", check.median_us, check.p99_us, check.max_us);
  fmt::print("reach (set() call to its tick)   {:8.1f} {:8.1f} {:8.1f}\n", reach.median_us, reach.p99_us, reach.max_us);
  fmt::print("reference: waiting for the next tick, spread over one period: median {:.1f}, p99 {:.1f} (+ check)\n",
             period_us / 2.0, period_us * 0.99);
  fmt::print("updates not applied: {}{}\n", lost, refused ? " (some were refused: mailbox full)" : "");
  return lost == 0 ? 0 : 1;
}
