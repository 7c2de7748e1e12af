// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/plausibility.hpp"

#include <algorithm>
#include <array>
#include <limits>

#include <fmt/format.h>

#include "toonforce/control/passivity_bound.hpp"

namespace toonforce {

namespace {

/// The range of dot(direction, x - point) over the corners of the workspace box.
std::pair<double, double> extent_along(const Vec3<double>& point, const Vec3<double>& direction, const Vec3<double>& lo,
                                       const Vec3<double>& hi) {
  double least = std::numeric_limits<double>::infinity();
  double most = -least;
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3<double> c{(corner & 1) ? hi.x : lo.x, (corner & 2) ? hi.y : lo.y, (corner & 4) ? hi.z : lo.z};
    const double s = dot(direction, c - point);
    least = std::min(least, s);
    most = std::max(most, s);
  }
  return {least, most};
}

struct Context {
  const host_sim::DeviceParams& device;
  double period_s;
  bool passivity_controller;
  double stiffest_alone_n_per_m;  // the bound on the device alone (no virtual damping)
  PlausibilityReport& report;
};

/// A plane (a wall's or a cliff's ground) against the workspace: touched at all, or everywhere.
void check_plane(const Context& c, const std::string& who, const Vec3<double>& point, const Vec3<double>& normal) {
  const auto [least, most] = extent_along(point, normal, c.device.workspace_min_m, c.device.workspace_max_m);
  if (least > 0.0) {
    c.report.warnings.push_back(fmt::format(
        "{}: its plane lies {:.3g} mm outside the device's workspace at the nearest: the handle can never touch it",
        who, least * 1e3));
  } else if (most < 0.0) {
    c.report.warnings.push_back(fmt::format(
        "{}: the whole workspace is inside it (its plane is {:.3g} mm beyond the workspace): the handle is pushed "
        "everywhere, against the workspace's edge",
        who, -most * 1e3));
  }
}

/// A penalty wall of stiffness K and virtual damping B against the passivity bound and the
/// device's force and resolution.
void check_wall(const Context& c, const std::string& who, double stiffness_n_per_m, double damping_n_s_per_m) {
  const int d = c.device.io_delay_ticks;
  const double alone = stiffest_passive_wall_n_per_m(c.device.damping_n_s_per_m, c.period_s, d, damping_n_s_per_m);
  const double held = stiffest_passive_wall_n_per_m(c.device.damping_n_s_per_m + kHeldHandDampingNsPerM, c.period_s, d,
                                                    damping_n_s_per_m);
  const std::string law = damping_n_s_per_m > 0.0
                              ? fmt::format("K = {:g} N/m, B = {:g} N s/m", stiffness_n_per_m, damping_n_s_per_m)
                              : fmt::format("K = {:g} N/m", stiffness_n_per_m);
  if (stiffness_n_per_m > held) {
    c.report.warnings.push_back(fmt::format(
        "{}: {} is over the passive bound even when held ({:.4g} N/m with a hand of {:g} N s/m: b + b_hand > "
        "(1 + 2 d) K T / 2 + |B|, b = {:g} N s/m, d = {}, T = {:g} ms; a sufficient bound, which overstates the need "
        "when d > 0 and B > 0): it can buzz in a firm hand; lower the stiffness or raise the rate",
        who, law, held, kHeldHandDampingNsPerM, c.device.damping_n_s_per_m, d, c.period_s * 1e3));
  } else if (stiffness_n_per_m > alone) {
    const std::string text = fmt::format(
        "{}: {} is passive only while held (up to {:.4g} N/m with a hand of {:g} N s/m; {:.4g} N/m on the device "
        "alone)",
        who, law, held, kHeldHandDampingNsPerM, alone);
    if (c.passivity_controller) {
      c.report.notes.push_back(text + ": let go, the passivity controller damps what it gives back");
    } else {
      c.report.warnings.push_back(text + ", and passivity_controller = false: let go, nothing stops it buzzing");
    }
  } else {
    c.report.notes.push_back(fmt::format("{}: {} is passive on the device alone (up to {:.4g} N/m)", who, law, alone));
  }
  // The depth at which the wall asks for the device's whole force, against one encoder count.
  if (c.device.max_force_n > 0.0) {
    const double full_depth_m = c.device.max_force_n / stiffness_n_per_m;
    if (c.device.encoder_step_m > 0.0 && full_depth_m < c.device.encoder_step_m) {
      c.report.warnings.push_back(fmt::format(
          "{}: it asks for the device's whole {:g} N within {:.3g} um, less than one encoder step ({:.3g} um): it "
          "switches between 0 and full force from one count to the next",
          who, c.device.max_force_n, full_depth_m * 1e6, c.device.encoder_step_m * 1e6));
    } else {
      c.report.notes.push_back(fmt::format("{}: the device's whole {:g} N is reached {:.3g} mm deep", who,
                                           c.device.max_force_n, full_depth_m * 1e3));
    }
  }
}

}  // namespace

PlausibilityReport check_plausibility(const SceneDescription& scene, const std::string& scene_path,
                                      const host_sim::DeviceParams& device, double rate_hz) {
  PlausibilityReport report;
  const double period_s = 1.0 / rate_hz;
  const Context c{device, period_s, scene.safety.passivity.controller,
                  stiffest_passive_wall_n_per_m(device.damping_n_s_per_m, period_s, device.io_delay_ticks), report};
  report.notes.push_back(fmt::format(
      "device {} at {:g} Hz: peak force {:g} N; workspace [{:g}, {:g}] x [{:g}, {:g}] x [{:g}, {:g}] m; damping b = {:g} "
      "N s/m, I/O delay {} tick(s) (host_sim/device_model.hpp)",
      device.name, rate_hz, device.max_force_n, device.workspace_min_m.x, device.workspace_max_m.x,
      device.workspace_min_m.y, device.workspace_max_m.y, device.workspace_min_m.z, device.workspace_max_m.z,
      device.damping_n_s_per_m, device.io_delay_ticks));
  report.notes.push_back(fmt::format(
      "passive a wall is passive on this device alone up to K = 2 b / ((1 + 2 d) T) = {:.4g} N/m, and held by a hand "
      "of {:g} N s/m up to {:.4g} N/m (Colgate and Brown 1994, with the delay of Diolaiti et al. 2006; a sufficient "
      "bound, exact for a spring: with delay, a wall's damping B > 0 needs less than the |B| it adds)",
      c.stiffest_alone_n_per_m, kHeldHandDampingNsPerM,
      stiffest_passive_wall_n_per_m(device.damping_n_s_per_m + kHeldHandDampingNsPerM, period_s,
                                    device.io_delay_ticks)));

  if (scene.limits.has_max_force && device.max_force_n > 0.0 && scene.limits.max_force_n > device.max_force_n) {
    report.warnings.push_back(fmt::format(
        "{}: [device] max_force = {:g} N is over the device's peak of {:g} N: the device gives at most that",
        scene_path, scene.limits.max_force_n, device.max_force_n));
  }

  const auto& surfaces = scene.of<RuntimeSurface>();
  for (std::size_t i = 0; i < surfaces.size(); ++i) {
    const auto& p = surfaces[i];
    const std::string who = fmt::format("{}:{}: surface[{}]", scene_path, scene.line_of<0>(i), i + 1);
    check_plane(c, who, p.plane.point_m, p.plane.normal);
    check_wall(c, who, p.wall.stiffness_n_per_m, p.wall.damping_n_s_per_m);
    if (p.tangential.kind == TangentialKind::kSlippery) {
      // Along the surface there is no spring: the negative damping mu alone against b.
      const double mu = p.tangential.slippery.mu_n_s_per_m;
      const std::string text =
          fmt::format("{}: slippery mu = {:g} N s/m is over the device's own damping b = {:g} N s/m (passive only for "
                      "mu < b)",
                      who, mu, device.damping_n_s_per_m);
      if (mu <= device.damping_n_s_per_m) {
        report.notes.push_back(fmt::format("{}: slippery mu = {:g} N s/m is within the device's own damping", who, mu));
      } else if (c.passivity_controller) {
        report.notes.push_back(text + ": by design; the passivity controller holds it to its energy budget");
      } else {
        report.warnings.push_back(text + ", and passivity_controller = false: nothing bounds the energy it gives");
      }
    }
    if (p.impact.enabled) {
      const double f = p.impact.law.frequency_hz;
      if (f >= rate_hz / 2.0) {
        report.warnings.push_back(fmt::format(
            "{}: impact frequency {:g} Hz is at or over half the servo rate ({:g} Hz): the vibration is aliased "
            "to another frequency",
            who, f, rate_hz / 2.0));
      } else if (f > rate_hz / 10.0) {
        report.notes.push_back(
            fmt::format("{}: impact frequency {:g} Hz is sampled {:.3g} times a cycle", who, f, rate_hz / f));
      }
    }
  }
  const auto& cliffs = scene.of<CartoonCliff>();
  for (std::size_t i = 0; i < cliffs.size(); ++i) {
    const auto& p = cliffs[i];
    const std::string who = fmt::format("{}:{}: cliff[{}]", scene_path, scene.line_of<1>(i), i + 1);
    check_plane(c, who, p.ground.point_m, p.ground.normal);
    check_wall(c, who, p.wall.stiffness_n_per_m, p.wall.damping_n_s_per_m);
    const auto [least, most] = extent_along(p.ground.point_m, p.axis, device.workspace_min_m, device.workspace_max_m);
    if (p.gap_max_m < least || p.gap_min_m > most) {
      report.warnings.push_back(fmt::format(
          "{}: the gap [{:g}, {:g}] m along its axis is outside the workspace (which spans [{:.3g}, {:.3g}] m along "
          "it): the handle never reaches the edge",
          who, p.gap_min_m, p.gap_max_m, least, most));
    }
    if (scene.safety.max_velocity_m_per_s > 0.0 && p.speed_threshold_m_per_s >= scene.safety.max_velocity_m_per_s) {
      report.warnings.push_back(fmt::format(
          "{}: speed_threshold {:g} m/s is at or over the velocity limit {:g} m/s: wherever the loop renders force "
          "the handle is slower than that (faster trips the limit), so it falls as soon as it is over the gap",
          who, p.speed_threshold_m_per_s, scene.safety.max_velocity_m_per_s));
    }
  }
  return report;
}

}  // namespace toonforce
