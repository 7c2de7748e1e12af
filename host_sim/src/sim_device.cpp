// SPDX-License-Identifier: Apache-2.0
#include "toonforce/host_sim/sim_device.hpp"

#include <cmath>

#include <fmt/format.h>

namespace toonforce::host_sim {

namespace {
constexpr std::size_t kRing = kMaxIoDelayTicks + 1;
std::size_t slot(std::int64_t tick) noexcept { return static_cast<std::size_t>(tick) % kRing; }
}  // namespace

Result<SimDevice> SimDevice::create(const DeviceParams& device, HandIntent intent, const PlantOptions& options,
                                    std::uint64_t seed) {
  if (device.io_delay_ticks < 0 || device.io_delay_ticks > kMaxIoDelayTicks) {
    return Error{fmt::format("{}: an I/O delay of {} ticks is outside 0..{}", device.name, device.io_delay_ticks,
                             kMaxIoDelayTicks)};
  }
  if (!(device.encoder_step_m >= 0.0) || !(device.force_step_n >= 0.0) || !(device.max_force_n >= 0.0) ||
      !(device.sensor_noise_m >= 0.0)) {
    return Error{fmt::format("{}: steps, maximum force and noise must be >= 0", device.name)};
  }
  auto plant = Plant::create(device, std::move(intent), options);
  if (!plant) return Error{plant.error()};
  SimDevice sim(std::move(plant).value(), seed);
  sim.samples_[0] = sim.measure(sim.plant_.position_m());
  return sim;
}

double SimDevice::quantise(double value, double step) const noexcept {
  return step > 0.0 ? std::round(value / step) * step : value;
}

Vec3<double> SimDevice::measure(const Vec3<double>& position_m) noexcept {
  Vec3<double> p = position_m;
  const DeviceParams& d = plant_.device();
  if (d.sensor_noise_m > 0.0) {
    p.x += d.sensor_noise_m * random_.normal();
    p.y += d.sensor_noise_m * random_.normal();
    p.z += d.sensor_noise_m * random_.normal();
  }
  return {quantise(p.x, d.encoder_step_m), quantise(p.y, d.encoder_step_m), quantise(p.z, d.encoder_step_m)};
}

Vec3<double> SimDevice::shape_force(const Vec3<double>& force_n) const noexcept {
  const DeviceParams& d = plant_.device();
  if (!is_finite(force_n)) return {};
  Vec3<double> f = force_n;
  if (d.max_force_n > 0.0) f = limit_magnitude(f, d.max_force_n);
  if (d.force_step_n > 0.0) {
    // Toward zero, so quantising never lifts a saturated force above the maximum.
    const auto truncate = [step = d.force_step_n](double value) { return std::trunc(value / step) * step; };
    f = {truncate(f.x), truncate(f.y), truncate(f.z)};
  }
  return f;
}

void SimDevice::set_state(const Vec3<double>& position_m, const Vec3<double>& velocity_m_per_s) noexcept {
  plant_.set_state(position_m, velocity_m_per_s);
  samples_[slot(tick_)] = measure(position_m);
}

DeviceStatus SimDevice::read(DeviceReading& reading) noexcept {
  const std::int64_t sampled = std::max<std::int64_t>(0, tick_ - plant_.device().io_delay_ticks);
  reading.position_m = samples_[slot(sampled)];
  reading.velocity_m_per_s = {};
  reading.has_velocity = false;
  reading.buttons = 0;
  return DeviceStatus::kOk;
}

DeviceStatus SimDevice::write(const Vec3<double>& force_n) noexcept {
  applied_n_ = zero_force_ ? Vec3<double>{} : shape_force(force_n);
  plant_.step(tick_, applied_n_);
  ++tick_;
  samples_[slot(tick_)] = measure(plant_.position_m());
  return DeviceStatus::kOk;
}

}  // namespace toonforce::host_sim
