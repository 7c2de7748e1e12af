// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The integrators the host simulation offers, chosen per run. Each advances the device and
/// hand over one sub-step h (a servo period divided into `substeps`); the device force is held
/// over the whole period (zero-order hold), the hand's intent is evaluated where the method
/// asks for it. Orders are the global error's, as the step h halves (tests measure them):
///
/// - kSemiImplicitEuler (symplectic Euler): v += h a(x, v); x += h v_new. Order 1: one force
///   evaluation, first-order Taylor match. Symplectic: on an undamped spring its energy is not
///   conserved but oscillates about a conserved modified energy, never drifts.
/// - kVelocityVerlet: x += h v + h^2/2 a0; a1 = a(x_new, v + h a0); v += h/2 (a0 + a1). Order 2
///   (trapezoidal in v, the velocity-dependent forces see a first-order predictor whose O(h^2)
///   error enters multiplied by h). With position-only forces it is the symplectic, time-
///   reversible Stormer-Verlet method.
/// - kRk4: classical fourth-order Runge-Kutta on (x, v). Order 4. Not symplectic: on an
///   undamped spring it loses a little energy per step, |R(i w h)|^2 = 1 - (wh)^6/72 + ...
///   (stable on the imaginary axis up to wh = 2 sqrt 2).
/// - kExact: the linear part (masses, hand spring, both dampers) is advanced by its exact
///   transition matrix (matrix exponential, computed once), the held device force exactly, the
///   hand's reference forces with a first-order hold (exact when they change linearly over h),
///   and the device's Coulomb friction held at its value at the start of the step. Exact (to
///   round-off) for a free or force-held mass-spring-damper; order 2 in the reference forces,
///   order 1 in the friction.
/// The stability facts above are standard linear stability analysis on the undamped
/// oscillator: each follows from the method's stability function R(i w h).

#include <cstdint>
#include <optional>
#include <string_view>

namespace toonforce::host_sim {

enum class Integrator : std::uint8_t { kSemiImplicitEuler, kVelocityVerlet, kRk4, kExact };

std::string_view integrator_name(Integrator integrator) noexcept;
std::optional<Integrator> parse_integrator(std::string_view name) noexcept;

/// The order of the global error in h on smooth problems (exact: 0, meaning "to round-off" on
/// a linear one).
int integrator_order(Integrator integrator) noexcept;

/// The stated bound on the energy an undamped spring-mass can gain, relative to its initial
/// energy, when integrated with step h at angular frequency w (wh = `omega_h` < 1):
/// E(t) <= (1 + bound) E(0).
/// - semi-implicit Euler conserves H~ = E - (h w^2 / 2) m x v exactly, and
///   |E - H~| <= (wh/2) E, so E(t) <= E(0) (1 + wh/2) / (1 - wh/2): bound wh / (1 - wh/2);
/// - velocity Verlet conserves H~ = E - (wh)^2/8 k x^2, so E(t) <= E(0) / (1 - (wh)^2/4):
///   bound (wh)^2/4 / (1 - (wh)^2/4);
/// - RK4 and exact: they never gain energy on a passive linear system (RK4 is dissipative for
///   wh <= 2 sqrt 2), so the bound on a gain is 0 (round-off aside).
double energy_gain_bound(Integrator integrator, double omega_h) noexcept;

}  // namespace toonforce::host_sim
