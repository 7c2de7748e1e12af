// SPDX-License-Identifier: Apache-2.0
#include "toonforce/host_sim/integrator.hpp"

#include <array>
#include <utility>

namespace toonforce::host_sim {

namespace {
constexpr std::array<std::pair<Integrator, std::string_view>, 4> kNames{{
    {Integrator::kSemiImplicitEuler, "semi-implicit-euler"},
    {Integrator::kVelocityVerlet, "velocity-verlet"},
    {Integrator::kRk4, "rk4"},
    {Integrator::kExact, "exact"},
}};
}  // namespace

std::string_view integrator_name(Integrator integrator) noexcept {
  for (const auto& [i, name] : kNames) {
    if (i == integrator) return name;
  }
  return "?";
}

std::optional<Integrator> parse_integrator(std::string_view name) noexcept {
  for (const auto& [i, n] : kNames) {
    if (n == name) return i;
  }
  return std::nullopt;
}

int integrator_order(Integrator integrator) noexcept {
  switch (integrator) {
    case Integrator::kSemiImplicitEuler: return 1;
    case Integrator::kVelocityVerlet: return 2;
    case Integrator::kRk4: return 4;
    case Integrator::kExact: return 0;
  }
  return 0;
}

double energy_gain_bound(Integrator integrator, double omega_h) noexcept {
  switch (integrator) {
    case Integrator::kSemiImplicitEuler: return omega_h / (1.0 - 0.5 * omega_h);
    case Integrator::kVelocityVerlet: {
      const double q = 0.25 * omega_h * omega_h;
      return q / (1.0 - q);
    }
    case Integrator::kRk4:
    case Integrator::kExact: return 0.0;
  }
  return 0.0;
}

}  // namespace toonforce::host_sim
