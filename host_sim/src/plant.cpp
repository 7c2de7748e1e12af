// SPDX-License-Identifier: Apache-2.0
#include "toonforce/host_sim/plant.hpp"

#include <cmath>

#include <fmt/format.h>

namespace toonforce::host_sim {

using Matrix4 = std::array<std::array<double, 4>, 4>;

namespace {

Matrix4 multiply(const Matrix4& a, const Matrix4& b) noexcept {
  Matrix4 c{};
  for (std::size_t i = 0; i < 4; ++i) {
    for (std::size_t j = 0; j < 4; ++j) {
      double sum = 0.0;
      for (std::size_t k = 0; k < 4; ++k) sum += a[i][k] * b[k][j];
      c[i][j] = sum;
    }
  }
  return c;
}

}  // namespace

Matrix4 matrix_exponential(const Matrix4& a) noexcept {
  // Scale so the norm is below 1/2, sum the Taylor series (20 terms: the remainder is below
  // 0.5^21 / 21!, far under one ulp), then square back.
  double norm = 0.0;
  for (const auto& row : a) {
    double sum = 0.0;
    for (const double v : row) sum += std::fabs(v);
    norm = std::max(norm, sum);
  }
  int squarings = 0;
  while (norm > 0.5 && squarings < 60) {
    norm *= 0.5;
    ++squarings;
  }
  const double scale = std::ldexp(1.0, -squarings);
  Matrix4 scaled{};
  for (std::size_t i = 0; i < 4; ++i) {
    for (std::size_t j = 0; j < 4; ++j) scaled[i][j] = a[i][j] * scale;
  }
  Matrix4 result{};
  Matrix4 term{};
  for (std::size_t i = 0; i < 4; ++i) {
    result[i][i] = 1.0;
    term[i][i] = 1.0;
  }
  for (int k = 1; k <= 20; ++k) {
    term = multiply(term, scaled);
    const double inverse_k = 1.0 / k;
    for (auto& row : term) {
      for (double& v : row) v *= inverse_k;
    }
    for (std::size_t i = 0; i < 4; ++i) {
      for (std::size_t j = 0; j < 4; ++j) result[i][j] += term[i][j];
    }
  }
  for (int s = 0; s < squarings; ++s) result = multiply(result, result);
  return result;
}

Plant::Plant(const DeviceParams& device, HandIntent intent, const PlantOptions& options)
    : device_(device), intent_(std::move(intent)), options_(options) {
  h_s_ = options_.period_s / options_.substeps;
  const HandImpedance& hand = intent_.impedance();
  for (std::size_t grasping = 0; grasping < 2; ++grasping) {
    Linear& l = linear_[grasping];
    l.mass_kg = device_.mass_kg + (grasping != 0 ? hand.mass_kg : 0.0);
    l.inverse_mass_per_kg = 1.0 / l.mass_kg;
    l.stiffness_n_per_m = grasping != 0 ? hand.stiffness_n_per_m : 0.0;
    l.hand_damping_n_s_per_m = grasping != 0 ? hand.damping_n_s_per_m : 0.0;
    l.damping_n_s_per_m = device_.damping_n_s_per_m + l.hand_damping_n_s_per_m;

    // d/ds [x, v, u, du] = [v, (u - k x - b v) / m, du, 0], over one sub-step.
    const double h = h_s_;
    Matrix4 f{};
    f[0][1] = h;
    f[1][0] = -l.stiffness_n_per_m / l.mass_kg * h;
    f[1][1] = -l.damping_n_s_per_m / l.mass_kg * h;
    f[1][2] = h / l.mass_kg;
    f[2][3] = h;
    const Matrix4 e = matrix_exponential(f);
    for (std::size_t r = 0; r < 2; ++r) {
      for (std::size_t c = 0; c < 4; ++c) l.transition[r][c] = e[r][c];
    }

    const double friction_rate =
        device_.coulomb_n > 0.0 ? device_.coulomb_n / device_.coulomb_smoothing_m_per_s / l.mass_kg : 0.0;
    const double rate =
        options_.integrator == Integrator::kExact
            ? friction_rate
            : std::max(std::sqrt(l.stiffness_n_per_m / l.mass_kg), l.damping_n_s_per_m / l.mass_kg + friction_rate);
    fastest_rate_per_s_ = std::max(fastest_rate_per_s_, rate);
  }
}

Result<Plant> Plant::create(const DeviceParams& device, HandIntent intent, const PlantOptions& options) {
  if (!(options.period_s > 0.0) || options.substeps < 1) {
    return Error{fmt::format("the servo period must be > 0 and sub-steps >= 1 (got {} s, {})", options.period_s,
                             options.substeps)};
  }
  if (!(device.mass_kg > 0.0) || !(intent.impedance().mass_kg >= 0.0)) {
    return Error{"the device's mass must be > 0 and the hand's >= 0"};
  }
  if (device.coulomb_n > 0.0 && !(device.coulomb_smoothing_m_per_s > 0.0)) {
    return Error{"a device with Coulomb friction needs a smoothing speed > 0"};
  }
  Plant plant(device, std::move(intent), options);
  const double h = plant.h_s_;
  if (h * plant.fastest_rate_per_s_ > 1.0) {
    const double needed = std::ceil(options.period_s * plant.fastest_rate_per_s_);
    return Error{
        fmt::format("a sub-step of {:.3g} ms is too long for {} with the {} integrator: the device and hand "
                    "have a rate of {:.0f}/s (friction smoothing and damping over the moving mass, or the hand "
                    "spring), and a step must stay below its inverse; use --substeps {} or more",
                    h * 1e3, device.name, integrator_name(options.integrator), plant.fastest_rate_per_s_, needed)};
  }
  plant.x_ = plant.intent_.start_m();
  return plant;
}

double Plant::hand_omega_rad_per_s() const noexcept {
  return std::sqrt(linear_[1].stiffness_n_per_m / linear_[1].mass_kg);
}

const HandTarget& Plant::target_at(double t_s) const noexcept {
  for (const Remembered& r : remembered_) {
    if (r.t_s == t_s) return r.target;
  }
  Remembered& slot = remembered_[next_slot_];
  next_slot_ = 1 - next_slot_;
  slot.t_s = t_s;
  slot.target = intent_.at(t_s);
  return slot.target;
}

Vec3<double> Plant::coulomb(const Vec3<double>& v) const noexcept {
  if (!(device_.coulomb_n > 0.0)) return {};
  const double smoothing = device_.coulomb_smoothing_m_per_s;
  return v * (device_.coulomb_n / std::sqrt(dot(v, v) + smoothing * smoothing));
}

Vec3<double> Plant::input(const Linear& l, bool grasping, double t_s, const Vec3<double>& force_n,
                          const Vec3<double>& v) const noexcept {
  Vec3<double> u = force_n - coulomb(v);
  if (grasping) {
    const HandTarget& target = target_at(t_s);
    u += target.position_m * l.stiffness_n_per_m + target.velocity_m_per_s * l.hand_damping_n_s_per_m + target.force_n;
  }
  return u;
}

Vec3<double> Plant::acceleration(const Linear& l, bool grasping, double t_s, const Vec3<double>& force_n,
                                 const Vec3<double>& x, const Vec3<double>& v) const noexcept {
  const Vec3<double> total = input(l, grasping, t_s, force_n, v) - x * l.stiffness_n_per_m - v * l.damping_n_s_per_m;
  return total * l.inverse_mass_per_kg;
}

void Plant::substep(const Linear& l, bool grasping, double t, const Vec3<double>& f) noexcept {
  const double h = h_s_;
  const Vec3<double> x0 = x_;
  const Vec3<double> v0 = v_;
  switch (options_.integrator) {
    case Integrator::kSemiImplicitEuler: {
      v_ = v0 + acceleration(l, grasping, t, f, x0, v0) * h;
      x_ = x0 + v_ * h;
      break;
    }
    case Integrator::kVelocityVerlet: {
      const Vec3<double> a0 = acceleration(l, grasping, t, f, x0, v0);
      x_ = x0 + v0 * h + a0 * (0.5 * h * h);
      const Vec3<double> v_predicted = v0 + a0 * h;
      const Vec3<double> a1 = acceleration(l, grasping, t + h, f, x_, v_predicted);
      v_ = v0 + (a0 + a1) * (0.5 * h);
      break;
    }
    case Integrator::kRk4: {
      const double half = 0.5 * h;
      const Vec3<double> k1v = acceleration(l, grasping, t, f, x0, v0);
      const Vec3<double> k1x = v0;
      const Vec3<double> k2x = v0 + k1v * half;
      const Vec3<double> k2v = acceleration(l, grasping, t + half, f, x0 + k1x * half, k2x);
      const Vec3<double> k3x = v0 + k2v * half;
      const Vec3<double> k3v = acceleration(l, grasping, t + half, f, x0 + k2x * half, k3x);
      const Vec3<double> k4x = v0 + k3v * h;
      const Vec3<double> k4v = acceleration(l, grasping, t + h, f, x0 + k3x * h, k4x);
      const double sixth = h / 6.0;
      x_ = x0 + (k1x + k2x * 2.0 + k3x * 2.0 + k4x) * sixth;
      v_ = v0 + (k1v + k2v * 2.0 + k3v * 2.0 + k4v) * sixth;
      break;
    }
    case Integrator::kExact: {
      // Held over the sub-step: the device force and the friction at its start; linear in
      // time (first-order hold): the hand's pull toward its moving reference.
      const Vec3<double> u0 = input(l, grasping, t, f, v0);
      Vec3<double> slope{};
      if (grasping) {
        const HandTarget a = target_at(t);
        const HandTarget b = target_at(t + h);
        const auto pull = [&l](const HandTarget& target) {
          return target.position_m * l.stiffness_n_per_m + target.velocity_m_per_s * l.hand_damping_n_s_per_m +
                 target.force_n;
        };
        slope = (pull(b) - pull(a)) * (1.0 / h);  // du/ds
      }
      const auto& m = l.transition;
      x_ = x0 * m[0][0] + v0 * m[0][1] + u0 * m[0][2] + slope * m[0][3];
      v_ = x0 * m[1][0] + v0 * m[1][1] + u0 * m[1][2] + slope * m[1][3];
      break;
    }
  }
  work_j_ += dot(f, x_ - x0);
}

void Plant::step(std::int64_t tick, const Vec3<double>& force_n) noexcept {
  const double t0 = static_cast<double>(tick) * options_.period_s;
  for (int j = 0; j < options_.substeps; ++j) {
    // Times from integers, never accumulated (the same rule as effects.md §0).
    const double t = t0 + static_cast<double>(j) * h_s_;
    const bool grasping = target_at(t).grasping;
    substep(linear_[grasping ? 1 : 0], grasping, t, force_n);
  }
}

double Plant::mechanical_energy_j(double t_s) const noexcept {
  const HandTarget target = intent_.at(t_s);
  const Linear& l = linear_[target.grasping ? 1 : 0];
  double energy = 0.5 * l.mass_kg * dot(v_, v_);
  if (target.grasping) {
    const Vec3<double> stretch = target.position_m - x_;
    energy += 0.5 * l.stiffness_n_per_m * dot(stretch, stretch);
  }
  return energy;
}

}  // namespace toonforce::host_sim
