// SPDX-License-Identifier: Apache-2.0
#include "sim_simple.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <utility>

namespace toonforce {
namespace {

std::int64_t monotonic_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// The segment of a looped piecewise-linear script that holds `t` (wrapped into the loop).
struct Segment {
  const SimpleSimConfig::Keyframe* a;
  const SimpleSimConfig::Keyframe* b;
  double t_s;
};
Segment segment(const std::vector<SimpleSimConfig::Keyframe>& keys, double loop_s, double t_s) noexcept {
  double t = loop_s > 0.0 ? std::fmod(t_s, loop_s) : 0.0;
  if (t < 0.0) t += loop_s;
  for (std::size_t i = 1; i < keys.size(); ++i) {
    if (t <= keys[i].t_s) return {&keys[i - 1], &keys[i], t};
  }
  return {&keys.back(), &keys.back(), t};
}

}  // namespace

DeviceInfo SimpleSimConfig::default_info() {
  DeviceInfo info;
  info.name = "simple simulated device (temporary, until host_sim)";
  info.max_force_n = 8.0;
  info.max_continuous_force_n = 4.0;
  info.workspace_min_m = {-0.06, -0.06, -0.06};
  info.workspace_max_m = {0.06, 0.06, 0.06};
  info.nominal_rate_hz = 1000.0;
  info.clocking = Clocking::kHostTimer;
  return info;
}

std::vector<SimpleSimConfig::Keyframe> SimpleSimConfig::default_script() {
  return {{0.0, {-0.03, 0.0, 0.02}},   {0.5, {-0.03, 0.0, 0.02}},  {0.65, {-0.03, 0.0, -0.004}},
          {1.0, {-0.03, 0.0, -0.004}}, {1.6, {0.03, 0.0, -0.004}}, {1.9, {0.03, 0.0, 0.02}},
          {3.0, {-0.03, 0.0, 0.02}}};
}

SimpleSimDevice::SimpleSimDevice(SimpleSimConfig config) : config_(std::move(config)) {
  if (config_.script.empty()) config_.script = SimpleSimConfig::default_script();
  loop_s_ = config_.script.back().t_s;
  position_m_ = config_.script.front().position_m;
}

Vec3<double> SimpleSimDevice::target_m(double t_s) const noexcept {
  const Segment s = segment(config_.script, loop_s_, t_s);
  const double span = s.b->t_s - s.a->t_s;
  const double u = span > 0.0 ? (s.t_s - s.a->t_s) / span : 0.0;
  return s.a->position_m + (s.b->position_m - s.a->position_m) * u;
}

Vec3<double> SimpleSimDevice::target_velocity_m_per_s(double t_s) const noexcept {
  const Segment s = segment(config_.script, loop_s_, t_s);
  const double span = s.b->t_s - s.a->t_s;
  return span > 0.0 ? (s.b->position_m - s.a->position_m) * (1.0 / span) : Vec3<double>{};
}

void SimpleSimDevice::advance(double dt_s) noexcept {
  dt_s = std::min(dt_s, config_.max_advance_s);
  if (!(dt_s > 0.0)) return;
  const auto steps = static_cast<int>(std::ceil(dt_s / config_.step_s));
  const double h = dt_s / steps;
  const Vec3<double> device_force = zeroed_.load(std::memory_order_acquire) ? Vec3<double>{} : force_n_;
  for (int i = 0; i < steps; ++i) {
    const Vec3<double> hand = (target_m(time_s_) - position_m_) * config_.hand_stiffness_n_per_m +
                              (target_velocity_m_per_s(time_s_) - velocity_m_per_s_) * config_.hand_damping_n_s_per_m;
    const Vec3<double> total = device_force + hand - velocity_m_per_s_ * config_.device_damping_n_s_per_m;
    velocity_m_per_s_ += total * (h / config_.mass_kg);  // semi-implicit Euler: v first, then x
    const Vec3<double> step = velocity_m_per_s_ * h;
    device_work_j_ += dot(device_force, step);
    position_m_ += step;
    time_s_ += h;
  }
}

DeviceStatus SimpleSimDevice::read(DeviceReading& reading) noexcept {
  if (config_.real_time) {
    const std::int64_t now = monotonic_ns();
    if (last_clock_ns_ >= 0) advance(static_cast<double>(now - last_clock_ns_) * 1e-9);
    last_clock_ns_ = now;
  } else if (!first_read_) {
    advance(config_.exchange_period_s);
  }
  first_read_ = false;
  reading.position_m = position_m_;
  reading.velocity_m_per_s = {};
  reading.has_velocity = false;
  reading.buttons = 0;
  return DeviceStatus::kOk;
}

DeviceStatus SimpleSimDevice::write(const Vec3<double>& force_n) noexcept {
  force_n_ = force_n;
  zeroed_.store(false, std::memory_order_release);
  return DeviceStatus::kOk;
}

void SimpleSimDevice::emergency_zero() noexcept {
  zeroed_.store(true, std::memory_order_release);
  emergency_zeros_.fetch_add(1, std::memory_order_relaxed);
}

std::unique_ptr<DeviceDriver> make_simple_sim_device(const SimpleSimConfig& config) {
  return std::make_unique<SimpleSimDevice>(config);
}

}  // namespace toonforce
