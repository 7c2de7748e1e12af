#include "toonforce/sim/closed_loop.hpp"

#include <cmath>

#include <fmt/format.h>

namespace toonforce {

namespace {

/// The controller part of the loop, one per scalar type.
class Loop {
 public:
  virtual ~Loop() = default;
  virtual SimRecord step(host_sim::SimDevice& device, double period_s) noexcept = 0;
};

template <Scalar S>
class ScalarLoop final : public Loop {
 public:
  ScalarLoop(const SceneDescription& scene, const ControllerConfig& config, std::optional<SineMethod> sine)
      : controller_(make_runtime_scene<S>(scene, sine), config) {}

  SimRecord step(host_sim::SimDevice& device, double period_s) noexcept override {
    SimRecord record;
    record.tick = device.tick();
    record.t_s = static_cast<double>(record.tick) * period_s;
    const host_sim::HandTarget target = device.plant().hand(record.t_s);
    record.true_position_m = device.plant().position_m();
    record.true_velocity_m_per_s = device.plant().velocity_m_per_s();
    record.hand_target_m = target.position_m;
    record.segment = target.segment;
    record.grasping = target.grasping;

    DeviceReading reading;
    const DeviceStatus status = device.read(reading);
    Sample sample;
    sample.position_m = reading.position_m;
    sample.velocity_m_per_s = reading.velocity_m_per_s;
    sample.has_velocity = reading.has_velocity;
    sample.now = Instant{record.tick, 0.0};
    sample.dt_s = period_s;
    const TickResult<S> result = controller_.tick(sample);
    // A device that is not ok gets zero force (hal/device.hpp); the simulated one always is.
    const Vec3<double> force = status == DeviceStatus::kOk ? to_double(result.force_n) : Vec3<double>{};

    record.position_m = reading.position_m;
    record.force_n = force;
    record.faults = result.faults.bits();
    record.limits = result.limits;
    record.has_diagnostics = !result.faults.has(Fault::kNonFiniteInput) && !result.faults.has(Fault::kNonFiniteForce);
    if (record.has_diagnostics) {
      record.velocity_m_per_s = to_double(controller_.last_velocity_m_per_s());
      record.diagnostics = controller_.diagnostics();
    }
    static_cast<void>(device.write(force));
    record.device_force_n = device.applied_force_n();
    return record;
  }

 private:
  Controller<RuntimeScene<S>> controller_;
};

}  // namespace

struct SimSession::Impl {
  Impl(host_sim::SimDevice d, SimConfig c, ControllerConfig cc)
      : device(std::move(d)), config(std::move(c)), controller_config(cc) {}
  host_sim::SimDevice device;
  SimConfig config;
  ControllerConfig controller_config;
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
  // On a device, the force limit is the smaller of the scene's and the device's (effects.md §6).
  ControllerConfig controller = toonforce::controller_config(scene, config.plant.period_s);
  if (config.device.max_force_n > 0.0 &&
      (!controller.limits.has_max_force || config.device.max_force_n < controller.limits.max_force_n)) {
    controller.limits.max_force_n = config.device.max_force_n;
    controller.limits.has_max_force = true;
  }
  auto impl = std::make_unique<Impl>(std::move(device).value(), config, controller);
  switch (config.scalar) {
    case ScalarKind::kDouble: impl->loop = std::make_unique<ScalarLoop<double>>(scene, controller, config.sine); break;
    case ScalarKind::kFloat: impl->loop = std::make_unique<ScalarLoop<float>>(scene, controller, config.sine); break;
    case ScalarKind::kQ16_16: impl->loop = std::make_unique<ScalarLoop<Q16_16>>(scene, controller, config.sine); break;
  }
  return SimSession(std::move(impl));
}

SimRecord SimSession::step() noexcept { return impl_->loop->step(impl_->device, impl_->config.plant.period_s); }

std::int64_t SimSession::ticks_for(double duration_s) const noexcept {
  return std::llround(duration_s / impl_->config.plant.period_s);
}

const host_sim::SimDevice& SimSession::device() const noexcept { return impl_->device; }
host_sim::SimDevice& SimSession::device() noexcept { return impl_->device; }
const SimConfig& SimSession::config() const noexcept { return impl_->config; }
const ControllerConfig& SimSession::controller_config() const noexcept { return impl_->controller_config; }

}  // namespace toonforce
