// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The scene's force for one tick, with the non-finite guard (spec effects.md §6.1): a scene
/// force that is not finite does not count: the effects' states stay as they were and the tick
/// gives zero force. The states are double-buffered: the effects update a copy, which becomes
/// the state only if the tick counts. The active parts (the slippery force, a running impact)
/// are reported by the effects themselves, for the passivity controller.
///
/// A live stage (kLive; docs/spec/live-scenes.md) also takes whole scene updates
/// between ticks (`apply`) and keeps the force continuous across them: the difference between
/// the old scene's force and the new one's at the update's tick is added to the new scene's
/// force and faded out linearly over the fade time, so a surface that appears around the handle
/// ramps in and a stiffness that jumps is felt as a ramp. That fading difference is not any
/// effect's law: it is reported as one more active part (the last slot), so the passivity
/// controller budgets the energy updates inject. A stage built without kLive has none of this.

#include <array>
#include <cstddef>
#include <limits>
#include <type_traits>

#include "toonforce/control/hip_sensor.hpp"
#include "toonforce/control/scene_updates.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {

template <Scalar S>
struct SceneForce {
  Vec3<S> force_n;      ///< the scene's force (zero when the tick does not count)
  bool counts = false;  ///< finite inputs and force: the effects' new states are committed
};

template <SceneType SceneT, bool kLive = false>
class SceneStage {
 public:
  using S = typename SceneT::Scalar;
  /// The scene's active parts, and in a live stage the update fade's after them.
  static constexpr std::size_t kActiveCapacity = SceneT::kActiveCapacity + (kLive ? 1 : 0);

  constexpr explicit SceneStage(const SceneT& scene) noexcept : scene_(scene) {}
  /// The active slots a stage on `scene` uses.
  static constexpr std::size_t slots_of(const SceneT& scene) noexcept { return scene.active_slots() + (kLive ? 1 : 0); }

  /// The inputs the effects see this tick.
  static constexpr TickInput<S> input(const Hip<S>& hip, const TickTime& time) noexcept {
    TickInput<S> in{};
    in.position_m = hip.position_m;
    in.velocity_m_per_s = hip.velocity_m_per_s;
    in.rate_hz = hip.rate_hz;
    in.now = time.now;
    in.period_s = time.period_s;
    if constexpr (kIsFixed<S>) in.period_ns = time.period_ns;
    return in;
  }

  /// The scene's force on `in`, the effects' new states committed if it is finite.
  SceneForce<S> force(const TickInput<S>& in) noexcept {
    Vec3<S> f;
    if constexpr (kIsFixed<S>) {
      // A Q force is always finite, so the tick always commits: the effects update their
      // states in place (the copy of the states was on every tick's bound). Only an
      // update flips current_, so a stage that is not live has its states at index 0: a fixed
      // address (the bound again: the cliff's state accesses each added the index).
      f = scene_.force(in, states_[kLive ? current_ : 0], active_.data());
    } else {
      f = scene_.force(in, states_[current_], states_[1 - current_], active_.data());
    }
    if constexpr (kLive) f += fade_.offset_n;
    // One test for the three components: the squared magnitude is non-finite if any component
    // is, and also when a finite force is so large that its square overflows (stiffness = 1e308):
    // the clamp and the rate limit measure the force by that square, and would scale such a
    // force to a silent 0. Such a force is a fault, like a NaN. A Q value is always
    // finite (it saturates instead).
    if constexpr (!kIsFixed<S>) {
      if (!is_finite(dot(f, f))) return {};
      current_ = 1 - current_;  // commit
    }
    started_ = true;
    if constexpr (kLive) fade_.advance(active_[scene_.active_slots()]);
    return {f, true};
  }

  /// Live stage, between two ticks (at the start of tick `now`, before its force): puts the
  /// update's scene in place whole, carries the effects' states over, fires its events. `in` is
  /// this tick's input if the HIP's position is known (else null: no force flows, nothing to
  /// keep continuous); the force difference fades over `fade_ticks` ticks (0: none).
  // clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
  // clang-format off
  template <class Update>  // SceneUpdate<SceneT>; a template so that a scene that cannot be live never names it
  void apply(const Update& update, const TickInput<S>* in, Instant now, std::int64_t fade_ticks) noexcept
    requires kLive
  {
    // clang-format on
    // What the old scene (with the fade still running) gives here, its states untouched.
    const bool measure = in != nullptr && started_ && fade_ticks > 0;
    Vec3<S> before{};
    if (measure) before = scene_.force(*in, states_[current_], scratch_, scratch_active_.data()) + fade_.offset_n;
    update.scene.carry(states_[current_], states_[1 - current_], update.continues.data());
    scene_ = update.scene;
    current_ = 1 - current_;
    Vec3<S> offset{};
    if (measure) {
      offset = before - scene_.force(*in, states_[current_], scratch_, scratch_active_.data());
      if constexpr (!kIsFixed<S>) {
        if (!is_finite(dot(offset, offset))) offset = Vec3<S>{};  // the guard of the tick decides
      }
    }
    fade_.start(offset, fade_ticks);
    // Events after the difference: a shake on demand is the effect's own law, not faded.
    for (std::size_t i = 0; i < update.event_count && i < update.events.size(); ++i) {
      const SceneEvent& e = update.events[i];
      static_cast<void>(scene_.fire(states_[current_], e.effect, e.event, e.value, now));
    }
  }
  /// Live stage: the force difference still fading [N].
  // clang-format off
  const Vec3<S>& fade_offset() const noexcept
    requires kLive
  {
    return fade_.offset_n;
  }
  // clang-format on

  /// This tick's active parts (valid after a tick that counted).
  const ActiveForce<S>* active() const noexcept { return active_.data(); }
  std::size_t active_slots() const noexcept { return slots_of(scene_); }
  /// The effects' values after the last tick that counted (outside the tick: for telemetry),
  /// given that tick's position, velocity and time (the loop keeps them: HipSensor) and the
  /// loop's time base.
  bool describe(double* values, const Vec3<S>& position_m, const Vec3<S>& velocity_m_per_s, Instant now,
                double period_s) const noexcept {
    if (!started_) {  // nothing to show before the first tick that counted
      for (std::size_t i = 0; i < scene_.value_count(); ++i) values[i] = std::numeric_limits<double>::quiet_NaN();
      return false;
    }
    TickInput<S> in{};
    in.position_m = position_m;
    in.velocity_m_per_s = velocity_m_per_s;
    in.now = now;
    in.period_s = period_s;
    return scene_.describe(states_[current_], in, values);
  }
  const SceneT& scene() const noexcept { return scene_; }
  const typename SceneT::State& state() const noexcept { return states_[current_]; }

 private:
  /// The update fade of a live stage: the offset added to the scene's force, stepping to zero.
  struct Fade {
    Vec3<S> offset_n{};
    Vec3<S> step_n{};
    std::int64_t ticks_left = 0;
    bool starting = false;  ///< a new fade episode (none was running)

    void start(const Vec3<S>& offset, std::int64_t ticks) noexcept {
      starting = starting || ticks_left == 0;
      if (ticks <= 0 || offset == Vec3<S>{}) {
        *this = Fade{};
        return;
      }
      offset_n = offset;
      step_n = offset * scalar_cast<S>(1.0 / static_cast<double>(ticks));
      ticks_left = ticks;
    }
    /// After a tick that counted: report this tick's offset as the active part, then step.
    void advance(ActiveForce<S>& slot) noexcept {
      slot = {offset_n, ticks_left > 0, starting};
      starting = false;
      if (ticks_left == 0) return;
      --ticks_left;
      offset_n = ticks_left == 0 ? Vec3<S>{} : offset_n - step_n;
    }
  };
  struct NoFade {};

  SceneT scene_;
  typename SceneT::State states_[2]{};
  int current_ = 0;
  std::array<ActiveForce<S>, (kActiveCapacity > 0 ? kActiveCapacity : 1)> active_{};
  [[no_unique_address]] std::conditional_t<kLive, Fade, NoFade> fade_{};
  // A live stage evaluates the old and the new scene at an update without committing either.
  [[no_unique_address]] std::conditional_t<kLive, typename SceneT::State, NoFade> scratch_{};
  [[no_unique_address]] std::conditional_t<kLive, decltype(active_), NoFade> scratch_active_{};
  bool started_ = false;  ///< some tick counted
};

}  // namespace toonforce
