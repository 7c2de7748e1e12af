// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/stability.hpp"

#include <time.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/passivity_bound.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/control/velocity_estimator.hpp"
#include "toonforce/host_sim/sim_device.hpp"
#include "toonforce/report/template.hpp"
#include "toonforce/report/templates.hpp"

namespace toonforce::report {

std::string_view stability_name(Stability s) noexcept {
  switch (s) {
    case Stability::kDecaying: return "decaying";
    case Stability::kBounded: return "bounded";
    case Stability::kUnstable: return "unstable";
  }
  return "?";
}

namespace {

/// V above this many times V0 is a runaway (walls; see stability.hpp).
constexpr double kRunawayRatio = 10.0;
constexpr double kPassiveTolerance = 1e-3;
constexpr double kGrowthRatio = 1.1;
/// Growth counts only above this share of V_ref: below it the energy is the dither of
/// quantisation and friction (a settled cartoon-wall run's last quarter can hold twice its
/// first quarter's 1e-7 V_ref).
constexpr double kGrowthFloor = 1e-3;

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

/// V_ref is the largest V up to `settle` samples (V0 with none): where the scene adds energy by
/// design (the cartoon wall's transient) the run-away and growth tests start after it, measured
/// against what it added, so they can still see a loop that grows on its own.
Outcome classify_with(const std::vector<double>& energy, double runaway_ratio, std::size_t settle = 0) {
  Outcome o;
  if (energy.empty()) return o;
  const double v0 = energy.front();
  o.initial_energy_j = v0;
  for (const double e : energy) {
    if (!std::isfinite(e)) {
      o.finite = false;
      o.stability = Stability::kUnstable;
      o.peak_ratio = std::numeric_limits<double>::infinity();
      return o;
    }
  }
  const std::size_t n = energy.size();
  settle = std::min(settle, n - 1);
  double reference = v0;
  for (std::size_t i = 0; i <= settle; ++i) reference = std::max(reference, energy[i]);
  const std::size_t after = n - settle;
  const std::size_t quarter = std::max<std::size_t>(after / 4, 1);
  double peak = 0.0;
  double peak_after = 0.0;
  double first = 0.0;
  double last = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double e = energy[i];
    peak = std::max(peak, e);
    if (i < settle) continue;
    peak_after = std::max(peak_after, e);
    if (i < settle + quarter) first = std::max(first, e);
    if (i >= n - quarter) last = std::max(last, e);
  }
  o.peak_ratio = reference > 0.0 ? peak_after / reference : 0.0;
  o.growth = first > 0.0 ? last / first : 0.0;
  if (o.peak_ratio > runaway_ratio || (o.growth > kGrowthRatio && last > kGrowthFloor * reference)) {
    o.stability = Stability::kUnstable;
  } else if (peak <= v0 * (1.0 + kPassiveTolerance)) {
    o.stability = Stability::kDecaying;
  } else {
    o.stability = Stability::kBounded;
  }
  return o;
}

Result<Outcome> run_with(const Experiment& e, double runaway_ratio) {
  auto desc = parse_scene(e.scene_toml, "sweep.toml");
  if (!desc) return Error{desc.error()};
  // The servo loop with the stages of effects.md §6 only: the control law itself (the map is
  // of the law's stability, which the safety layer would otherwise hide).
  ServoConfig config = servo_config(desc.value(), e.period_s);
  if (e.velocity_cutoff_hz > 0.0) config.velocity_cutoff_hz = e.velocity_cutoff_hz;

  // The hand holds at its aim for the whole run, pressing with `press_n` at once.
  host_sim::HandScript script;
  script.name = "sweep";
  script.start_m = e.hand_aim_m;
  script.impedance = e.hand;
  host_sim::HandSegment hold;
  hold.kind = host_sim::SegmentKind::kHold;
  hold.duration_s = e.duration_s + 1.0;
  hold.force_ramp_s = 0.0;
  const double press = norm(e.press_n);
  if (press > 0.0) {
    hold.force_n = press;
    hold.normal = e.press_n * (-1.0 / press);
  }
  script.segments.push_back(hold);
  host_sim::PlanError plan_error;
  auto intent = host_sim::HandIntent::plan(script, plan_error);
  if (!intent) return Error{fmt::format("sweep hand: {}: {}", plan_error.key, plan_error.problem)};
  host_sim::PlantOptions plant;
  plant.integrator = e.integrator;
  plant.substeps = e.substeps;
  plant.period_s = e.period_s;
  auto created = host_sim::SimDevice::create(e.device, std::move(*intent), plant);
  if (!created) return Error{created.error()};
  created->set_state(e.start_m, e.start_velocity_m_per_s);
  ServoLoop<host_sim::SimDevice, RuntimeScene<double>, NullPins, kSpecStages> loop(
      std::move(created).value(), make_runtime_scene<double>(desc.value()), config);
  const host_sim::SimDevice* device = &loop.device();

  const double mass = e.device.mass_kg + e.hand.mass_kg;
  const auto energy = [&](const Vec3<double>& x, const Vec3<double>& v) {
    const Vec3<double> stretch = x - e.hand_aim_m;
    const double depth = std::max(0.0, -x.z);
    return 0.5 * mass * dot(v, v) + 0.5 * e.hand.stiffness_n_per_m * dot(stretch, stretch) +
           wall_energy_j(e.wall_stiffness_n_per_m, depth, e.wall_max_force_n) - dot(e.press_n, x);
  };
  const double rest = energy(e.equilibrium_m, Vec3<double>{});

  const auto ticks = static_cast<std::int64_t>(std::llround(e.duration_s / e.period_s));
  std::vector<double> v;
  v.reserve(static_cast<std::size_t>(ticks) + 1);
  v.push_back(energy(device->plant().position_m(), device->plant().velocity_m_per_s()) - rest);
  double max_force = 0.0;
  for (std::int64_t k = 0; k < ticks; ++k) {
    static_cast<void>(loop.tick(k));
    max_force = std::max(max_force, norm(loop.force()));
    const double now = energy(device->plant().position_m(), device->plant().velocity_m_per_s()) - rest;
    v.push_back(now);
    if (!std::isfinite(now) || now > 1e6) break;  // gone: no need to run on
  }
  const auto settle = static_cast<std::size_t>(std::llround(e.settle_s / e.period_s));
  Outcome o = classify_with(v, runaway_ratio, settle);
  o.max_force_n = max_force;
  return o;
}

std::vector<double> logspace(double lo, double hi, int n) {
  std::vector<double> out;
  for (int i = 0; i < n; ++i) {
    const double f = n == 1 ? 0.0 : static_cast<double>(i) / (n - 1);
    out.push_back(lo * std::pow(hi / lo, f));
  }
  return out;
}

/// A device with only its mass and the given viscous damping: no Coulomb friction, encoder or
/// DAC steps, I/O delay or force saturation (the setting of the Colgate-Brown bound).
host_sim::DeviceParams ideal_device(double damping_n_s_per_m) {
  host_sim::DeviceParams d = host_sim::falcon_params();
  d.name = "ideal Falcon-mass device";
  d.damping_n_s_per_m = damping_n_s_per_m;
  d.coulomb_n = 0.0;
  d.max_force_n = 0.0;
  d.encoder_step_m = 0.0;
  d.force_step_n = 0.0;
  d.io_delay_ticks = 0;
  d.sensor_noise_m = 0.0;
  return d;
}

std::string wall_toml(double stiffness, double damping) {
  return fmt::format("[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = {}\ndamping = {}\n",
                     stiffness, damping);
}

constexpr double kPressN = 1.0;
constexpr double kVelocityCutoffHz = 1e9;  // the estimator becomes the plain backward difference

/// Pressed onto a wall (no limits), starting at the equilibrium depth F/K moving in at half
/// the speed that would reach the surface: a small oscillation about equilibrium, in contact
/// as long as it does not grow (the linear setting of the bound).
Experiment pressed_wall(double k, double virtual_damping, double device_damping, double period_s, double duration_s) {
  Experiment e;
  e.device = ideal_device(device_damping);
  e.press_n = {0.0, 0.0, -kPressN};
  e.period_s = period_s;
  e.duration_s = duration_s;
  e.scene_toml = wall_toml(k, virtual_damping);
  e.velocity_cutoff_hz = kVelocityCutoffHz;
  e.wall_stiffness_n_per_m = k;
  e.equilibrium_m = {0.0, 0.0, -kPressN / k};
  e.start_m = e.equilibrium_m;
  e.hand_aim_m = e.equilibrium_m;
  const double omega = std::sqrt(k / e.device.mass_kg);
  e.start_velocity_m_per_s = {0.0, 0.0, -0.5 * (kPressN / k) * omega};
  return e;
}

struct Sweep {
  StabilityMap map;
  std::vector<double> xs;
  std::vector<double> ys;
  std::function<Experiment(double, double)> make;
  std::function<bool(double, double)> inside_bound;
  double runaway_ratio = kRunawayRatio;
  /// The loop's linear model(s) at a point (the slippery map: normal and tangential axes; rho
  /// is the largest); empty: none.
  std::function<std::vector<SampledLoop>(double, double)> linear;
  /// The port-energy check's drives, one per loop of `linear` (same order); empty: none.
  std::function<std::vector<PortDrive>(double, double)> drives;
  /// Lengthen a point's run when its rho > 1 (the linear maps; the impact maps' clamp and
  /// friction hold what grows, and their model is only the in-contact linearisation).
  bool lengthen = false;
};

/// The estimator's gain a at the period, from the estimator itself (what the loop computes).
double velocity_gain(double cutoff_hz, double period_s) {
  return VelocityEstimator<double>(cutoff_hz).gain(1.0 / period_s);
}

/// The normal axis of `pressed_wall`: the ideal device on the wall, no hand spring.
SampledLoop pressed_wall_loop(double k, double virtual_damping, double device_damping, double period_s) {
  SampledLoop l;
  const host_sim::DeviceParams d = ideal_device(device_damping);
  l.mass_kg = d.mass_kg;
  l.damping_n_s_per_m = device_damping;
  l.period_s = period_s;
  l.delay_ticks = d.io_delay_ticks;
  l.velocity_gain = velocity_gain(kVelocityCutoffHz, period_s);
  l.stiffness_n_per_m = k;
  l.velocity_feedback_n_s_per_m = -virtual_damping;
  return l;
}

/// The port-energy check's amplitude: 1 um keeps every force far inside any cap (the
/// slippery map's tangential force is at most mu 2 A / T = 0.06 N against its 2 N).
constexpr double kPortAmplitudeM = 1e-6;

/// Driving `pressed_wall`'s normal axis: deep enough that K (depth - A) exceeds the wall's
/// damping force B 2 A / T (the backward difference's largest), so the wall pushes all the time.
PortDrive wall_drive(const std::string& scene_toml, double k, double virtual_damping, double device_damping,
                     double period_s) {
  PortDrive d;
  d.scene_toml = scene_toml;
  d.period_s = period_s;
  d.device_damping_n_s_per_m = device_damping;
  d.delay_ticks = ideal_device(device_damping).io_delay_ticks;
  d.velocity_cutoff_hz = kVelocityCutoffHz;
  d.amplitude_m = kPortAmplitudeM;
  const double depth_m = 2.0 * kPortAmplitudeM * (1.0 + 2.0 * std::abs(virtual_damping) / (k * period_s));
  d.x0_m = {0.0, 0.0, -depth_m};
  d.direction = {0.0, 0.0, 1.0};
  return d;
}

std::vector<Sweep> sweeps(const StabilityOptions& o) {
  const int n = o.resolution;
  const double b_falcon = host_sim::falcon_params().damping_n_s_per_m;
  const double mass = host_sim::falcon_params().mass_kg;
  const int d = ideal_device(b_falcon).io_delay_ticks;  // the linear maps' device: no delay
  std::vector<Sweep> all;
  const auto bound_curve = [](const std::vector<double>& xs, const std::function<double(double)>& f) {
    std::vector<std::pair<double, double>> c;
    for (const double x : logspace(xs.front(), xs.back(), 200)) c.emplace_back(x, f(x));
    return c;
  };

  {  // K x T
    Sweep s;
    s.map.name = "stiffness_period";
    s.map.title = fmt::format("Stiffness and servo period (b = {} N s/m, B = 0)", b_falcon);
    s.map.x_label = "virtual stiffness K [N/m]";
    s.map.y_label = "servo period T [s]";
    s.map.setup =
        render_prose(templates::stability_stiffness_period_setup_md, {{"mass", fmt::format("{}", mass)},
                                                                      {"damping", fmt::format("{}", b_falcon)},
                                                                      {"duration_s", fmt::format("{}", o.duration_s)}});
    s.map.bound = "(1 + 2 d) K T / 2 < b with the device's delay d = 0, i.e. T < 2 b / K";
    s.xs = logspace(10.0, 1e5, n);
    s.ys = logspace(1e-4, 2e-3, n);
    s.make = [o, b_falcon](double k, double t) { return pressed_wall(k, 0.0, b_falcon, t, o.duration_s); };
    s.inside_bound = [b_falcon, d](double k, double t) { return damping_needed_n_s_per_m(k, t, d) < b_falcon; };
    // The stiffest passive wall is inversely proportional to T: at T it is (its value at 1 s) / T.
    s.map.bound_curve =
        bound_curve(s.xs, [b_falcon, d](double k) { return stiffest_passive_wall_n_per_m(b_falcon, 1.0, d) / k; });
    s.linear = [b_falcon](double k, double t) { return std::vector{pressed_wall_loop(k, 0.0, b_falcon, t)}; };
    s.drives = [b_falcon](double k, double t) {
      return std::vector{wall_drive(wall_toml(k, 0.0), k, 0.0, b_falcon, t)};
    };
    s.lengthen = true;
    all.push_back(std::move(s));
  }
  {  // K x b
    Sweep s;
    s.map.name = "stiffness_device_damping";
    s.map.title = "Stiffness and the device's damping (T = 1 ms, B = 0)";
    s.map.x_label = "virtual stiffness K [N/m]";
    s.map.y_label = "device damping b [N s/m]";
    s.map.setup = fmt::format("As above at T = 1 ms, sweeping the device's viscous damping b (a hand holding the "
                              "grip adds its own: 8-15 N s/m in docs/HAND_SCRIPTS.md); {} s per point.",
                              o.duration_s);
    s.map.bound = "b > (1 + 2 d) K T / 2 with d = 0";
    s.xs = logspace(10.0, 1e5, n);
    s.ys = logspace(0.01, 30.0, n);
    s.make = [o](double k, double b) { return pressed_wall(k, 0.0, b, 1e-3, o.duration_s); };
    s.inside_bound = [d](double k, double b) { return b > damping_needed_n_s_per_m(k, 1e-3, d); };
    s.map.bound_curve = bound_curve(s.xs, [d](double k) { return damping_needed_n_s_per_m(k, 1e-3, d); });
    s.linear = [](double k, double b) { return std::vector{pressed_wall_loop(k, 0.0, b, 1e-3)}; };
    s.drives = [](double k, double b) { return std::vector{wall_drive(wall_toml(k, 0.0), k, 0.0, b, 1e-3)}; };
    s.lengthen = true;
    all.push_back(std::move(s));
  }
  {  // K x B
    Sweep s;
    s.map.name = "stiffness_virtual_damping";
    s.map.title = fmt::format("Stiffness and virtual damping (T = 1 ms, b = {} N s/m)", b_falcon);
    s.map.x_label = "virtual stiffness K [N/m]";
    s.map.y_label = "wall damping B [N s/m]";
    s.map.setup = fmt::format("As the first map at T = 1 ms, with the wall's damping B (backward-difference "
                              "velocity; the wall's damping acts only inside and never pulls: max(0, K delta - B "
                              "n.v)); {} s per point.",
                              o.duration_s);
    s.map.bound = "b > (1 + 2 d) K T / 2 + |B| with d = 0, i.e. B < b - K T / 2 (only for K < 2 b / T)";
    s.xs = logspace(10.0, 1e5, n);
    s.ys = logspace(1e-3, 300.0, n);
    s.make = [o, b_falcon](double k, double b) { return pressed_wall(k, b, b_falcon, 1e-3, o.duration_s); };
    s.inside_bound = [b_falcon, d](double k, double b) { return b_falcon > damping_needed_n_s_per_m(k, 1e-3, d, b); };
    for (const double k : logspace(s.xs.front(), stiffest_passive_wall_n_per_m(b_falcon, 1e-3, d), 100)) {
      const double b = b_falcon - damping_needed_n_s_per_m(k, 1e-3, d);
      if (b > s.ys.front()) s.map.bound_curve.emplace_back(k, b);
    }
    s.linear = [b_falcon](double k, double b) { return std::vector{pressed_wall_loop(k, b, b_falcon, 1e-3)}; };
    s.drives = [b_falcon](double k, double b) {
      return std::vector{wall_drive(wall_toml(k, b), k, b, b_falcon, 1e-3)};
    };
    s.lengthen = true;
    all.push_back(std::move(s));
  }
  {  // mu x b
    Sweep s;
    s.map.name = "slippery_device_damping";
    s.map.title = "Super-slippery gain and the device's damping (T = 1 ms)";
    s.map.x_label = "slippery gain mu [N s/m]";
    s.map.y_label = "device damping b [N s/m]";
    constexpr double kWall = 50.0;
    constexpr double kPress = 0.5;
    s.map.setup =
        render_prose(templates::stability_slippery_setup_md, {{"press", fmt::format("{}", kPress)},
                                                              {"wall", fmt::format("{}", kWall)},
                                                              {"duration_s", fmt::format("{}", o.duration_s)}});
    s.map.bound = "b > (1 + 2 d) K T / 2 + |B| along the surface, where K = 0 and B = -mu: b > mu";
    s.xs = logspace(0.01, 30.0, n);
    s.ys = logspace(0.03, 30.0, n);
    s.make = [o](double mu, double b) {
      Experiment e;
      e.device = ideal_device(b);
      e.press_n = {0.0, 0.0, -kPress};
      e.duration_s = o.duration_s;
      e.scene_toml = wall_toml(kWall, 0.0) + fmt::format("  [surface.slippery]\n  mu = {}\n", mu);
      e.velocity_cutoff_hz = kVelocityCutoffHz;
      e.wall_stiffness_n_per_m = kWall;
      e.equilibrium_m = {0.0, 0.0, -kPress / kWall};
      e.start_m = e.equilibrium_m;
      e.hand_aim_m = e.equilibrium_m;
      e.start_velocity_m_per_s = {0.05, 0.0, 0.0};
      return e;
    };
    s.inside_bound = [d](double mu, double b) { return b > damping_needed_n_s_per_m(0.0, 1e-3, d, mu); };
    s.map.bound_curve = bound_curve(s.xs, [d](double mu) { return damping_needed_n_s_per_m(0.0, 1e-3, d, mu); });
    s.linear = [](double mu, double b) {
      // Normal axis: the wall; tangential: no spring, the slippery force +mu v along the motion.
      SampledLoop tangential = pressed_wall_loop(0.0, 0.0, b, 1e-3);
      tangential.velocity_feedback_n_s_per_m = mu;
      return std::vector{pressed_wall_loop(kWall, 0.0, b, 1e-3), tangential};
    };
    s.drives = [](double mu, double b) {
      const std::string scene = wall_toml(kWall, 0.0) + fmt::format("  [surface.slippery]\n  mu = {}\n", mu);
      PortDrive normal = wall_drive(scene, kWall, 0.0, b, 1e-3);
      PortDrive along = normal;  // pressed in, moving along the surface
      along.direction = {1.0, 0.0, 0.0};
      return std::vector{normal, along};
    };
    s.lengthen = true;
    all.push_back(std::move(s));
  }
  for (const bool cartoon : {false, true}) {  // impact speed x K, realistic
    Sweep s;
    const host_sim::DeviceParams falcon = host_sim::falcon_params();
    const host_sim::HandImpedance hand{0.1, 300.0, 15.0};  // the firm grip of scenes/hands/strike.toml
    s.map.name = cartoon ? "impact_cartoon_wall" : "impact_penalty_wall";
    s.map.title =
        cartoon ? "Impact speed and stiffness: the cartoon wall" : "Impact speed and stiffness: a penalty wall";
    s.map.x_label = "impact speed [m/s]";
    s.map.y_label = "virtual stiffness K [N/m]";
    constexpr double kAim = -0.002;
    constexpr double kImpactDuration = 1.0;
    s.map.setup = render_prose(
        templates::stability_impact_setup_md,
        {{"mass", fmt::format("{}", falcon.mass_kg)},
         {"damping", fmt::format("{}", falcon.damping_n_s_per_m)},
         {"coulomb", fmt::format("{}", falcon.coulomb_n)},
         {"saturation", fmt::format("{}", falcon.max_force_n)},
         {"wall", cartoon
                      ? "the cartoon wall (scenes/cartoon_wall.toml's transient: k_r 200, k_osc 400 N/m, 0.15 s, 30 Hz)"
                      : "a penalty wall"},
         {"duration_s", fmt::format("{}", kImpactDuration)},
         {"transient",
          cartoon
              ? " The transient adds energy by design for 0.15 s after each entry, so the run-away and growth tests "
                "start at 0.2 s and measure against the largest energy until then (which includes what it added)."
              : ""}});
    const double b_total = falcon.damping_n_s_per_m + hand.damping_n_s_per_m;
    const double k_bound = stiffest_passive_wall_n_per_m(b_total, 1e-3, falcon.io_delay_ticks);
    s.map.bound = fmt::format(
        "b + b_hand > (1 + 2 d) K T / 2 with the device's delay d = {}, i.e. K < 2 (0.1 + 15) / (3 x 0.001) = {:.0f} N/m "
        "(Coulomb friction, quantisation and the clamp left out)",
        falcon.io_delay_ticks, k_bound);
    s.map.linear_model = fmt::format(
        "the loop in contact without Coulomb friction, quantisation, the clamp{}: device and hand mass {} kg, "
        "damping {} N s/m, the hand's spring {} N/m, one tick of I/O delay",
        cartoon ? " or the transient" : "", falcon.mass_kg + hand.mass_kg, b_total, hand.stiffness_n_per_m);
    s.xs = logspace(0.02, 1.5, n);
    s.ys = logspace(300.0, 1e5, n);
    s.make = [hand, cartoon](double speed, double k) {
      Experiment e;
      e.device = host_sim::falcon_params();
      e.hand = hand;
      e.hand_aim_m = {0.0, 0.0, kAim};
      e.duration_s = kImpactDuration;
      e.scene_toml = "[device]\nmax_force = 8.0\nmax_force_rate = 2000.0\n" + wall_toml(k, 0.0);
      if (cartoon) {
        e.scene_toml += "  [surface.impact]\n  recoil_gain = 200.0\n  oscillation_gain = 400.0\n  duration = 0.15\n"
                        "  frequency = 30.0\n";
      }
      e.wall_stiffness_n_per_m = k;
      e.wall_max_force_n = 8.0;  // the scene's clamp (and the device's saturation)
      if (cartoon) e.settle_s = 0.2;
      e.equilibrium_m = {0.0, 0.0, hand.stiffness_n_per_m * kAim / (hand.stiffness_n_per_m + k)};
      e.start_m = {0.0, 0.0, 0.001};
      e.start_velocity_m_per_s = {0.0, 0.0, -speed};
      e.substeps = 4;
      return e;
    };
    s.inside_bound = [k_bound](double, double k) { return k < k_bound; };
    for (const double x : logspace(s.xs.front(), s.xs.back(), 2)) s.map.bound_curve.emplace_back(x, k_bound);
    s.linear = [falcon, hand, b_total](double, double k) {
      SampledLoop l;
      l.mass_kg = falcon.mass_kg + hand.mass_kg;
      l.damping_n_s_per_m = b_total;
      l.spring_n_per_m = hand.stiffness_n_per_m;
      l.period_s = 1e-3;
      l.delay_ticks = falcon.io_delay_ticks;
      l.velocity_gain = velocity_gain(VelocityEstimator<double>::kDefaultCutoffHz, 1e-3);
      l.stiffness_n_per_m = k;
      return std::vector{l};
    };
    all.push_back(std::move(s));
  }
  return all;
}

}  // namespace

Outcome classify(const std::vector<double>& energy_j) { return classify_with(energy_j, kRunawayRatio); }

Result<Outcome> run_experiment(const Experiment& e) { return run_with(e, kRunawayRatio); }

double wall_energy_j(double stiffness_n_per_m, double depth_m, double max_force_n) noexcept {
  if (depth_m <= 0.0) return 0.0;
  if (max_force_n > 0.0 && stiffness_n_per_m * depth_m > max_force_n) {
    const double clamp_depth_m = max_force_n / stiffness_n_per_m;
    return max_force_n * (depth_m - clamp_depth_m) + 0.5 * stiffness_n_per_m * clamp_depth_m * clamp_depth_m;
  }
  return 0.5 * stiffness_n_per_m * depth_m * depth_m;
}

Matrix transition_matrix(const SampledLoop& l) {
  const int d = std::max(0, l.delay_ticks);
  const std::size_t n = static_cast<std::size_t>(d) + 4;
  // Indices: 0 x_k, 1 v_k, 1 + j x_(k-j) for j = 1 .. d + 1, n - 1 the estimate v_(k-1).
  const auto pos = [](int j) { return j == 0 ? std::size_t{0} : static_cast<std::size_t>(j) + 1; };
  const std::size_t est = n - 1;
  // The exact step of m a = -b v - k x + F over T with F held: exp of [[0, 1, 0], [-k/m, -b/m,
  // 1/m], [0, 0, 0]] T (the simulation's kExact integrator uses the same exponential).
  std::array<std::array<double, 4>, 4> a{};
  a[0][1] = l.period_s;
  a[1][0] = -l.spring_n_per_m / l.mass_kg * l.period_s;
  a[1][1] = -l.damping_n_s_per_m / l.mass_kg * l.period_s;
  a[1][2] = l.period_s / l.mass_kg;
  const auto e = host_sim::matrix_exponential(a);
  // The estimate at k and the force at k, as rows over the state.
  std::vector<double> estimate(n, 0.0);
  estimate[est] = 1.0 - l.velocity_gain;
  estimate[pos(d)] += l.velocity_gain / l.period_s;
  estimate[pos(d + 1)] -= l.velocity_gain / l.period_s;
  std::vector<double> force(n, 0.0);
  for (std::size_t j = 0; j < n; ++j) force[j] = l.velocity_feedback_n_s_per_m * estimate[j];
  force[pos(d)] -= l.stiffness_n_per_m;
  Matrix m(n, std::vector<double>(n, 0.0));
  for (std::size_t r = 0; r < 2; ++r) {
    for (std::size_t j = 0; j < n; ++j) m[r][j] = e[r][2] * force[j];
    m[r][0] += e[r][0];
    m[r][1] += e[r][1];
  }
  for (int j = 1; j <= d + 1; ++j) m[pos(j)][pos(j - 1)] = 1.0;  // the delay line shifts
  m[est] = estimate;
  if (l.stiffness_n_per_m != 0.0 || l.spring_n_per_m != 0.0) return m;
  // No spring: nothing depends on x_k itself, only on differences of positions. In the
  // coordinates x_k, v_k, x_(k-j) - x_k, v_(k-1) (P m P^-1), x_k's column is (1, 0, ..., 0):
  // its eigenvalue 1 is the free position; drop it.
  Matrix p(n, std::vector<double>(n, 0.0));
  Matrix p_inverse(n, std::vector<double>(n, 0.0));
  for (std::size_t i = 0; i < n; ++i) p[i][i] = p_inverse[i][i] = 1.0;
  for (int j = 1; j <= d + 1; ++j) {
    p[pos(j)][0] = -1.0;
    p_inverse[pos(j)][0] = 1.0;
  }
  const auto multiply = [n](const Matrix& x, const Matrix& y) {
    Matrix z(n, std::vector<double>(n, 0.0));
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < n; ++k) {
        for (std::size_t j = 0; j < n; ++j) z[i][j] += x[i][k] * y[k][j];
      }
    }
    return z;
  };
  const Matrix relative = multiply(multiply(p, m), p_inverse);
  Matrix reduced(n - 1, std::vector<double>(n - 1, 0.0));
  for (std::size_t i = 1; i < n; ++i) {
    for (std::size_t j = 1; j < n; ++j) reduced[i - 1][j - 1] = relative[i][j];
  }
  return reduced;
}

Result<double> loop_spectral_radius(const SampledLoop& loop) { return spectral_radius(transition_matrix(loop)); }

double required_damping_at_n_s_per_m(const SampledLoop& l, double theta) noexcept {
  using Complex = std::complex<double>;
  const Complex z_inverse = std::polar(1.0, -theta);
  const double half_sin = std::sin(theta / 2.0);
  const double one_minus_cos = 2.0 * half_sin * half_sin;    // 1 - cos theta without cancellation
  const Complex difference(one_minus_cos, std::sin(theta));  // 1 - z^-1, likewise
  const Complex estimator = l.velocity_gain * difference / (l.period_s * (1.0 - (1.0 - l.velocity_gain) * z_inverse));
  const Complex h =
      std::pow(z_inverse, l.delay_ticks) * (l.stiffness_n_per_m - l.velocity_feedback_n_s_per_m * estimator);
  return l.period_s / 2.0 * std::real(difference * h) / one_minus_cos;
}

double required_damping_n_s_per_m(const SampledLoop& l) noexcept {
  constexpr int kFrequencies = 4096;
  constexpr double kPi = 3.14159265358979323846;
  double required = -std::numeric_limits<double>::infinity();
  for (int i = 0; i <= kFrequencies; ++i) {
    // i = 0 stands for the limit theta -> 0 (where the spring's and the slippery gain's b_req
    // lie): 1e-7 rad meets it to 1e-14 relative, and the expression is evaluated without
    // cancellation.
    const double theta = i == 0 ? 1e-7 : kPi * static_cast<double>(i) / kFrequencies;
    required = std::max(required, required_damping_at_n_s_per_m(l, theta));
  }
  return required;
}

namespace {

constexpr double kTwoPi = 6.28318530717958647692;
/// Forcing windows of fewer ticks than a period of this many are q = 1009 ticks long.
constexpr std::int64_t kShortestOnePeriodWindow = 50;
constexpr std::int64_t kPrimeWindowTicks = 1009;
/// The sums' round-off relative to the dampings compared (measured: below 1e-11; see each
/// section's model difference).
constexpr double kPortRelativeTolerance = 1e-9;

/// The handle as a motion source: reads x(kT) = x0 + A sin(2 pi p k / q), records the force the
/// loop writes at each tick (along the drive's direction; work along any other is zero).
struct MotionSource {
  const PortDrive* drive;
  std::int64_t periods;
  std::int64_t ticks;
  std::vector<double>* forces_n;
  std::int64_t k = 0;
  DeviceStatus read(DeviceReading& r) noexcept {
    // The phase from integers, so a long window's sine is as exact as its first period's.
    const double phase = kTwoPi * static_cast<double>((periods * k) % ticks) / static_cast<double>(ticks);
    r.position_m = drive->x0_m + drive->direction * (drive->amplitude_m * std::sin(phase));
    r.has_velocity = false;
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>& force_n) noexcept {
    (*forces_n)[static_cast<std::size_t>(k)] = dot(force_n, drive->direction);
    ++k;
    return DeviceStatus::kOk;
  }
};

Result<PortCycle> port_cycle_of(const PortDrive& drive, const SceneDescription& desc, std::int64_t p, std::int64_t q) {
  if (p < 1 || q < 3 || (2 * p) % q == 0) {
    return Error{fmt::format("port forcing: {} periods in {} ticks alias to DC", p, q)};
  }
  // The spec's stages only, and no clamp or rate limit: the law itself, linear.
  ServoConfig config = servo_config(desc, drive.period_s);
  if (drive.velocity_cutoff_hz > 0.0) config.velocity_cutoff_hz = drive.velocity_cutoff_hz;
  config.limits.has_max_force = false;
  config.limits.has_max_force_rate = false;
  const double a = velocity_gain(config.velocity_cutoff_hz, drive.period_s);
  // The estimator forgets its start as (1 - a)^k: 40 / a ticks leave e^-40 of it.
  const std::int64_t settle = drive.delay_ticks + 2 + static_cast<std::int64_t>(std::ceil(40.0 / a));
  std::vector<double> forces(static_cast<std::size_t>(settle + q), 0.0);
  ServoLoop<MotionSource, RuntimeScene<double>, NullPins, kSpecStages> loop(MotionSource{&drive, p, q, &forces},
                                                                            make_runtime_scene<double>(desc), config);
  for (std::int64_t k = 0; k < settle + q - drive.delay_ticks; ++k) static_cast<void>(loop.tick(k));

  // Hold interval j = [jT, (j+1)T] carries the force written at tick j - d. Over q ticks (p
  // whole periods) the displacements sum to zero, so a constant force does no work: the press
  // force is taken out before summing, to keep its round-off out of the small net.
  const double amplitude = drive.amplitude_m;
  const double pi_over_q = kTwoPi / 2.0 / static_cast<double>(q);
  const double half_step = 2.0 * amplitude * std::sin(pi_over_q * static_cast<double>(p));
  const double reference_n = forces[static_cast<std::size_t>(settle - drive.delay_ticks)];
  double work = 0.0;
  double ramp = 0.0;
  for (std::int64_t j = settle; j < settle + q; ++j) {
    // x((j+1)T) - x(jT) = 2 A sin(pi p / q) cos(pi p (2 j + 1) / q), the phase again exact.
    const double dx = half_step * std::cos(pi_over_q * static_cast<double>((p * (2 * j + 1)) % (2 * q)));
    work += (forces[static_cast<std::size_t>(j - drive.delay_ticks)] - reference_n) * dx;
    ramp += dx * dx / drive.period_s;
  }
  PortCycle c;
  c.frequency_hz = static_cast<double>(p) / (static_cast<double>(q) * drive.period_s);
  c.theta_rad = kTwoPi * static_cast<double>(p) / static_cast<double>(q);
  c.damping_n_s_per_m = drive.device_damping_n_s_per_m;
  const double per_cycle = 1.0 / (static_cast<double>(p) * amplitude * amplitude);
  c.controller_work_j_per_m2 = work * per_cycle;
  c.ramp_v2_per_m2 = ramp * per_cycle;
  c.sine_v2_per_m2 = kTwoPi * c.frequency_hz * kTwoPi / 2.0;  // integral of (A w cos)^2 over 2 pi / w, per A^2
  return c;
}

}  // namespace

std::vector<std::pair<std::int64_t, std::int64_t>> port_frequencies(double period_s, int count) {
  std::vector<std::pair<std::int64_t, std::int64_t>> out;
  const double nyquist_hz = 0.5 / period_s;
  for (const double f : logspace(0.1, nyquist_hz, count)) {
    const double cycles_per_tick = f * period_s;
    std::pair<std::int64_t, std::int64_t> pq;
    if (cycles_per_tick * static_cast<double>(kShortestOnePeriodWindow) <= 1.0) {
      pq = {1, std::llround(1.0 / cycles_per_tick)};
    } else {
      const auto p = std::llround(cycles_per_tick * static_cast<double>(kPrimeWindowTicks));
      pq = {std::clamp<std::int64_t>(p, 1, (kPrimeWindowTicks - 1) / 2), kPrimeWindowTicks};
    }
    if (out.empty() || out.back() != pq) out.push_back(pq);
  }
  return out;
}

Result<PortCycle> port_cycle(const PortDrive& drive, std::int64_t periods, std::int64_t ticks) {
  auto desc = parse_scene(drive.scene_toml, "port.toml");
  if (!desc) return Error{desc.error()};
  return port_cycle_of(drive, desc.value(), periods, ticks);
}

Result<PortPassivity> port_passivity(const PortDrive& drive, int count, const SampledLoop* model) {
  auto desc = parse_scene(drive.scene_toml, "port.toml");
  if (!desc) return Error{desc.error()};
  PortPassivity r;
  const double b = drive.device_damping_n_s_per_m;
  for (const auto& [p, q] : port_frequencies(drive.period_s, count)) {
    auto c = port_cycle_of(drive, desc.value(), p, q);
    if (!c) return Error{c.error()};
    ++r.frequencies;
    const double sine = c->required_sine_n_s_per_m() - b;
    const double ramp = c->required_ramp_n_s_per_m() - b;
    r.tolerance_n_s_per_m = std::max({r.tolerance_n_s_per_m, kPortRelativeTolerance * b,
                                      kPortRelativeTolerance * std::abs(c->required_sine_n_s_per_m()),
                                      kPortRelativeTolerance * std::abs(c->required_ramp_n_s_per_m())});
    if (sine > r.margin_sine_n_s_per_m) {
      r.margin_sine_n_s_per_m = sine;
      r.worst_sine_hz = c->frequency_hz;
    }
    if (ramp > r.margin_ramp_n_s_per_m) {
      r.margin_ramp_n_s_per_m = ramp;
      r.worst_ramp_hz = c->frequency_hz;
    }
    if (model != nullptr) {
      const double modelled = required_damping_at_n_s_per_m(*model, c->theta_rad);
      r.model_difference_n_s_per_m =
          std::max(r.model_difference_n_s_per_m, std::abs(modelled - c->required_ramp_n_s_per_m()));
      r.model_grid_margin_n_s_per_m = std::max(r.model_grid_margin_n_s_per_m, modelled - b);
      // A sinusoid dissipates theta^2 / (2 (1 - cos theta)) times what the ramp through its samples does.
      const double half_sin = std::sin(c->theta_rad / 2.0);
      r.model_grid_sine_margin_n_s_per_m = std::max(
          r.model_grid_sine_margin_n_s_per_m, modelled * 4.0 * half_sin * half_sin / (c->theta_rad * c->theta_rad) - b);
    }
  }
  return r;
}

namespace {
/// The point's port check over several axes: the worst of each.
void merge(PortPassivity& into, const PortPassivity& axis) {
  if (axis.margin_sine_n_s_per_m > into.margin_sine_n_s_per_m) {
    into.margin_sine_n_s_per_m = axis.margin_sine_n_s_per_m;
    into.worst_sine_hz = axis.worst_sine_hz;
  }
  if (axis.margin_ramp_n_s_per_m > into.margin_ramp_n_s_per_m) {
    into.margin_ramp_n_s_per_m = axis.margin_ramp_n_s_per_m;
    into.worst_ramp_hz = axis.worst_ramp_hz;
  }
  into.model_difference_n_s_per_m = std::max(into.model_difference_n_s_per_m, axis.model_difference_n_s_per_m);
  into.model_grid_margin_n_s_per_m = std::max(into.model_grid_margin_n_s_per_m, axis.model_grid_margin_n_s_per_m);
  into.model_grid_sine_margin_n_s_per_m =
      std::max(into.model_grid_sine_margin_n_s_per_m, axis.model_grid_sine_margin_n_s_per_m);
  into.frequencies = std::max(into.frequencies, axis.frequencies);
  into.tolerance_n_s_per_m = std::max(into.tolerance_n_s_per_m, axis.tolerance_n_s_per_m);
}
}  // namespace

Result<StabilityReport> run_stability(const StabilityOptions& options, const Progress& progress) {
  StabilityReport report;
  report.options = options;
  report.machine = machine_info();
  const double start = cpu_seconds();
  for (Sweep& s : sweeps(options)) {
    if (!selected(s.map.name, options.filter)) continue;
    if (progress) progress(fmt::format("sweeping {} ({} points)", s.map.name, s.xs.size() * s.ys.size()));
    for (const double y : s.ys) {
      for (const double x : s.xs) {
        Experiment experiment = s.make(x, y);
        SweepPoint p;
        p.x = x;
        p.y = y;
        if (s.linear) {
          p.has_spectrum = true;
          p.passivity_margin_n_s_per_m = -std::numeric_limits<double>::infinity();
          for (const SampledLoop& l : s.linear(x, y)) {
            const auto rho = loop_spectral_radius(l);
            if (!rho) return Error{fmt::format("{} at ({}, {}): {}", s.map.name, x, y, rho.error())};
            p.spectral_radius = std::max(p.spectral_radius, rho.value());
            // The damping b_req is compared with: the loop's, which on the impact maps includes
            // the hand's (as the bound drawn there does).
            p.passivity_margin_n_s_per_m =
                std::max(p.passivity_margin_n_s_per_m, required_damping_n_s_per_m(l) - l.damping_n_s_per_m);
          }
          if (s.drives && options.port_frequencies > 0) {
            const auto loops = s.linear(x, y);
            const auto drives = s.drives(x, y);
            p.has_port = true;
            for (std::size_t i = 0; i < drives.size(); ++i) {
              auto port = port_passivity(drives[i], options.port_frequencies, &loops[i]);
              if (!port) return Error{fmt::format("{} at ({}, {}): port energy: {}", s.map.name, x, y, port.error())};
              merge(p.port, port.value());
            }
          }
          if (p.spectral_radius > 1.0) {
            p.efold_s = experiment.period_s / std::log(p.spectral_radius);
            if (s.lengthen) {
              experiment.duration_s = std::max(experiment.duration_s, std::min(options.longest_run_s, 3.0 * p.efold_s));
            }
          }
        }
        p.run_s = experiment.duration_s;
        auto outcome = run_with(experiment, s.runaway_ratio);
        if (!outcome) return Error{fmt::format("{} at ({}, {}): {}", s.map.name, x, y, outcome.error())};
        p.outcome = outcome.value();
        p.inside_bound = s.inside_bound(x, y);
        s.map.points.push_back(p);
      }
    }
    report.maps.push_back(std::move(s.map));
  }
  report.cpu_s = cpu_seconds() - start;
  return report;
}

std::string stability_csv(const StabilityMap& map) {
  std::string csv =
      "kind,x,y,class,inside_bound,peak_ratio,growth,max_force_n,spectral_radius,efold_s,run_s,passivity_margin_n_s_per_m,"
      "port_margin_ramp_n_s_per_m,port_margin_sine_n_s_per_m\n";
  for (const auto& p : map.points) {
    csv +=
        fmt::format("point,{:.6g},{:.6g},{},{},{:.6g},{:.6g},{:.6g},{},{},{:.6g},{},{},{}\n", p.x, p.y,
                    stability_name(p.outcome.stability), p.inside_bound ? 1 : 0, p.outcome.peak_ratio, p.outcome.growth,
                    p.outcome.max_force_n, p.has_spectrum ? fmt::format("{:.9f}", p.spectral_radius) : std::string(),
                    p.efold_s > 0.0 ? fmt::format("{:.6g}", p.efold_s) : std::string(), p.run_s,
                    p.has_spectrum ? fmt::format("{:.6g}", p.passivity_margin_n_s_per_m) : std::string(),
                    p.has_port ? fmt::format("{:.6g}", p.port.margin_ramp_n_s_per_m) : std::string(),
                    p.has_port ? fmt::format("{:.6g}", p.port.margin_sine_n_s_per_m) : std::string());
  }
  for (const auto& [x, y] : map.bound_curve) csv += fmt::format("bound,{:.6g},{:.6g},,,,,,,,,,,\n", x, y);
  return csv;
}

namespace {

/// A run shows growth that e-folds in tau if it lasts a few tau: 3 (the energy grows e^6).
constexpr double kEfoldsToSee = 3.0;
/// A point within round-off of b_req (a grid point exactly on the bound, b = mu) is neither.
constexpr double kOnTheBoundNsPerM = 1e-9;

/// The port-energy check beside b_req: agreement for both motions, and the disagreements.
std::string port_markdown(const StabilityMap& map) {
  struct Disagreement {
    const SweepPoint* p;
    const char* motion;
    const char* why;
  };
  std::vector<Disagreement> disagreements;
  int counted = 0;
  int on_the_bound = 0;
  int agree_ramp = 0;
  int agree_sine = 0;
  int frequencies = 0;
  double model_difference = 0.0;
  for (const auto& p : map.points) {
    if (!p.has_port) continue;
    frequencies = std::max(frequencies, p.port.frequencies);
    model_difference = std::max(model_difference, p.port.model_difference_n_s_per_m);
    if (std::abs(p.passivity_margin_n_s_per_m) <= kOnTheBoundNsPerM) {
      ++on_the_bound;
      continue;
    }
    ++counted;
    const bool by_b_req = p.passivity_margin_n_s_per_m < 0.0;
    const bool ramp = p.port.passive_ramp();
    const bool sine = p.port.passive_sine();
    // The model on the same frequencies: if it says what the measurement says, the measurement
    // is right and b_req's maximum lies off the grid (or, for the sinusoid, at a frequency where
    // a sinusoid is not the worst input).
    const bool grid_ramp = p.port.model_grid_margin_n_s_per_m <= p.port.tolerance_n_s_per_m;
    const bool grid_sine = p.port.model_grid_sine_margin_n_s_per_m <= p.port.tolerance_n_s_per_m;
    if (ramp == by_b_req) {
      ++agree_ramp;
    } else {
      disagreements.push_back(
          {&p, "ramp",
           grid_ramp == ramp ? "b_req's maximum lies off the forcing frequencies" : "the code parts from the model"});
    }
    if (sine == by_b_req) {
      ++agree_sine;
    } else {
      disagreements.push_back({&p, "sinusoid",
                               grid_sine != sine ? "the code parts from the model"
                               : grid_ramp == by_b_req
                                   ? "a sinusoid dissipates more than the worst motion through its samples"
                                   : "b_req's maximum lies off the forcing frequencies"});
    }
  }
  std::string md = render_prose(
      templates::stability_port_passivity_md,
      {{"frequencies", fmt::format("{}", frequencies)},
       {"agree_ramp", fmt::format("{}", agree_ramp)},
       {"counted", fmt::format("{}", counted)},
       {"agree_sine", fmt::format("{}", agree_sine)},
       {"on_the_bound",
        on_the_bound == 0 ? std::string() : fmt::format(" ({} on the bound left out, as above)", on_the_bound)},
       {"model_difference", fmt::format("{:.2g}", model_difference)}});
  if (disagreements.empty()) return md;
  md += fmt::format("\n{} disagreements{}:\n\n", disagreements.size(),
                    disagreements.size() > 8 ? " (the 8 nearest the bound)" : "");
  std::sort(disagreements.begin(), disagreements.end(), [](const Disagreement& a, const Disagreement& b) {
    return std::abs(a.p->passivity_margin_n_s_per_m) < std::abs(b.p->passivity_margin_n_s_per_m);
  });
  md += fmt::format("| {} | {} | motion | b_req - b [N s/m] | measured margin [N s/m] | at [Hz] | why |\n"
                    "| ---: | ---: | --- | ---: | ---: | ---: | --- |\n",
                    map.x_label, map.y_label);
  for (std::size_t i = 0; i < std::min<std::size_t>(disagreements.size(), 8); ++i) {
    const auto& d = disagreements[i];
    const bool ramp = std::string_view(d.motion) == "ramp";
    md += fmt::format("| {:.4g} | {:.4g} | {} | {:.3g} | {:.3g} | {:.4g} | {} |\n", d.p->x, d.p->y, d.motion,
                      d.p->passivity_margin_n_s_per_m,
                      ramp ? d.p->port.margin_ramp_n_s_per_m : d.p->port.margin_sine_n_s_per_m,
                      ramp ? d.p->port.worst_ramp_hz : d.p->port.worst_sine_hz, d.why);
  }
  return md;
}

std::string spectral_markdown(const StabilityMap& map) {
  std::string md;
  int table[2][3] = {};
  int inside_unstable = 0;
  int inside = 0;
  std::vector<const SweepPoint*> unseen;  // rho > 1, the run showed no growth
  for (const auto& p : map.points) {
    const bool grows = p.spectral_radius > 1.0;
    table[grows ? 1 : 0][static_cast<int>(p.outcome.stability)]++;
    if (p.inside_bound) {
      ++inside;
      if (grows) ++inside_unstable;
    }
    if (grows && p.outcome.stability != Stability::kUnstable) unseen.push_back(&p);
  }
  md += "By the spectral radius rho of the loop's transition matrix (the reference) and by the run (columns):\n\n";
  md += "| points | decaying | bounded | unstable |\n| --- | ---: | ---: | ---: |\n";
  md += fmt::format("| rho < 1 (linear loop stable) | {} | {} | {} |\n", table[0][0], table[0][1], table[0][2]);
  md += fmt::format("| rho > 1 (linear loop unstable) | {} | {} | {} |\n", table[1][0], table[1][1], table[1][2]);
  int passive[2][2] = {};  // [inside the bound][passive by b_req]
  int on_the_bound = 0;
  for (const auto& p : map.points) {
    if (std::abs(p.passivity_margin_n_s_per_m) <= kOnTheBoundNsPerM) {
      ++on_the_bound;
      continue;
    }
    passive[p.inside_bound ? 1 : 0][p.passivity_margin_n_s_per_m < 0.0 ? 1 : 0]++;
  }
  // For these maps' laws b_req is the drawn bound (stability_model_test.cpp), so these counts
  // repeat the bound's rows: say so, so they are not read as a second, independent verdict.
  const bool as_the_bound = passive[1][0] == 0 && passive[0][1] == 0;
  md += fmt::format(
      "\nPassivity by Colgate and Schenkel's b_req of the discrete law (necessary and sufficient for the linear "
      "port): inside the bound {} passive, {} not; outside it {} passive, {} not{}.{}\n",
      passive[1][1], passive[1][0], passive[0][1], passive[0][0],
      on_the_bound == 0
          ? std::string()
          : fmt::format("; {} on it, b = b_req within {:g} N s/m (marginal)", on_the_bound, kOnTheBoundNsPerM),
      as_the_bound ? " *True by construction*: for this map's law b_req is the drawn bound (a closed form, "
                     "tests/stability_model_test.cpp), so these counts are the bound's rows again, not independent "
                     "evidence; the measured check of passivity is the port energy below."
                   : " These counts differ from the bound's rows: b_req and the drawn bound part here.");
  if (!map.points.empty() && map.points.front().has_port) md += port_markdown(map);
  // |rho - 1| within the eigenvalue routine's accuracy (about 1e-15; a margin of 1e-9): marginal,
  // on the stability boundary (the slippery map's b = mu exactly), whichever row it fell in.
  constexpr double kMarginalRho = 1e-9;
  const auto marginal = std::count_if(map.points.begin(), map.points.end(), [](const SweepPoint& p) {
    return std::abs(p.spectral_radius - 1.0) <= kMarginalRho;
  });
  if (marginal > 0) {
    md += fmt::format("\n{} of these points are marginal, |rho - 1| <= {:g}: on the stability boundary, their row is "
                      "round-off.\n",
                      marginal, kMarginalRho);
  }
  md += fmt::format("\nInside the bound: {} points, {} of them with rho > 1{}.\n", inside, inside_unstable,
                    inside_unstable == 0
                        ? " (*true by construction*: a loop passive by the bound is stable with any passive "
                          "termination, and the model obeys that theorem; a consistency check of the model, not "
                          "evidence of stability beyond it)"
                        : " (the bound should imply rho < 1: a model or bound error)");
  if (!unseen.empty()) {
    std::sort(unseen.begin(), unseen.end(),
              [](const SweepPoint* a, const SweepPoint* b) { return a->efold_s > b->efold_s; });
    int too_short = 0;
    for (const auto* p : unseen) {
      if (p->run_s < kEfoldsToSee * p->efold_s) ++too_short;
    }
    md += render_prose(templates::stability_unseen_md,
                       {{"unseen", fmt::format("{}", unseen.size())},
                        {"too_short", fmt::format("{}", too_short)},
                        {"efoldings", fmt::format("{:g}", kEfoldsToSee)},
                        {"long_enough", fmt::format("{}", static_cast<int>(unseen.size()) - too_short)}});
    md += fmt::format(
        "| {} | {} | rho | e-folding [s] | run [s] | run's class |\n| ---: | ---: | ---: | ---: | ---: | --- |\n",
        map.x_label, map.y_label);
    for (std::size_t i = 0; i < std::min<std::size_t>(unseen.size(), 8); ++i) {
      const auto* p = unseen[i];
      md += fmt::format("| {:.4g} | {:.4g} | {:.7f} | {:.3g} | {:.3g} | {} |\n", p->x, p->y, p->spectral_radius,
                        p->efold_s, p->run_s, stability_name(p->outcome.stability));
    }
  }
  return md;
}

}  // namespace

std::string stability_markdown(const StabilityReport& r, const std::string& plot_dir) {
  std::string md;
  for (const auto& map : r.maps) {
    md += fmt::format("\n### {}\n\n{}\n\nBound drawn: {}.\n\n", map.title, map.setup, map.bound);
    if (!map.linear_model.empty()) md += fmt::format("Linear model: {}.\n\n", map.linear_model);
    if (!plot_dir.empty()) md += fmt::format("![{}]({}/{}.png)\n\n", map.title, plot_dir, map.name);
    int counts[2][3] = {};
    for (const auto& p : map.points) counts[p.inside_bound ? 0 : 1][static_cast<int>(p.outcome.stability)]++;
    md += "By the bound (rows) and by the run (columns):\n\n";
    md += "| points | decaying | bounded | unstable |\n| --- | ---: | ---: | ---: |\n";
    md += fmt::format("| inside the bound | {} | {} | {} |\n", counts[0][0], counts[0][1], counts[0][2]);
    md += fmt::format("| outside the bound | {} | {} | {} |\n\n", counts[1][0], counts[1][1], counts[1][2]);
    if (!map.points.empty() && map.points.front().has_spectrum) md += spectral_markdown(map);
  }
  md += fmt::format(
      "\n{} points, {:.1f} s of CPU.\n",
      [&r] {
        std::size_t n = 0;
        for (const auto& m : r.maps) n += m.points.size();
        return n;
      }(),
      r.cpu_s);
  return md;
}

}  // namespace toonforce::report
