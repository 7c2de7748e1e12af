// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A real-time run of a world (world.hpp): the same session as one device's (servo_session.hpp:
/// signals, the writer thread, 'r' and 'q' on a terminal, the runner on the host's timer), with
/// one WorldFrame a tick in the ring instead of one TelemetryFrame. The runner sees the devices
/// as one `DeviceGroup`: its emergency zero, from the heartbeat watchdog or a fatal signal,
/// zeroes every device, one after the other.
///
/// Every device of the world is ticked by one thread on the host's clock: a device clocked by
/// its own servo thread (the Omni: Clocking::kDeviceThread) joins through a ClockBridge
/// (clock_bridge.hpp), and the group refuses one that comes without, rather than let one
/// device's I/O wait on another's clock.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "toonforce/control/servo_session.hpp"
#include "toonforce/control/world_frame.hpp"

namespace toonforce {

/// 8192 world frames: 8 s of a world at 1 kHz before the writer must catch up.
using WorldRing = SpscRing<WorldFrame, 8192>;

/// The devices of a world, for the runner: one clock (the host's timer), one emergency zero
/// that zeroes them all. read() and write() are not the runner's and say kNotReady.
class DeviceGroup final : public DeviceDriver {
 public:
  /// `devices` outlive the group. Refused (an error in words): none, or one clocked by its own
  /// servo thread.
  static Result<std::unique_ptr<DeviceGroup>> create(const std::vector<DeviceDriver*>& devices,
                                                     const std::vector<std::string>& names);
  DeviceStatus read(DeviceReading&) noexcept override { return DeviceStatus::kNotReady; }
  DeviceStatus write(const Vec3<double>&) noexcept override { return DeviceStatus::kNotReady; }
  void emergency_zero() noexcept override {
    for (DeviceDriver* d : devices_) d->emergency_zero();
  }
  const DeviceInfo& info() const noexcept override { return info_; }

 private:
  DeviceGroup() = default;
  std::vector<DeviceDriver*> devices_;
  DeviceInfo info_;
};

/// A world as the runner's task: the world's tick, one frame into the ring, zero force on every
/// device at the end. Everything here runs on the servo thread: no allocation, no lock.
template <class WorldT>
class WorldTask final : public PeriodicTask {
 public:
  WorldTask(WorldT& world, WorldRing& ring, double period_s) noexcept
      : world_(world), ring_(ring), period_s_(period_s) {}
  void tick(std::int64_t k) noexcept override { status_ = world_.tick(k); }
  void publish(std::int64_t k, const TickTiming& timing) noexcept override {
    fill_world_frame(world_, status_, k, period_s_, frame_);
    frame_.timing = timing;
    missed_ = timing.missed_total;
    static_cast<void>(ring_.push(frame_));  // a full ring drops and counts, never waits
  }
  void shutdown(std::int64_t k) noexcept override {
    world_.shutdown(k);  // zero force on every device before anything else
    fill_world_frame(world_, shutdown_status(world_), k, period_s_, frame_);
    frame_.timing = TickTiming{};
    frame_.timing.missed_total = missed_;
    last_frame_ready_ = true;
  }
  /// The shut-down frame, for the session to deliver once the servo thread is done.
  const WorldFrame* last_frame() const noexcept { return last_frame_ready_ ? &frame_ : nullptr; }

 private:
  WorldT& world_;
  WorldRing& ring_;
  double period_s_;
  decltype(std::declval<WorldT&>().tick(0)) status_{};
  WorldFrame frame_{};
  std::int64_t missed_ = 0;
  bool last_frame_ready_ = false;
};

/// Runs `world` (its devices in `group`) until options.realtime.deadlines periods have passed or
/// a signal or 'q' stops it; `consumer` (consume(const WorldFrame&), finish()) gets every frame
/// on the writer thread. 'r' re-arms every device.
template <class WorldT, class Consumer>
Result<SessionReport> run_world(WorldT& world, DeviceGroup& group, Consumer& consumer, const SessionOptions& options) {
  auto ring = std::make_unique<WorldRing>();  // allocated before the servo thread starts
  auto task = std::make_unique<WorldTask<WorldT>>(world, *ring, 1.0 / options.realtime.rate_hz);
  const auto last = [t = task.get()]() -> const WorldFrame* { return t->last_frame(); };
  RingDrain<WorldFrame, WorldRing::kCapacity, Consumer, decltype(last)> drain(*ring, consumer, last);
  const RearmRequest rearm{[](void* w) noexcept { static_cast<WorldT*>(w)->request_rearm(); }, &world};
  return run_session(*task, drain, group, options, rearm);
}

}  // namespace toonforce
