// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The passivity bound of a sampled virtual wall, with the device's I/O delay.
///
/// Colgate and Brown (ICRA 1994): a device of physical damping b, sampled every T with a
/// zero-order hold, rendering F = -K x - B v passively needs b > K T / 2 + |B|. Diolaiti et al.
/// ("Stability of haptic rendering: discretization, quantization, time delay, and Coulomb
/// effects", IEEE T-RO 22(2), 2006) extend it to a delay t_d between reading and force:
/// b > K (T / 2 + t_d) + |B|. With a delay of d whole ticks (t_d = d T, the simulated Falcon's
/// one exchange: host_sim/device_model.hpp `io_delay_ticks`) that is b > (1 + 2 d) K T / 2 + |B|.
/// A sufficient bound, not always the exact need: against Colgate and Schenkel's b_req of the
/// same discrete law (tools/report stability.hpp required_damping_n_s_per_m) it is exact without
/// delay, and with delay when B <= 0 (spring and negative damping both need most at low
/// frequency); with delay and B > 0 it overstates (the damper needs most at Nyquist, where the
/// delayed spring needs least): b_req 1.30 against 1.70 N s/m at d = 1, K = 1000 N/m,
/// B = 0.2 N s/m, T = 1 ms (docs/STABILITY.md; test StabilityModel.TheDelayAwareBound...).
/// So a wall the functions below call passive is passive; one they do not may still be.
/// `toonforce check`, `run` and `sim` (the plausibility report) and the stability maps
/// (tools/report) use these same functions, so what a user is warned of is what the maps draw.
#include <algorithm>

namespace toonforce {

/// The stiffest wall [N/m] that is passive on the device alone: 2 (b - |B|) / ((1 + 2 d) T);
/// 0 when |B| >= b (no stiffness is, then). `period_s` > 0, `delay_ticks` >= 0.
constexpr double stiffest_passive_wall_n_per_m(double device_damping_n_s_per_m, double period_s, int delay_ticks,
                                               double virtual_damping_n_s_per_m = 0.0) noexcept {
  const double b_left = device_damping_n_s_per_m -
                        (virtual_damping_n_s_per_m < 0.0 ? -virtual_damping_n_s_per_m : virtual_damping_n_s_per_m);
  return std::max(0.0, 2.0 * b_left / ((1.0 + 2.0 * static_cast<double>(delay_ticks)) * period_s));
}

/// The physical damping [N s/m] that makes a wall of stiffness K and virtual damping B passive:
/// (1 + 2 d) K T / 2 + |B| (enough; more than needed with d > 0 and B > 0, see above).
constexpr double damping_needed_n_s_per_m(double stiffness_n_per_m, double period_s, int delay_ticks,
                                          double virtual_damping_n_s_per_m = 0.0) noexcept {
  return (1.0 + 2.0 * static_cast<double>(delay_ticks)) * stiffness_n_per_m * period_s / 2.0 +
         (virtual_damping_n_s_per_m < 0.0 ? -virtual_damping_n_s_per_m : virtual_damping_n_s_per_m);
}

}  // namespace toonforce
