// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/fixed_point_map.hpp"

#include <fmt/format.h>

#include "toonforce/config/scene_file.hpp"

namespace toonforce::report {

namespace {

/// The largest `x` in [0, hi] for which `scene_text(x)` loads for q16.16 (accepted at 0).
template <class F>
double largest_accepted(F scene_text, double hi) {
  const auto ok = [&](double x) {
    return static_cast<bool>(parse_scene(scene_text(x), "map.toml", ScalarKind::kQ16_16));
  };
  if (ok(hi)) return hi;
  double lo = 0.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (ok(mid) ? lo : hi) = mid;
  }
  return lo;
}

/// A floor at z = 0 (normal +z) in a workspace reaching `depth_m` below it, entered at up to
/// `speed_m_per_s`, with the surface's other keys `keys`.
std::string floor_scene(double depth_m, double speed_m_per_s, const std::string& keys) {
  return fmt::format("[device]\nworkspace_min = [-0.08, -0.065, {}]\nworkspace_max = [0.08, 0.065, 0.06]\n"
                     "max_velocity = {}\n[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\n{}",
                     -depth_m, speed_m_per_s, keys);
}

}  // namespace

std::string fixed_point_map_markdown() {
  std::string md;
  md += "Largest servo rate a Q16.16 loop accepts (`fixed_point::max_rate`; whole rates):\n\n";
  md += "| what sets it | largest rate [Hz] |\n| --- | ---: |\n";
  const auto rate_row = [&](const std::string& what, const std::string& device, const std::string& cliff_tau) {
    std::string text = device;
    if (!cliff_tau.empty()) {
      text += "[[cliff]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\naxis = [1, 0, 0]\ngap_min = -0.01\ngap_max = 0.01\n"
              "stiffness = 1500\nspeed_threshold = 0.08\ntau = " +
              cliff_tau + "\n";
    }
    const auto scene = parse_scene(text, "map.toml", ScalarKind::kQ16_16);
    if (!scene) return;
    const auto limit = fixed_point::max_rate(scene.value(), scene->of<CartoonCliff>());
    md += fmt::format("| {} | {:.6g} |\n", what, limit.max_rate_hz);
  };
  rate_row("1/dt itself (any scene; default velocity_cutoff 50 Hz)", "", "");
  rate_row("cliff tau = 0.02 s (bundled cliff)", "", "0.02");
  rate_row("cliff tau = 1 s", "", "1");
  rate_row("cliff tau = 5 s", "", "5");
  rate_row("velocity_cutoff = 0.1 Hz", "[device]\nvelocity_cutoff = 0.1\n", "");
  rate_row("velocity_cutoff = 0.01 Hz", "[device]\nvelocity_cutoff = 0.01\n", "");

  md += "\nLargest wall stiffness against the deepest penetration the workspace allows (max_velocity 1.2 m/s, "
        "no damping; 32767 N/m is the value's own limit, Q16.16 holding values below 32768):\n\n";
  md += "| deepest penetration [m] | largest stiffness [N/m] | k x depth [N] |\n| ---: | ---: | ---: |\n";
  for (const double depth : {0.06, 0.5, 1.0, 2.0, 5.0, 20.0}) {
    const double k = largest_accepted(
        [&](double x) { return floor_scene(depth, 1.2, fmt::format("stiffness = {}\n", x)); }, 32767.0);
    md += fmt::format("| {:g} | {:.6g} | {:.6g} |\n", depth, k, k * depth);
  }

  md += "\nLargest Coulomb coefficient against the wall's stiffness (0.06 m deep, regularization_speed 0.02 m/s; "
        "the gain mu_c N / v_reg must fit):\n\n";
  md += "| stiffness [N/m] | wall force at 0.06 m [N] | largest coulomb |\n| ---: | ---: | ---: |\n";
  for (const double k : {500.0, 1500.0, 3000.0, 10000.0, 30000.0}) {
    const double mu = largest_accepted(
        [&](double x) {
          return floor_scene(0.06, 1.2, fmt::format("stiffness = {}\n[surface.friction]\ncoulomb = {}\n", k, x));
        },
        32767.0);
    md += fmt::format("| {:g} | {:g} | {:.6g} |\n", k, k * 0.06, mu);
  }

  md += "\nLargest speed gains against the top speed ([device] max_velocity; wall 1500 N/m, 0.06 m deep):\n\n";
  md +=
      "| max_velocity [m/s] | damping [N s/m] | slippery mu [N s/m] | impact abs(k_r) + abs(k_osc), d = 0.15 s [N/m] | "
      "impact, d = 1 s [N/m] |\n| ---: | ---: | ---: | ---: | ---: |\n";
  for (const double v : {0.5, 1.2, 2.0, 5.0, 10.0}) {
    const auto with = [&](const std::string& keys) { return floor_scene(0.06, v, "stiffness = 1500\n" + keys); };
    const double b = largest_accepted([&](double x) { return with(fmt::format("damping = {}\n", x)); }, 32767.0);
    const double mu =
        largest_accepted([&](double x) { return with(fmt::format("[surface.slippery]\nmu = {}\n", x)); }, 32767.0);
    const auto impact = [&](double d) {
      return largest_accepted(
          [&](double x) {
            return with(fmt::format("[surface.impact]\nrecoil_gain = {}\noscillation_gain = {}\nduration = {}\n"
                                    "frequency = 5\n",
                                    x / 3.0, 2.0 * x / 3.0, d));
          },
          32767.0);
    };
    md += fmt::format("| {:g} | {:.6g} | {:.6g} | {:.6g} | {:.6g} |\n", v, b, mu, impact(0.15), impact(1.0));
  }
  return md;
}

}  // namespace toonforce::report
