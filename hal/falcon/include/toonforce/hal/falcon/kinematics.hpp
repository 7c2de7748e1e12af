// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Falcon delta kinematics (R. E. Stamper's model with libnifalcon's constants, FALCON.md §5):
/// closed-form inverse kinematics, the exact Jacobian of that IK (by implicit differentiation,
/// checked against finite differences), forward kinematics by damped Newton with a fixed
/// iteration cap warm-started from the previous tick, and force -> motor words through the
/// TRUE transpose. Falcon frame: x right, y up, z toward the user, origin inside the device
/// [m]; angles [rad]. Bounded work, no allocation, noexcept: safe in the servo tick.

#include <array>
#include <cstdint>

#include "toonforce/math/vec3.hpp"

namespace toonforce::falcon {

using Angles = std::array<double, 3>;  ///< theta1 of arms 1..3 [rad]

/// Row-major 3x3 matrix.
struct Mat3 {
  std::array<std::array<double, 3>, 3> m{};
  constexpr double operator()(std::size_t r, std::size_t c) const noexcept { return m[r][c]; }
  constexpr double& operator()(std::size_t r, std::size_t c) noexcept { return m[r][c]; }
};

/// Inverts `a`; false when |det| is below `min_abs_det` (a singular pose).
bool invert(const Mat3& a, Mat3& inverse, double min_abs_det = 1e-15) noexcept;

/// Link lengths and offsets [m] and arm-plane angles (FALCON.md §5 "Constants": libnifalcon's
/// FalconGeometry.h after the 2009 r/s swap). PI is exact here; libnifalcon's literal
/// 3.14159265 differs by 4e-9 rad, far below one encoder count (6.4e-4 rad).
struct FalconGeometry {
  double a_m = 0.060;                                                             ///< thigh
  double b_m = 0.1025;                                                            ///< parallelogram side
  double c_m = 0.01443;                                                           ///< effector offset along u
  double f_m = -0.025;                                                            ///< effector offset along v
  double d_m = 0.01125;                                                           ///< joint offset
  double e_m = 0.01125;                                                           ///< joint offset
  double r_m = 0.0400;                                                            ///< leg-base offset along u
  double s_m = -0.02309;                                                          ///< leg-base offset along v
  Angles phi_rad{1.8325957145940461, -0.26179938779914941, -2.3561944901923448};  ///< 105, -15, -135 deg
};

/// Encoder counts <-> theta1 (FALCON.md §5 "Encoder to angle"): 320-slot wheel x 4, capstan
/// 0.110/0.01425, count 0 at 35 degrees: theta1 = 35 deg + 0.0364347 deg * count.
inline constexpr double kRadPerCount = (0.01425 / (320.0 * 4.0) / 0.110) * 2.0 * 3.14159265358979323846;
inline constexpr double kTheta1AtZeroCountRad = 35.0 * 3.14159265358979323846 / 180.0;
constexpr double encoder_to_theta1_rad(double count) noexcept { return kTheta1AtZeroCountRad + kRadPerCount * count; }
constexpr double theta1_rad_to_encoder(double theta1_rad) noexcept {
  return (theta1_rad - kTheta1AtZeroCountRad) / kRadPerCount;
}

/// Closed-form IK (FALCON.md §5): false when the point is outside the model's reach (acos
/// argument out of range or no real root), leaving `theta1` unchanged.
bool inverse_kinematics(const FalconGeometry& g, const Vec3<double>& p_m, Angles& theta1_rad) noexcept;

/// d(theta1)/d(p) at p, whose IK is `theta1_rad`, by implicit differentiation of the IK's
/// constraint (A - a cos t1)^2 + (w - a sin t1)^2 = K^2. This equals libnifalcon's rows with the
/// third entry sin(theta2) sin(theta3)/den (libnifalcon/libnifalcon#66, FALCON.md §5); its
/// sin^2(theta2)/den is off by ~25% on z (tests/falcon/kinematics_test.cpp compares both with
/// finite differences).
bool angle_jacobian(const FalconGeometry& g, const Vec3<double>& p_m, const Angles& theta1_rad,
                    Mat3& dtheta_dp) noexcept;

/// J = dp/d(theta1) [m/rad] at p: the inverse of angle_jacobian.
bool position_jacobian(const FalconGeometry& g, const Vec3<double>& p_m, Mat3& dp_dtheta) noexcept;

/// Joint torques tau = J^T F [N m] for a force F [N] at the grip (virtual work: F.v = tau.w).
/// J^T is formed explicitly from J's entries; libnifalcon's in-place setTranspose aliasing bug
/// (which yields a symmetric matrix from J's lower triangle, FALCON.md §5/§8) is not copied.
constexpr Vec3<double> joint_torques(const Mat3& dp_dtheta, const Vec3<double>& force_n) noexcept {
  const auto& j = dp_dtheta;
  return {j(0, 0) * force_n.x + j(1, 0) * force_n.y + j(2, 0) * force_n.z,
          j(0, 1) * force_n.x + j(1, 1) * force_n.y + j(2, 1) * force_n.z,
          j(0, 2) * force_n.x + j(1, 2) * force_n.y + j(2, 2) * force_n.z};
}

/// Motor-word scaling (FALCON.md §5 "Forces"): word = -10000 * tau, truncated; libnifalcon
/// calls both its constants "rather random" (uncalibrated). The command range is limited to
/// +-4095 (what Novint's own driver stayed within, FALCON.md §3 captures).
struct MotorScale {
  double words_per_n_m = 10000.0;
  std::int16_t max_word = 4095;
};

struct MotorWords {
  std::array<std::int16_t, 3> word{};
  bool saturated = false;  ///< the request exceeded max_word and was scaled down
};

/// Force [N, Falcon frame] -> motor words through tau = J^T F. When any word would exceed the
/// range, all three are scaled down by the same factor, which keeps the force's direction
/// (clamping each word alone would bend it). Non-finite input gives zero words.
MotorWords force_to_motor_words(const Mat3& dp_dtheta, const Vec3<double>& force_n,
                                const MotorScale& scale = {}) noexcept;

/// The unclamped words before truncation (for tests and diagnostics).
constexpr Vec3<double> motor_words_exact(const Mat3& dp_dtheta, const Vec3<double>& force_n,
                                         const MotorScale& scale = {}) noexcept {
  return joint_torques(dp_dtheta, force_n) * -scale.words_per_n_m;
}

/// The force envelope: how much force the +-max_word motor words can give at a pose. The words
/// for a force f u (u a unit vector) are -k f J^T u, linear in f, so the largest force along u
/// is max_word / (k max_i |(J^T u)_i|), the same along -u. Over all directions the smallest of
/// these is max_word / (k max_i |column i of J|) (|(J^T u)_i| = |J_i . u| <= |J_i| with
/// equality along J_i): the force the Falcon can give whichever way it is asked.
struct ForceEnvelope {
  Vec3<double> axis_n;           ///< largest force along +-x, +-y, +-z of the frame [N]
  double every_direction_n = 0;  ///< largest force available in every direction [N]
};

/// Largest force [N] along `direction` (any non-zero vector; its length does not matter) at
/// the pose whose Jacobian is `dp_dtheta`; 0 for a zero or non-finite direction.
double max_force_along(const Mat3& dp_dtheta, const Vec3<double>& direction, const MotorScale& scale = {}) noexcept;

ForceEnvelope force_envelope(const Mat3& dp_dtheta, const MotorScale& scale = {}) noexcept;

/// The envelope at a point [m, Falcon frame]; false when the point is out of the model's reach.
bool force_envelope_at(const FalconGeometry& g, const Vec3<double>& p_m, const MotorScale& scale,
                       ForceEnvelope& envelope) noexcept;

/// Forward kinematics by damped Newton: p <- p + g J(p) (theta_target - IK(p)), full step
/// first, halved (and retried) whenever the angle error grows or the IK leaves the reach.
/// Warm-started from the previous solution, so a 1 kHz loop needs one or two iterations;
/// `max_iterations` bounds the work per call whatever happens (FALCON.md §5: libnifalcon caps
/// at 15 with gain 0.5 and a 0.01 rad tolerance; this solves to 1e-9 rad, far below a count).
struct FkOptions {
  int max_iterations = 12;
  double tolerance_rad = 1e-9;                   ///< stop when |theta_target - IK(p)| is below this
  Vec3<double> initial_guess_m{0.0, 0.0, 0.11};  ///< the workspace centre (FALCON.md §5)
};

struct FkResult {
  Vec3<double> position_m;  ///< best estimate (kept from the previous call if none better)
  Mat3 dp_dtheta;           ///< Jacobian at position_m (valid when jacobian_valid)
  double residual_rad = 0;  ///< |theta_target - IK(position_m)|
  int iterations = 0;
  bool converged = false;  ///< residual <= tolerance
  bool jacobian_valid = false;
};

class ForwardKinematics {
 public:
  explicit ForwardKinematics(const FalconGeometry& geometry = {}, const FkOptions& options = {}) noexcept;

  /// Solves for the grip position whose IK gives `theta1_rad`, starting from the last result.
  FkResult solve(const Angles& theta1_rad) noexcept;
  /// Forget the warm start (after homing re-bases the encoders, FALCON.md §4).
  void reset() noexcept;

  const FalconGeometry& geometry() const noexcept { return geometry_; }
  const FkOptions& options() const noexcept { return options_; }

 private:
  FalconGeometry geometry_;
  FkOptions options_;
  Vec3<double> last_m_;
};

}  // namespace toonforce::falcon
