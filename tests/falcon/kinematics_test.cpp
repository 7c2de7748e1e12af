// SPDX-License-Identifier: Apache-2.0
// Falcon kinematics against docs/FALCON.md §5 and §8: IK vectors, FK round trips,
// the Jacobian against finite differences, force -> motor words through the true transpose.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "alloc_counter.hpp"
#include "toonforce/hal/falcon/frames.hpp"
#include "toonforce/hal/falcon/kinematics.hpp"

namespace toonforce::falcon {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
const FalconGeometry kGeometry{};

Angles ik(const Vec3<double>& p) {
  Angles t{};
  EXPECT_TRUE(inverse_kinematics(kGeometry, p, t)) << p.x << " " << p.y << " " << p.z;
  return t;
}

Mat3 finite_difference_dtheta_dp(const Vec3<double>& p, double h = 1e-7) {
  Mat3 m;
  for (std::size_t c = 0; c < 3; ++c) {
    Vec3<double> dp{};
    (c == 0 ? dp.x : c == 1 ? dp.y : dp.z) = h;
    const Angles plus = ik(p + dp);
    const Angles minus = ik(p - dp);
    for (std::size_t r = 0; r < 3; ++r) m(r, c) = (plus[r] - minus[r]) / (2 * h);
  }
  return m;
}

double distance(const Vec3<double>& a, const Vec3<double>& b) { return norm(a - b); }

// ---- inverse kinematics: FALCON.md §8 "Kinematic vectors" (given to 3 decimals of a degree) ----

struct IkVector {
  Vec3<double> p;
  Angles theta1_deg;
  std::array<double, 3> encoder;
};

TEST(FalconKinematics, InverseKinematicsMatchesTheReferenceVectors) {
  const IkVector vectors[] = {
      {{0, 0, 0.110}, {16.188, 16.188, 16.188}, {-516.3, -516.3, -516.3}},
      {{0, 0, 0.080}, {-11.800, -11.800, -11.800}, {-1284.5, -1284.5, -1284.5}},
      {{0, 0, 0.150}, {47.243, 47.243, 47.243}, {336.0, 336.0, 336.0}},
      {{0.03, 0, 0.11}, {26.689, -1.217, 33.966}, {-228.1, -994.0, -28.4}},
      {{0, 0.03, 0.11}, {-0.903, 25.543, 34.775}, {-985.4, -259.6, -6.2}},
  };
  for (const auto& v : vectors) {
    const Angles t = ik(v.p);
    for (std::size_t i = 0; i < 3; ++i) {
      // The reference rounds to 3 decimals (26.68847 is listed as 26.689): allow one unit.
      EXPECT_NEAR(t[i] / kDeg, v.theta1_deg[i], 0.001) << "arm " << i + 1 << " at z " << v.p.z;
      EXPECT_NEAR(theta1_rad_to_encoder(t[i]), v.encoder[i], 0.05) << "arm " << i + 1;
    }
  }
}

TEST(FalconKinematics, EncoderScaleIs0Point0364347DegreesPerCountFrom35Degrees) {
  EXPECT_NEAR(encoder_to_theta1_rad(0) / kDeg, 35.0, 1e-12);
  EXPECT_NEAR((encoder_to_theta1_rad(1000) - encoder_to_theta1_rad(0)) / kDeg / 1000, 0.0364347, 1e-7);
  EXPECT_NEAR(theta1_rad_to_encoder(encoder_to_theta1_rad(-1234.5)), -1234.5, 1e-9);
}

TEST(FalconKinematics, UnreachablePointsAreReportedNotInvented) {
  Angles t{1, 2, 3};
  EXPECT_FALSE(inverse_kinematics(kGeometry, {0, 0, 0.5}, t));
  EXPECT_FALSE(inverse_kinematics(kGeometry, {0.3, 0, 0.1}, t));
  EXPECT_FALSE(inverse_kinematics(kGeometry, {std::nan(""), 0, 0.1}, t));
  EXPECT_EQ(t, (Angles{1, 2, 3}));
}

// ---- forward kinematics ----

TEST(FalconKinematics, ZeroEncodersAreNearZ0Point1346) {
  ForwardKinematics fk;
  const FkResult r = fk.solve({encoder_to_theta1_rad(0), encoder_to_theta1_rad(0), encoder_to_theta1_rad(0)});
  ASSERT_TRUE(r.converged);
  EXPECT_NEAR(r.position_m.x, 0.0, 1e-9);
  EXPECT_NEAR(r.position_m.y, 0.0, 1e-9);
  EXPECT_NEAR(r.position_m.z, 0.1346, 0.00005);
}

TEST(FalconKinematics, ForwardKinematicsRoundTripsWithin10Micrometres) {
  // The §8 points and a grid over the HDAL box, each from a cold start (the centre).
  std::vector<Vec3<double>> points{{0, 0, 0.110}, {0, 0, 0.080}, {0, 0, 0.150}, {0.03, 0, 0.11}, {0, 0.03, 0.11}};
  for (double x = -0.04; x <= 0.0401; x += 0.02) {
    for (double y = -0.04; y <= 0.0401; y += 0.02) {
      for (double z = 0.085; z <= 0.1551; z += 0.0175) points.push_back({x, y, z});
    }
  }
  int checked = 0;
  for (const auto& p : points) {
    Angles t{};
    if (!inverse_kinematics(kGeometry, p, t)) continue;
    ForwardKinematics fk;
    const FkResult r = fk.solve(t);
    EXPECT_TRUE(r.converged) << p.x << " " << p.y << " " << p.z << " residual " << r.residual_rad;
    EXPECT_LT(distance(r.position_m, p), 10e-6) << p.x << " " << p.y << " " << p.z;
    ++checked;
  }
  EXPECT_GT(checked, 100);
}

TEST(FalconKinematics, WarmStartTracksAMovingGripInAFewIterationsPerTick) {
  ForwardKinematics fk;
  int worst = 0;
  for (int k = 0; k < 2000; ++k) {
    // A 2 Hz circle of 3 cm radius at 1 kHz: 0.38 m/s, a fast hand.
    const double phase = 2 * std::numbers::pi * 2.0 * k * 0.001;
    const Vec3<double> p{0.03 * std::cos(phase), 0.03 * std::sin(phase), 0.11 + 0.01 * std::sin(phase)};
    const FkResult r = fk.solve(ik(p));
    ASSERT_TRUE(r.converged) << k;
    ASSERT_LT(distance(r.position_m, p), 10e-6) << k;
    worst = std::max(worst, r.iterations);
  }
  EXPECT_LE(worst, 4);  // from 0.4 mm away, quadratic convergence to 1e-9 rad
}

TEST(FalconKinematics, IterationCapBoundsTheWorkAndSuccessiveCallsConverge) {
  FkOptions options;
  options.max_iterations = 1;
  ForwardKinematics fk(FalconGeometry{}, options);
  const Vec3<double> target{0.035, -0.025, 0.145};
  const Angles t = ik(target);
  FkResult r = fk.solve(t);
  EXPECT_EQ(r.iterations, 1);
  EXPECT_FALSE(r.converged);
  const double first = distance(r.position_m, target);
  for (int call = 0; call < 10 && !r.converged; ++call) {
    r = fk.solve(t);
    EXPECT_LE(r.iterations, 1);
  }
  EXPECT_TRUE(r.converged);
  EXPECT_LT(distance(r.position_m, target), 1e-6);
  EXPECT_GT(first, 1e-4);
}

TEST(FalconKinematics, UnreachableTargetKeepsThePreviousEstimate) {
  ForwardKinematics fk;
  const Vec3<double> p{0.01, 0.02, 0.12};
  ASSERT_TRUE(fk.solve(ik(p)).converged);
  const FkResult r = fk.solve({3.0, 3.0, 3.0});  // angles no pose produces
  EXPECT_FALSE(r.converged);
  // Damped and bounded: the estimate stays a pose the linkage can take, never NaN or beyond.
  Angles reachable{};
  EXPECT_TRUE(inverse_kinematics(kGeometry, r.position_m, reachable));
}

// ---- the Jacobian ----

TEST(FalconKinematics, AngleJacobianMatchesFiniteDifferences) {
  const Vec3<double> points[] = {
      {0, 0, 0.11}, {0.03, 0.02, 0.12}, {-0.04, 0.01, 0.09}, {0.02, -0.045, 0.15}, {-0.03, -0.03, 0.1}};
  for (const auto& p : points) {
    Mat3 analytic;
    ASSERT_TRUE(angle_jacobian(kGeometry, p, ik(p), analytic));
    const Mat3 fd = finite_difference_dtheta_dp(p);
    for (std::size_t r = 0; r < 3; ++r) {
      for (std::size_t c = 0; c < 3; ++c) {
        EXPECT_NEAR(analytic(r, c), fd(r, c), 1e-6 * (1 + std::abs(fd(r, c)))) << r << "," << c;
      }
    }
  }
}

/// libnifalcon's row formula (FALCON.md §5 "Jacobian") with its third entry sin^2(theta2)/den,
/// or libnifalcon/libnifalcon#66's sin(theta2) sin(theta3)/den: an oracle for the reference table, not our code.
Mat3 libnifalcon_dtheta_dp(const Vec3<double>& p, bool issue66) {
  const FalconGeometry& g = kGeometry;
  const Angles t1 = ik(p);
  Mat3 m;
  for (std::size_t i = 0; i < 3; ++i) {
    const double phi = g.phi_rad[i];
    const double u = std::cos(phi) * p.x + std::sin(phi) * p.y - g.r_m;
    const double v = -std::sin(phi) * p.x + std::cos(phi) * p.y - g.s_m;
    const double t3 = std::acos((v + g.f_m) / g.b_m);
    const double t2 = std::acos((-u + g.a_m * std::cos(t1[i]) - g.c_m) / (-(g.d_m + g.e_m + g.b_m * std::sin(t3))));
    const double den = -g.a_m * std::sin(t3) * std::sin(t1[i] - t2);
    m(i, 0) = (std::cos(phi) * std::cos(t2) * std::sin(t3) - std::sin(phi) * std::cos(t3)) / den;
    m(i, 1) = (std::sin(phi) * std::cos(t2) * std::sin(t3) + std::cos(phi) * std::cos(t3)) / den;
    m(i, 2) = (issue66 ? std::sin(t2) * std::sin(t3) : std::sin(t2) * std::sin(t2)) / den;
  }
  return m;
}

TEST(FalconKinematics, Issue66ThirdEntryIsTheRightOneAndLibnifalconsIsNot) {
  const Vec3<double> p{0.03, 0.02, 0.12};
  Mat3 ours;
  ASSERT_TRUE(angle_jacobian(kGeometry, p, ik(p), ours));
  const Mat3 fixed = libnifalcon_dtheta_dp(p, true);
  const Mat3 original = libnifalcon_dtheta_dp(p, false);
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(ours(r, c), fixed(r, c), 1e-9);
    EXPECT_GT(std::abs(original(r, 2) - ours(r, 2)), 0.1) << "row " << r;
  }
}

TEST(FalconKinematics, PositionJacobianAtTheCentreMatchesTheReferenceTableInXAndY) {
  // FALCON.md §8 "J = dp/dtheta1 at (0, 0, 0.11)". Its x and y rows match; its z row
  // (0.032395) comes from libnifalcon's sin^2 entry (reproduced here through the oracle),
  // while finite differences of the IK give 0.024180 (checked just above).
  Mat3 j;
  ASSERT_TRUE(position_jacobian(kGeometry, {0, 0, 0.11}, j));
  const double x_row[] = {0.015488, -0.052725, 0.037237};
  const double y_row[] = {-0.051940, 0.012557, 0.039383};
  for (std::size_t c = 0; c < 3; ++c) {
    EXPECT_NEAR(j(0, c), x_row[c], 1e-6);
    EXPECT_NEAR(j(1, c), y_row[c], 1e-6);
  }
  Mat3 lib;
  ASSERT_TRUE(invert(libnifalcon_dtheta_dp({0, 0, 0.11}, false), lib));
  Mat3 fd;
  ASSERT_TRUE(invert(finite_difference_dtheta_dp({0, 0, 0.11}), fd));
  for (std::size_t c = 0; c < 3; ++c) {
    EXPECT_NEAR(lib(2, c), 0.032395, 1e-6) << "the reference's z row is libnifalcon's";
    EXPECT_NEAR(j(2, c), fd(2, c), 1e-8) << "ours follows the IK";
  }
}

TEST(FalconKinematics, OneCountIsAbout15MicrometresAlongZAtTheCentre) {
  Mat3 j;
  ASSERT_TRUE(position_jacobian(kGeometry, {0, 0, 0.11}, j));
  // Moving all three arms by one count moves the grip along z only.
  const double dz = (j(2, 0) + j(2, 1) + j(2, 2)) * kRadPerCount;
  EXPECT_NEAR(std::abs(dz) * 1e6, 3 * 0.024180 * kRadPerCount * 1e6, 0.01);
  EXPECT_NEAR((j(0, 0) + j(0, 1) + j(0, 2)) * kRadPerCount, 0.0, 1e-9);
}

// ---- force -> motor words (FALCON.md §5 "Forces", §8 "Motor words") ----

TEST(FalconKinematics, TrueTransposeGivesTheListedMotorWordsForXAndYForces) {
  Mat3 j;
  ASSERT_TRUE(position_jacobian(kGeometry, {0, 0, 0.11}, j));
  const MotorScale unlimited{10000.0, 32767};
  EXPECT_EQ(force_to_motor_words(j, {10, 0, 0}, unlimited).word, (std::array<std::int16_t, 3>{-1548, 5272, -3723}));
  EXPECT_EQ(force_to_motor_words(j, {0, 10, 0}, unlimited).word, (std::array<std::int16_t, 3>{5193, -1255, -3938}));
}

TEST(FalconKinematics, ZForceWordsFollowTheFiniteDifferenceJacobianNotLibnifalcons) {
  // The table lists (4049, 4049, 4049) for (0, 0, -12.5) N: that is libnifalcon's z row.
  Mat3 j;
  ASSERT_TRUE(position_jacobian(kGeometry, {0, 0, 0.11}, j));
  Mat3 lib;
  ASSERT_TRUE(invert(libnifalcon_dtheta_dp({0, 0, 0.11}, false), lib));
  const Vec3<double> f{0, 0, -12.5};
  const Vec3<double> theirs = motor_words_exact(lib, f);
  EXPECT_EQ(static_cast<int>(theirs.x), 4049);
  Mat3 fd;
  ASSERT_TRUE(invert(finite_difference_dtheta_dp({0, 0, 0.11}), fd));
  const MotorWords ours = force_to_motor_words(j, f);
  const Vec3<double> expected = motor_words_exact(fd, f);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(ours.word[i], (i == 0 ? expected.x : i == 1 ? expected.y : expected.z), 1.0);
    EXPECT_GT(ours.word[i], 0) << "pushing the grip in (-z) drives every motor positive";
  }
}

TEST(FalconKinematics, LibnifalconsAliasedTransposeIsNotWhatWeCompute) {
  // FALCON.md §5: setTranspose in place on column-major storage gives a symmetric matrix built
  // from J's lower triangle. Rebuild it and check it gives the "with the bug" column of §8.
  Mat3 j;
  ASSERT_TRUE(position_jacobian(kGeometry, {0, 0, 0.11}, j));
  Mat3 aliased;  // used as "J^T": entry (r, c) of the transpose taken from the lower triangle
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) aliased(r, c) = r >= c ? j(r, c) : j(c, r);
  }
  const auto buggy_words = [&](const Vec3<double>& f) {
    // tau = aliased * F (libnifalcon multiplies its "transpose" by F).
    const double t0 = aliased(0, 0) * f.x + aliased(0, 1) * f.y + aliased(0, 2) * f.z;
    const double t1 = aliased(1, 0) * f.x + aliased(1, 1) * f.y + aliased(1, 2) * f.z;
    return std::array<int, 2>{static_cast<int>(-10000 * t0), static_cast<int>(-10000 * t1)};
  };
  EXPECT_EQ(buggy_words({10, 0, 0}), (std::array<int, 2>{-1548, 5193}));
  const MotorWords ours = force_to_motor_words(j, {10, 0, 0}, {10000.0, 32767});
  EXPECT_EQ(ours.word[1], 5272) << "the true transpose differs where the bug bites";
}

TEST(FalconKinematics, LargeForcesScaleDownKeepingTheDirection) {
  Mat3 j;
  ASSERT_TRUE(position_jacobian(kGeometry, {0.01, -0.02, 0.12}, j));
  const Vec3<double> f{30, -20, 45};
  const MotorWords w = force_to_motor_words(j, f);
  EXPECT_TRUE(w.saturated);
  const Vec3<double> exact = motor_words_exact(j, f);
  const int largest = std::max({std::abs(w.word[0]), std::abs(w.word[1]), std::abs(w.word[2])});
  EXPECT_EQ(largest, 4095);
  const double k = 4095.0 / std::max({std::abs(exact.x), std::abs(exact.y), std::abs(exact.z)});
  EXPECT_NEAR(w.word[0], exact.x * k, 1.0);
  EXPECT_NEAR(w.word[1], exact.y * k, 1.0);
  EXPECT_NEAR(w.word[2], exact.z * k, 1.0);
  EXPECT_FALSE(force_to_motor_words(j, {0.5, 0.5, 0.5}).saturated);
}

// ---- the force envelope (what the +-4095 words allow, per pose and direction) ----

/// The oracle: the largest force along u from the finite-difference Jacobian of the IK, by
/// bisection on the words' magnitude (no closed form shared with the code under test).
double envelope_by_bisection(const Vec3<double>& p, const Vec3<double>& u, double words_per_n_m = 10000.0) {
  Mat3 fd;
  EXPECT_TRUE(invert(finite_difference_dtheta_dp(p), fd));
  const auto largest_word = [&](double f) {
    const Vec3<double> tau = joint_torques(fd, u * f);
    return words_per_n_m * std::max({std::abs(tau.x), std::abs(tau.y), std::abs(tau.z)});
  };
  double lo = 0.0;
  double hi = 1000.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (largest_word(mid) <= 4095.0 ? lo : hi) = mid;
  }
  return lo;
}

TEST(FalconEnvelope, AlongEachAxisItIsTheForceAtWhichTheLargestWordReaches4095) {
  for (const Vec3<double>& p : {Vec3<double>{0, 0, 0.11}, Vec3<double>{0.04, -0.03, 0.09},
                                Vec3<double>{-0.04, 0.03, 0.15}, Vec3<double>{0.0, -0.055, 0.13}}) {
    ForceEnvelope e;
    ASSERT_TRUE(force_envelope_at(kGeometry, p, {}, e));
    EXPECT_NEAR(e.axis_n.x, envelope_by_bisection(p, {1, 0, 0}), 1e-4 * e.axis_n.x) << p.x << " " << p.y << " " << p.z;
    EXPECT_NEAR(e.axis_n.y, envelope_by_bisection(p, {0, 1, 0}), 1e-4 * e.axis_n.y);
    EXPECT_NEAR(e.axis_n.z, envelope_by_bisection(p, {0, 0, 1}), 1e-4 * e.axis_n.z);
  }
}

TEST(FalconEnvelope, AtTheCentreXAndYFollowTheReferenceJacobianAndZTheIk) {
  // FALCON.md §8's J at (0, 0, 0.11): the largest |x-row| entry is 0.052725 m/rad, y's
  // 0.051940, so 4095 / (10000 * that) = 7.77 N and 7.88 N; along z, where the table's row is
  // libnifalcon's, the IK's own 0.024180 gives 16.9 N (the expected "7.8, 7.9 and 17 N").
  ForceEnvelope e;
  ASSERT_TRUE(force_envelope_at(kGeometry, {0, 0, 0.11}, {}, e));
  EXPECT_NEAR(e.axis_n.x, 4095.0 / (10000.0 * 0.052725), 0.001);
  EXPECT_NEAR(e.axis_n.y, 4095.0 / (10000.0 * 0.051940), 0.001);
  EXPECT_NEAR(e.axis_n.z, 4095.0 / (10000.0 * 0.024180), 0.01);
}

TEST(FalconEnvelope, EveryDirectionIsTheWeakestDirection) {
  for (const Vec3<double>& p : {Vec3<double>{0.03, 0.02, 0.10}, Vec3<double>{0.04, -0.03, 0.09},
                                Vec3<double>{0.0, -0.055, 0.13}, Vec3<double>{-0.035, 0.01, 0.16}}) {
    Mat3 j;
    ASSERT_TRUE(position_jacobian(kGeometry, p, j));
    const ForceEnvelope e = force_envelope(j);
    double weakest = 1e9;
    // Directions spread over the sphere (a Fibonacci lattice).
    constexpr int kDirections = 4000;
    for (int i = 0; i < kDirections; ++i) {
      const double z = 1.0 - 2.0 * (i + 0.5) / kDirections;
      const double r = std::sqrt(1.0 - z * z);
      const double phi = i * std::numbers::pi * (3.0 - std::sqrt(5.0));
      weakest = std::min(weakest, max_force_along(j, {r * std::cos(phi), r * std::sin(phi), z}));
    }
    EXPECT_GE(weakest, e.every_direction_n * (1 - 1e-12)) << "no direction is weaker";
    EXPECT_NEAR(weakest, e.every_direction_n, 0.01 * e.every_direction_n) << "a lattice direction comes close";
    EXPECT_LE(e.every_direction_n, std::min({e.axis_n.x, e.axis_n.y, e.axis_n.z}));
  }
}

TEST(FalconEnvelope, AForceInsideTheEnvelopeIsGivenAndOneBeyondIsScaledBack) {
  Mat3 j;
  ASSERT_TRUE(position_jacobian(kGeometry, {-0.02, 0.04, 0.13}, j));
  const Vec3<double> v{1, -2, 0.5};
  const Vec3<double> u = v * (1.0 / norm(v));
  const double limit = max_force_along(j, u);
  EXPECT_FALSE(force_to_motor_words(j, u * (limit * 0.999)).saturated);
  const MotorWords beyond = force_to_motor_words(j, u * (limit * 1.01));
  EXPECT_TRUE(beyond.saturated);
  EXPECT_EQ(std::max({std::abs(beyond.word[0]), std::abs(beyond.word[1]), std::abs(beyond.word[2])}), 4095);
}

TEST(FalconEnvelope, MoreWordsPerNewtonMetreMeanProportionallyLessForce) {
  // A calibrated constant twice libnifalcon's halves every limit (the words are k tau).
  ForceEnvelope a;
  ForceEnvelope b;
  ASSERT_TRUE(force_envelope_at(kGeometry, {0, 0, 0.11}, MotorScale{10000.0, 4095}, a));
  ASSERT_TRUE(force_envelope_at(kGeometry, {0, 0, 0.11}, MotorScale{20000.0, 4095}, b));
  EXPECT_NEAR(b.axis_n.x, a.axis_n.x / 2, 1e-12);
  EXPECT_NEAR(b.every_direction_n, a.every_direction_n / 2, 1e-12);
  EXPECT_NEAR(envelope_by_bisection({0, 0, 0.11}, {0, 1, 0}, 20000.0), b.axis_n.y, 1e-4);
}

TEST(FalconKinematics, NonFiniteForceGivesZeroWords) {
  Mat3 j;
  ASSERT_TRUE(position_jacobian(kGeometry, {0, 0, 0.11}, j));
  EXPECT_EQ(force_to_motor_words(j, {std::nan(""), 0, 0}).word, (std::array<std::int16_t, 3>{0, 0, 0}));
  EXPECT_EQ(force_to_motor_words(j, {HUGE_VAL, 0, 0}).word, (std::array<std::int16_t, 3>{0, 0, 0}));
}

TEST(FalconKinematics, TickWorkDoesNotAllocate) {
  ForwardKinematics fk;
  const Angles t = ik({0.02, 0.01, 0.12});
  test::AllocationScope scope;
  for (int k = 0; k < 1000; ++k) {
    const FkResult r = fk.solve(t);
    const MotorWords w = force_to_motor_words(r.dp_dtheta, {1, 2, 3});
    ASSERT_TRUE(r.jacobian_valid && w.word[0] != 32767);
  }
  EXPECT_EQ(scope.count(), 0u);
}

// ---- the frame conversion of effects.md §0 ----

TEST(FalconFrame, SceneIsXMinusZYAfterTheCentre) {
  const Vec3<double> centre{0, 0, 0.11};
  const auto expect_near = [](const Vec3<double>& a, const Vec3<double>& b) {
    EXPECT_NEAR(a.x, b.x, 1e-15);
    EXPECT_NEAR(a.y, b.y, 1e-15);
    EXPECT_NEAR(a.z, b.z, 1e-15);
  };
  // Grip pulled toward the user (+z Falcon) is toward the user in the scene (-y); up is up.
  expect_near(falcon_to_scene({0, 0, 0.13}, centre), {0, -0.02, 0});
  expect_near(falcon_to_scene({0, 0.01, 0.11}, centre), {0, 0, 0.01});
  expect_near(falcon_to_scene({0.03, 0, 0.11}, centre), {0.03, 0, 0});
  const Vec3<double> p{0.012, -0.034, 0.097};
  expect_near(scene_to_falcon(falcon_to_scene(p, centre), centre), p);
  // Forces rotate the same way: scene +z (up) is Falcon +y, scene +y (away) is Falcon -z.
  expect_near(scene_force_to_falcon({0, 0, 1}), {0, 1, 0});
  expect_near(scene_force_to_falcon({0, 1, 0}), {0, 0, -1});
}

}  // namespace
}  // namespace toonforce::falcon
