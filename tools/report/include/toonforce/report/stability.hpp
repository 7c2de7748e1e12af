#pragma once
/// `toonforce report stability`: sweeps of virtual stiffness K, virtual damping B, slippery
/// gain mu, servo period T, device damping b and impact speed on the host simulation (host_sim:
/// the device's mass and physical damping, a hand or a press force, the servo loop with the
/// spec's stages closing the loop every T), each point classified by its energy, and the Colgate-Brown passivity bound
/// b > K T / 2 + |B| (shared/reference/realtime-safety-stability.md §4) drawn over each map.
///
/// Energy: V = 1/2 m |v|^2 + 1/2 k_h |x - r|^2 + 1/2 K max(0, delta)^2 - F_press . x, minus its
/// value at the static equilibrium (so V >= 0, and V = 0 at rest there); sampled at every tick
/// from the simulation's true state. m is the moving mass (device, plus the hand's when it
/// grasps), k_h and r the hand's stiffness and aim, K the wall's. V0 is its initial value.
/// Classification of a run:
///   - unstable: a non-finite state, or V above 10 V0 at any time, or the peak of V over the
///     last quarter of the run above 1.1 times its peak over the first quarter (still growing);
///   - passive: V never above V0 (1 + 1e-3): the loop, with the device's own damping, never
///     gave back more energy than it started with;
///   - bounded: neither: V rose above V0 but did not grow (a decaying or steady oscillation).

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/host_sim/device_model.hpp"
#include "toonforce/host_sim/hand_script.hpp"
#include "toonforce/host_sim/integrator.hpp"
#include "toonforce/report/latency.hpp"
#include "toonforce/report/machine.hpp"

namespace toonforce::report {

enum class Stability : std::uint8_t { kPassive, kBounded, kUnstable };
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
  std::string scene_toml;                 ///< the scene, as a scene file
  double velocity_cutoff_hz = 0.0;        ///< > 0 overrides the scene's
  double wall_stiffness_n_per_m = 0.0;    ///< K of the plane z = 0 (energy)
  Vec3<double> equilibrium_m;             ///< where V is 0
  host_sim::Integrator integrator = host_sim::Integrator::kExact;
  int substeps = 1;
};

struct Outcome {
  Stability stability = Stability::kPassive;
  double initial_energy_j = 0.0;
  double peak_ratio = 0.0;      ///< max V / V0
  double growth = 0.0;          ///< peak over the last quarter / peak over the first quarter
  double max_force_n = 0.0;     ///< largest commanded force
  bool finite = true;
};

Result<Outcome> run_experiment(const Experiment& e);
/// The classification of an energy series (V0 = energy.front()).
Outcome classify(const std::vector<double>& energy_j);

struct SweepPoint {
  double x = 0.0;
  double y = 0.0;
  Outcome outcome;
  bool inside_bound = false;  ///< the bound predicts passivity here
};

struct StabilityMap {
  std::string name;      ///< file stem
  std::string title;
  std::string x_label;
  std::string y_label;
  bool log_x = true;
  bool log_y = true;
  std::string setup;     ///< what was simulated, for the document
  std::string bound;     ///< the bound drawn, in words
  std::vector<std::pair<double, double>> bound_curve;
  std::vector<SweepPoint> points;
};

struct StabilityOptions {
  int resolution = 24;       ///< points per axis
  double duration_s = 4.0;   ///< simulated time per point (the impact maps: 1 s)
  std::string filter;        ///< only maps whose name contains one of these
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
