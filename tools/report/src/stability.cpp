#include "toonforce/report/stability.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include <fmt/format.h>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/host_sim/sim_device.hpp"

namespace toonforce::report {

std::string_view stability_name(Stability s) noexcept {
  switch (s) {
    case Stability::kPassive: return "passive";
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

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

/// The run-away test only where the scene's laws are passive: an active effect (the impact
/// transient) adds energy by design, so there only growth counts.
Outcome classify_with(const std::vector<double>& energy, double runaway_ratio) {
  Outcome o;
  if (energy.empty()) return o;
  const double v0 = energy.front();
  o.initial_energy_j = v0;
  const std::size_t n = energy.size();
  const std::size_t quarter = std::max<std::size_t>(n / 4, 1);
  double peak = 0.0;
  double first = 0.0;
  double last = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double e = energy[i];
    if (!std::isfinite(e)) {
      o.finite = false;
      o.stability = Stability::kUnstable;
      o.peak_ratio = std::numeric_limits<double>::infinity();
      return o;
    }
    peak = std::max(peak, e);
    if (i < quarter) first = std::max(first, e);
    if (i >= n - quarter) last = std::max(last, e);
  }
  o.peak_ratio = v0 > 0.0 ? peak / v0 : 0.0;
  o.growth = first > 0.0 ? last / first : 0.0;
  if (o.peak_ratio > runaway_ratio || o.growth > kGrowthRatio) {
    o.stability = Stability::kUnstable;
  } else if (peak <= v0 * (1.0 + kPassiveTolerance)) {
    o.stability = Stability::kPassive;
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
           0.5 * e.wall_stiffness_n_per_m * depth * depth - dot(e.press_n, x);
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
  Outcome o = classify_with(v, runaway_ratio);
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
};

std::vector<Sweep> sweeps(const StabilityOptions& o) {
  const int n = o.resolution;
  const double b_falcon = host_sim::falcon_params().damping_n_s_per_m;
  const double mass = host_sim::falcon_params().mass_kg;
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
    s.map.setup = fmt::format(
        "Falcon-mass device ({} kg) with only its viscous damping b = {} N s/m (Coulomb friction, encoder and DAC "
        "steps, I/O delay and force saturation off), pressed onto a penalty wall with 1 N, starting at the "
        "equilibrium depth 1 N / K moving in at half the speed that would reach the surface; no safety limits; "
        "velocity by plain backward difference; {} s per point.",
        mass, b_falcon, o.duration_s);
    s.map.bound = "K T / 2 < b, i.e. T < 2 b / K";
    s.xs = logspace(10.0, 1e5, n);
    s.ys = logspace(1e-4, 2e-3, n);
    s.make = [o, b_falcon](double k, double t) { return pressed_wall(k, 0.0, b_falcon, t, o.duration_s); };
    s.inside_bound = [b_falcon](double k, double t) { return k * t / 2.0 < b_falcon; };
    s.map.bound_curve = bound_curve(s.xs, [b_falcon](double k) { return 2.0 * b_falcon / k; });
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
    s.map.bound = "b > K T / 2";
    s.xs = logspace(10.0, 1e5, n);
    s.ys = logspace(0.01, 30.0, n);
    s.make = [o](double k, double b) { return pressed_wall(k, 0.0, b, 1e-3, o.duration_s); };
    s.inside_bound = [](double k, double b) { return b > k * 1e-3 / 2.0; };
    s.map.bound_curve = bound_curve(s.xs, [](double k) { return k * 1e-3 / 2.0; });
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
    s.map.bound = "b > K T / 2 + |B|, i.e. B < b - K T / 2 (only for K < 2 b / T)";
    s.xs = logspace(10.0, 1e5, n);
    s.ys = logspace(1e-3, 300.0, n);
    s.make = [o, b_falcon](double k, double b) { return pressed_wall(k, b, b_falcon, 1e-3, o.duration_s); };
    s.inside_bound = [b_falcon](double k, double b) { return b_falcon > k * 1e-3 / 2.0 + b; };
    for (const double k : logspace(s.xs.front(), 2.0 * b_falcon / 1e-3, 100)) {
      const double b = b_falcon - k * 1e-3 / 2.0;
      if (b > s.ys.front()) s.map.bound_curve.emplace_back(k, b);
    }
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
    s.map.setup = fmt::format(
        "The same ideal device pressed with {} N onto a slippery surface (wall {} N/m, so the normal direction is "
        "inside its own bound for every b swept; cap 2 N), starting at the equilibrium depth and sliding at 0.05 m/s; "
        "velocity by plain backward difference; {} s per point. The slippery force is a negative damping -mu along "
        "the surface, where the wall's K is 0.",
        kPress, kWall, o.duration_s);
    s.map.bound = "b > |B| = mu";
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
    s.inside_bound = [](double mu, double b) { return b > mu; };
    s.map.bound_curve = bound_curve(s.xs, [](double mu) { return mu; });
    all.push_back(std::move(s));
  }
  for (const bool cartoon : {false, true}) {  // impact speed x K, realistic
    Sweep s;
    const host_sim::DeviceParams falcon = host_sim::falcon_params();
    const host_sim::HandImpedance hand{0.1, 300.0, 15.0};  // the firm grip of scenes/hands/strike.toml
    s.map.name = cartoon ? "impact_cartoon_wall" : "impact_penalty_wall";
    s.map.title = cartoon ? "Impact speed and stiffness: the cartoon wall" : "Impact speed and stiffness: a penalty wall";
    s.map.x_label = "impact speed [m/s]";
    s.map.y_label = "virtual stiffness K [N/m]";
    constexpr double kAim = -0.002;
    constexpr double kImpactDuration = 1.0;
    s.map.setup = fmt::format(
        "The Falcon-class simulated device as `toonforce sim` runs it (mass {} kg, b = {} N s/m, Coulomb {} N, 20 um "
        "encoder steps, force DAC steps, one tick of I/O delay, {} N saturation; exact integration of the linear part, "
        "4 sub-steps) held by a firm hand (0.1 kg, 300 N/m, 15 N s/m) aiming 2 mm into the wall, thrown at it from "
        "1 mm above at the impact speed; {} with the bundled scenes' safety stage (8 N, 2000 N/s) and velocity "
        "estimate (50 Hz); T = 1 ms; {} s per point.{}",
        falcon.mass_kg, falcon.damping_n_s_per_m, falcon.coulomb_n, falcon.max_force_n,
        cartoon ? "the cartoon wall (scenes/cartoon_wall.toml's transient: k_r 200, k_osc 400 N/m, 0.15 s, 30 Hz)"
                : "a penalty wall",
        kImpactDuration,
        cartoon ? " The transient adds energy by design, so only growth (not the 10 V0 run-away test) makes a point "
                  "unstable here."
                : "");
    s.map.bound = "b + b_hand > K T / 2, i.e. K < 2 (0.1 + 15) / 0.001 = 30 200 N/m (no delay, no friction)";
    s.xs = logspace(0.02, 1.5, n);
    s.ys = logspace(300.0, 1e5, n);
    s.runaway_ratio = cartoon ? std::numeric_limits<double>::infinity() : kRunawayRatio;
    s.make = [hand, cartoon](double speed, double k) {
      Experiment e;
      e.device = host_sim::falcon_params();
      e.hand = hand;
      e.hand_aim_m = {0.0, 0.0, kAim};
      e.duration_s = kImpactDuration;
      e.scene_toml = "[device]\nmax_force = 8.0\nmax_force_rate = 2000.0\n" + wall_toml(k, 0.0);
      if (cartoon) {
        e.scene_toml +=
            "  [surface.impact]\n  recoil_gain = 200.0\n  oscillation_gain = 400.0\n  duration = 0.15\n"
            "  frequency = 30.0\n";
      }
      e.wall_stiffness_n_per_m = k;
      e.equilibrium_m = {0.0, 0.0, hand.stiffness_n_per_m * kAim / (hand.stiffness_n_per_m + k)};
      e.start_m = {0.0, 0.0, 0.001};
      e.start_velocity_m_per_s = {0.0, 0.0, -speed};
      e.substeps = 4;
      return e;
    };
    const double b_total = falcon.damping_n_s_per_m + hand.damping_n_s_per_m;
    s.inside_bound = [b_total](double, double k) { return k * 1e-3 / 2.0 < b_total; };
    for (const double x : logspace(s.xs.front(), s.xs.back(), 2)) s.map.bound_curve.emplace_back(x, 2.0 * b_total / 1e-3);
    all.push_back(std::move(s));
  }
  return all;
}

}  // namespace

Outcome classify(const std::vector<double>& energy_j) { return classify_with(energy_j, kRunawayRatio); }

Result<Outcome> run_experiment(const Experiment& e) { return run_with(e, kRunawayRatio); }

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
        auto outcome = run_with(s.make(x, y), s.runaway_ratio);
        if (!outcome) return Error{fmt::format("{} at ({}, {}): {}", s.map.name, x, y, outcome.error())};
        SweepPoint p;
        p.x = x;
        p.y = y;
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
  std::string csv = "kind,x,y,class,inside_bound,peak_ratio,growth,max_force_n\n";
  for (const auto& p : map.points) {
    csv += fmt::format("point,{:.6g},{:.6g},{},{},{:.6g},{:.6g},{:.6g}\n", p.x, p.y, stability_name(p.outcome.stability),
                       p.inside_bound ? 1 : 0, p.outcome.peak_ratio, p.outcome.growth, p.outcome.max_force_n);
  }
  for (const auto& [x, y] : map.bound_curve) csv += fmt::format("bound,{:.6g},{:.6g},,,,,\n", x, y);
  return csv;
}

std::string stability_markdown(const StabilityReport& r, const std::string& plot_dir) {
  std::string md;
  for (const auto& map : r.maps) {
    md += fmt::format("\n### {}\n\n{}\n\nBound drawn: {}.\n\n", map.title, map.setup, map.bound);
    if (!plot_dir.empty()) md += fmt::format("![{}]({}/{}.png)\n\n", map.title, plot_dir, map.name);
    int counts[2][3] = {};
    for (const auto& p : map.points) counts[p.inside_bound ? 0 : 1][static_cast<int>(p.outcome.stability)]++;
    md += "| points | passive | bounded | unstable |\n| --- | ---: | ---: | ---: |\n";
    md += fmt::format("| inside the bound | {} | {} | {} |\n", counts[0][0], counts[0][1], counts[0][2]);
    md += fmt::format("| outside the bound | {} | {} | {} |\n", counts[1][0], counts[1][1], counts[1][2]);
    const int total = counts[0][0] + counts[0][1] + counts[0][2] + counts[1][0] + counts[1][1] + counts[1][2];
    if (total > 0) {
      md += fmt::format("\nThe bound predicts the class of {:.0f} % of the points (passive inside it, bounded or unstable "
                        "outside).\n",
                        100.0 * (counts[0][0] + counts[1][1] + counts[1][2]) / total);
    }
  }
  md += fmt::format("\n{} points, {:.1f} s of CPU.\n", [&r] {
    std::size_t n = 0;
    for (const auto& m : r.maps) n += m.points.size();
    return n;
  }(), r.cpu_s);
  return md;
}

}  // namespace toonforce::report
