#pragma once
/// The per-tick computation shared by replay, the host simulation and the servo loop:
///   inputs -> [velocity estimate] -> scene forces -> safety stage -> force.
/// Takes measurements in double (as devices and files give them), converts them to the scene's
/// scalar once, and never allocates, throws, locks or calls the system.
///
/// Non-finite data (spec effects.md §6.1): a non-finite position or velocity, or a non-finite
/// scene force, gives exactly zero force that tick and a fault bit; effect and estimator
/// states stay as they were (time still advances). The next good tick's rate 1/dt then spans
/// the time since the last good one, so a dropped sample does not double the velocity estimate.

#include <cmath>
#include <type_traits>

#include "toonforce/control/faults.hpp"
#include "toonforce/control/force_safety.hpp"
#include "toonforce/control/velocity_estimator.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {

/// One tick's measurement, in double.
struct Sample {
  Vec3<double> position_m;
  Vec3<double> velocity_m_per_s;  ///< used only when has_velocity
  bool has_velocity = false;      ///< the device or input supplies velocity: no estimator
  Instant now;
  double dt_s = 0.0;              ///< [s] true time since the previous tick, > 0
};

struct ControllerConfig {
  ForceLimits limits;
  double velocity_cutoff_hz = VelocityEstimator<double>::kDefaultCutoffHz;
  /// [s] > 0 when ticks are on a fixed period (Instant::tick counts them); 0 for stamped time.
  double period_s = 0.0;
};

template <Scalar S>
struct TickResult {
  Vec3<S> force_n;        ///< what to command, after the safety stage
  Vec3<S> scene_force_n;  ///< the scene's force before the safety stage (0 on a fault)
  FaultSet faults;
  std::uint8_t limits = 0;  ///< Limit bits
};

template <SceneType SceneT>
class Controller {
 public:
  using S = typename SceneT::Scalar;
  using Estimator = std::conditional_t<has(SceneT::kNeeds, Needs::kVelocity), VelocityEstimator<S>,
                                       NoVelocityEstimator<S>>;

  constexpr Controller(const SceneT& scene, const ControllerConfig& config) noexcept
      : scene_(scene), config_(config), safety_(config.limits), estimator_(config.velocity_cutoff_hz) {}

  constexpr TickResult<S> tick(const Sample& sample) noexcept {
    if constexpr (kIsFixed<S>) static_cast<void>(take_fixed_saturated());  // this tick's flag only
    TickResult<S> result{};
    const bool inputs_finite = is_finite(sample.position_m) &&
                               (!sample.has_velocity || is_finite(sample.velocity_m_per_s));
    if (!inputs_finite) {
      result.faults.set(Fault::kNonFiniteInput);
      dropped_since_commit_ = true;
      safety_.zero();
      return result;
    }

    // 1/dt of this tick, for the force-rate limit; the laws and the estimator take 1/dt since
    // the last committed tick, the same unless ticks were dropped as non-finite.
    const S tick_rate_hz = scalar_cast<S>(1.0 / sample.dt_s);
    TickInput<S> in{};
    in.now = sample.now;
    in.period_s = config_.period_s;
    in.rate_hz = tick_rate_hz;
    if (started_ && dropped_since_commit_) in.rate_hz = scalar_cast<S>(1.0 / in.seconds_since(last_commit_));
    in.position_m = vec_cast<S>(sample.position_m);

    const bool estimate = !sample.has_velocity && has(scene_.needs(), Needs::kVelocity);
    if (sample.has_velocity) {
      in.velocity_m_per_s = vec_cast<S>(sample.velocity_m_per_s);
    } else if (estimate) {
      in.velocity_m_per_s = estimator_.estimate(in.position_m, in.rate_hz);
    }

    typename SceneT::State& next = states_[1 - current_];
    scene_.copy_state(states_[current_], next);
    const Vec3<S> scene_force = scene_.force(in, next);
    if (!is_finite(scene_force)) {
      result.faults.set(Fault::kNonFiniteForce);
      dropped_since_commit_ = true;
      safety_.zero();
      return result;
    }
    current_ = 1 - current_;  // commit the effects' and the estimator's new states
    if (estimate) estimator_.commit(in.position_m, in.velocity_m_per_s);
    last_commit_ = sample.now;
    last_position_m_ = in.position_m;
    last_velocity_m_per_s_ = in.velocity_m_per_s;
    dropped_since_commit_ = false;
    started_ = true;

    const auto out = safety_.limit(scene_force, tick_rate_hz);
    result.force_n = out.force_n;
    result.scene_force_n = scene_force;
    result.limits = out.limits;
    if constexpr (kIsFixed<S>) {
      if (take_fixed_saturated()) result.faults.set(Fault::kFixedSaturation);
    }
    return result;
  }

  /// What the effects report after the last good tick (for traces; not needed by the loop).
  constexpr Diagnostics diagnostics() const noexcept {
    if (!started_) return Diagnostics{};
    TickInput<S> in{};
    in.position_m = last_position_m_;
    in.velocity_m_per_s = last_velocity_m_per_s_;
    in.now = last_commit_;
    in.period_s = config_.period_s;
    return scene_.diagnostics(states_[current_], in);
  }
  /// The velocity the scene used on the last good tick (estimated, given, or zero when the
  /// scene needs none), for traces; not needed by the loop.
  constexpr const Vec3<S>& last_velocity_m_per_s() const noexcept { return last_velocity_m_per_s_; }
  constexpr const SceneT& scene() const noexcept { return scene_; }
  constexpr ForceSafety<S>& safety() noexcept { return safety_; }

 private:
  SceneT scene_;
  ControllerConfig config_;
  ForceSafety<S> safety_;
  [[no_unique_address]] Estimator estimator_;
  typename SceneT::State states_[2]{};
  int current_ = 0;
  Instant last_commit_{};
  Vec3<S> last_position_m_{};        // of the last committed tick, for diagnostics()
  Vec3<S> last_velocity_m_per_s_{};
  bool dropped_since_commit_ = false;  // a tick since the last commit was non-finite
  bool started_ = false;
};

}  // namespace toonforce
