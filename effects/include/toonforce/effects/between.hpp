// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Force laws between several HIPs, in the world frame (control/world.hpp puts each device's
/// HIP there): a virtual coupling, a spring-damper that lets two hands feel each other, and a
/// shared dynamic object, a ball that every HIP can push and that bounces off a wall. Like the
/// single-HIP effects these are pure: no I/O, no clock, no allocation; the caller gives the
/// positions, the velocities and the period, and owns the states.
///
/// Both laws are written so that the forces they put on their bodies sum to zero at every tick
/// (Newton's third law, exactly, not to rounding: one force is computed and the other is its
/// negation), so a world of hands and balls neither gains nor loses momentum through them.
///
/// The ball's surface may also carry the paper's cartoon effects (spec effects.md §3, the
/// super-slippery surface, and §4, the impact recoil and oscillation), with the single-HIP laws
/// and parameters (SuperSlippery, ImpactTransient) applied on a sphere that moves: the normal n
/// runs from the ball's centre to the HIP, and what counts is the HIP's velocity relative to
/// the ball's. Each HIP has its own impact state (BallHipState), which the caller owns.

#include <cmath>
#include <cstddef>

#include "toonforce/effects/friction.hpp"
#include "toonforce/effects/impact.hpp"
#include "toonforce/effects/tick.hpp"
#include "toonforce/math/scalar.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce::between {

/// A spring-damper between the HIPs of two devices (Colgate, Stanley and Brown, "Issues in the
/// haptic display of tool use", IROS 1995: the virtual coupling), here between two hands.
struct CouplingParams {
  double stiffness_n_per_m = 200.0;  ///< k >= 0
  double damping_n_s_per_m = 2.0;    ///< b >= 0
  double rest_length_m = 0.0;        ///< the spring's length at rest (0: the HIPs are pulled together)
};

/// Why a coupling's parameters are refused (empty: accepted).
inline const char* check(const CouplingParams& p) noexcept {
  if (!(std::isfinite(p.stiffness_n_per_m) && p.stiffness_n_per_m >= 0.0)) return "stiffness must be finite and >= 0";
  if (!(std::isfinite(p.damping_n_s_per_m) && p.damping_n_s_per_m >= 0.0)) return "damping must be finite and >= 0";
  if (!(std::isfinite(p.rest_length_m) && p.rest_length_m >= 0.0)) return "rest length must be finite and >= 0";
  return "";
}

/// The force on HIP a [N]; HIP b gets its negation.
///   F_a = -k (|d| - L) d/|d| - b (v_a - v_b),  d = x_a - x_b
/// With L = 0 the first term is -k d (no division, no square root).
template <Scalar S>
constexpr Vec3<S> coupling_force(const CouplingParams& p, const Vec3<S>& a_m, const Vec3<S>& a_m_per_s,
                                 const Vec3<S>& b_m, const Vec3<S>& b_m_per_s) noexcept {
  const Vec3<S> d = a_m - b_m;
  const S k = scalar_cast<S>(p.stiffness_n_per_m);
  const S b = scalar_cast<S>(p.damping_n_s_per_m);
  Vec3<S> stretch = d;
  if (p.rest_length_m > 0.0) {
    const double length = std::sqrt(to_double(dot(d, d)));
    // Coincident HIPs: no direction to push along; the spring gives nothing.
    stretch = length > 0.0 ? d * scalar_cast<S>((length - p.rest_length_m) / length) : Vec3<S>{};
  }
  return -(stretch * k) - (a_m_per_s - b_m_per_s) * b;
}

/// A ball in the world that the HIPs push (each HIP a point, felt as a penalty spring and a
/// one-sided damper on the ball's surface) and that bounces off one wall (a plane, the same
/// law). Integrated with semi-implicit (symplectic) Euler, one step a tick.
struct BallParams {
  double radius_m = 0.02;
  double mass_kg = 0.1;
  double stiffness_n_per_m = 800.0;  ///< HIP-ball contact
  double damping_n_s_per_m = 1.0;    ///< HIP-ball contact, only while pressing in (no pull)
  double drag_n_s_per_m = 0.5;       ///< the ball's own viscous drag (it comes to rest)
  Vec3<double> start_m{};            ///< where the ball is at the start, at rest
  /// Gravity on the ball [m/s^2] (the scenes' z is up). Without it a ball squeezed between two
  /// HIPs a little below its centre is pressed up and out, and nothing brings it back.
  Vec3<double> gravity_m_per_s2{0.0, 0.0, -9.81};
  bool has_wall = false;  ///< a wall the ball bounces off
  Vec3<double> wall_point_m{};
  Vec3<double> wall_normal{0.0, 0.0, 1.0};  ///< unit, pointing out of the wall (normalised by check_and_normalise)
  double wall_stiffness_n_per_m = 2000.0;
  double wall_damping_n_s_per_m = 2.0;
  /// The super-slippery surface on the ball (§3): F_t = mu v_t, v_t the HIP's velocity
  /// relative to the ball's, tangential to the ball, while the HIP is inside; capped at
  /// max_tangential_force (direction kept). mu has no default (a file must give it).
  bool has_slippery = false;
  SuperSlippery<double>::Params slippery{0.0, 2.0};
  /// The impact transient on the ball (§4), per HIP: it triggers when a HIP enters the ball
  /// closing at v_i = -(n.(v_hip - v_ball)) >= min_impact_speed while armed, then pushes along
  /// +n (n as the HIP is now) by v_i (d - t) (k_r + k_osc sin(omega t)) for 0 <= t <= d.
  bool has_impact = false;
  ImpactTransient<double>::Params impact{0.0, 0.0, 0.0, 0.0, 0.05, 0.001, SineMethod::kAuto};
};

/// Why a ball's parameters are refused (empty: accepted); normalises the wall's normal.
inline const char* check_and_normalise(BallParams& p) noexcept {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  const auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!positive(p.radius_m)) return "radius must be finite and > 0";
  if (!positive(p.mass_kg)) return "mass must be finite and > 0";
  if (!non_negative(p.stiffness_n_per_m) || !non_negative(p.damping_n_s_per_m) || !non_negative(p.drag_n_s_per_m)) {
    return "stiffness, damping and drag must be finite and >= 0";
  }
  if (!is_finite(p.start_m)) return "start must be finite";
  if (!is_finite(p.gravity_m_per_s2)) return "gravity must be finite";
  if (p.has_wall) {
    const double n = std::sqrt(dot(p.wall_normal, p.wall_normal));
    if (!(std::isfinite(n) && n > 0.0)) return "the wall's normal must be finite and not zero";
    p.wall_normal = p.wall_normal * (1.0 / n);
    if (!is_finite(p.wall_point_m)) return "the wall's point must be finite";
    if (!non_negative(p.wall_stiffness_n_per_m) || !non_negative(p.wall_damping_n_s_per_m)) {
      return "the wall's stiffness and damping must be finite and >= 0";
    }
  }
  // The ranges of the scene-file keys (SuperSlippery's and ImpactTransient's schemas), for a
  // configuration built in code.
  if (p.has_slippery) {
    if (!positive(p.slippery.mu_n_s_per_m)) return "slippery: mu must be finite and > 0";
    if (!positive(p.slippery.max_tangential_force_n)) return "slippery: max_tangential_force must be finite and > 0";
  }
  if (p.has_impact) {
    const ImpactTransient<double>::Params& i = p.impact;
    if (!std::isfinite(i.recoil_gain_n_per_m) || !std::isfinite(i.oscillation_gain_n_per_m)) {
      return "impact: recoil_gain and oscillation_gain must be finite";
    }
    if (!positive(i.duration_s) || !positive(i.frequency_hz))
      return "impact: duration and frequency must be finite and > 0";
    if (!non_negative(i.min_impact_speed_m_per_s) || !non_negative(i.rearm_distance_m)) {
      return "impact: min_impact_speed and rearm_distance must be finite and >= 0";
    }
  }
  return "";
}

struct BallState {
  Vec3<double> position_m;
  Vec3<double> velocity_m_per_s;
  bool touched_wall = false;  ///< in contact with the wall after the last step
};

/// The force a HIP at `hip_m` moving at `hip_m_per_s` feels from the ball [N]; the ball feels
/// its negation. Zero outside the ball.
inline Vec3<double> ball_force_on_hip(const BallParams& p, const BallState& ball, const Vec3<double>& hip_m,
                                      const Vec3<double>& hip_m_per_s) noexcept {
  const Vec3<double> d = hip_m - ball.position_m;
  const double r2 = dot(d, d);
  if (!(r2 < p.radius_m * p.radius_m)) return {};  // outside, on the surface, or not finite
  const double r = std::sqrt(r2);
  // At the very centre any direction is as good as another: out along +z.
  const Vec3<double> n = r > 0.0 ? d * (1.0 / r) : Vec3<double>{0.0, 0.0, 1.0};
  const double depth = p.radius_m - r;
  const double closing = -dot(hip_m_per_s - ball.velocity_m_per_s, n);  // > 0: pressing in
  const double push = p.stiffness_n_per_m * depth + (closing > 0.0 ? p.damping_n_s_per_m * closing : 0.0);
  return n * push;
}

/// One HIP's state against the ball's surface effects (the caller keeps one per HIP): the
/// impact's trigger state (armed, the running transient's trigger tick and v_i, the previous
/// tick's depth). A HIP that leaves the world gets a fresh one: on its first tick back nothing
/// triggers (the state's previous depth is "inside") and it is armed.
struct BallHipState {
  ImpactTransient<double>::State impact{};
};

/// A HIP's force from the ball and its parts [N]: the ball feels -force_n.
struct BallHipForce {
  Vec3<double> force_n;     ///< the sum: contact spring and damper, slippery, impact
  Vec3<double> slippery_n;  ///< the slippery surface's part
  Vec3<double> impact_n;    ///< the impact transient's part
  bool in_contact = false;  ///< the HIP is inside the ball
  bool impact_running = false;
  bool impact_triggered = false;  ///< a transient (re)started on this tick
};

/// The force a HIP feels from the ball with its surface effects, on the tick `now` of a loop
/// whose ticks are `period_s` apart (the impact's t is (k - k_trigger) period, spec §0); updates
/// the HIP's impact state. With neither effect on, force_n is ball_force_on_hip's bit for bit.
/// A non-finite HIP or ball gives nothing and leaves the state as it was.
inline BallHipForce ball_force_on_hip(const BallParams& p, const BallState& ball, BallHipState& hip,
                                      const Vec3<double>& hip_m, const Vec3<double>& hip_m_per_s, Instant now,
                                      double period_s) noexcept {
  BallHipForce out;
  const Vec3<double> d = hip_m - ball.position_m;
  const double r2 = dot(d, d);
  if (!std::isfinite(r2)) return out;
  // Outside the ball only the impact has anything to do (its re-arm): no square root for the rest.
  if (!p.has_impact && !(r2 < p.radius_m * p.radius_m)) return out;
  const double r = std::sqrt(r2);
  // At the very centre any direction is as good as another: out along +z.
  const Vec3<double> n = r > 0.0 ? d * (1.0 / r) : Vec3<double>{0.0, 0.0, 1.0};
  const double depth = p.radius_m - r;
  const Vec3<double> v = hip_m_per_s - ball.velocity_m_per_s;  // relative to the ball
  const double n_dot_v = dot(v, n);
  if (r2 < p.radius_m * p.radius_m) {
    out.in_contact = true;
    const double closing = -n_dot_v;  // > 0: pressing in
    const double push = p.stiffness_n_per_m * depth + (closing > 0.0 ? p.damping_n_s_per_m * closing : 0.0);
    out.force_n = n * push;
    if (p.has_slippery) {
      out.slippery_n = SuperSlippery<double>::force(p.slippery, v - n * n_dot_v, push);
      out.force_n += out.slippery_n;
    }
  }
  if (p.has_impact) {
    // The plane law's contact, on the sphere: delta = R - |x - c|, n.v relative to the ball.
    TickInput<double> in{};
    in.now = now;
    in.period_s = period_s;
    const ImpactOutput<double> impact =
        ImpactTransient<double>::force(p.impact, hip.impact, Contact<double>{depth, n_dot_v}, in);
    out.impact_running = impact.running;
    out.impact_triggered = impact.triggered;
    if (impact.running) {
      out.impact_n = n * impact.force_n;
      out.force_n += out.impact_n;
    }
  }
  return out;
}

/// Advances the ball by `dt_s` under `force_on_ball_n` (what the HIPs put on it), gravity, its
/// drag and the wall. Returns the wall's force on the ball [N] (for the record).
inline Vec3<double> step_ball(const BallParams& p, BallState& ball, const Vec3<double>& force_on_ball_n,
                              double dt_s) noexcept {
  Vec3<double> wall{};
  ball.touched_wall = false;
  if (p.has_wall) {
    const double depth = p.radius_m - dot(ball.position_m - p.wall_point_m, p.wall_normal);
    if (depth > 0.0) {
      const double closing = -dot(ball.velocity_m_per_s, p.wall_normal);
      const double push = p.wall_stiffness_n_per_m * depth + (closing > 0.0 ? p.wall_damping_n_s_per_m * closing : 0.0);
      wall = p.wall_normal * push;
      ball.touched_wall = true;
    }
  }
  const Vec3<double> total =
      force_on_ball_n + wall + p.gravity_m_per_s2 * p.mass_kg - ball.velocity_m_per_s * p.drag_n_s_per_m;
  ball.velocity_m_per_s += total * (dt_s / p.mass_kg);
  ball.position_m += ball.velocity_m_per_s * dt_s;
  return wall;
}

}  // namespace toonforce::between
