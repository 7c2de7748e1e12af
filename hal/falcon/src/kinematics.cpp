// SPDX-License-Identifier: Apache-2.0
// Falcon delta kinematics (FALCON.md §5). See kinematics.hpp for the contract.
#include "toonforce/hal/falcon/kinematics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace toonforce::falcon {
namespace {

/// One arm's leg-frame quantities at a point (FALCON.md §5 "Inverse kinematics, per arm i").
struct ArmPose {
  double u = 0, v = 0, w = 0;
  double cos_t3 = 0, sin_t3 = 0;
  double big_a = 0;  ///< u + c
  double big_k = 0;  ///< b sin(theta3) + d + e
};

bool arm_pose(const FalconGeometry& g, std::size_t arm, const Vec3<double>& p, ArmPose& out) noexcept {
  const double cp = std::cos(g.phi_rad[arm]);
  const double sp = std::sin(g.phi_rad[arm]);
  out.u = cp * p.x + sp * p.y - g.r_m;
  out.v = -sp * p.x + cp * p.y - g.s_m;
  out.w = p.z;
  out.cos_t3 = (out.v + g.f_m) / g.b_m;
  if (!(out.cos_t3 > -1.0 && out.cos_t3 < 1.0)) return false;  // also rejects NaN
  out.sin_t3 = std::sqrt(1.0 - out.cos_t3 * out.cos_t3);       // theta3 = acos(.) is in (0, pi)
  out.big_a = out.u + g.c_m;
  out.big_k = g.b_m * out.sin_t3 + g.d_m + g.e_m;
  return true;
}

double norm3(const Angles& e) noexcept { return std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]); }

}  // namespace

bool invert(const Mat3& a, Mat3& inverse, double min_abs_det) noexcept {
  const double c00 = a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1);
  const double c01 = a(1, 2) * a(2, 0) - a(1, 0) * a(2, 2);
  const double c02 = a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0);
  const double det = a(0, 0) * c00 + a(0, 1) * c01 + a(0, 2) * c02;
  if (!(std::abs(det) > min_abs_det)) return false;
  const double k = 1.0 / det;
  Mat3 r;
  r(0, 0) = c00 * k;
  r(1, 0) = c01 * k;
  r(2, 0) = c02 * k;
  r(0, 1) = (a(0, 2) * a(2, 1) - a(0, 1) * a(2, 2)) * k;
  r(1, 1) = (a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0)) * k;
  r(2, 1) = (a(0, 1) * a(2, 0) - a(0, 0) * a(2, 1)) * k;
  r(0, 2) = (a(0, 1) * a(1, 2) - a(0, 2) * a(1, 1)) * k;
  r(1, 2) = (a(0, 2) * a(1, 0) - a(0, 0) * a(1, 2)) * k;
  r(2, 2) = (a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0)) * k;
  inverse = r;
  return true;
}

bool inverse_kinematics(const FalconGeometry& g, const Vec3<double>& p_m, Angles& theta1_rad) noexcept {
  Angles out{};
  for (std::size_t arm = 0; arm < 3; ++arm) {
    ArmPose q;
    if (!arm_pose(g, arm, p_m, q)) return false;
    // (B + 2aA) T^2 - 4aw T + (B - 2aA) = 0 with T = tan(theta1/2); the "minus" root.
    const double big_b = q.w * q.w + q.big_a * q.big_a + g.a_m * g.a_m - q.big_k * q.big_k;
    const double qa = big_b + 2.0 * g.a_m * q.big_a;
    const double qb = -4.0 * g.a_m * q.w;
    const double qc = big_b - 2.0 * g.a_m * q.big_a;
    const double disc = qb * qb - 4.0 * qa * qc;
    if (!(disc >= 0.0)) return false;
    const double root = std::sqrt(disc);
    // (-qb - root) / (2 qa) == 2 qc / (-qb + root): use the form without cancellation.
    double t = 0;
    if (qb <= 0.0) {
      const double den = -qb + root;
      if (den == 0.0) return false;
      t = 2.0 * qc / den;
    } else {
      if (qa == 0.0) return false;
      t = (-qb - root) / (2.0 * qa);
    }
    out[arm] = 2.0 * std::atan(t);
    if (!std::isfinite(out[arm])) return false;
  }
  theta1_rad = out;
  return true;
}

bool angle_jacobian(const FalconGeometry& g, const Vec3<double>& p_m, const Angles& theta1_rad,
                    Mat3& dtheta_dp) noexcept {
  Mat3 out;
  for (std::size_t arm = 0; arm < 3; ++arm) {
    ArmPose q;
    if (!arm_pose(g, arm, p_m, q)) return false;
    const double ct1 = std::cos(theta1_rad[arm]);
    const double st1 = std::sin(theta1_rad[arm]);
    // G(theta1, p) = A^2 + w^2 + a^2 - K^2 - 2a (A cos t1 + w sin t1) = 0 along the IK.
    const double dg_dt1 = 2.0 * g.a_m * (q.big_a * st1 - q.w * ct1);
    if (!(std::abs(dg_dt1) > 1e-12)) return false;  // singular: the thigh is aligned with the leg
    const double dg_du = 2.0 * q.big_a - 2.0 * g.a_m * ct1;
    const double dg_dw = 2.0 * q.w - 2.0 * g.a_m * st1;
    // K = sqrt(b^2 - (v+f)^2) + d + e, so dK/dv = -cos(t3)/sin(t3) and dG/dv = 2K cos/sin.
    const double dg_dv = 2.0 * q.big_k * q.cos_t3 / q.sin_t3;
    const double cp = std::cos(g.phi_rad[arm]);
    const double sp = std::sin(g.phi_rad[arm]);
    out(arm, 0) = -(dg_du * cp - dg_dv * sp) / dg_dt1;
    out(arm, 1) = -(dg_du * sp + dg_dv * cp) / dg_dt1;
    out(arm, 2) = -dg_dw / dg_dt1;
  }
  dtheta_dp = out;
  return true;
}

bool position_jacobian(const FalconGeometry& g, const Vec3<double>& p_m, Mat3& dp_dtheta) noexcept {
  Angles theta{};
  Mat3 dtheta_dp;
  return inverse_kinematics(g, p_m, theta) && angle_jacobian(g, p_m, theta, dtheta_dp) && invert(dtheta_dp, dp_dtheta);
}

MotorWords force_to_motor_words(const Mat3& dp_dtheta, const Vec3<double>& force_n, const MotorScale& scale) noexcept {
  MotorWords out;
  Vec3<double> exact = motor_words_exact(dp_dtheta, force_n, scale);
  if (!is_finite(exact)) return out;
  const double largest = std::max({std::abs(exact.x), std::abs(exact.y), std::abs(exact.z)});
  const double limit = static_cast<double>(scale.max_word);
  if (largest > limit) {
    exact = exact * (limit / largest);
    out.saturated = true;
  }
  // Truncation toward zero, as libnifalcon's conversion to int; |value| <= max_word here.
  out.word = {static_cast<std::int16_t>(std::clamp(exact.x, -limit, limit)),
              static_cast<std::int16_t>(std::clamp(exact.y, -limit, limit)),
              static_cast<std::int16_t>(std::clamp(exact.z, -limit, limit))};
  return out;
}

double max_force_along(const Mat3& dp_dtheta, const Vec3<double>& direction, const MotorScale& scale) noexcept {
  const double length = std::sqrt(dot(direction, direction));
  if (!(length > 0.0) || !std::isfinite(length)) return 0.0;
  const Vec3<double> per_newton = motor_words_exact(dp_dtheta, direction * (1.0 / length), scale);
  const double largest = std::max({std::abs(per_newton.x), std::abs(per_newton.y), std::abs(per_newton.z)});
  if (!(largest > 0.0)) return 0.0;
  return static_cast<double>(scale.max_word) / largest;
}

ForceEnvelope force_envelope(const Mat3& dp_dtheta, const MotorScale& scale) noexcept {
  ForceEnvelope e;
  e.axis_n = {max_force_along(dp_dtheta, {1, 0, 0}, scale), max_force_along(dp_dtheta, {0, 1, 0}, scale),
              max_force_along(dp_dtheta, {0, 0, 1}, scale)};
  double longest = 0.0;
  for (std::size_t c = 0; c < 3; ++c) {
    const double column = std::sqrt(dp_dtheta(0, c) * dp_dtheta(0, c) + dp_dtheta(1, c) * dp_dtheta(1, c) +
                                    dp_dtheta(2, c) * dp_dtheta(2, c));
    longest = std::max(longest, column);
  }
  const double per_newton = longest * std::abs(scale.words_per_n_m);
  e.every_direction_n = per_newton > 0.0 ? static_cast<double>(scale.max_word) / per_newton : 0.0;
  return e;
}

bool force_envelope_at(const FalconGeometry& g, const Vec3<double>& p_m, const MotorScale& scale,
                       ForceEnvelope& envelope) noexcept {
  Mat3 j;
  if (!position_jacobian(g, p_m, j)) return false;
  envelope = force_envelope(j, scale);
  return true;
}

ForwardKinematics::ForwardKinematics(const FalconGeometry& geometry, const FkOptions& options) noexcept
    : geometry_(geometry), options_(options), last_m_(options.initial_guess_m) {}

void ForwardKinematics::reset() noexcept { last_m_ = options_.initial_guess_m; }

FkResult ForwardKinematics::solve(const Angles& target) noexcept {
  FkResult result;
  result.position_m = last_m_;
  result.residual_rad = std::numeric_limits<double>::infinity();

  Vec3<double> p = last_m_;
  Angles theta{};
  if (!inverse_kinematics(geometry_, p, theta)) {
    p = options_.initial_guess_m;  // the warm start left the reach: restart from the centre
    if (!inverse_kinematics(geometry_, p, theta)) return result;
  }
  const auto error_of = [&target](const Angles& t) {
    return Angles{target[0] - t[0], target[1] - t[1], target[2] - t[2]};
  };
  Angles err = error_of(theta);
  double err_norm = norm3(err);
  if (!std::isfinite(err_norm)) return result;

  int iterations = 0;
  double gain = 1.0;
  Mat3 j;
  bool j_at_p = false;
  // Each pass costs one IK (and one Jacobian after an accepted step): max_iterations bounds it.
  while (iterations < options_.max_iterations && err_norm > options_.tolerance_rad) {
    if (!j_at_p) {
      Mat3 dtheta_dp;
      if (!angle_jacobian(geometry_, p, theta, dtheta_dp) || !invert(dtheta_dp, j)) break;
      j_at_p = true;
      gain = 1.0;
    }
    const Vec3<double> step{j(0, 0) * err[0] + j(0, 1) * err[1] + j(0, 2) * err[2],
                            j(1, 0) * err[0] + j(1, 1) * err[1] + j(1, 2) * err[2],
                            j(2, 0) * err[0] + j(2, 1) * err[1] + j(2, 2) * err[2]};
    const Vec3<double> trial = p + step * gain;
    Angles trial_theta{};
    ++iterations;
    if (inverse_kinematics(geometry_, trial, trial_theta)) {
      const Angles trial_err = error_of(trial_theta);
      const double trial_norm = norm3(trial_err);
      if (trial_norm < err_norm) {
        p = trial;
        theta = trial_theta;
        err = trial_err;
        err_norm = trial_norm;
        j_at_p = false;
        continue;
      }
    }
    gain *= 0.5;  // the error grew or the step left the reach: damp
  }

  result.position_m = p;
  result.residual_rad = err_norm;
  result.iterations = iterations;
  result.converged = err_norm <= options_.tolerance_rad;
  if (j_at_p) {
    result.dp_dtheta = j;
    result.jacobian_valid = true;
  } else {
    Mat3 dtheta_dp;
    result.jacobian_valid = angle_jacobian(geometry_, p, theta, dtheta_dp) && invert(dtheta_dp, result.dp_dtheta);
  }
  last_m_ = p;
  return result;
}

}  // namespace toonforce::falcon
