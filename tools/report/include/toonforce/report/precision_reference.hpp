// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The numerical pieces of the precision report, free of the servo
/// loop so that tests can check them on data whose answer is known:
///   - the analytic wall: a spring wall (effects.md §1, F = K depth n) along a sinusoidal
///     penetration path, whose force is known in closed form at every instant;
///   - the observed order of convergence from errors at successive doublings of the rate, and
///     the Richardson estimate of the finest run's own error (Richardson 1911; e.g. Roache,
///     "Verification and Validation in Computational Science and Engineering", 1998, ch. 5);
///   - events (contact onset and end, impact trigger, cliff fall) found in a run's ticks, their
///     lateness against a reference run's, and the windows around them that the "away from
///     events" error norms leave out;
///   - a streaming least-squares line (the drift fits: |difference| against time).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string_view>
#include <vector>

#include "toonforce/math/vec3.hpp"

namespace toonforce::report {

/// A spring wall z < 0 (normal +z, stiffness K) pressed along a sine: the handle at height
/// z(t) = z0 - A sin(2 pi f t) above the surface. F(t) = K max(0, -z(t)) along +z exactly
/// (effects.md §1 with zero damping), with no rate-limit or clamp event as long as K A < the
/// clamp and K A 2 pi f < the force-rate limit (the report checks both).
struct AnalyticWall {
  double stiffness_n_per_m = 1500.0;
  double offset_m = 0.001;     ///< z0: starts 1 mm above the surface
  double amplitude_m = 0.003;  ///< A: 2 mm deepest penetration, 3 N at 1500 N/m
  double frequency_hz = 2.0;   ///< f: at most 57 N/s, far below the scenes' 2000 N/s

  double period_s() const noexcept { return 1.0 / frequency_hz; }
  double height_m(double t_s) const noexcept { return offset_m - amplitude_m * std::sin(kTwoPi * frequency_hz * t_s); }
  /// The law in closed form: K depth, depth = max(0, -z).
  double force_n(double t_s) const noexcept {
    const double z = height_m(t_s);
    return z < 0.0 ? -stiffness_n_per_m * z : 0.0;
  }
  /// dF/dt in closed form (0 out of contact).
  double force_rate_n_per_s(double t_s) const noexcept {
    if (height_m(t_s) >= 0.0) return 0.0;
    return stiffness_n_per_m * amplitude_m * kTwoPi * frequency_hz * std::cos(kTwoPi * frequency_hz * t_s);
  }
  double peak_force_n() const noexcept { return stiffness_n_per_m * std::max(0.0, amplitude_m - offset_m); }
  double peak_force_rate_n_per_s() const noexcept { return stiffness_n_per_m * amplitude_m * kTwoPi * frequency_hz; }

  static constexpr double kTwoPi = 6.283185307179586;
};

/// Zero-order-hold error of forces sampled at `rate_hz` (one per tick k at t = t0 + k / rate)
/// against a closed-form force, evaluated at `sub` points inside each tick (midpoints of `sub`
/// equal parts, so the RMS is the midpoint rule of the continuous RMS).
struct HeldError {
  double max_n = 0.0;
  double rms_n = 0.0;
};
template <class Exact>
HeldError held_error(const std::vector<double>& force_n, double t0_s, double rate_hz, const Exact& exact,
                     int sub = 64) {
  HeldError e;
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < force_n.size(); ++k) {
    for (int j = 0; j < sub; ++j) {
      const double t = t0_s + (static_cast<double>(k) + (j + 0.5) / sub) / rate_hz;
      const double d = std::abs(force_n[k] - exact(t));
      e.max_n = std::max(e.max_n, d);
      sum += d * d;
      ++n;
    }
  }
  e.rms_n = n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
  return e;
}

/// Zero-order-hold error of a run at rate r against a reference run at m r (m = `step`, each
/// run's tick k at k / its rate): the run's force held over its tick (what the device renders)
/// against the reference taken as a continuous force, linear between its ticks, integrated
/// exactly over every reference tick: with e0, e1 the differences at a reference tick's two
/// ends, the mean of |e|^2 over it is (|e0|^2 + e0.e1 + |e1|^2) / 3 and the largest |e| is at
/// one end. Sampling e at each reference tick's left end instead (what the report did) reads a
/// ramp's RMS low by sqrt((m - 1)(2 m - 1) / (2 m^2)) (0.977 at m = 32: 10 kHz against 320 kHz).
/// The reference's last tick has no right end: it is taken as held. `away(i)` says whether
/// reference tick i counts in the "away from events" RMS.
struct HeldDifference {
  double max_n = 0.0;
  double rms_n = 0.0;
  double away_rms_n = 0.0;
};
template <class Away>
HeldDifference held_difference(const std::vector<Vec3<double>>& run, const std::vector<Vec3<double>>& reference,
                               std::size_t step, const Away& away) {
  HeldDifference d;
  double sum = 0.0, away_sum = 0.0;
  std::size_t n = 0, away_n = 0;
  for (std::size_t i = 0; i < reference.size() && i / step < run.size(); ++i) {
    const Vec3<double>& held = run[i / step];
    const Vec3<double> e0 = held - reference[i];
    const Vec3<double> e1 = i + 1 < reference.size() ? held - reference[i + 1] : e0;
    const double mean_square = (dot(e0, e0) + dot(e0, e1) + dot(e1, e1)) / 3.0;
    d.max_n = std::max({d.max_n, norm(e0), norm(e1)});
    sum += mean_square;
    ++n;
    if (away(i)) {
      away_sum += mean_square;
      ++away_n;
    }
  }
  d.rms_n = n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
  d.away_rms_n = away_n > 0 ? std::sqrt(away_sum / static_cast<double>(away_n)) : 0.0;
  return d;
}

/// Observed order p from the errors of a run at rate r and at 2 r: e(r) / e(2r) = 2^p.
/// NaN when either is zero or not finite (nothing to observe).
double observed_order(double error_at_rate, double error_at_double_rate) noexcept;

/// Richardson: a run at 2r whose difference to the run at r is `difference`, with order p,
/// is off the converged answer by about difference / (2^p - 1). With no order (NaN) or p <= 0
/// (not converging) the difference itself is returned: the honest bound is "at least that".
double richardson_error(double difference, double order) noexcept;

/// The finest run's own error from its ladder's last two observed orders: Richardson with the
/// last order when the two agree within 0.5 (the runs are in the asymptotic range), else the last
/// difference itself, the conservative bound (an order that jumps, e.g. from 1 to 4 when an
/// event happens to fall on the same tick at both rates, would make Richardson far too small).
double ladder_error(double difference, double previous_order, double order) noexcept;

/// What happened at one tick that the report counts as an event.
enum class EventKind : std::uint8_t { kContactOnset, kContactEnd, kImpactTrigger, kCliffFall };
std::string_view event_kind_name(EventKind kind) noexcept;

struct Event {
  EventKind kind = EventKind::kContactOnset;
  double t_s = 0.0;  ///< time of the tick it was first seen at
};

/// Per tick of a run: whether the HIP touched a geometry, the largest running impact's time
/// since trigger (NaN: none), and how many cliffs have fallen.
struct TickState {
  bool in_contact = false;
  double impact_t_s = std::nan("");
  int cliffs_fallen = 0;
};

/// The events of a run sampled every 1 / rate_hz from t0_s: contact onset and end (in_contact
/// changes), an impact trigger (impact time restarts: NaN to a number, or smaller than the
/// previous tick's), a cliff fall (the count of fallen cliffs grows).
std::vector<Event> find_events(const std::vector<TickState>& ticks, double t0_s, double rate_hz);

/// Lateness of a run's events against a reference's: each reference event matched with the
/// run's first event of the same kind in [t_ref - early_s, t_ref + late_s] (the first, not the
/// nearest: two triggers a tick apart would otherwise be matched to the wrong one);
/// lateness = t_run - t_ref.
struct Lateness {
  EventKind kind = EventKind::kContactOnset;
  std::size_t matched = 0;
  std::size_t unmatched = 0;  ///< reference events the run did not show within match_s
  double max_late_s = 0.0;    ///< the largest (most late) lateness
  double min_late_s = 0.0;    ///< the smallest (negative: early)
  double mean_late_s = 0.0;
};
std::vector<Lateness> event_lateness(const std::vector<Event>& reference, const std::vector<Event>& run, double early_s,
                                     double late_s);

/// Whether `t_s` lies in a window around an event: [t_e - before_s, t_e + after_s].
/// `events` sorted by time.
bool near_event(const std::vector<Event>& events, double t_s, double before_s, double after_s) noexcept;

/// Least-squares line y = a + b t, accumulated one point at a time (the drift runs have 10^7
/// points: nothing is stored). Centred on the first point to keep the sums well conditioned.
class LineFit {
 public:
  void add(double t, double y) noexcept {
    if (n_ == 0) t0_ = t;
    const double x = t - t0_;
    ++n_;
    sx_ += x;
    sy_ += y;
    sxx_ += x * x;
    sxy_ += x * y;
    syy_ += y * y;
  }
  std::uint64_t count() const noexcept { return n_; }
  /// b; 0 with fewer than two distinct times.
  double slope() const noexcept {
    const double n = static_cast<double>(n_);
    const double d = n * sxx_ - sx_ * sx_;
    return n_ > 1 && d > 0.0 ? (n * sxy_ - sx_ * sy_) / d : 0.0;
  }
  /// a (at t = 0).
  double intercept() const noexcept {
    if (n_ == 0) return 0.0;
    const double n = static_cast<double>(n_);
    return (sy_ - slope() * sx_) / n - slope() * t0_;
  }
  /// Coefficient of determination (1: a straight line; near 0: no linear trend).
  double r_squared() const noexcept {
    const double n = static_cast<double>(n_);
    const double vx = n * sxx_ - sx_ * sx_;
    const double vy = n * syy_ - sy_ * sy_;
    if (n_ < 2 || vx <= 0.0 || vy <= 0.0) return 0.0;
    const double c = n * sxy_ - sx_ * sy_;
    return c * c / (vx * vy);
  }

 private:
  std::uint64_t n_ = 0;
  double t0_ = 0.0;
  double sx_ = 0.0, sy_ = 0.0, sxx_ = 0.0, sxy_ = 0.0, syy_ = 0.0;
};

/// A seeded generator whose numbers are the same on every platform (std::uniform_real_
/// distribution's are not specified): SplitMix64 (Steele, Lea & Flood, OOPSLA 2014).
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) noexcept : state_(seed) {}
  std::uint64_t next() noexcept {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  /// Uniform in [lo, hi).
  double uniform(double lo, double hi) noexcept {
    return lo + (hi - lo) * static_cast<double>(next() >> 11) * 0x1.0p-53;
  }

 private:
  std::uint64_t state_;
};

}  // namespace toonforce::report
