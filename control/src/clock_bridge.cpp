// SPDX-License-Identifier: Apache-2.0
#include "toonforce/control/clock_bridge.hpp"

#include <cmath>
#include <exception>

#include <fmt/format.h>

#include "toonforce/control/realtime_runner.hpp"

namespace toonforce {

ClockBridge::ClockBridge(DeviceDriver& device, double max_force_age_s)
    : device_(device),
      info_(device.info()),
      max_age_ns_(static_cast<std::int64_t>(std::llround(max_force_age_s * 1e9))) {
  // To the world it is ticked on the host's clock: the device's own thread is the bridge's.
  info_.clocking = Clocking::kHostTimer;
  info_.name += " (its own servo thread, bridged)";
}

Result<std::unique_ptr<ClockBridge>> ClockBridge::start(DeviceDriver& device, double max_force_age_s) {
  if (!(max_force_age_s > 0.0 && std::isfinite(max_force_age_s))) return Error{"the bridge's force age must be > 0 s"};
  if (device.info().clocking != Clocking::kDeviceThread) {
    return Error{fmt::format("{}: not clocked by its own servo thread: it needs no bridge", device.info().name)};
  }
  auto bridge = std::unique_ptr<ClockBridge>(new ClockBridge(device, max_force_age_s));
  ClockBridge* b = bridge.get();
  try {
    b->thread_ = std::thread([b] {
      static_cast<void>(use_alternate_signal_stack());
      auto ended = b->device_.run_clocked(&ClockBridge::on_tick, b);
      if (!ended) {
        b->end_ = ended.error();
      } else if (!ended->device_stopped.empty()) {
        b->end_ = ended->device_stopped;
      }
      b->ended_.store(true, std::memory_order_release);
    });
  } catch (const std::exception& e) {
    return Error{fmt::format("{}: its servo thread could not be started: {}", device.info().name, e.what())};
  }
  return bridge;
}

ClockBridge::~ClockBridge() { stop(); }

void ClockBridge::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

TickVerdict ClockBridge::on_tick(void* self, const ClockedTick& clock) noexcept {
  static_cast<void>(clock);
  auto* b = static_cast<ClockBridge*>(self);
  Sample sample;
  sample.status = b->device_.read(sample.reading);
  const std::int64_t now = now_ns();
  sample.stamp_ns = now;
  b->samples_.write(sample);
  Force force;
  static_cast<void>(b->forces_.read(force));
  const bool stopping = b->stop_.load(std::memory_order_acquire);
  Vec3<double> out{};
  if (force.stamp_ns != 0) {
    const std::int64_t age = now - force.stamp_ns;
    b->force_age_.record(age);
    if (age > b->max_age_ns_) {
      b->stale_.store(b->stale_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    } else if (!stopping && !b->zero_.load(std::memory_order_acquire)) {
      out = force.force_n;
    }
  }
  static_cast<void>(b->device_.write(out));
  return stopping ? TickVerdict::kStop : TickVerdict::kContinue;
}

DeviceStatus ClockBridge::read(DeviceReading& reading) noexcept {
  static_cast<void>(samples_.read(last_sample_));
  if (last_sample_.stamp_ns == 0) {
    reading = {};
    return ended_.load(std::memory_order_acquire) ? DeviceStatus::kDisconnected : DeviceStatus::kNotReady;
  }
  const std::int64_t age = now_ns() - last_sample_.stamp_ns;
  reading_age_.record(age);
  reading = last_sample_.reading;
  if (age > max_age_ns_) return DeviceStatus::kTimeout;  // its thread stalled or ended
  return last_sample_.status;
}

DeviceStatus ClockBridge::write(const Vec3<double>& force_n) noexcept {
  forces_.write(Force{force_n, now_ns()});
  if (last_sample_.stamp_ns == 0) return DeviceStatus::kNotReady;
  return last_sample_.status;
}

void ClockBridge::emergency_zero() noexcept {
  zero_.store(true, std::memory_order_release);
  device_.emergency_zero();
}

std::string ClockBridge::last_error() const {
  if (ended_.load(std::memory_order_acquire) && !end_.empty()) {
    return fmt::format("its servo thread ended: {}", end_);
  }
  if (last_sample_.stamp_ns != 0 && now_ns() - last_sample_.stamp_ns > max_age_ns_) {
    return fmt::format("no reading from its own servo thread for over {:.1f} ms (stalled or ended)",
                       static_cast<double>(max_age_ns_) * 1e-6);
  }
  return device_.last_error();
}

}  // namespace toonforce
