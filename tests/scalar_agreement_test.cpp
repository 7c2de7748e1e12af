// SPDX-License-Identifier: Apache-2.0
// float and Q16.16 against the double reference (spec effects.md §8), scene by scene, each
// with the bound it must meet and where the bound comes from. Motions stay clear of the laws'
// discontinuities (the contact boundary, the cliff's strip edges and speed threshold): there a
// one-LSB difference moves a switch by a tick, which is a timing difference, not a precision
// one; those ticks are excluded explicitly and counted.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "spec_loop.hpp"
#include "toonforce/config/scene_file.hpp"

namespace toonforce::test {
namespace {

constexpr double kDt = 1e-3;
constexpr double kLsb = 1.0 / 65536.0;  // Q16.16 resolution

struct Point {
  Vec3<double> x;
  Vec3<double> v;
};
using Motion = std::function<Point(double t)>;

template <Scalar S>
std::vector<Vec3<double>> forces(const std::string& scene_name, ScalarKind kind, const Motion& motion, int ticks,
                                 bool given_velocity, std::vector<bool>* fault = nullptr) {
  const auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/" + scene_name + ".toml", kind);
  EXPECT_TRUE(scene) << scene.error();
  SpecLoop ctl(make_runtime_scene<S>(scene.value()), servo_config(scene.value(), kDt));
  std::vector<Vec3<double>> out;
  for (int k = 0; k < ticks; ++k) {
    const Point p = motion(k * kDt);
    Sample s = sample(k, p.x);
    s.velocity_m_per_s = p.v;
    s.has_velocity = given_velocity;
    const auto r = ctl.tick(s);
    out.push_back(to_double(r.force_n));
    if (fault != nullptr) fault->push_back(static_cast<bool>(r.faults));
  }
  return out;
}

/// Max |F_S - F_double| over the ticks `keep` accepts.
double max_difference(const std::vector<Vec3<double>>& reference, const std::vector<Vec3<double>>& other,
                      const std::function<bool(int)>& keep) {
  double worst = 0.0;
  for (std::size_t i = 0; i < reference.size(); ++i) {
    if (!keep(static_cast<int>(i))) continue;
    worst = std::max(worst, norm(reference[i] - other[i]));
  }
  return worst;
}

// In and out of a floor at z = 0, sliding sideways: delta up to 4 mm.
Point in_and_out(double t) {
  return {{-0.03 + 0.02 * t, 0.003 * std::sin(3 * t), -0.001 + 0.004 * std::sin(5 * t)},
          {0.02, 0.009 * std::cos(3 * t), 0.02 * std::cos(5 * t)}};
}
// Penetration of in_and_out: away from the contact boundary by more than 4 LSB.
bool clear_of_contact_edge(int k) { return std::abs(in_and_out(k * kDt).x.z) > 4 * kLsb; }

constexpr int kTicks = 4000;
constexpr double kStiffness = 1500.0;  // all bundled scenes

TEST(ScalarAgreement, PenaltyWall) {
  const auto d = forces<double>("wall", ScalarKind::kDouble, in_and_out, kTicks, false);
  // float: k delta with delta ~ 4e-3 m carries a relative error of a few float epsilons
  // (1.2e-7): k * 4e-3 * 1e-6 = 6e-6 N bounds it with margin.
  EXPECT_LT(
      max_difference(d, forces<float>("wall", ScalarKind::kFloat, in_and_out, kTicks, false), clear_of_contact_edge),
      6e-6);
  // Q16.16: the position rounds by half an LSB (k * 2^-17 = 0.0114 N) and the product by half
  // an LSB more; the clamp to 8 N only shrinks differences.
  EXPECT_LT(
      max_difference(d, forces<Q16_16>("wall", ScalarKind::kQ16_16, in_and_out, kTicks, false), clear_of_contact_edge),
      kStiffness * kLsb / 2 + 2 * kLsb);
}

TEST(ScalarAgreement, RealisticFrictionWithMeasuredVelocity) {
  const auto d = forces<double>("realistic_friction", ScalarKind::kDouble, in_and_out, kTicks, true);
  // float: the largest gain is the Coulomb damper below v_reg, mu_c N / v_reg = 0.3 * 6 / 0.02
  // = 90 N s/m; float rounding of v (~1e-9 m/s) and N through it stays far under 1e-5 N.
  EXPECT_LT(max_difference(d, forces<float>("realistic_friction", ScalarKind::kFloat, in_and_out, kTicks, true),
                           clear_of_contact_edge),
            1e-5);
  // Q16.16: the wall's 0.0114 N error reaches the Coulomb part times mu_c (0.3), and the
  // velocity's half-LSB rounding goes through the 90 N s/m damper (0.0007 N): 0.02 N bounds
  // the sum with margin for the quotient's rounding.
  EXPECT_LT(max_difference(d, forces<Q16_16>("realistic_friction", ScalarKind::kQ16_16, in_and_out, kTicks, true),
                           clear_of_contact_edge),
            0.02);
}

TEST(ScalarAgreement, VelocityEstimateInQ16IsBoundedByOneCountPerTick) {
  // With estimated velocity the Q16.16 error is dominated by the estimator: a position
  // difference of one LSB per tick is 2^-16 * 1000 Hz = 0.0153 m/s, and the low-pass, a convex
  // combination, cannot exceed it. Seen through a damped wall (b = 20 N s/m, spring-free
  // motion outside nothing else) the force error is at most b times that, plus the wall's own.
  const auto scene_text =
      std::string("[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1500\ndamping = 20\n");
  const auto dd = parse_scene(scene_text, "damped.toml", ScalarKind::kDouble);
  const auto dq = parse_scene(scene_text, "damped.toml", ScalarKind::kQ16_16);
  ASSERT_TRUE(dd && dq);
  SpecLoop cd(make_runtime_scene<double>(dd.value()), servo_config(dd.value(), kDt));
  SpecLoop cq(make_runtime_scene<Q16_16>(dq.value()), servo_config(dq.value(), kDt));
  double worst = 0.0;
  for (int k = 0; k < kTicks; ++k) {
    const Sample s = sample(k, in_and_out(k * kDt).x);
    const auto a = to_double(cd.tick(s).force_n);
    const auto b = to_double(cq.tick(s).force_n);
    if (clear_of_contact_edge(k) && a.z > 0.5) worst = std::max(worst, std::abs(a.z - b.z));
  }
  EXPECT_LT(worst, 20.0 * kLsb * 1000.0 + kStiffness * kLsb / 2 + 4 * kLsb);
  EXPECT_GT(worst, kStiffness * kLsb / 2);  // the estimator's share is real, and visible here
}

TEST(ScalarAgreement, SuperSlippery) {
  const auto d = forces<double>("slippery", ScalarKind::kDouble, in_and_out, kTicks, true);
  EXPECT_LT(
      max_difference(d, forces<float>("slippery", ScalarKind::kFloat, in_and_out, kTicks, true), clear_of_contact_edge),
      6e-6);
  // Q16.16: the wall's error plus mu times half an LSB of velocity (4 * 7.6e-6) and the cap's
  // rescaling (a quotient and a product, an LSB each).
  EXPECT_LT(max_difference(d, forces<Q16_16>("slippery", ScalarKind::kQ16_16, in_and_out, kTicks, true),
                           clear_of_contact_edge),
            kStiffness * kLsb / 2 + 4.0 * kLsb / 2 + 4 * kLsb);
}

// Strikes the floor at 0.2 m/s every 0.5 s, enters 2 mm deep, and leaves. The surface is
// crossed half a tick away from any tick, so no entry is decided by the last bit.
Point strikes(double t) {
  const double phase = std::fmod(t, 0.5);
  const double z = 0.0101 - 0.2 * phase + (phase > 0.06 ? 0.2 * (phase - 0.06) * 2.0 : 0.0);
  const double vz = phase > 0.06 ? 0.2 : -0.2;
  return {{0.0, 0.0, z}, {0.0, 0.0, vz}};
}

TEST(ScalarAgreement, CartoonWallImpactTransient) {
  auto clear = [](int k) { return std::abs(strikes(k * kDt).x.z) > 4 * kLsb; };
  const auto d = forces<double>("cartoon_wall", ScalarKind::kDouble, strikes, kTicks, true);
  int transient_ticks_out_of_contact = 0;  // the transient really ran (not a wall-only run)
  for (std::size_t k = 0; k < d.size(); ++k) {
    transient_ticks_out_of_contact += strikes(static_cast<double>(k) * kDt).x.z > 0 && norm(d[k]) > 1.0;
  }
  EXPECT_GT(transient_ticks_out_of_contact, 100);
  // float: t and the phase f t round at 1e-7 relative; the transient's scale
  // v_i d (k_r + k_osc) = 18 N times 1e-6 bounds it.
  EXPECT_LT(max_difference(d, forces<float>("cartoon_wall", ScalarKind::kFloat, strikes, kTicks, true), clear), 2e-5);
  // Q16.16: t rounds by half an LSB (7.6e-6 s), so the phase f t by 2.3e-4 turns, moving the
  // sine by up to 2 pi * 2.3e-4 = 1.4e-3; times v_i (d - t) k_osc <= 0.2 * 0.15 * 400 = 12 N
  // that is 0.017 N; the recoil's slope v_i k_r (40 N/s) over half an LSB of t and the wall's
  // 0.0114 N add less than 0.012 N. The clamp (8 N) only shrinks differences.
  EXPECT_LT(max_difference(d, forces<Q16_16>("cartoon_wall", ScalarKind::kQ16_16, strikes, kTicks, true), clear), 0.03);
}

// A phase f t past Q16.16's range (20 kHz for 3 s: 60,000 turns; a scene file cannot say so,
// ImpactTransient::check, but the law takes any parameters): only the phase's fraction matters
// to the sine, and Q16.16 keeps it, so the force is the double law's at the Q16.16 time. With a
// saturated phase the sine would stop at sin(2 pi (1 - 2^-16)) and the force with it.
TEST(ScalarAgreement, Q16ImpactPhasePastTheRangeKeepsItsFraction) {
  using Law = ImpactTransient<Q16_16>;
  Law::Params p{};
  p.oscillation_gain_n_per_m = scalar_cast<Q16_16>(100.0);
  p.duration_s = scalar_cast<Q16_16>(3.0);
  p.frequency_hz = scalar_cast<Q16_16>(20000.0);
  p.sine = SineMethod::kPolynomial;
  Law::State s{};
  ASSERT_TRUE(Law::fire(p, s, 0.5, Instant{0, 0}));  // v_i = 0.5 m/s from tick 0
  TickInput<Q16_16> in{};
  in.period_ns = 100'000;  // 10 kHz
  const Contact<Q16_16> outside{scalar_cast<Q16_16>(-0.01), Q16_16{}};
  double largest = 0.0;
  for (std::int64_t k = 20'000; k < 20'050; ++k) {  // t = 2 s on: f t from 40,000 turns
    in.now = Instant{k, 0};
    const double t = to_double(Q16_16::from_ratio(k * in.period_ns, 1'000'000'000));
    const double want = 0.5 * (3.0 - t) * 100.0 * std::sin(2.0 * M_PI * std::fmod(20000.0 * t, 1.0));
    // The phase rounds by 2^-17 turns: the sine by 4.8e-5, times 0.5 (3 - t) 100 <= 50 N.
    EXPECT_NEAR(to_double(Law::force(p, s, outside, in).force_n), want, 0.01) << "t = " << t;
    largest = std::max(largest, std::abs(want));
  }
  EXPECT_GT(largest, 20.0);  // the sine really swings
  EXPECT_FALSE(take_fixed_saturated());
}

// Along +x across the cliff's gap [0, 0.02] at constant speed, 1 mm into the ground, at
// positions that stay 0.1 mm clear of the strip edges on every tick.
Motion crossing(double speed) {
  return [speed](double t) { return Point{{-0.03005 + speed * t, 0.0, -0.001}, {speed, 0.0, 0.0}}; };
}

TEST(ScalarAgreement, CartoonCliffTakesTheSameDecisions) {
  for (const double speed : {0.2, 0.03}) {  // bridged (fast) and fallen (slow)
    const Motion m = crossing(speed);
    const int ticks = static_cast<int>(0.06 / speed / kDt);
    const auto d = forces<double>("cliff", ScalarKind::kDouble, m, ticks, true);
    const auto f = forces<float>("cliff", ScalarKind::kFloat, m, ticks, true);
    const auto q = forces<Q16_16>("cliff", ScalarKind::kQ16_16, m, ticks, true);
    const auto all = [](int) { return true; };
    // Same state sequence: a different fall tick would differ by the whole wall force (1.5 N).
    EXPECT_LT(max_difference(d, f, all), 6e-6) << speed;
    // Q16.16: the ground's force errs as the wall's; the side face past the strip takes
    // k (u - gap_max) with both u and gap_max rounded by half an LSB: k * LSB, plus products.
    EXPECT_LT(max_difference(d, q, all), kStiffness * kLsb + 2 * kLsb) << speed;
  }
}

}  // namespace
}  // namespace toonforce::test
