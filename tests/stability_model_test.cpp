// The stability maps' linear analysis (tools/report: spectral.hpp, stability.hpp SampledLoop):
// the eigenvalue routine on matrices whose eigenvalues are known by construction, and the
// sampled loop's transition matrix against closed forms, against the passivity bound it must
// agree with, and against the simulation it models.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <vector>

#include "toonforce/control/passivity_bound.hpp"
#include "toonforce/report/spectral.hpp"
#include "toonforce/report/stability.hpp"

namespace toonforce::report {
namespace {

using Complex = std::complex<double>;

Matrix multiply(const Matrix& a, const Matrix& b) {
  const std::size_t n = a.size();
  Matrix c(n, std::vector<double>(n, 0.0));
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = 0; k < n; ++k) {
      for (std::size_t j = 0; j < n; ++j) c[i][j] += a[i][k] * b[k][j];
    }
  }
  return c;
}

/// Every expected eigenvalue is matched by one computed within `tolerance` (each used once).
void expect_eigenvalues(const Matrix& a, std::vector<Complex> expected, double tolerance) {
  auto got = eigenvalues(a);
  ASSERT_TRUE(got) << got.error();
  ASSERT_EQ(got->size(), expected.size());
  std::vector<Complex> left = got.value();
  for (const Complex& z : expected) {
    const auto nearest = std::min_element(left.begin(), left.end(), [&z](const Complex& p, const Complex& q) {
      return std::abs(p - z) < std::abs(q - z);
    });
    EXPECT_LE(std::abs(*nearest - z), tolerance) << "expected " << z << ", nearest " << *nearest;
    left.erase(nearest);
  }
}

/// S A S^-1 for S = I + N (N strictly upper triangular, so S^-1 = I - N + N^2 - ... exactly
/// finite): a non-normal matrix with A's eigenvalues.
Matrix similar(const Matrix& a) {
  const std::size_t n = a.size();
  Matrix s(n, std::vector<double>(n, 0.0));
  Matrix nil(n, std::vector<double>(n, 0.0));
  for (std::size_t i = 0; i < n; ++i) {
    s[i][i] = 1.0;
    for (std::size_t j = i + 1; j < n; ++j) nil[i][j] = s[i][j] = 0.7 + 0.3 * static_cast<double>(i) - 0.45 * static_cast<double>(j);
  }
  Matrix inverse(n, std::vector<double>(n, 0.0));
  Matrix power(n, std::vector<double>(n, 0.0));
  for (std::size_t i = 0; i < n; ++i) power[i][i] = 1.0;
  for (std::size_t k = 0; k < n; ++k) {
    const double sign = k % 2 == 0 ? 1.0 : -1.0;
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = 0; j < n; ++j) inverse[i][j] += sign * power[i][j];
    }
    power = multiply(power, nil);
  }
  return multiply(multiply(s, a), inverse);
}

TEST(StabilitySpectral, FindsTheEigenvaluesOfADiagonalMatrix) {
  expect_eigenvalues({{0.3, 0.0, 0.0}, {0.0, -2.0, 0.0}, {0.0, 0.0, 5.0}}, {0.3, -2.0, 5.0}, 1e-14);
  expect_eigenvalues({{0.75}}, {0.75}, 0.0);
}

TEST(StabilitySpectral, FindsRealAndComplexEigenvaluesOfANonNormalMatrix) {
  // Block diagonal: a rotation by 0.4 rad scaled by 0.9 (eigenvalues 0.9 e^(+-0.4 i)), 1.01,
  // 0.2 and -0.5, made non-normal by a similarity.
  const double c = 0.9 * std::cos(0.4);
  const double s = 0.9 * std::sin(0.4);
  const Matrix block{{c, -s, 0, 0, 0}, {s, c, 0, 0, 0}, {0, 0, 1.01, 0, 0}, {0, 0, 0, 0.2, 0}, {0, 0, 0, 0, -0.5}};
  const Matrix a = similar(block);
  expect_eigenvalues(a, {std::polar(0.9, 0.4), std::polar(0.9, -0.4), 1.01, 0.2, -0.5}, 1e-12);
  const auto rho = spectral_radius(a);
  ASSERT_TRUE(rho);
  EXPECT_NEAR(rho.value(), 1.01, 1e-12);
}

TEST(StabilitySpectral, FindsTheRootsOfACompanionMatrix) {
  // (z - 0.5)(z + 0.3)(z^2 - 1.2 z + 0.72): roots 0.5, -0.3, 0.6 +- 0.6 i. Coefficients by
  // multiplying out the factors here.
  std::vector<double> p{1.0};  // highest power first
  const auto times = [&p](const std::vector<double>& f) {
    std::vector<double> q(p.size() + f.size() - 1, 0.0);
    for (std::size_t i = 0; i < p.size(); ++i) {
      for (std::size_t j = 0; j < f.size(); ++j) q[i + j] += p[i] * f[j];
    }
    p = q;
  };
  times({1.0, -0.5});
  times({1.0, 0.3});
  times({1.0, -1.2, 0.72});
  const std::size_t n = p.size() - 1;
  Matrix companion(n, std::vector<double>(n, 0.0));
  for (std::size_t j = 0; j < n; ++j) companion[0][j] = -p[j + 1];
  for (std::size_t i = 1; i < n; ++i) companion[i][i - 1] = 1.0;
  expect_eigenvalues(companion, {0.5, -0.3, Complex(0.6, 0.6), Complex(0.6, -0.6)}, 1e-12);
}

TEST(StabilitySpectral, BadlyScaledEntriesDoNotCostAccuracy) {
  // D A D^-1 with D = diag(1, 1e6, 1e-6, 1): the transition matrices mix metres, m/s and
  // N/m over 10 decades; balancing removes the scaling.
  const Matrix a = similar({{0.99, 0.05, 0, 0}, {-0.05, 0.99, 0, 0}, {0, 0, 0.3, 0}, {0, 0, 0, 1e-3}});
  const std::vector<double> d{1.0, 1e6, 1e-6, 1.0};
  Matrix scaled = a;
  for (std::size_t i = 0; i < 4; ++i) {
    for (std::size_t j = 0; j < 4; ++j) scaled[i][j] = d[i] * a[i][j] / d[j];
  }
  expect_eigenvalues(scaled, {Complex(0.99, 0.05), Complex(0.99, -0.05), 0.3, 1e-3}, 1e-12);
}

// ---- the sampled loop ----------------------------------------------------------------------

TEST(StabilityModel, AFreeDampedMassDecaysAtExpOfMinusBTOverM) {
  // No spring, no feedback: the velocity decays by e^(-b T / m) per tick; the free position
  // (eigenvalue 1) is removed, so that is the spectral radius.
  for (const int delay : {0, 1, 3}) {
    SampledLoop l;
    l.mass_kg = 0.15;
    l.damping_n_s_per_m = 2.0;
    l.delay_ticks = delay;
    const auto rho = loop_spectral_radius(l);
    ASSERT_TRUE(rho) << rho.error();
    EXPECT_NEAR(rho.value(), std::exp(-2.0 * 1e-3 / 0.15), 1e-13) << "delay " << delay;
  }
}

TEST(StabilityModel, AnUndampedSampledSpringGrowsAsTheZeroOrderHoldPredicts) {
  // b = 0, F_k = -K x_k held over T: x_k obeys (z - 1)^2 + a (z + 1) = 0 with a = K T^2 / (2 m)
  // (the ZOH equivalent of 1 / (m s^2): T^2 (z + 1) / (2 m (z - 1)^2)), whose complex roots
  // have |z|^2 = 1 + a: every stiffness grows without physical damping (Colgate and Brown).
  for (const double k : {10.0, 1000.0, 30000.0}) {
    SampledLoop l;
    l.mass_kg = 0.15;
    l.stiffness_n_per_m = k;
    const auto rho = loop_spectral_radius(l);
    ASSERT_TRUE(rho) << rho.error();
    EXPECT_NEAR(rho.value(), std::sqrt(1.0 + k * 1e-6 / 0.3), 1e-12) << "K " << k;
  }
}

TEST(StabilityModel, InsideThePassivityBoundEveryLoopIsStable) {
  // The delay-aware Colgate-Brown bound is sufficient for passivity, hence for the stability of
  // the device pressed by a constant force: every loop inside it must have rho < 1. Two
  // independent computations (the bound's formula and the eigenvalues) must agree.
  int checked = 0;
  for (const int d : {0, 1, 2}) {
    for (const double t : {1e-4, 1e-3, 2e-3}) {
      for (const double b : {0.05, 0.1, 1.0, 15.1}) {
        for (const double share : {0.1, 0.5, 0.9, 0.99}) {  // of b that the bound's terms use
          for (const double virtual_share : {0.0, 0.5}) {   // of it that |B| takes
            const double b_virtual = share * b * virtual_share;
            const double k = stiffest_passive_wall_n_per_m(share * b, t, d, b_virtual);
            for (const double sign : {-1.0, 1.0}) {  // a wall's damping, or a slippery gain
              SampledLoop l;
              l.mass_kg = 0.15;
              l.damping_n_s_per_m = b;
              l.period_s = t;
              l.delay_ticks = d;
              l.stiffness_n_per_m = k;
              l.velocity_feedback_n_s_per_m = sign * b_virtual;
              ASSERT_LT(damping_needed_n_s_per_m(k, t, d, b_virtual), b);
              const auto rho = loop_spectral_radius(l);
              ASSERT_TRUE(rho) << rho.error();
              EXPECT_LT(rho.value(), 1.0) << "d " << d << ", T " << t << ", b " << b << ", K " << k << ", c "
                                          << l.velocity_feedback_n_s_per_m;
              ++checked;
            }
          }
        }
      }
    }
  }
  EXPECT_EQ(checked, 3 * 3 * 4 * 4 * 2 * 2);
}

TEST(StabilityModel, TheSimulationGrowsAtTheRateTheEigenvaluePredicts) {
  // An undamped ideal device pressed onto a 1000 N/m wall at 1 kHz (rho = sqrt(1 + K T^2 /
  // 2m) > 1), started with a small oscillation so that it stays in contact for the whole run:
  // its energy must grow as rho^(2k). The run's peak energy over its last quarter against
  // that over its first is the growth over about three quarters of the run.
  constexpr double kK = 1000.0;
  constexpr double kMassKg = 0.15;
  Experiment e;
  e.device.name = "ideal";
  e.device.mass_kg = kMassKg;
  e.device.io_delay_ticks = 0;
  e.press_n = {0.0, 0.0, -1.0};
  e.duration_s = 2.0;
  e.scene_toml = "[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 1000.0\n";
  e.velocity_cutoff_hz = 1e9;
  e.wall_stiffness_n_per_m = kK;
  e.equilibrium_m = {0.0, 0.0, -1.0 / kK};
  e.start_m = e.equilibrium_m;
  e.hand_aim_m = e.equilibrium_m;
  e.start_velocity_m_per_s = {0.0, 0.0, -0.01 * (1.0 / kK) * std::sqrt(kK / kMassKg)};
  const auto outcome = run_experiment(e);
  ASSERT_TRUE(outcome) << outcome.error();
  SampledLoop l;
  l.mass_kg = kMassKg;
  l.stiffness_n_per_m = kK;
  l.velocity_gain = 1.0;
  const auto rho = loop_spectral_radius(l);
  ASSERT_TRUE(rho);
  // Quarter peaks at about 500 and 2000 ticks: 1500 ticks apart, within an oscillation period
  // (77 ticks) either way.
  const double predicted = std::pow(rho.value(), 2.0 * 1500.0);
  EXPECT_GT(outcome->growth, predicted * std::pow(rho.value(), -2.0 * 80.0));
  EXPECT_LT(outcome->growth, predicted * std::pow(rho.value(), 2.0 * 80.0));
  EXPECT_EQ(outcome->stability, Stability::kUnstable);
}

TEST(StabilityModel, ColgateSchenkelsRequiredDampingIsTheBoundForASpringADamperAndTheSlipperyGain) {
  // Closed forms of b_req (Colgate and Schenkel 1997) for the laws the bound was derived for:
  // a spring K behind d ticks, (T/2) max (cos d theta - cos (d+1) theta) / (1 - cos theta), which
  // is (1 + 2 d) K T / 2 at theta -> 0 (d = 0: constant; d = 1: 1 + 2 cos theta); a backward-
  // difference damper B, max -B cos theta... = B at theta = pi; a negative one (the slippery
  // gain mu), mu cos theta, mu at theta -> 0 (evaluated at 1e-7 rad: met to 1e-14).
  for (const int d : {0, 1}) {
    SampledLoop spring;
    spring.delay_ticks = d;
    spring.stiffness_n_per_m = 5000.0;
    EXPECT_NEAR(required_damping_n_s_per_m(spring), damping_needed_n_s_per_m(5000.0, 1e-3, d), 1e-12);
  }
  SampledLoop damper;
  damper.velocity_feedback_n_s_per_m = -3.0;
  EXPECT_NEAR(required_damping_n_s_per_m(damper), 3.0, 1e-12);
  SampledLoop slippery;
  slippery.velocity_feedback_n_s_per_m = 3.0;
  EXPECT_NEAR(required_damping_n_s_per_m(slippery), 3.0, 1e-12);
  // And the delay-aware bound is sufficient for every combination: b_req never exceeds it.
  for (const int d : {0, 1, 2, 3}) {
    for (const double k : {0.0, 100.0, 1e4}) {
      for (const double c : {-5.0, 0.0, 5.0}) {
        SampledLoop l;
        l.delay_ticks = d;
        l.stiffness_n_per_m = k;
        l.velocity_feedback_n_s_per_m = c;
        EXPECT_LE(required_damping_n_s_per_m(l), damping_needed_n_s_per_m(k, 1e-3, d, c) * (1.0 + 1e-12))
            << "d " << d << ", K " << k << ", c " << c;
      }
    }
  }
}

TEST(StabilityModel, AClampedWallStoresItsForceIntegral) {
  // U(d) = integral of min(K s, F_max) ds.
  EXPECT_DOUBLE_EQ(wall_energy_j(1000.0, 0.004, 8.0), 0.5 * 1000.0 * 0.004 * 0.004);
  EXPECT_DOUBLE_EQ(wall_energy_j(1000.0, 0.02, 8.0), 8.0 * (0.02 - 0.008) + 0.5 * 8.0 * 0.008);
  EXPECT_DOUBLE_EQ(wall_energy_j(1000.0, 0.02, 0.0), 0.5 * 1000.0 * 0.02 * 0.02);
  EXPECT_EQ(wall_energy_j(1000.0, -0.01, 8.0), 0.0);
  double integral = 0.0;  // midpoint rule, exact for a piecewise-linear force with a knot on the grid
  const int n = 20000;
  for (int i = 0; i < n; ++i) integral += std::min(1000.0 * (i + 0.5) * 1e-6, 8.0) * 1e-6;
  EXPECT_NEAR(wall_energy_j(1000.0, 0.02, 8.0), integral, 1e-12);
}

}  // namespace
}  // namespace toonforce::report
