#pragma once
/// The handle as the loop sees it on one tick (spec effects.md §0): the device's position
/// converted to the scalar once, and its velocity, the device's own when it measures one, else
/// the one velocity estimator of the loop (control/velocity_estimator.hpp) when the scene or the
/// safety layer needs a velocity. The estimate is not committed until the tick counts (a
/// non-finite tick leaves the estimator as it was, spec §6.1), and 1/dt is taken since the last
/// tick that counted, so a dropped sample does not double the estimate.

#include "toonforce/control/clock.hpp"
#include "toonforce/control/velocity_estimator.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce {

template <Scalar S>
struct Hip {
  Vec3<S> position_m;
  Vec3<S> velocity_m_per_s;       ///< zero when nothing needs a velocity
  S rate_hz{};                    ///< 1/dt since the last tick that counted [Hz]
  bool position_finite = false;   ///< the position can be used (the passivity observer needs only it)
  bool finite = false;            ///< position and any given velocity finite: the tick can count
  bool estimated = false;         ///< velocity_m_per_s is the estimator's, not yet committed
};

/// `kMayEstimate` false compiles the estimator out (no scene effect, no safety stage needs it).
template <Scalar S, bool kMayEstimate>
class HipSensor {
 public:
  /// `period_s` > 0: ticks come on this period, and 1/dt and the filter's gain for one period
  /// are computed once, here.
  constexpr HipSensor(double velocity_cutoff_hz, bool estimate, double period_s) noexcept
      : estimator_(velocity_cutoff_hz),
        estimate_(kMayEstimate && estimate),
        period_rate_hz_(scalar_cast<S>(1.0 / period_s)),
        period_gain_(estimator_.gain(period_rate_hz_)) {}

  /// `reading` in double, or already in S (a device that reads in the loop's scalar: a
  /// fixed-point target's, tools/mcu).
  template <class T>
  Hip<S> sense(const BasicDeviceReading<T>& reading, const TickTime& time) const noexcept {
    Hip<S> h;
    h.position_finite = is_finite(reading.position_m);
    h.finite = h.position_finite && (!reading.has_velocity || is_finite(reading.velocity_m_per_s));
    if (!h.position_finite) return h;
    h.position_m = in_scalar(reading.position_m);
    // One period since the last tick that counted, the usual case: the rate computed once.
    const std::int64_t since = has_commit_ ? time.now.tick - last_commit_.tick : time.gap;  // ticks
    bool one_period;
    if constexpr (kIsFixed<S>) {  // integer time (control/clock.hpp): 1e9 / ns, no floating point
      one_period = since == 1 && time.period_ns > 0;
      h.rate_hz = one_period ? period_rate_hz_
                             : S::from_ratio(kNsPerS, has_commit_ ? time.ns_since(last_commit_) : time.dt_ns);
    } else {
      one_period = since == 1 && time.period_s > 0.0;
      h.rate_hz = one_period ? period_rate_hz_
                             : scalar_cast<S>(1.0 / (has_commit_ ? time.seconds_since(last_commit_) : time.dt_s()));
    }
    if (reading.has_velocity) {
      h.velocity_m_per_s = in_scalar(reading.velocity_m_per_s);
    } else if constexpr (kMayEstimate) {
      if (estimate_) {
        h.velocity_m_per_s = estimator_.estimate(h.position_m, h.rate_hz,
                                                 one_period ? period_gain_ : estimator_.gain(h.rate_hz));
        h.estimated = true;
      }
    }
    return h;
  }

  /// The tick counted: its estimate becomes the estimator's state.
  constexpr void commit(const Hip<S>& h, const TickTime& time) noexcept {
    if constexpr (kMayEstimate) {
      if (h.estimated) estimator_.commit(h.position_m, h.velocity_m_per_s);
    }
    last_commit_ = time.now;
    has_commit_ = true;
  }

 private:
  template <class T>
  static constexpr Vec3<S> in_scalar(const Vec3<T>& v) noexcept {
    if constexpr (std::is_same_v<T, S>) {
      return v;
    } else {
      return vec_cast<S>(v);
    }
  }

  [[no_unique_address]] std::conditional_t<kMayEstimate, VelocityEstimator<S>, NoVelocityEstimator<S>> estimator_;
  bool estimate_;
  S period_rate_hz_;  ///< 1/T
  S period_gain_;     ///< the filter's gain at 1/T
  bool has_commit_ = false;
  Instant last_commit_{};
};

}  // namespace toonforce
