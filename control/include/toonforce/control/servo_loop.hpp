#pragma once
/// The servo loop: one deterministic tick at integer time k (spec effects.md §0, §6):
///   pins (tick toggle, e-stop, enable) -> device read -> velocity (the device's, or the
///   filtered backward difference when the scene or the safety layer needs one) -> Controller
///   (scene force, non-finite guard, [safety layer stage], force-rate limit, clamp last) ->
///   device write -> lights.
/// The safety layer around the controller:
///   - watchdog: a gap of more than `watchdog_periods` between ticks, or `device_timeout_periods`
///     failed device exchanges in a row, latch a fault; an engaged e-stop latches at once.
///     Latched faults give zero force until `request_rearm()` with their cause gone;
///   - enable (deadman) released, device homing, over speed, outside the workspace, a device
///     error, non-finite data: zero force that tick, bypassing the rate limit;
///   - engage: after start, enable and re-arm, forces come on only once the scene force at the
///     current position is below `engage_force`;
///   - soft start: a linear ramp from 0 after engaging and after every fault;
///   - thermal derating: the clamp follows the thermal model (the clamp stays last);
///   - passivity: the Hannaford-Ryu observer every tick, and the controller's damping for the
///     active effects' energy beyond their budget (control/passivity.hpp).
/// Time is the integer tick count: dt = (k - k_previous) * period, so a skipped tick gives
/// dt = 2T and a loop that has run for a day computes dt exactly as in its first second.
///
/// The tick is noexcept and allocation-, lock- and exception-free; its only system calls are
/// the device's and the pins' own. `tick(k)` is callable from any scheduler: the real-time
/// runner (control/realtime_runner.hpp) or a self-clocked device's (`tick()` takes k + 1).
/// `request_rearm()` may be called from any thread (one atomic flag).

#include <atomic>
#include <cstdint>

#include "toonforce/control/active_effects.hpp"
#include "toonforce/control/controller.hpp"
#include "toonforce/control/passivity.hpp"
#include "toonforce/control/pins.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/control/telemetry.hpp"
#include "toonforce/control/thermal_model.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce {

/// What the loop is doing.
enum class LoopState : std::uint8_t {
  kIdle = 0,      ///< enable released (or shut down): no force
  kHoming,        ///< the device is not ready yet (homing, calibrating): no force
  kEngaging,      ///< waiting for the scene force to drop below engage_force
  kRamping,       ///< soft start
  kActive,        ///< full force
  kFaulted,       ///< a latched fault: no force until re-armed
};

constexpr const char* to_string(LoopState s) noexcept {
  switch (s) {
    case LoopState::kIdle: return "idle";
    case LoopState::kHoming: return "homing";
    case LoopState::kEngaging: return "engaging";
    case LoopState::kRamping: return "ramping";
    case LoopState::kActive: return "active";
    case LoopState::kFaulted: return "faulted";
  }
  return "?";
}

/// The outcome of one tick.
struct TickStatus {
  LoopState state = LoopState::kIdle;
  FaultSet faults;        ///< this tick's faults, latched ones included
  std::uint8_t limits = 0;  ///< Limit bits
  DeviceStatus read = DeviceStatus::kOk;
  DeviceStatus write = DeviceStatus::kOk;
  bool rearm_refused = false;  ///< a re-arm was asked for while a latched cause persists
  constexpr bool ok() const noexcept {
    return !faults && read == DeviceStatus::kOk && write == DeviceStatus::kOk;
  }
};

template <ServoDevice Device, SceneType SceneT, class PinsT = NullPins>
class ServoLoop {
 public:
  using S = typename SceneT::Scalar;
  using Active = ActiveEffects<SceneT>;

  /// `config` must pass check_servo_config(); the loop starts engaging at its first tick.
  ServoLoop(Device device, const SceneT& scene, const ServoConfig& config, PinsT pins = {}) noexcept
      : device_(device),
        pins_(pins),
        controller_(scene, config.controller),
        thermal_(config.safety.thermal, config.controller.period_s, max_force_or(config, kUnlimitedForceN)),
        passivity_(config.safety.passivity, max_force_or(config, kUnlimitedForceN)),
        period_s_(config.controller.period_s),
        rate_hz_(scalar_cast<S>(1.0 / config.controller.period_s)),
        soft_start_s_(config.safety.soft_start_s),
        max_force_n_(scalar_cast<S>(max_force_or(config, kUnlimitedForceN))),
        has_max_force_(config.controller.limits.has_max_force),
        engage_force_n_(scalar_cast<S>(config.safety.engage_force_n)),
        max_velocity_m_per_s_(scalar_cast<S>(config.safety.has_max_velocity ? config.safety.max_velocity_m_per_s : 0.0)),
        workspace_min_m_(vec_cast<S>(config.safety.workspace_min_m)),
        workspace_max_m_(vec_cast<S>(config.safety.workspace_max_m)),
        has_max_velocity_(config.safety.has_max_velocity),
        has_workspace_(config.safety.has_workspace),
        watchdog_periods_(config.safety.watchdog_periods),
        device_timeout_periods_(config.safety.device_timeout_periods),
        slots_(Active::slots(scene)),
        estimator_(config.controller.velocity_cutoff_hz) {
    needs_velocity_ = has(scene.needs(), Needs::kVelocity) || has_max_velocity_ ||
                      (config.safety.passivity.controller && slots_ > 0);
  }

  /// One tick at integer time `k` (strictly increasing; a smaller k is taken as last + 1).
  TickStatus tick(std::int64_t k) noexcept {
    pins_.tick.toggle();
    TickStatus status;
    std::int64_t gap = 1;
    if (started_) {
      gap = k - last_tick_;
      if (gap < 1) {
        gap = 1;
        k = last_tick_ + 1;
      }
    }
    if constexpr (kIsFixed<S>) static_cast<void>(take_fixed_saturated());
    FaultSet faults;
    std::uint8_t limits = 0;

    // Inputs that cut the force this very tick.
    const PinLevel estop = pins_.estop.read();
    const bool enabled = pins_.enable.read() == PinLevel::kActive;
    DeviceReading reading{};
    status.read = device_.read(reading);
    const bool read_ok = status.read == DeviceStatus::kOk;
    const bool homing = status.read == DeviceStatus::kNotReady;

    if (rearm_requested_.exchange(false, std::memory_order_acq_rel) && latched_) {
      if (estop == PinLevel::kInactive && read_ok) {
        latched_ = FaultSet{};
        mode_ = LoopState::kEngaging;
      } else {
        status.rearm_refused = true;
      }
    }
    if (estop != PinLevel::kInactive) latched_.set(Fault::kEstop);
    if (started_ && gap > watchdog_periods_) latched_.set(Fault::kWatchdog);
    if (read_ok || homing) {
      failed_reads_ = 0;
    } else {
      faults.set(Fault::kDeviceError);
      if (++failed_reads_ >= device_timeout_periods_) latched_.set(Fault::kDeviceSilent);
    }

    started_ = true;
    last_tick_ = k;
    frame_tick_ = k;
    thermal_.advance(held_force_n_, gap);  // the previous output was held for `gap` periods
    if (thermal_.enabled()) controller_.safety().set_max_force(thermal_.allowed_force());

    // Gates evaluated before the scene: latched fault, enable, homing, failed read.
    if (latched_) {
      mode_ = LoopState::kFaulted;
    } else if (!enabled) {
      mode_ = LoopState::kIdle;
    } else if (homing) {
      mode_ = LoopState::kHoming;
    } else if (mode_ == LoopState::kFaulted || mode_ == LoopState::kIdle || mode_ == LoopState::kHoming) {
      mode_ = LoopState::kEngaging;  // enabled again, homed, or re-armed: engage first
    }
    const bool cut_before = latched_ || !enabled || homing || !read_ok;
    if (!read_ok) restart_ramp(k + 1);

    gain_ = S{};
    damping_n_ = Vec3<S>{};
    TickResult<S> result{};
    if (!read_ok) {
      controller_.safety().zero();  // no position: nothing to compute; command zero
    } else {
      result = control(k, gap, reading, cut_before, faults, limits);
    }
    faults |= result.faults;
    limits = static_cast<std::uint8_t>(limits | result.limits);

    // Out to the device.
    held_force_n_ = result.force_n;
    force_n_ = result.force_n;
    scene_force_n_ = result.scene_force_n;
    status.write = device_.write(to_double(result.force_n));
    if (status.write != DeviceStatus::kOk) {
      faults.set(Fault::kDeviceError);
      if (++failed_writes_ >= device_timeout_periods_) latched_.set(Fault::kDeviceSilent);
      if (mode_ == LoopState::kRamping || mode_ == LoopState::kActive) restart_ramp(k + 1);
    } else {
      failed_writes_ = 0;
    }
    if (latched_) mode_ = LoopState::kFaulted;

    if (thermal_.enabled() && has_max_force_ && controller_.safety().max_force() < max_force_n_) {
      limits = limits | Limit::kThermal;
    }
    if constexpr (kIsFixed<S>) {
      if (take_fixed_saturated()) faults.set(Fault::kFixedSaturation);
    }
    show_lights();

    faults |= latched_;
    status.state = mode_;
    status.faults = faults;
    status.limits = limits;
    last_status_ = status;
    return status;
  }

  /// The next tick after the last one (for a self-clocked device's scheduler).
  TickStatus tick() noexcept { return tick(started_ ? last_tick_ + 1 : 0); }

  /// The last tick of a run: commands zero force (bypassing every limit) and goes idle, so a
  /// stop leaves the device without force before anything else happens.
  TickStatus shutdown(std::int64_t k) noexcept {
    TickStatus status;
    DeviceReading reading{};
    status.read = device_.read(reading);
    if (status.read == DeviceStatus::kOk) position_m_ = reading.position_m;
    controller_.safety().zero();
    held_force_n_ = force_n_ = damping_n_ = Vec3<S>{};
    gain_ = S{};
    status.write = device_.write(Vec3<double>{});
    mode_ = LoopState::kIdle;
    frame_tick_ = started_ && k <= last_tick_ ? last_tick_ + 1 : k;
    last_tick_ = frame_tick_;
    started_ = true;
    pins_.lights.show(LightState::kIdle);
    shown_ = LoopState::kIdle;
    status.state = mode_;
    status.faults = latched_;
    last_status_ = status;
    return status;
  }

  /// Asks the loop to clear its latched faults at its next tick; refused (TickStatus::
  /// rearm_refused) while the e-stop is engaged or the device does not answer. Any thread.
  void request_rearm() noexcept { rearm_requested_.store(true, std::memory_order_release); }

  /// The last tick as a telemetry frame (outside the tick's budget: converts to double and
  /// asks the scene for its diagnostics). Timing is the runner's to fill.
  void fill_frame(TelemetryFrame& f) const noexcept {
    f.tick = frame_tick_;
    f.t_s = static_cast<double>(frame_tick_) * period_s_;
    f.position_m = position_m_;
    f.velocity_m_per_s = to_double(velocity_m_per_s_);
    f.force_n = to_double(force_n_);
    f.scene_force_n = to_double(scene_force_n_);
    f.damping_n = to_double(damping_n_);
    f.faults = last_status_.faults.bits();
    f.latched = latched_.bits();
    f.limits = last_status_.limits;
    f.state = static_cast<std::uint8_t>(last_status_.state);
    const Diagnostics d = controller_.diagnostics();
    f.in_contact = d.in_contact;
    f.impact_time_s = d.impact_time_s;
    f.cliff_state = d.cliff_state;
    f.max_force_n = controller_.safety().has_max_force() ? to_double(controller_.safety().max_force())
                                                          : std::numeric_limits<double>::infinity();
    f.temperature = thermal_.temperature().to_double();
    f.observed_energy_j = observer_.energy().to_double();
    f.episode_energy_j = passivity_.max_episode_energy(slots_).to_double();
    f.gain = to_double(gain_);
  }

  LoopState state() const noexcept { return mode_; }
  FaultSet latched() const noexcept { return latched_; }
  const TickStatus& last_status() const noexcept { return last_status_; }
  std::int64_t last_tick() const noexcept { return last_tick_; }
  const Controller<SceneT>& controller() const noexcept { return controller_; }
  const ThermalModel<S>& thermal() const noexcept { return thermal_; }
  ThermalModel<S>& thermal() noexcept { return thermal_; }
  const PassivityObserver<S>& observer() const noexcept { return observer_; }
  const PassivityController<S, Active::kCapacity>& passivity() const noexcept { return passivity_; }
  std::size_t active_slots() const noexcept { return slots_; }
  /// The last commanded force [N] (what was written).
  const Vec3<S>& force() const noexcept { return force_n_; }
  const Vec3<S>& velocity() const noexcept { return velocity_m_per_s_; }
  Device& device() noexcept { return device_; }
  PinsT& pins() noexcept { return pins_; }

 private:
  /// Without a configured max force, the thermal model and the damping cap use this [N].
  static constexpr double kUnlimitedForceN = 1000.0;
  static double max_force_or(const ServoConfig& c, double fallback) noexcept {
    return c.controller.limits.has_max_force ? c.controller.limits.max_force_n : fallback;
  }

  /// The part of the tick that has a position: observer, velocity, controller with the
  /// safety layer's stage.
  TickResult<S> control(std::int64_t k, std::int64_t gap, const DeviceReading& reading,
                        bool cut_before, FaultSet& faults, std::uint8_t& limits) noexcept {
    Sample sample;
    sample.position_m = reading.position_m;
    sample.now = Instant{k, 0.0};
    sample.dt_s = static_cast<double>(gap) * period_s_;
    position_m_ = reading.position_m;

    const bool position_finite = is_finite(reading.position_m);
    const Vec3<S> x = position_finite ? vec_cast<S>(reading.position_m) : Vec3<S>{};
    if (position_finite) {
      // The force held since the last good position moved the HIP to x (zero-order hold).
      if (has_position_) {
        const Vec3<S> dx = x - previous_position_m_;
        observer_.observe(held_force_n_, dx);
        passivity_.account(dx, applied_, slots_);
      }
      previous_position_m_ = x;
      has_position_ = true;
    }

    Vec3<S> estimate{};
    bool estimated = false;
    if (reading.has_velocity) {
      sample.velocity_m_per_s = reading.velocity_m_per_s;
      sample.has_velocity = true;
    } else if (needs_velocity_ && position_finite) {
      // 1/dt since the last committed tick, as the controller's own estimator would.
      const std::int64_t since = has_commit_ ? k - last_commit_ : gap;
      const S rate = scalar_cast<S>(1.0 / (static_cast<double>(since) * period_s_));
      estimate = estimator_.estimate(x, rate);  // committed below once the tick is good
      sample.velocity_m_per_s = to_double(estimate);
      sample.has_velocity = true;
      estimated = true;
    }

    bool cut = cut_before;
    bool engaging = false;
    Vec3<S> wanted{};
    const auto stage = [&](const Vec3<S>& scene_force, const TickInput<S>& in,
                           const typename SceneT::State& state) noexcept -> Shaped<S> {
      velocity_m_per_s_ = in.velocity_m_per_s;
      // Episodes are tracked whatever the gates say: the budget is per contact, not per ramp.
      Active::collect(controller_.scene(), state, in, active_.data());
      damping_n_ = passivity_.update(active_.data(), slots_, in.velocity_m_per_s, rate_hz_);
      if (has_max_velocity_ && norm(in.velocity_m_per_s) > max_velocity_m_per_s_) {
        faults.set(Fault::kOverspeed);
        cut = true;
      }
      if (has_workspace_ && !inside_workspace(in.position_m)) {
        faults.set(Fault::kOutsideWorkspace);
        cut = true;
      }
      if (cut) {
        if (!cut_before) restart_ramp(k + 1);
        return {Vec3<S>{}, true};
      }
      if (mode_ == LoopState::kEngaging) {
        if (norm(scene_force) < engage_force_n_) {
          start_ramp(k);
        } else {
          engaging = true;
          return {Vec3<S>{}, true};
        }
      }
      gain_ = ramp_gain(k);
      wanted = scene_force + damping_n_;
      return {wanted * gain_, false};
    };
    TickResult<S> result = controller_.tick(sample, stage);

    if (result.faults.has(Fault::kNonFiniteInput) || result.faults.has(Fault::kNonFiniteForce)) {
      // Nothing committed: keep the estimator; force was zeroed; ramp again afterwards.
      if (mode_ == LoopState::kRamping || mode_ == LoopState::kActive) restart_ramp(k + 1);
      applied_ = S{};
      return result;
    }
    if (estimated) estimator_.commit(x, estimate);
    last_commit_ = k;
    has_commit_ = true;
    if (!sample.has_velocity) velocity_m_per_s_ = Vec3<S>{};

    if (engaging) limits = limits | Limit::kEngaging;
    if (cut || engaging) {
      applied_ = S{};
      gain_ = S{};
      return result;
    }
    constexpr S kOne = scalar_cast<S>(1.0);
    if (gain_ < kOne) limits = limits | Limit::kSoftStart;
    if (damping_n_ != Vec3<S>{}) limits = limits | Limit::kPassivity;
    // The share of the wanted force that reached the device (ramp, rate limit and clamp),
    // for the passivity controller's bookkeeping of the next interval.
    const S wanted_squared = dot(wanted, wanted);
    applied_ = wanted_squared > S{} ? max(S{}, min(kOne, dot(result.force_n, wanted) / wanted_squared)) : S{};
    return result;
  }

  bool inside_workspace(const Vec3<S>& x) const noexcept {
    return workspace_min_m_.x <= x.x && x.x <= workspace_max_m_.x && workspace_min_m_.y <= x.y &&
           x.y <= workspace_max_m_.y && workspace_min_m_.z <= x.z && x.z <= workspace_max_m_.z;
  }

  /// Soft start: the gain is 0 at tick `k` and reaches 1 after soft_start seconds.
  void start_ramp(std::int64_t k) noexcept {
    mode_ = LoopState::kRamping;
    ramp_start_ = k;
  }
  /// After a fault that cut the force: ramp again from `k` if the force was (coming) on; a loop
  /// still waiting to engage keeps waiting.
  void restart_ramp(std::int64_t k) noexcept {
    if (mode_ == LoopState::kRamping || mode_ == LoopState::kActive) start_ramp(k);
  }

  S ramp_gain(std::int64_t k) noexcept {
    constexpr S kOne = scalar_cast<S>(1.0);
    if (mode_ != LoopState::kRamping) return kOne;
    // Time from integer ticks, in double, converted once (spec §0).
    const double elapsed_s = static_cast<double>(k - ramp_start_) * period_s_;
    if (!(elapsed_s < soft_start_s_)) {
      mode_ = LoopState::kActive;
      return kOne;
    }
    return scalar_cast<S>(elapsed_s / soft_start_s_);
  }

  void show_lights() noexcept {
    if (mode_ == shown_) return;
    shown_ = mode_;
    switch (mode_) {
      case LoopState::kIdle: pins_.lights.show(LightState::kIdle); break;
      case LoopState::kHoming: pins_.lights.show(LightState::kHoming); break;
      case LoopState::kEngaging:
      case LoopState::kRamping:
      case LoopState::kActive: pins_.lights.show(LightState::kArmed); break;
      case LoopState::kFaulted: pins_.lights.show(LightState::kFault); break;
    }
  }

  Device device_;
  [[no_unique_address]] PinsT pins_;
  Controller<SceneT> controller_;
  ThermalModel<S> thermal_;
  PassivityObserver<S> observer_;
  PassivityController<S, Active::kCapacity> passivity_;
  std::array<ActiveForce<S>, (Active::kCapacity > 0 ? Active::kCapacity : 1)> active_{};

  // Configuration, converted once.
  double period_s_;
  S rate_hz_;
  double soft_start_s_;
  S max_force_n_;
  bool has_max_force_;
  S engage_force_n_;
  S max_velocity_m_per_s_;
  Vec3<S> workspace_min_m_;
  Vec3<S> workspace_max_m_;
  bool has_max_velocity_;
  bool has_workspace_;
  std::int64_t watchdog_periods_;
  std::int64_t device_timeout_periods_;
  std::size_t slots_;
  bool needs_velocity_ = false;

  // State.
  std::atomic<bool> rearm_requested_{false};
  LoopState mode_ = LoopState::kEngaging;
  LoopState shown_ = LoopState::kIdle;
  FaultSet latched_;
  bool started_ = false;
  std::int64_t last_tick_ = 0;
  std::int64_t ramp_start_ = 0;
  std::int64_t failed_reads_ = 0;
  std::int64_t failed_writes_ = 0;
  VelocityEstimator<S> estimator_;
  std::int64_t last_commit_ = 0;
  bool has_commit_ = false;
  Vec3<S> previous_position_m_{};
  bool has_position_ = false;
  Vec3<S> held_force_n_{};  ///< the force commanded at the previous tick (held since)
  S applied_{};             ///< share of the previous tick's wanted force that was commanded
  S gain_{};

  // For telemetry.
  std::int64_t frame_tick_ = 0;
  Vec3<double> position_m_{};
  Vec3<S> velocity_m_per_s_{};
  Vec3<S> force_n_{};
  Vec3<S> scene_force_n_{};
  Vec3<S> damping_n_{};
  TickStatus last_status_{};
};

}  // namespace toonforce
