// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A device clocked by its own servo thread (the Omni: OpenHaptics' scheduler calls it every
/// period, hal/device.hpp Clocking::kDeviceThread) in a world ticked on the host's clock
/// (world.hpp), with neither thread ever waiting on the other.
///
/// The device keeps its own thread. Each of its ticks reads the device, hands the reading over
/// (a `Handoff`: a triple buffer, wait-free on both sides), takes the newest force the world
/// thread handed back and writes it, or zero if that force is older than `max_force_age_s`
/// (the world thread stalled or ended) or an emergency zero was asked. On the world's side the
/// bridge is an ordinary DeviceDriver: read() gives the newest reading (kTimeout once it is
/// older than `max_force_age_s`: the device's thread stalled or ended), write() hands the force
/// over. The device's safety chain runs in the world's loop for it, as for any device; the
/// device's own thread keeps its own limits (the Omni's cap, ramp and calibration gate).
///
/// What it costs: a reading is up to one device period old when the world uses it, plus the
/// phase between the clocks; a force is up to one world period old when the device applies it.
/// Both ages are measured on every use (`reading_age`, `force_age`), and the coupling between
/// differently clocked devices is a coupling with that much more delay (docs/performance/world.md
/// gives the passivity bound against delay).

#include <time.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <type_traits>

#include "toonforce/common/result.hpp"
#include "toonforce/control/latency_histogram.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce {

/// One value handed from one thread to another, the newest whole value wins: a triple buffer.
/// The writer always has a slot of its own and the reader one of its own; the third is swapped
/// in one atomic exchange. Neither side ever waits or retries.
template <class T>
class Handoff {
  static_assert(std::is_trivially_copyable_v<T>);
  static constexpr std::uint8_t kFresh = 4;
  static constexpr std::uint8_t kIndex = 3;

 public:
  /// Writer side (one thread).
  void write(const T& value) noexcept {
    slots_[back_] = value;
    back_ = static_cast<std::uint8_t>(
        middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh), std::memory_order_acq_rel) & kIndex);
  }
  /// Reader side (one thread): the newest value written; true if it is new since the last read.
  /// Before any write, a value-initialised T and false.
  bool read(T& out) noexcept {
    bool fresh = false;
    if ((middle_.load(std::memory_order_relaxed) & kFresh) != 0) {
      front_ = static_cast<std::uint8_t>(middle_.exchange(front_, std::memory_order_acq_rel) & kIndex);
      fresh = true;
    }
    out = slots_[front_];
    return fresh;
  }

 private:
  std::array<T, 3> slots_{};
  std::uint8_t back_ = 0;                ///< the writer's
  std::atomic<std::uint8_t> middle_{1};  ///< the one in between, and whether it is fresh
  std::uint8_t front_ = 2;               ///< the reader's
};

class ClockBridge final : public DeviceDriver {
 public:
  /// Starts `device`'s own servo thread (run_clocked, on a thread of the bridge's); `device`
  /// outlives the bridge. `max_force_age_s` > 0.
  static Result<std::unique_ptr<ClockBridge>> start(DeviceDriver& device, double max_force_age_s);
  ~ClockBridge() override;
  ClockBridge(const ClockBridge&) = delete;
  ClockBridge& operator=(const ClockBridge&) = delete;

  DeviceStatus read(DeviceReading& reading) noexcept override;
  DeviceStatus write(const Vec3<double>& force_n) noexcept override;
  void emergency_zero() noexcept override;
  const DeviceInfo& info() const noexcept override { return info_; }
  ExternalZero external_zero() const noexcept override { return device_.external_zero(); }
  std::string last_error() const override;

  /// Ends the device's thread (its last tick writes zero) and waits for it.
  void stop();
  /// The age of each reading the world used [ns] (world thread; read it after stop()).
  const LatencyHistogram& reading_age() const noexcept { return reading_age_; }
  /// The age of each force the device applied [ns] (device thread; read it after stop()).
  const LatencyHistogram& force_age() const noexcept { return force_age_; }
  /// Device ticks that wrote zero because the newest force was too old.
  std::int64_t stale_force_ticks() const noexcept { return stale_.load(std::memory_order_relaxed); }

 private:
  struct Sample {
    DeviceReading reading;
    DeviceStatus status = DeviceStatus::kNotReady;
    std::int64_t stamp_ns = 0;  ///< 0: none yet
  };
  struct Force {
    Vec3<double> force_n;
    std::int64_t stamp_ns = 0;  ///< 0: none yet
  };
  ClockBridge(DeviceDriver& device, double max_force_age_s);
  static TickVerdict on_tick(void* self, const ClockedTick& clock) noexcept;
  static std::int64_t now_ns() noexcept {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  }

  DeviceDriver& device_;
  DeviceInfo info_;
  std::int64_t max_age_ns_;
  Handoff<Sample> samples_;
  Handoff<Force> forces_;
  Sample last_sample_{};
  LatencyHistogram reading_age_{10'000, 10'000};  ///< 10 us bins to 100 ms
  LatencyHistogram force_age_{10'000, 10'000};
  std::atomic<bool> stop_{false};
  std::atomic<bool> zero_{false};
  std::atomic<bool> ended_{false};
  std::atomic<std::int64_t> stale_{0};
  std::string end_;  ///< why the device's thread ended on its own (after ended_)
  std::thread thread_;
};

}  // namespace toonforce
