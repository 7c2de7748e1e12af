// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The servo loop: the one closed loop of toonforce (`run` on every device, `sim`, `figures`,
/// `replay`, the examples and the tests all drive it). One tick at integer time k, data flowing
/// one way (spec effects.md §0, §6):
///
///   read the device -> supervisor (latches, watchdog, enable, e-stop, homing: a gate)
///   -> the handle (position; velocity given or estimated, control/hip_sensor.hpp)
///   -> scene force with the non-finite guard (control/scene_stage.hpp)
///   -> safety chain: engage and soft start, passivity, thermal, workspace and speed, rate
///      limit, clamp last -> write the device.
///
/// Each stage is a small type with its own tests. Which stages exist is a compile-time choice
/// (LoopStages, servo_config.hpp): a stage the loop is not built with is an empty type and
/// costs nothing, as does the velocity estimator when neither the scene nor a stage needs it.
/// Time is the integer tick count (control/clock.hpp): dt = (k - k_previous) T.
///
/// The tick is noexcept and allocation-, lock- and exception-free; its only system calls are
/// the device's and the pins' own. `tick(k)` is callable from any scheduler: the host's timer
/// (control/realtime_runner.hpp), a self-clocked device's own servo thread, or a simulation.
/// `request_rearm()` may be called from any thread (one atomic counter, which the tick only reads).

#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>

#include "toonforce/control/clock.hpp"
#include "toonforce/control/engage.hpp"
#include "toonforce/control/faults.hpp"
#include "toonforce/control/force_safety.hpp"
#include "toonforce/control/hip_sensor.hpp"
#include "toonforce/control/motion_limits.hpp"
#include "toonforce/control/passivity.hpp"
#include "toonforce/control/scene_stage.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/control/supervisor.hpp"
#include "toonforce/control/telemetry.hpp"
#include "toonforce/control/thermal_model.hpp"
#include "toonforce/hal/device.hpp"
#include "toonforce/hal/pins.hpp"

namespace toonforce {

namespace detail {
template <class SceneT, bool kLive>
struct MailboxOf {
  using type = void;
};
template <class SceneT>
struct MailboxOf<SceneT, true> {
  using type = SceneMailbox<SceneT>;
};
/// A live loop's own side of its mailbox (its index and copies); nothing in a loop that is not.
struct NoIntake {};
template <class SceneT, bool kLive>
struct IntakeOf {
  using type = NoIntake;
};
template <class SceneT>
struct IntakeOf<SceneT, true> {
  using type = SceneIntake<SceneT>;
};
/// Where a live loop keeps an update offered to it (ServoLoop::offer); nothing when not live
/// (a type of its own: two empty members of one type may not share an address, and a byte
/// more in the loop moved its tick's code).
struct NoOffer {};
template <class SceneT, bool kLive>
struct OfferOf {
  using type = NoOffer;
};
template <class SceneT>
struct OfferOf<SceneT, true> {
  using type = const SceneUpdate<SceneT>*;
};
}  // namespace detail

/// The outcome of one tick.
struct TickStatus {
  LoopState state = LoopState::kIdle;
  FaultSet faults;          ///< this tick's faults, latched ones included
  std::uint8_t limits = 0;  ///< Limit bits
  DeviceStatus read = DeviceStatus::kOk;
  DeviceStatus write = DeviceStatus::kOk;
  bool rearm_refused = false;  ///< a re-arm was asked for while a latched cause persists
  constexpr bool ok() const noexcept { return !faults && read == DeviceStatus::kOk && write == DeviceStatus::kOk; }
};

template <ServoDevice Device, SceneType SceneT, class PinsT = NullPins, LoopStages kStages = kEveryStage>
class ServoLoop {
 public:
  using S = typename SceneT::Scalar;
  using Scene = SceneT;
  using Stage = SceneStage<SceneT, kStages.live>;
  static constexpr std::size_t kSlots = Stage::kActiveCapacity;
  /// Whether anything in this loop can need a velocity estimate (else the estimator is compiled out).
  static constexpr bool kMayEstimate =
      has(SceneT::kNeeds, Needs::kVelocity) || kStages.motion_limits || (kStages.passivity && kSlots > 0);
  /// What a live loop's updates come through (scene_updates.hpp; void unless live).
  using Mailbox = typename detail::MailboxOf<SceneT, kStages.live>::type;
  /// What the device reads and is written in: double, or the loop's own scalar (hal/device.hpp).
  using DeviceScalar = device_scalar_t<Device>;
  static_assert(std::same_as<DeviceScalar, double> || std::same_as<DeviceScalar, S>,
                "a device reads in double or in the loop's scalar");
  /// A Q loop with a passivity stage whose device reads in its scalar: every tick with a
  /// position counts (a Q value is finite), so the sensor's step since the last counted tick is
  /// the passivity observer's step since the last good position, taken once (HipSensor's kStep).
  static constexpr bool kStepShared = kIsFixed<S> && std::same_as<DeviceScalar, S> && kStages.passivity;
  /// A fixed-point loop keeps its time in integer nanoseconds (no floating point on a tick).
  using Clock = BasicLoopClock<kIsFixed<S>>;

  /// `config` must pass check_servo_config(); the loop starts engaging at its first tick.
  /// constexpr: a target may build its loop at compile time, its double settings converted
  /// by the compiler (tools/mcu), and copy it into place.
  constexpr ServoLoop(Device device, const SceneT& scene, const ServoConfig& config, PinsT pins = {}) noexcept
      : device_(std::move(device)),
        pins_(pins),
        clock_(config.period_s, kStages.stamps && config.time_from_stamps),
        supervisor_(config.supervisor()),
        scene_(scene),
        engage_(config.engage()),
        passivity_(config.safety.passivity, Stage::slots_of(scene), unlimited_or(config.limits), config.period_s),
        thermal_(config.safety.thermal, config.period_s, unlimited_or(config.limits)),
        motion_(config.motion_limits()),
        safety_(config.limits),
        // A live scene may come to need the velocity: what its type may need decides.
        sensor_(config.velocity_cutoff_hz,
                has(kStages.live ? SceneT::kNeeds : scene.needs(), Needs::kVelocity) || motion_.needs_velocity() ||
                    passivity_.needs_velocity(),
                config.period_s),
        max_force_n_(scalar_cast<S>(unlimited_or(config.limits))),
        fade_ticks_(kStages.live ? std::llround(config.safety.update_fade_s / config.period_s) : 0) {}

  /// A live loop takes its scene updates from `mailbox` (the application's side pushes them;
  /// config/scene_editor.hpp) from the next tick on, from the mailbox's first update: no other
  /// loop has taken any of it. Before the loop runs, or from its thread.
  // clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
  // clang-format off
  template <class M>
  void listen(M& mailbox) noexcept
    requires(kStages.live && std::same_as<M, Mailbox>)
  {
    mailbox_ = &mailbox;
    intake_.restart();
  }
  /// A live loop whose updates another checks (a World: one update for all its devices, so
  /// that they change on the same tick): applies `checked` at its next tick, before anything
  /// from its mailbox. `checked` passed check_update against this loop's scene() and stays in
  /// place until that tick. Before the loop runs, or from its thread.
  template <class U>
  void offer(const U& checked) noexcept
    requires(kStages.live && std::same_as<const U*, typename detail::OfferOf<SceneT, kStages.live>::type>)
  {
    offered_ = &checked;
  }
  // clang-format on
  /// Live loop: updates applied since the start.
  std::uint64_t updates_applied() const noexcept { return updates_applied_; }
  /// Live loop: updates refused since the start (torn, or failing the checks of
  /// docs/spec/live-scenes.md): taken off the mailbox and not applied.
  std::uint64_t updates_refused() const noexcept {
    if constexpr (kStages.live) {
      return intake_.refused();
    } else {
      return 0;
    }
  }

  /// One tick at integer time `k` (strictly increasing; a smaller k is taken as last + 1).
  TickStatus tick(std::int64_t k) noexcept { return tick(Instant{k, 0}); }

  /// One tick at `now`; with ServoConfig::time_from_stamps its stamp gives dt (replay).
  TickStatus tick(Instant now) noexcept {
    pins_.tick.toggle();
    if constexpr (kIsFixed<S>) clear_fixed_saturated();  // this tick's flag only (read at its end)
    const TickTime time = clock_.advance(now);

    // In: the device, and whether force may flow at all.
    BasicDeviceReading<DeviceScalar> reading{};
    const DeviceStatus read = device_.read(reading);
    const Gate gate = supervisor_.admit(time.gap, pins_.estop.read(), pins_.enable.read(), read);
    if (gate.position) position_m_ = reading.position_m;
    if (gate.reopened) engage_.reset();
    if (gate.ramp_again_now) engage_.restart(time.now.tick);
    if (gate.ramp_again_next) engage_.restart(time.now.tick + 1);

    // The handle; what the force held since the last tick did: heat (thermal), energy (passivity).
    const Hip<S> hip = gate.position ? sensor_.sense(reading, time) : Hip<S>{};
    thermal_.advance(out_.force_n, time.gap);
    bool derated = false;
    if (thermal_.enabled()) {
      const S allowed = thermal_.allowed_force();
      safety_.set_max_force(allowed);
      derated = allowed < max_force_n_;
    }
    if constexpr (kStepShared) {
      passivity_.observe_step(out_.force_n, sensor_.step(), hip.stepped);
    } else {
      passivity_.observe(out_.force_n, hip.position_m, hip.position_finite);
    }
    if constexpr (kStages.live) take_update(gate, hip, time);

    // The scene and the safety chain (into out_); no position, no force.
    Outcome& out = out_;
    out.faults = FaultSet{};
    out.limits = 0;
    if (gate.position) {
      shape(gate, hip, time, out);
    } else {
      out.scene_n = out.damping_n = Vec3<S>{};
      cut(out, -1);
    }

    // Out.
    const DeviceStatus write = device_.write(to_device(out.force_n));
    out.faults |= gate.faults | supervisor_.wrote(write);
    if (derated) out.limits = out.limits | Limit::kThermal;
    if (reading.force_limited) out.limits = out.limits | Limit::kDeviceLimited;
    if constexpr (kIsFixed<S>) {
      if (fixed_saturated()) out.faults.set(Fault::kFixedSaturation);
    }
    return finish(out, gate, read, write);
  }

  /// The next tick after the last one (for a self-clocked device's scheduler).
  TickStatus tick() noexcept { return tick(clock_.next()); }

  /// The last tick of a run: commands zero force (bypassing every limit) and goes idle, so a
  /// stop leaves the device without force before anything else happens.
  TickStatus shutdown(std::int64_t k) noexcept {
    TickStatus status;
    BasicDeviceReading<DeviceScalar> reading{};
    status.read = device_.read(reading);
    if (status.read == DeviceStatus::kOk) position_m_ = reading.position_m;
    safety_.zero();
    out_.force_n = out_.damping_n = Vec3<S>{};
    out_.gain = S{};
    status.write = device_.write(Vec3<DeviceScalar>{});
    supervisor_.shut_down();
    const Instant next = clock_.next();
    static_cast<void>(clock_.advance(Instant{clock_.started() && k < next.tick ? next.tick : k, next.stamp_ns}));
    pins_.lights.show(LightState::kIdle);
    shown_ = LoopState::kIdle;
    state_ = LoopState::kIdle;
    status.state = state_;
    status.faults = supervisor_.latched();
    last_status_ = status;
    return status;
  }

  /// Asks the loop to clear its latched faults at its next tick; refused (TickStatus::
  /// rearm_refused) while the e-stop is engaged or the device does not answer. Any thread.
  void request_rearm() noexcept { supervisor_.request_rearm(); }

  /// The last tick as a telemetry frame (outside the tick's budget: converts to double and
  /// asks the effects for their values). Timing is the runner's to fill.
  void fill_frame(TelemetryFrame& f) const noexcept {
    f.tick = clock_.last().tick;
    f.t_s = clock_.time_s();
    f.position_m = to_double(position_m_);
    f.velocity_m_per_s = to_double(sensor_.committed_velocity());
    f.force_n = to_double(out_.force_n);
    f.scene_force_n = to_double(out_.scene_n);
    f.damping_n = to_double(out_.damping_n);
    f.faults = last_status_.faults.bits();
    f.latched = supervisor_.latched().bits();
    f.limits = last_status_.limits;
    f.state = static_cast<std::uint8_t>(last_status_.state);
    const std::size_t n = scene_.scene().value_count();
    f.value_count = static_cast<std::uint16_t>(n < kMaxEffectValues ? n : kMaxEffectValues);
    if constexpr (SceneT::kValueCapacity <= kMaxEffectValues) {
      f.in_contact = describe(f.values.data());
    } else {  // a scene that may show more than a frame carries: the first kMaxEffectValues
      std::array<double, SceneT::kValueCapacity> all{};
      f.in_contact = describe(all.data());
      for (std::size_t i = 0; i < f.value_count; ++i) f.values[i] = all[i];
    }
    f.max_force_n = safety_.has_max_force() ? to_double(safety_.max_force()) : std::numeric_limits<double>::infinity();
    f.temperature = thermal_.temperature().to_double();
    if constexpr (kStages.passivity) {
      f.observed_energy_j = passivity_.observer().energy().to_double();
      f.episode_energy_j = passivity_.controller().max_episode_energy(passivity_.slots()).to_double();
    }
    f.gain = to_double(out_.gain);
  }

  LoopState state() const noexcept { return state_; }
  FaultSet latched() const noexcept { return supervisor_.latched(); }
  const TickStatus& last_status() const noexcept { return last_status_; }
  std::int64_t last_tick() const noexcept { return clock_.last().tick; }
  const SceneT& scene() const noexcept { return scene_.scene(); }
  const typename SceneT::State& scene_state() const noexcept { return scene_.state(); }
  /// The effects' values after the last tick that counted (`scene().value_count()` of them).
  bool describe(double* values) const noexcept {
    return scene_.describe(values, sensor_.committed_position(), sensor_.committed_velocity(), sensor_.committed_at(),
                           clock_.period_s_for_input());
  }
  const auto& thermal() const noexcept { return thermal_; }
  auto& thermal() noexcept { return thermal_; }
  const auto& passivity() const noexcept { return passivity_; }
  const auto& force_safety() const noexcept { return safety_; }
  /// The last commanded force [N] (what was written).
  const Vec3<S>& force() const noexcept { return out_.force_n; }
  /// The scene's force before the safety chain on the last tick that counted [N].
  const Vec3<S>& scene_force() const noexcept { return out_.scene_n; }
  /// The velocity the scene saw on the last tick that counted [m/s] (zero if none needed).
  const Vec3<S>& velocity() const noexcept { return sensor_.committed_velocity(); }
  Device& device() noexcept { return device_; }
  const Device& device() const noexcept { return device_; }
  PinsT& pins() noexcept { return pins_; }

 private:
  /// What the scene and the safety chain made of one tick.
  struct Outcome {
    Vec3<S> force_n;    ///< to command
    Vec3<S> scene_n;    ///< the scene's force (zero on a tick that did not count)
    Vec3<S> damping_n;  ///< the passivity controller's
    S gain{};           ///< soft start
    FaultSet faults;
    std::uint8_t limits = 0;
  };

  /// The scene with the non-finite guard, then the safety chain, into `o`.
  void shape(const Gate& gate, const Hip<S>& hip, const TickTime& time, Outcome& o) noexcept {
    const std::int64_t k = time.now.tick;
    SceneForce<S> scene{};
    // The [[likely]]/[[unlikely]] hints here lay the dearer side in line: it is the tick's static
    // bound's path, where a taken branch costs 1 + 3 cycles and one not taken 1 (Cortex-M3 TRM r2p1
    // table 3-1); no value changes.
    if (hip.finite) [[likely]]
      scene = scene_.force(Stage::input(hip, time));
    o.scene_n = scene.force_n;
    if (!scene.counts) {  // spec §6.1: zero now, bypassing the rate limit; states kept
      o.faults.set(hip.finite ? Fault::kNonFiniteForce : Fault::kNonFiniteInput);
      o.damping_n = Vec3<S>{};
      cut(o, k);  // the velocity stays the last one the scene saw
      return;
    }
    sensor_.commit(hip, time);
    // Episodes are tracked whatever the gate says: the budget is per contact, not per ramp.
    const bool damping = passivity_.damping(scene_.active(), hip.velocity_m_per_s, o.damping_n);
    o.faults |= motion_.check(hip.position_m, hip.velocity_m_per_s);
    // (The hint: the dearer side in line, for the bound.)
    if (!gate.open || o.faults) [[unlikely]]
      return cut(o, gate.open ? k : -1);
    o.gain = engage_.gain(scene.force_n, k);
    if (engage_.engaging()) {
      o.limits = o.limits | Limit::kEngaging;
      return cut(o, -1);
    }
    // A Q scene without active parts has no damping, and 0 + f is f: the saturating add is an
    // asm statement GCC cannot fold away, so it is not written (16 instructions of
    // the bound). Floating point adds as it did (f + 0 turns -0 into the +0 traces print).
    const Vec3<S> wanted = [&] {
      if constexpr (kIsFixed<S> && kSlots == 0) {
        return scene.force_n;
      } else {
        return scene.force_n + o.damping_n;
      }
    }();
    const auto limited = safety_.limit_step(times_in_range(wanted, o.gain), max_step_of(time));  // gain in [0, 1]
    o.force_n = limited.force_n;
    o.limits = static_cast<std::uint8_t>(o.limits | limited.limits);
    if (o.gain < scalar_cast<S>(1.0)) o.limits = o.limits | Limit::kSoftStart;
    if (damping) o.limits = o.limits | Limit::kPassivity;
    passivity_.settle(wanted, o.force_n);
  }

  /// A live loop's one update a tick, if there is one: copied out of the mailbox into the
  /// loop's own memory and checked whole (SceneIntake), then applied whole before the scene's
  /// force; a refused one is counted and the scene stays as it was. A tick without an update
  /// reads the mailbox's one index.
  void take_update(const Gate& gate, const Hip<S>& hip, const TickTime& time) noexcept {
    if constexpr (kStages.live) {
      const typename Mailbox::Update* update = offered_;
      offered_ = nullptr;
      const bool mailed = update == nullptr;
      if (mailed) {
        if (mailbox_ == nullptr) return;
        if (intake_.take(*mailbox_, scene_.scene()) != Intake::Taken::kChecked) return;
        update = &intake_.update();
      }
      const TickInput<S> in = Stage::input(hip, time);
      scene_.apply(*update, gate.position && hip.finite ? &in : nullptr, time.now, fade_ticks_);
      passivity_.relayout(scene_.active_slots());
      if (mailed) mailbox_->report_applied(update->sequence);
      ++updates_applied_;
    }
  }

  /// Zero force now (bypassing the rate limit); if it was on at tick `k` >= 0, ramp again after.
  void cut(Outcome& o, std::int64_t k) noexcept {
    if (k >= 0) engage_.restart(k + 1);
    safety_.zero();
    passivity_.cut();
    o.force_n = Vec3<S>{};
    o.gain = S{};
  }

  TickStatus finish(const Outcome& out, const Gate& gate, DeviceStatus read, DeviceStatus write) noexcept {
    state_ = supervisor_.latched()             ? LoopState::kFaulted
             : gate.mode != LoopState::kActive ? gate.mode
                                               : engage_.state();
    show_lights();
    TickStatus status;
    status.state = state_;
    status.faults = out.faults | supervisor_.latched();
    status.limits = out.limits;
    status.read = read;
    status.write = write;
    status.rearm_refused = gate.rearm_refused;
    last_status_ = status;
    return status;
  }

  /// The rate limit's largest step this tick, max_force_rate * dt (the period's, computed
  /// once, on a regular tick).
  S max_step_of(const TickTime& time) const noexcept {
    if constexpr (kIsFixed<S>) {  // integer time: 1e9 / dt_ns
      if (!kStages.stamps || time.period_ns > 0) {
        // A fixed period: gap periods' step, no division in the tick. Past the
        // largest gap that fits it saturates, with the flag, as the division did.
        if (time.gap == 1) return period_max_step_;
        if (time.gap > max_step_gaps_) {
          return period_max_step_.raw() > 0 ? S::from_wide(std::int64_t{std::numeric_limits<std::int32_t>::max()} + 1)
                                            : S{};  // a step of 0 (rate T below 2^-16 N) stays 0
        }
        // gap <= max_step_gaps_ = floor((2^31 - 1) / step): the product fits 32 bits, so it is
        // one 32-bit multiply without a saturation test (a 64-bit one was three).
        return S::from_raw(period_max_step_.raw() * static_cast<typename S::Raw>(time.gap));
      }
      // Stamps: a dt of the configured period takes the step computed once.
      if (time.dt_ns == clock_.period_ns()) return period_max_step_;
      return safety_.max_step_for_ns(time.dt_ns);
    } else {
      if (time.gap == 1 && time.period_s > 0.0) return period_max_step_;
      return safety_.max_step_for(scalar_cast<S>(1.0 / time.dt_s()));
    }
  }

  static constexpr std::int64_t largest_step_gap(S period_step) noexcept {
    if constexpr (kIsFixed<S>) {
      return period_step.raw() > 0 ? std::numeric_limits<std::int32_t>::max() / period_step.raw()
                                   : std::numeric_limits<std::int32_t>::max();  // step >= 0 (rate > 0)
    } else {
      return 0;
    }
  }
  /// max_force_rate * period: fixed point from the integer period, as a stamped tick computes it.
  static constexpr S period_step(const ForceSafety<S>& safety, const Clock& clock) noexcept {
    if constexpr (kIsFixed<S>) {
      return safety.max_step_for_ns(clock.period_ns());
    } else {
      return safety.max_step_for(scalar_cast<S>(1.0 / clock.period_s()));
    }
  }

  /// The force as the device takes it: double, or the loop's scalar as it is.
  static constexpr Vec3<DeviceScalar> to_device(const Vec3<S>& force_n) noexcept {
    if constexpr (std::same_as<DeviceScalar, double>) {
      return to_double(force_n);
    } else {
      return force_n;
    }
  }

  void show_lights() noexcept {
    if (state_ == shown_) return;
    shown_ = state_;
    switch (state_) {
      case LoopState::kIdle: pins_.lights.show(LightState::kIdle); break;
      case LoopState::kHoming: pins_.lights.show(LightState::kHoming); break;
      case LoopState::kEngaging:
      case LoopState::kRamping:
      case LoopState::kActive: pins_.lights.show(LightState::kArmed); break;
      case LoopState::kFaulted: pins_.lights.show(LightState::kFault); break;
    }
  }

  /// Without a configured max force, the thermal model and the damping cap use this [N].
  static constexpr double kUnlimitedForceN = 1000.0;
  static constexpr double unlimited_or(const ForceLimits& l) noexcept {
    return l.has_max_force ? l.max_force_n : kUnlimitedForceN;
  }

  template <bool kOn, template <class> class On, template <class> class Off>
  using StageOf = std::conditional_t<kOn, On<S>, Off<S>>;
  template <class T>
  using PassivityOn = Passivity<T, kSlots>;
  template <class T>
  using PassivityOff = NoPassivity<T, kSlots>;

  Device device_;
  [[no_unique_address]] PinsT pins_;
  Clock clock_;
  std::conditional_t<kStages.supervisor, Supervisor, NoSupervisor> supervisor_;
  Stage scene_;
  [[no_unique_address]] StageOf<kStages.engage, Engage, NoEngage> engage_;
  [[no_unique_address]] StageOf<kStages.passivity, PassivityOn, PassivityOff> passivity_;
  StageOf<kStages.thermal, ThermalModel, NoThermal> thermal_;
  [[no_unique_address]] StageOf<kStages.motion_limits, MotionLimits, NoMotionLimits> motion_;
  ForceSafety<S> safety_;
  HipSensor<S, kMayEstimate, kStages.stamps, kStepShared> sensor_;
  S max_force_n_;  ///< the configured clamp (the thermal model derates below it)
  S period_max_step_ = period_step(safety_, clock_);
  /// Fixed point: the largest gap whose step gap * period_max_step_ fits the format.
  std::int64_t max_step_gaps_ = largest_step_gap(period_max_step_);
  std::int64_t fade_ticks_;  ///< live: the update fade, in ticks
  Mailbox* mailbox_ = nullptr;
  using Intake = typename detail::IntakeOf<SceneT, kStages.live>::type;
  [[no_unique_address]] Intake intake_{};  ///< live: the loop's index and copies (not shared)
  /// Live: an update another checked for this loop (offer), applied at the next tick.
  [[no_unique_address]] typename detail::OfferOf<SceneT, kStages.live>::type offered_{};
  std::uint64_t updates_applied_ = 0;

  // State between ticks: the last tick's outcome (its force is held until the next write).
  Outcome out_{};
  LoopState state_ = LoopState::kEngaging;
  LoopState shown_ = LoopState::kIdle;

  // For telemetry.
  TickStatus last_status_{};
  Vec3<DeviceScalar> position_m_{};
};

}  // namespace toonforce
