// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce-lab report stability`: sweeps of virtual stiffness K, virtual damping B, slippery
/// gain mu, servo period T, device damping b and impact speed on the host simulation (host_sim:
/// the device's mass and physical damping, a hand or a press force, the servo loop with the
/// spec's stages closing the loop every T), each point classified twice:
///
/// 1. by the spectral radius rho of the sampled loop's transition matrix (`SampledLoop`): the
///    loop linearised in contact, built exactly as simulated (mass and damping integrated
///    exactly over T under the zero-order-held force, the device's I/O delay, the velocity
///    estimator, the wall law). rho < 1: every disturbance decays; rho > 1: one grows as
///    rho^k, e-folding in T / ln rho. This is the reference for the linear maps.
/// 2. by the energy of one autonomous run on the simulation (the nonlinear truth: one-sided
///    contact, clamps, friction, quantisation where the map has them).
///
/// On the linear maps passivity is decided twice too: by Colgate and Schenkel's b_req of the
/// modelled law (`required_damping_n_s_per_m`), and measured as port energy on the real servo
/// loop driven by an imposed motion over a band of frequencies (`port_passivity`).
///
/// The passivity bound of control/passivity_bound.hpp (Colgate-Brown with the delay term of
/// Diolaiti et al. 2006: b > (1 + 2 d) K T / 2 + |B|) is drawn over each map with the delay d of
/// the map's device. It is a sufficient condition for passivity (stability with any passive
/// user), so inside it rho < 1; outside it a given loop may still be stable.
///
/// Energy: V = 1/2 m |v|^2 + 1/2 k_h |x - r|^2 + U_wall(depth) - F_press . x, minus its value
/// at the static equilibrium (so V >= 0, and V = 0 at rest there); sampled at every tick from
/// the simulation's true state. m is the moving mass (device, plus the hand's when it grasps),
/// k_h and r the hand's stiffness and aim. U_wall is the potential of the wall's force: K d^2/2
/// for a linear wall, and for one clamped at F_max (the safety layer's clamp) K d^2/2 up to the
/// clamp depth d_c = F_max / K, then F_max (d - d_c) + K d_c^2 / 2. V0 is its initial value.
/// Classification of a run:
///   - unstable: a non-finite state, or V above 10 V_ref at any time after the settling time
///     (V_ref: the largest V up to the settling time, which is 0 except where the scene adds
///     energy by design, the cartoon wall's transient; there V_ref includes what it added), or
///     the peak of V over the last quarter of the run (after settling) above 1.1 times its peak
///     over the first quarter (still growing; not counted below 1e-3 V_ref, the dither of
///     quantisation and friction);
///   - decaying: V never above V0 (1 + 1e-3). This is not passivity (a property of the port,
///     under every input); an autonomous run cannot test it;
///   - bounded: neither: V rose above V0 but did not grow (a decaying or steady oscillation).

#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/host_sim/hand_script.hpp"
#include "toonforce/host_sim/integrator.hpp"
#include "toonforce/report/latency.hpp"
#include "toonforce/report/machine.hpp"
#include "toonforce/report/spectral.hpp"

namespace toonforce::report {

enum class Stability : std::uint8_t { kDecaying, kBounded, kUnstable };
std::string_view stability_name(Stability s) noexcept;

/// One closed-loop run on the host simulation. The surface is the plane z = 0, normal +z.
struct Experiment {
  host_sim::DeviceParams device;
  host_sim::HandImpedance hand{0.0, 0.0, 0.0};  ///< none: a pure press force
  Vec3<double> hand_aim_m;                      ///< r, while the hand has stiffness
  Vec3<double> press_n;                         ///< constant force the hand applies
  Vec3<double> start_m;
  Vec3<double> start_velocity_m_per_s;
  double period_s = 1e-3;
  double duration_s = 4.0;
  std::string scene_toml;               ///< the scene, as a scene file
  double velocity_cutoff_hz = 0.0;      ///< > 0 overrides the scene's
  double wall_stiffness_n_per_m = 0.0;  ///< K of the plane z = 0 (energy)
  double wall_max_force_n = 0.0;        ///< the clamp on the wall's force (energy); 0: none
  double settle_s = 0.0;                ///< energy the scene adds by design ends by then
  Vec3<double> equilibrium_m;           ///< where V is 0
  host_sim::Integrator integrator = host_sim::Integrator::kExact;
  int substeps = 1;
};

struct Outcome {
  Stability stability = Stability::kDecaying;
  double initial_energy_j = 0.0;
  double peak_ratio = 0.0;   ///< max V / V0
  double growth = 0.0;       ///< peak over the last quarter / peak over the first quarter
  double max_force_n = 0.0;  ///< largest commanded force
  bool finite = true;
};

Result<Outcome> run_experiment(const Experiment& e);
/// The classification of an energy series (V0 = energy.front(); no settling time).
Outcome classify(const std::vector<double>& energy_j);

/// The potential of a wall's force at `depth_m` (0 outside): K d^2 / 2, or for a force clamped
/// at `max_force_n` > 0, K d^2 / 2 up to d_c = F_max / K and F_max (d - d_c) + K d_c^2 / 2 beyond.
double wall_energy_j(double stiffness_n_per_m, double depth_m, double max_force_n) noexcept;

/// One axis of a sampled loop in contact, as the simulation runs it: a mass m with viscous
/// damping b and a spring k (the hand's, 0 without one) to its equilibrium, advanced exactly
/// over each period T under the force held from the tick (zero-order hold); the force computed
/// at tick k from the reading y_k = x_(k-d) (the device's I/O delay d) and the velocity estimate
/// v_k = v_(k-1) + a ((y_k - y_(k-1)) / T - v_(k-1)) (control/velocity_estimator.hpp; a = 1 is
/// the plain backward difference):  F_k = -K y_k + c v_k  (c = -B for a wall's damping, +mu for
/// the slippery surface's negative damping). State: x_k, v_k, x_(k-1) .. x_(k-d-1), v_(k-1).
struct SampledLoop {
  double mass_kg = 0.15;
  double damping_n_s_per_m = 0.0;
  double spring_n_per_m = 0.0;
  double period_s = 1e-3;
  int delay_ticks = 0;
  double velocity_gain = 1.0;
  double stiffness_n_per_m = 0.0;
  double velocity_feedback_n_s_per_m = 0.0;
};

/// The loop's transition matrix s_(k+1) = A s_k (size d + 4). Without any spring (K = 0 and
/// k = 0) the position itself is a free integrator (eigenvalue exactly 1: the handle can rest
/// anywhere); the matrix is then given in positions relative to x_k with that state removed
/// (size d + 3), so its spectral radius speaks of the motion only.
Matrix transition_matrix(const SampledLoop& loop);
/// The spectral radius of transition_matrix(loop).
Result<double> loop_spectral_radius(const SampledLoop& loop);

/// Passivity, not stability: Colgate and Schenkel ("Passivity of a class of sampled-data
/// systems: application to haptic interfaces", J. Robotic Systems 14(1), 1997) show that the
/// device of physical damping b with the discrete force law F = -H(z) x behind a zero-order
/// hold is passive if and only if
///   b > b_req = max over 0 < theta <= pi of (T / 2) Re{(1 - e^(-j theta)) H(e^(j theta))} / (1 - cos theta).
/// Here H(z) = z^-d (K - c V(z)), V(z) = a (1 - z^-1) / (T (1 - (1 - a) z^-1)) the velocity
/// estimator. Evaluated on 4096 frequencies and at 1e-7 rad for the limit theta -> 0 (the
/// expression is smooth). For K alone it is (1 + 2 d) K T / 2, for a backward-
/// difference damper B alone |B| (the bound of control/passivity_bound.hpp). The loop's mass,
/// physical damping and spring do not enter: they are the device and the user.
double required_damping_n_s_per_m(const SampledLoop& loop) noexcept;

/// Colgate and Schenkel's integrand at one normalised frequency 0 < theta <= pi: the damping
/// the loop's discrete law needs against inputs at theta, (T / 2) Re{(1 - e^(-j theta))
/// H(e^(j theta))} / (1 - cos theta) [N s/m]; b_req is its maximum over theta.
double required_damping_at_n_s_per_m(const SampledLoop& loop, double theta_rad) noexcept;

/// The port-energy check of passivity: the handle is a motion source driving the real servo
/// loop (`ServoLoop` with the spec's stages, no clamp or rate limit) along `direction` with
/// x(t) = x0 + A sin(w t); the loop reads x(kT), and each force it writes is held over
/// [(k + d) T, (k + d + 1) T] (the device's I/O delay d and zero-order hold). The law must be
/// linear there: x0 keeps the handle in contact and A keeps every force inside any cap.
struct PortDrive {
  std::string scene_toml;
  double period_s = 1e-3;
  double device_damping_n_s_per_m = 0.0;  ///< b, the device's own viscous damping
  int delay_ticks = 0;
  double velocity_cutoff_hz = 0.0;  ///< > 0 overrides the scene's
  Vec3<double> x0_m;
  Vec3<double> direction{0.0, 0.0, 1.0};  ///< unit
  double amplitude_m = 1e-6;
};

/// One forcing frequency, over whole periods after the estimator's transient. Energies are
/// per cycle and per A^2; the law is linear, so they do not depend on A.
struct PortCycle {
  double frequency_hz = 0.0;       ///< p / (q T): p whole periods in q whole ticks
  double theta_rad = 0.0;          ///< w T
  double damping_n_s_per_m = 0.0;  ///< b
  /// Work the loop's held forces do on the handle [J/m^2]: the sum over hold intervals of
  /// F . dx (exact, F being constant over each); > 0 is energy the controller gives out.
  double controller_work_j_per_m2 = 0.0;
  /// integral v^2 dt [1/s] of the sinusoid (w pi per cycle), and of the motion through the
  /// same samples moving linearly between them (sum dx^2 / T: the least any motion through
  /// those samples dissipates in b, Colgate's worst case). b times these is what b absorbs.
  double sine_v2_per_m2 = 0.0;
  double ramp_v2_per_m2 = 0.0;
  /// Net energy the device and controller absorb per cycle [J/m^2]; >= 0 at every
  /// frequency: passive.
  double absorbed_sine_j_per_m2() const noexcept {
    return damping_n_s_per_m * sine_v2_per_m2 - controller_work_j_per_m2;
  }
  double absorbed_ramp_j_per_m2() const noexcept {
    return damping_n_s_per_m * ramp_v2_per_m2 - controller_work_j_per_m2;
  }
  /// The damping b that would absorb exactly what the controller gives [N s/m] (the ramp's
  /// is Colgate and Schenkel's integrand at theta, measured).
  double required_sine_n_s_per_m() const noexcept { return controller_work_j_per_m2 / sine_v2_per_m2; }
  double required_ramp_n_s_per_m() const noexcept { return controller_work_j_per_m2 / ramp_v2_per_m2; }
};

/// `count` forcing frequencies log-spaced from 0.1 Hz to just under Nyquist, each moved to
/// p / (q T) with whole p periods in q ticks: q = 1 / (f T) rounded (p = 1) for periods of 50
/// ticks and more, else q = 1009 (a prime, so the sample phases never repeat within the window
/// and never alias to DC: p <= 504 < q / 2). Returned as (p, q).
std::vector<std::pair<std::int64_t, std::int64_t>> port_frequencies(double period_s, int count);
/// The port's energy at p periods in q ticks.
Result<PortCycle> port_cycle(const PortDrive& drive, std::int64_t periods, std::int64_t ticks);

/// The measured margin: the largest required damping over the frequencies minus b [N s/m]
/// (> 0: some frequency's port gives energy out, not passive), for both motions.
struct PortPassivity {
  double margin_sine_n_s_per_m = -std::numeric_limits<double>::infinity();
  double margin_ramp_n_s_per_m = -std::numeric_limits<double>::infinity();
  double worst_sine_hz = 0.0;
  double worst_ramp_hz = 0.0;
  /// With a model: the largest |measured - modelled| required damping at the same theta
  /// (the ramp's; Colgate-Schenkel's integrand) [N s/m], and the model's margin on the same
  /// frequencies (how far the grid's maximum falls short of b_req's).
  double model_difference_n_s_per_m = 0.0;
  double model_grid_margin_n_s_per_m = -std::numeric_limits<double>::infinity();
  double model_grid_sine_margin_n_s_per_m = -std::numeric_limits<double>::infinity();
  int frequencies = 0;
  /// Round-off of the sums: margins within this of 0 [N s/m] (1e-9 of the largest damping
  /// involved, b or a frequency's need) count as 0, on the bound.
  double tolerance_n_s_per_m = 0.0;
  bool passive_sine() const noexcept { return margin_sine_n_s_per_m <= tolerance_n_s_per_m; }
  bool passive_ramp() const noexcept { return margin_ramp_n_s_per_m <= tolerance_n_s_per_m; }
};
/// Every frequency of port_frequencies(period, count); `model` (may be null) is the linear
/// model of the same axis, compared at each theta.
Result<PortPassivity> port_passivity(const PortDrive& drive, int count, const SampledLoop* model = nullptr);

struct SweepPoint {
  double x = 0.0;
  double y = 0.0;
  Outcome outcome;
  bool inside_bound = false;  ///< the bound predicts passivity here
  bool has_spectrum = false;  ///< the map has a linear model of the loop
  double spectral_radius = 0.0;
  double efold_s = 0.0;  ///< T / ln rho when rho > 1 (the amplitude's e-folding time), else 0
  double run_s = 0.0;    ///< simulated seconds of this point's run
  /// The largest Colgate-Schenkel b_req minus the damping it is compared with, over the map's
  /// loops: < 0 passive (the port, under any input), > 0 not. Meaningful when has_spectrum.
  double passivity_margin_n_s_per_m = 0.0;
  /// The port-energy check over the map's axes (the largest margins): has_port when measured.
  bool has_port = false;
  PortPassivity port;
};

struct StabilityMap {
  std::string name;  ///< file stem
  std::string title;
  std::string x_label;
  std::string y_label;
  bool log_x = true;
  bool log_y = true;
  std::string setup;         ///< what was simulated, for the document
  std::string bound;         ///< the bound drawn, in words
  std::string linear_model;  ///< what the spectral radius is of, in words (empty: none)
  std::vector<std::pair<double, double>> bound_curve;
  std::vector<SweepPoint> points;
};

struct StabilityOptions {
  int resolution = 24;      ///< points per axis
  double duration_s = 4.0;  ///< simulated time per point (the impact maps: 1 s)
  /// A linear-map point whose rho > 1 runs for max(duration_s, min(this, 3 e-folding times)),
  /// so the growth the eigenvalue predicts shows in the run (or the point says it could not).
  double longest_run_s = 300.0;
  std::string filter;  ///< only maps whose name contains one of these
  /// Forcing frequencies of the port-energy check on every linear-map point; 0: no check.
  int port_frequencies = 40;
};

struct StabilityReport {
  MachineInfo machine;
  StabilityOptions options;
  std::vector<StabilityMap> maps;
  double cpu_s = 0.0;
};

Result<StabilityReport> run_stability(const StabilityOptions& options, const Progress& progress = {});
std::string stability_csv(const StabilityMap& map);
std::string stability_markdown(const StabilityReport& report, const std::string& plot_dir_in_docs = {});

}  // namespace toonforce::report
