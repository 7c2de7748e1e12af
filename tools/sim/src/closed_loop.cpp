// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/closed_loop.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "toonforce/control/servo_loop.hpp"
#include "toonforce/host_sim/sim_driver.hpp"
#include "toonforce/trace/telemetry_trace.hpp"

namespace toonforce {

namespace {

/// The loop for one scalar type, behind one virtual call per tick.
class Loop {
 public:
  virtual ~Loop() = default;
  virtual void step(SimRecord& record) noexcept = 0;
  virtual void shutdown(SimRecord& record) noexcept = 0;
  virtual host_sim::SimDevice& device() noexcept = 0;
};

template <Scalar S>
class ScalarLoop final : public Loop {
 public:
  ScalarLoop(host_sim::SimDevice device, const RuntimeScene<S>& scene, const ServoConfig& config)
      : loop_(std::move(device), scene, config) {}

  void step(SimRecord& r) noexcept override {
    host_sim::SimDevice& d = loop_.device();
    const std::int64_t k = d.tick();
    const host_sim::HandTarget target = d.plant().hand(d.time_s());
    r.true_position_m = d.plant().position_m();
    r.true_velocity_m_per_s = d.plant().velocity_m_per_s();
    r.hand_target_m = target.position_m;
    r.segment = target.segment;
    r.grasping = target.grasping;
    static_cast<void>(loop_.tick(k));
    loop_.fill_frame(r.frame);
    r.device_force_n = d.applied_force_n();
  }
  void shutdown(SimRecord& r) noexcept override {
    host_sim::SimDevice& d = loop_.device();
    r.true_position_m = d.plant().position_m();
    r.true_velocity_m_per_s = d.plant().velocity_m_per_s();
    static_cast<void>(loop_.shutdown(d.tick()));
    loop_.fill_frame(r.frame);
    r.device_force_n = d.applied_force_n();
  }
  host_sim::SimDevice& device() noexcept override { return loop_.device(); }

 private:
  ServoLoop<host_sim::SimDevice, RuntimeScene<S>> loop_;
};

}  // namespace

struct SimSession::Impl {
  SimConfig config;
  ServoConfig servo;
  std::vector<std::string> names;
  std::unique_ptr<Loop> loop;
};

SimSession::SimSession(std::unique_ptr<Impl> impl) noexcept : impl_(std::move(impl)) {}
SimSession::~SimSession() = default;
SimSession::SimSession(SimSession&&) noexcept = default;
SimSession& SimSession::operator=(SimSession&&) noexcept = default;

Result<SimSession> SimSession::create(const SceneDescription& scene, const HandScriptFile& hand,
                                      const SimConfig& config) {
  auto device = host_sim::SimDevice::create(config.device, hand.intent, config.plant, config.seed);
  if (!device) return Error{device.error()};
  auto impl = std::make_unique<Impl>();
  impl->config = config;
  // The configuration `run --device sim` uses: the scene's, the device's limits filling the gaps.
  impl->servo = with_device(toonforce::servo_config(scene, config.plant.period_s),
                            host_sim::device_info(config.device, config.plant.period_s));
  if (const std::string problems = check_servo_config(impl->servo); !problems.empty()) {
    return Error{fmt::format("{}: the servo configuration does not work:\n{}", scene.source, problems)};
  }
  auto built = with_scalar(
      config.scalar,
      [&]<Scalar S>() -> Result<bool> {
        const RuntimeScene<S> runtime = make_runtime_scene<S>(scene);
        impl->names = effect_value_names(runtime);
        impl->loop = std::make_unique<ScalarLoop<S>>(std::move(device).value(), runtime, impl->servo);
        return true;
      },
      [](ScalarKind kind) -> Result<bool> {
        return Error{fmt::format("--scalar {}: this build has no servo loop for it", scalar_kind_name(kind))};
      });
  if (!built) return Error{built.error()};
  return SimSession(std::move(impl));
}

SimRecord SimSession::step() noexcept {
  SimRecord record;
  impl_->loop->step(record);
  return record;
}

SimRecord SimSession::shutdown() noexcept {
  SimRecord record;
  impl_->loop->shutdown(record);
  return record;
}

std::int64_t SimSession::ticks_for(double duration_s) const noexcept {
  return std::llround(duration_s / impl_->config.plant.period_s);
}

const host_sim::SimDevice& SimSession::device() const noexcept { return impl_->loop->device(); }
host_sim::SimDevice& SimSession::device() noexcept { return impl_->loop->device(); }
const SimConfig& SimSession::config() const noexcept { return impl_->config; }
const ServoConfig& SimSession::servo_config() const noexcept { return impl_->servo; }
const std::vector<std::string>& SimSession::value_names() const noexcept { return impl_->names; }

std::size_t SimSession::value_index(std::string_view name) const noexcept {
  for (std::size_t i = 0; i < impl_->names.size(); ++i) {
    if (impl_->names[i] == name) return i;
  }
  return impl_->names.size();
}

double value_of(const SimRecord& record, const std::vector<std::string>& names, std::string_view name) noexcept {
  for (std::size_t i = 0; i < names.size() && i < record.frame.value_count; ++i) {
    if (names[i] == name) return record.frame.values[i];
  }
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace toonforce
