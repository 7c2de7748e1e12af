// SPDX-License-Identifier: Apache-2.0
#include "toonforce/config/scene_file.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include <fmt/format.h>

#include "toonforce/config/device_keys.hpp"
#include "toonforce/config/scene_reader.hpp"

namespace toonforce {

namespace {

void read_device(const toml::table& table, ErrorList& errors, ScalarKind scalar, SceneSettings& scene) {
  TableReader r(table, "device", errors, scalar);
  read_device_keys(r, scene);  // each key declared once, in device_keys.cpp
  if (scalar == ScalarKind::kQ16_16) {
    const double time_constant_s = 1.0 / (2.0 * 3.14159265358979323846 * scene.velocity_cutoff_hz);
    if (Q16_16::from_double(time_constant_s).raw() == 0) {
      r.error("velocity_cutoff",
              fmt::format("{} Hz is too high for Q16.16: its time constant rounds to 0", scene.velocity_cutoff_hz));
    }
  }
  r.finish();
}

}  // namespace

namespace scene_reader {

void read_settings(TableReader& root, SceneSettings& settings) {
  if (auto name = root.optional_string("name")) settings.name = std::move(*name);
  if (const toml::table* device = root.optional_table("device")) {
    read_device(*device, root.errors(), root.scalar(), settings);
  }
}

bool refuse_world(const toml::table& root, ErrorList& errors) {
  const toml::node* device = root.get("device");
  if (device == nullptr || !device->is_array_of_tables()) return false;
  const toml::array& tables = *device->as_array();
  errors.add(tables.empty() ? device->source().begin.line : tables[0].source().begin.line, "device",
             fmt::format("[[device]] tables make this a world scene of {} device{}; `toonforce sim --scene FILE "
                         "--script NAME=HAND_SCRIPT ...` and `toonforce run --device sim|scene --scene FILE ...` run "
                         "a world",
                         tables.size(), tables.size() == 1 ? "" : "s"));
  return true;
}

void check_scene(const std::vector<SceneEntry>&, std::size_t values, const std::string& file, ErrorList& errors) {
  if (values > kMaxEffectValues) {
    errors.add(1, "",
               fmt::format("{}: its effects show {} values, more than the {} a telemetry frame carries; "
                           "split the scene",
                           file, values, kMaxEffectValues));
  }
}

namespace {

using fixed_point::kMaxProduct;

/// Normal use, for the Q16.16 scene rule: the HIP anywhere in the workspace the loop enforces
/// (the scene's, else the largest a device fills in) at up to the safety layer's max_velocity
/// (above it the loop turns the force off, effects.md §6).
struct Envelope {
  Vec3<double> min_m;
  Vec3<double> max_m;
  double speed_m_per_s;
  std::string workspace;  ///< how messages name it
};

Envelope envelope_of(const SceneSettings& s) {
  Envelope e;
  if (s.safety.has_workspace) {
    e.min_m = s.safety.workspace_min_m;
    e.max_m = s.safety.workspace_max_m;
    e.workspace = "the [device] workspace";
  } else {
    e.min_m = fixed_point::kDefaultWorkspaceMinM;
    e.max_m = fixed_point::kDefaultWorkspaceMaxM;
    e.workspace = "the largest device workspace";
  }
  e.speed_m_per_s = s.safety.max_velocity_m_per_s;
  return e;
}

/// The largest value of `f` (affine in the position) over the workspace box: at a corner.
template <class F>
double max_over_workspace(const Envelope& e, F f) {
  double most = -std::numeric_limits<double>::infinity();
  for (int corner = 0; corner < 8; ++corner) {
    const Vec3<double> c{(corner & 1) != 0 ? e.max_m.x : e.min_m.x, (corner & 2) != 0 ? e.max_m.y : e.min_m.y,
                         (corner & 4) != 0 ? e.max_m.z : e.min_m.z};
    most = std::max(most, f(c));
  }
  return most;
}

/// The deepest penetration delta = -n.(x - p0) the workspace allows (0: never in contact).
double deepest_m(const Envelope& e, const Plane<double>& plane) {
  return std::max(0.0,
                  max_over_workspace(e, [&](const Vec3<double>& x) { return -dot(plane.normal, x - plane.point_m); }));
}

/// The penalty wall's largest force in normal use, k delta_max + b v_max (effects.md §1: the
/// damping term is largest entering at full speed), checked against Q16.16. Returns it.
double check_wall(TableReader& r, const Envelope& e, const Plane<double>& plane, const PenaltyWall<double>::Params& w) {
  const double depth_m = deepest_m(e, plane);
  const double spring_n = w.stiffness_n_per_m * depth_m;
  const double damper_n = w.damping_n_s_per_m * e.speed_m_per_s;
  if (!(spring_n + damper_n > kMaxProduct)) return spring_n + damper_n;
  const auto stiffness_error = [&](double allowed_n) {
    r.error("stiffness",
            fmt::format("{:g} N/m saturates Q16.16: at the deepest penetration {} allows ({:g} m) the wall "
                        "pushes {:g} N{}, over the {:g} N Q16.16 holds; allowed with --scalar q16.16: "
                        "stiffness up to {:.6g} N/m",
                        w.stiffness_n_per_m, e.workspace, depth_m, spring_n + damper_n,
                        damper_n > 0.0 ? fmt::format(" (with damping x max_velocity {:g} N)", damper_n) : "",
                        kMaxProduct, allowed_n / depth_m));
  };
  const auto damping_error = [&](double allowed_n) {
    r.error("damping", fmt::format("{:g} N s/m saturates Q16.16: entering at max_velocity {:g} m/s the wall's damping "
                                   "pushes {:g} N{}, over the {:g} N Q16.16 holds; allowed with --scalar q16.16: "
                                   "damping up to {:.6g} N s/m",
                                   w.damping_n_s_per_m, e.speed_m_per_s, damper_n,
                                   spring_n > 0.0 ? fmt::format(" on top of the spring's {:g} N", spring_n) : "",
                                   kMaxProduct, allowed_n / e.speed_m_per_s));
  };
  if (spring_n > kMaxProduct || damper_n > kMaxProduct) {  // each term on its own
    if (spring_n > kMaxProduct) stiffness_error(kMaxProduct);
    if (damper_n > kMaxProduct) damping_error(kMaxProduct);
  } else if (spring_n >= damper_n) {  // only the sum: the larger term, given the other
    stiffness_error(kMaxProduct - damper_n);
  } else {
    damping_error(kMaxProduct - spring_n);
  }
  return spring_n + damper_n;
}

}  // namespace

void check_fixed_point(TableReader& r, const SceneSettings& settings, const RuntimeSurface<double>::Params& p) {
  const Envelope e = envelope_of(settings);
  const double v = e.speed_m_per_s;
  // N of the friction law is the wall's force on the same tick (effects.md §2), unclamped.
  const double normal_n = std::min(check_wall(r, e, p.plane, p.wall), kMaxProduct);
  const auto& t = p.tangential;
  if (t.kind == TangentialKind::kFriction && normal_n > 0.0) {
    // effects.md §2: F_t = v_t (mu_v - mu_c N / max(|v_t|, v_reg)); the gain is largest below
    // v_reg, the force at full speed.
    const double viscous = std::fabs(t.friction.viscous_n_s_per_m);
    const double v_reg = t.friction.regularization_speed_m_per_s;
    const double gain = viscous + t.friction.coulomb * normal_n / v_reg;
    const double force_n = viscous * v + t.friction.coulomb * normal_n;
    if (gain > kMaxProduct || force_n > kMaxProduct) {
      if (t.friction.coulomb > 0.0) {
        const double allowed = std::min((kMaxProduct - viscous) * v_reg, kMaxProduct - viscous * v) / normal_n;
        r.error(
            "friction.coulomb",
            fmt::format("{:g} saturates Q16.16: against the wall's {:g} N at the deepest penetration its gain "
                        "mu_c N / v_reg is {:g} N s/m, over the {:g} N s/m Q16.16 holds; allowed with --scalar q16.16: "
                        "coulomb up to {:.6g}",
                        t.friction.coulomb, normal_n, gain, kMaxProduct, std::max(0.0, allowed)));
      } else {
        r.error("friction.viscous",
                fmt::format("{:g} N s/m saturates Q16.16 at max_velocity {:g} m/s ({:g} N); allowed with --scalar "
                            "q16.16: viscous down to {:.6g} N s/m",
                            t.friction.viscous_n_s_per_m, v, force_n, -kMaxProduct / std::max(1.0, v)));
      }
    }
  } else if (t.kind == TangentialKind::kSlippery && t.slippery.mu_n_s_per_m * v > kMaxProduct) {
    // effects.md §3: F_t = mu v_t before the cap.
    r.error("slippery.mu",
            fmt::format("{:g} N s/m saturates Q16.16: at max_velocity {:g} m/s mu v_t is {:g} N, over "
                        "the {:g} N Q16.16 holds; allowed with --scalar q16.16: mu up to {:.6g} N s/m",
                        t.slippery.mu_n_s_per_m, v, t.slippery.mu_n_s_per_m * v, kMaxProduct, kMaxProduct / v));
  }
  if (p.impact.enabled) {
    // effects.md §4: F = v_i (d - t) (k_r + k_osc sin(omega t)), largest at t = 0 with
    // v_i = max_velocity and the sine at +-1; the gains' sum is itself an intermediate.
    const auto& law = p.impact.law;
    const double gains = std::fabs(law.recoil_gain_n_per_m) + std::fabs(law.oscillation_gain_n_per_m);
    const double scale = std::max(1.0, v * law.duration_s);
    if (gains * scale > kMaxProduct) {
      const bool recoil = std::fabs(law.recoil_gain_n_per_m) >= std::fabs(law.oscillation_gain_n_per_m);
      r.error(recoil ? "impact.recoil_gain" : "impact.oscillation_gain",
              fmt::format("saturates Q16.16: recoil_gain {:g} and oscillation_gain {:g} N/m at an impact speed of "
                          "max_velocity {:g} m/s over duration {:g} s give up to {:g} N, over the {:g} N Q16.16 "
                          "holds; allowed with --scalar q16.16: |recoil_gain| + |oscillation_gain| up to {:.6g} N/m",
                          law.recoil_gain_n_per_m, law.oscillation_gain_n_per_m, v, law.duration_s,
                          gains * v * law.duration_s, kMaxProduct, kMaxProduct / scale));
    }
  }
}

void check_fixed_point(TableReader& r, const SceneSettings& settings, const CartoonCliff<double>::Params& p) {
  const Envelope e = envelope_of(settings);
  const double wall_n = check_wall(r, e, p.ground, p.wall);
  if (wall_n > kMaxProduct) return;  // said
  // effects.md §5: under a ledge the side face pushes k times the distance past the edge.
  const double past_m = std::max(0.0, max_over_workspace(e, [&](const Vec3<double>& x) {
                                   const double across = dot(p.axis, x - p.ground.point_m);
                                   return std::max(p.gap_min_m - across, across - p.gap_max_m);
                                 }));
  if (deepest_m(e, p.ground) > 0.0 && p.wall.stiffness_n_per_m * past_m > kMaxProduct) {
    r.error("stiffness", fmt::format("{:g} N/m saturates Q16.16: {} lets the HIP go {:g} m past a ledge's edge, where "
                                     "the side face pushes {:g} N, over the {:g} N Q16.16 holds; allowed with "
                                     "--scalar q16.16: stiffness up to {:.6g} N/m",
                                     p.wall.stiffness_n_per_m, e.workspace, past_m, p.wall.stiffness_n_per_m * past_m,
                                     kMaxProduct, kMaxProduct / past_m));
  }
}

void check_fixed_point_device(TableReader& root, const SceneSettings& settings) {
  // passivity.hpp: the controller's force is v (magnitude / |v|) with magnitude / |v| up to
  // max_damping, and it compares power with cap |v| = max_damping |v|^2.
  const double v = settings.safety.max_velocity_m_per_s;
  const double damping = settings.safety.passivity.max_damping_n_s_per_m;
  const double scale = std::max(v, v * v);
  if (settings.safety.passivity.controller && damping * scale > kMaxProduct) {
    root.error("device.passivity_max_damping",
               fmt::format("{:g} N s/m saturates Q16.16 at max_velocity {:g} m/s ({:g}); allowed with --scalar "
                           "q16.16: passivity_max_damping up to {:.6g} N s/m",
                           damping, v, damping * scale, kMaxProduct, kMaxProduct / scale));
  }
}

}  // namespace scene_reader

Result<SceneDescription> load_scene_file(const std::string& path, ScalarKind scalar) {
  return read_scene_file<TOONFORCE_BUILTIN_EFFECTS>(path, scalar);
}

Result<SceneDescription> parse_scene(std::string_view text, std::string_view source_name, ScalarKind scalar) {
  return read_scene<TOONFORCE_BUILTIN_EFFECTS>(text, source_name, scalar);
}

ServoConfig servo_config(const SceneSettings& scene, double period_s) {
  ServoConfig config;
  config.period_s = period_s;
  config.limits = scene.limits;
  config.velocity_cutoff_hz = scene.velocity_cutoff_hz;
  config.safety = scene.safety;
  return config;
}

ServoConfig replay_config(const SceneSettings& scene, double first_dt_s) {
  ServoConfig config = servo_config(scene, first_dt_s);
  config.time_from_stamps = true;
  return config;
}

template RuntimeScene<double> make_runtime_scene<double>(const SceneDescription&);
template RuntimeScene<float> make_runtime_scene<float>(const SceneDescription&);
template RuntimeScene<Q16_16> make_runtime_scene<Q16_16>(const SceneDescription&);

namespace fixed_point {

RateLimit max_rate(const SceneSettings& settings, const std::vector<CartoonCliff<double>::Params>& cliffs) {
  // The loop holds 1/dt itself (TickInput::rate_hz, hip_sensor.hpp); it fits below kMaxValue,
  // and the guard keeps the whole-unit headroom of every product. The passivity controller's
  // power X rate has X <= 1 J (PassivityController::kMaxExcessJ), so it fits when the rate does;
  // the rate limit's step comes from the integer dt, not the rate (ForceSafety::max_step_for_ns).
  RateLimit limit{kMaxProduct, fmt::format("1/dt itself must fit Q16.16, whose largest value is {:.10g}", kMaxValue)};
  // velocity_estimator.hpp: a = 1 / (1 + rate tau_c), tau_c = 1 / (2 pi f_c).
  const double tau_c_s = 1.0 / (2.0 * 3.14159265358979323846 * settings.velocity_cutoff_hz);
  if ((kMaxProduct - 1.0) / tau_c_s < limit.max_rate_hz) {
    limit = {(kMaxProduct - 1.0) / tau_c_s,
             fmt::format("the velocity estimator's 1 + rate / (2 pi velocity_cutoff) must stay within {:g} "
                         "(velocity_cutoff = {:g} Hz)",
                         kMaxProduct, settings.velocity_cutoff_hz)};
  }
  // cliff.hpp: s_f += (s - s_f) / (1 + tau rate).
  for (std::size_t i = 0; i < cliffs.size(); ++i) {
    const double tau_s = cliffs[i].tau_s;
    if (tau_s > 0.0 && (kMaxProduct - 1.0) / tau_s < limit.max_rate_hz) {
      limit = {(kMaxProduct - 1.0) / tau_s,
               fmt::format("cliff[{}]'s filter 1 + tau x rate must stay within {:g} (tau = {:g} s)", i + 1, kMaxProduct,
                           tau_s)};
    }
  }
  return limit;
}

std::string check_rate(double rate_hz, ScalarKind scalar, const SceneDescription& scene) {
  if (scalar != ScalarKind::kQ16_16) return {};
  const RateLimit limit = max_rate(scene, scene.of<CartoonCliff>());
  if (rate_hz <= limit.max_rate_hz) return {};
  return fmt::format("{:g} Hz is too fast for Q16.16 ({}); allowed with --scalar q16.16: up to {:.6g} Hz", rate_hz,
                     limit.reason, limit.max_rate_hz);
}

}  // namespace fixed_point

void override_sine(SceneDescription& scene, SineMethod method) {
  for (auto& surface : scene.of<RuntimeSurface>()) surface.impact.law.sine = method;
}

std::string empty_scene_problem(const SceneDescription& scene, std::string_view path) {
  if (!scene.order.empty()) return {};
  return fmt::format("{}: the scene has no [[surface]] or [[cliff]]: it renders zero force everywhere "
                     "(--allow-empty if that is what you want)",
                     path);
}

}  // namespace toonforce
