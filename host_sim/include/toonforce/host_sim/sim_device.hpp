// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A simulated haptic device with a hand on it, behind the same seam as the real backends
/// (hal/device.hpp, concept ServoDevice). One read/write exchange is one servo period:
///   read():  the position the device reports: the handle's position `io_delay_ticks` ticks
///            ago, plus seeded Gaussian noise, quantised to the encoder step (no velocity);
///   write(): the force is saturated to the device's maximum (direction kept), quantised per
///            axis toward zero (as libnifalcon truncates its motor words, FALCON.md §5), held
///            over the period, and the handle and hand are advanced by one period.
/// Neither allocates, throws, locks or calls the system. Same inputs, same bits.

#include <array>
#include <cstdint>

#include "toonforce/common/result.hpp"
#include "toonforce/hal/device.hpp"
#include "toonforce/host_sim/plant.hpp"
#include "toonforce/host_sim/random.hpp"

namespace toonforce::host_sim {

class SimDevice {
 public:
  /// Fails if the device's I/O delay is outside 0..kMaxIoDelayTicks or the plant cannot run.
  static Result<SimDevice> create(const DeviceParams& device, HandIntent intent, const PlantOptions& options,
                                  std::uint64_t seed = 1);

  DeviceStatus read(DeviceReading& reading) noexcept;
  DeviceStatus write(const Vec3<double>& force_n) noexcept;

  /// Puts the handle at `position_m` moving at `velocity_m_per_s` now (set-up code: tests
  /// start from a chosen state), and re-measures the current tick's reading.
  void set_state(const Vec3<double>& position_m, const Vec3<double>& velocity_m_per_s) noexcept;

  /// While set, every write applies zero force (the single-threaded form; SimDriver latches
  /// it from any thread).
  void force_zero(bool zero) noexcept { zero_force_ = zero; }

  /// The force as the device would produce it: saturated, then quantised toward zero.
  Vec3<double> shape_force(const Vec3<double>& force_n) const noexcept;

  /// Ticks exchanged so far; the simulated time is tick() * period.
  std::int64_t tick() const noexcept { return tick_; }
  double time_s() const noexcept { return static_cast<double>(tick_) * plant_.options().period_s; }
  /// The force applied over the last period (after saturation and quantisation).
  const Vec3<double>& applied_force_n() const noexcept { return applied_n_; }
  const Plant& plant() const noexcept { return plant_; }
  Plant& plant() noexcept { return plant_; }
  const DeviceParams& params() const noexcept { return plant_.device(); }

 private:
  explicit SimDevice(Plant plant, std::uint64_t seed) noexcept : plant_(std::move(plant)), random_(seed) {}
  Vec3<double> measure(const Vec3<double>& position_m) noexcept;
  double quantise(double value, double step) const noexcept;

  Plant plant_;
  Random random_;
  std::array<Vec3<double>, kMaxIoDelayTicks + 1> samples_{};  ///< ring, indexed by tick
  std::int64_t tick_ = 0;
  Vec3<double> applied_n_{};
  bool zero_force_ = false;
};
static_assert(ServoDevice<SimDevice>);

}  // namespace toonforce::host_sim
