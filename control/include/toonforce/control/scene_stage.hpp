#pragma once
/// The scene's force for one tick, with the non-finite guard (spec effects.md §6.1): a scene
/// force that is not finite does not count: the effects' states stay as they were and the tick
/// gives zero force. The states are double-buffered: the effects update a copy, which becomes
/// the state only if the tick counts. The active parts (the slippery force, a running impact)
/// are reported by the effects themselves, for the passivity controller.

#include <array>
#include <cstddef>
#include <limits>

#include "toonforce/control/hip_sensor.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {

template <Scalar S>
struct SceneForce {
  Vec3<S> force_n;     ///< the scene's force (zero when the tick does not count)
  bool counts = false; ///< finite inputs and force: the effects' new states are committed
};

template <SceneType SceneT>
class SceneStage {
 public:
  using S = typename SceneT::Scalar;
  static constexpr std::size_t kActiveCapacity = SceneT::kActiveCapacity;

  explicit SceneStage(const SceneT& scene) noexcept : scene_(scene) {}

  /// The inputs the effects see this tick.
  static TickInput<S> input(const Hip<S>& hip, const TickTime& time) noexcept {
    TickInput<S> in{};
    in.position_m = hip.position_m;
    in.velocity_m_per_s = hip.velocity_m_per_s;
    in.rate_hz = hip.rate_hz;
    in.now = time.now;
    in.period_s = time.period_s;
    return in;
  }

  /// The scene's force on `in`, the effects' new states committed if it is finite.
  SceneForce<S> force(const TickInput<S>& in) noexcept {
    const Vec3<S> f = scene_.force(in, states_[current_], states_[1 - current_], active_.data());
    // One test for the three components: a sum is non-finite if any term is (or if the sum of
    // three finite ones overflows, a force no device could take either). A Q value is always
    // finite (it saturates instead).
    if constexpr (!kIsFixed<S>) {
      if (!is_finite(f.x + f.y + f.z)) return {};
    }
    current_ = 1 - current_;  // commit
    last_position_m_ = in.position_m;  // what describe() needs besides the velocity
    last_now_ = in.now;
    started_ = true;
    return {f, true};
  }

  /// This tick's active parts (valid after a tick that counted).
  const ActiveForce<S>* active() const noexcept { return active_.data(); }
  std::size_t active_slots() const noexcept { return scene_.active_slots(); }
  /// The effects' values after the last tick that counted (outside the tick: for telemetry),
  /// given the velocity that tick saw and the loop's time base.
  bool describe(double* values, const Vec3<S>& velocity_m_per_s, double period_s) const noexcept {
    if (!started_) {  // nothing to show before the first tick that counted
      for (std::size_t i = 0; i < scene_.value_count(); ++i) values[i] = std::numeric_limits<double>::quiet_NaN();
      return false;
    }
    TickInput<S> in{};
    in.position_m = last_position_m_;
    in.velocity_m_per_s = velocity_m_per_s;
    in.now = last_now_;
    in.period_s = period_s;
    return scene_.describe(states_[current_], in, values);
  }
  const SceneT& scene() const noexcept { return scene_; }
  const typename SceneT::State& state() const noexcept { return states_[current_]; }

 private:
  SceneT scene_;
  typename SceneT::State states_[2]{};
  int current_ = 0;
  std::array<ActiveForce<S>, (kActiveCapacity > 0 ? kActiveCapacity : 1)> active_{};
  Vec3<S> last_position_m_{};  ///< of the last tick that counted (for describe)
  Instant last_now_{};
  bool started_ = false;
};

}  // namespace toonforce
