// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The simulated device and hand behind the run-time seam (DeviceDriver), so a real-time
/// runner (`toonforce run --device sim`) drives it like any backend: every read/write exchange
/// advances the simulation by one period, however long the exchange took on the wall clock
/// (simulated time follows the exchanges, not the clock; a skipped tick is simply not
/// simulated). emergency_zero() may be called from any thread: it latches zero force, applied
/// from the next write on, until rearm().

#include <atomic>
#include <memory>

#include "toonforce/host_sim/sim_device.hpp"

namespace toonforce::host_sim {

/// What a simulated device says about itself (DeviceInfo), for a loop at `period_s`: the same
/// for `run --device sim` and `sim`, so a scene previewed in one behaves as in the other.
DeviceInfo device_info(const DeviceParams& device, double period_s);

class SimDriver final : public DeviceDriver {
 public:
  /// A driver for `device` with a hand following `intent`, exchanging every
  /// `options.period_s` seconds. Sensor noise uses `seed`.
  static Result<std::unique_ptr<SimDriver>> create(const DeviceParams& device, HandIntent intent,
                                                   const PlantOptions& options, std::uint64_t seed = 1);

  DeviceStatus read(DeviceReading& reading) noexcept override { return device_.read(reading); }
  DeviceStatus write(const Vec3<double>& force_n) noexcept override {
    device_.force_zero(zero_latched_.load(std::memory_order_relaxed));
    return device_.write(force_n);
  }
  void emergency_zero() noexcept override { zero_latched_.store(true, std::memory_order_relaxed); }
  const DeviceInfo& info() const noexcept override { return info_; }

  /// Clears the emergency latch (forces flow again from the next write).
  void rearm() noexcept { zero_latched_.store(false, std::memory_order_relaxed); }
  bool zero_latched() const noexcept { return zero_latched_.load(std::memory_order_relaxed); }
  const SimDevice& device() const noexcept { return device_; }
  SimDevice& device() noexcept { return device_; }

 private:
  SimDriver(SimDevice device, DeviceInfo info) noexcept : device_(std::move(device)), info_(std::move(info)) {}

  SimDevice device_;
  DeviceInfo info_;
  std::atomic<bool> zero_latched_{false};
};

}  // namespace toonforce::host_sim
