#include "toonforce/config/scene_file.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

namespace toonforce {

std::optional<SineMethod> parse_sine_method(std::string_view name) {
  for (const SineMethod m : {SineMethod::kLibrary, SineMethod::kPolynomial, SineMethod::kTable}) {
    if (sine_method_name(m) == name) return m;
  }
  return std::nullopt;
}

namespace {

double length(const Vec3<double>& v) { return std::sqrt(dot(v, v)); }

/// A unit vector from `key`, or an error for a zero one (spec §0: zero length is an error).
std::optional<Vec3<double>> unit_vector(TableReader& r, std::string_view key) {
  const auto v = r.required_vec3(key, "(unit after normalising)");
  if (!v) return std::nullopt;
  const double len = length(*v);
  if (!(len > 1e-12)) {
    r.error(key, "must not be a zero vector (it is normalised on load)");
    return std::nullopt;
  }
  return *v * (1.0 / len);
}

std::optional<SceneDescription::Plane> read_plane(TableReader& r) {
  const auto point = r.required_vec3("point", "[m]");
  const auto normal = unit_vector(r, "normal");
  if (!point || !normal) return std::nullopt;
  return SceneDescription::Plane{*point, *normal};
}

/// The servo loop's [device] keys (toonforce extensions; interfaces.md lists them with their
/// defaults, effects.md §6 says what they do).
void read_safety(TableReader& r, SafetyConfig& s) {
  s.engage_force_n = r.number_or("engage_force", s.engage_force_n, Range::kPositive);
  s.soft_start_s = r.number_or("soft_start", s.soft_start_s, Range::kNonNegative);
  s.max_velocity_m_per_s = r.number_or("max_velocity", s.max_velocity_m_per_s, Range::kPositive);
  const auto lo = r.optional_vec3("workspace_min", "[m]");
  const auto hi = r.optional_vec3("workspace_max", "[m]");
  if (lo.has_value() != hi.has_value()) {
    r.error(lo ? "workspace_min" : "workspace_max", "needs workspace_min and workspace_max together");
  } else if (lo && hi) {
    if (!(lo->x < hi->x && lo->y < hi->y && lo->z < hi->z)) {
      r.error("workspace_max", "must be greater than workspace_min on every axis");
    } else {
      s.has_workspace = true;
      s.workspace_min_m = *lo;
      s.workspace_max_m = *hi;
    }
  }
  s.watchdog_periods = r.optional_integer("watchdog_periods", 1).value_or(s.watchdog_periods);
  s.device_timeout_periods = r.optional_integer("device_timeout_periods", 1).value_or(s.device_timeout_periods);
  s.thermal.continuous_force_n = r.number_or("continuous_force", 0.0, Range::kPositive);
  s.thermal.time_constant_s = r.number_or("thermal_time_constant", s.thermal.time_constant_s, Range::kPositive);
  if (const auto d = r.optional_number("thermal_derate_start", Range::kNonNegative)) {
    if (*d >= 1.0) {
      r.error("thermal_derate_start", fmt::format("must be below 1 (got {}): 1 is the rated temperature", *d));
    } else {
      s.thermal.derate_start = *d;
    }
  }
  s.passivity.controller = r.optional_bool("passivity_controller").value_or(s.passivity.controller);
  s.passivity.budget_j = r.number_or("passivity_budget", s.passivity.budget_j, Range::kPositive);
  s.passivity.max_damping_n_s_per_m =
      r.number_or("passivity_max_damping", s.passivity.max_damping_n_s_per_m, Range::kPositive);
}

void read_device(const toml::table& table, ErrorList& errors, ScalarKind scalar, SceneDescription& scene) {
  TableReader r(table, "device", errors, scalar);
  if (const auto f = r.optional_number("max_force", Range::kPositive)) {
    scene.limits.max_force_n = *f;
    scene.limits.has_max_force = true;
  }
  if (const auto f = r.optional_number("max_force_rate", Range::kPositive)) {
    scene.limits.max_force_rate_n_per_s = *f;
    scene.limits.has_max_force_rate = true;
  }
  scene.velocity_cutoff_hz = r.number_or("velocity_cutoff", scene.velocity_cutoff_hz, Range::kPositive);
  read_safety(r, scene.safety);
  if (scalar == ScalarKind::kQ16_16) {
    const double time_constant_s = 1.0 / (2.0 * 3.14159265358979323846 * scene.velocity_cutoff_hz);
    if (Q16_16::from_double(time_constant_s).raw() == 0) {
      r.error("velocity_cutoff", fmt::format("{} Hz is too high for Q16.16: its time constant rounds to 0",
                                             scene.velocity_cutoff_hz));
    }
  }
  r.finish();
}

std::optional<SceneDescription::Friction> read_friction(const toml::table& table, const std::string& path,
                                                        ErrorList& errors, ScalarKind scalar) {
  TableReader r(table, path, errors, scalar);
  SceneDescription::Friction f;
  // A positive viscous coefficient adds energy: that is the super-slippery surface (spec §3).
  if (const auto v = r.optional_number("viscous", Range::kAny)) {
    if (*v > 0.0) {
      r.error("viscous", fmt::format("must be <= 0 (got {}): realistic viscous friction opposes motion; "
                                     "for mu > 0 use a [surface.slippery] table instead", *v));
    } else {
      f.viscous_n_s_per_m = *v;
    }
  }
  f.coulomb = r.number_or("coulomb", f.coulomb, Range::kNonNegative);
  f.regularization_speed_m_per_s =
      r.number_or("regularization_speed", f.regularization_speed_m_per_s, Range::kPositive);
  r.finish();
  return f;
}

std::optional<SceneDescription::Slippery> read_slippery(const toml::table& table, const std::string& path,
                                                        ErrorList& errors, ScalarKind scalar) {
  TableReader r(table, path, errors, scalar);
  SceneDescription::Slippery s;
  const auto mu = r.required_number("mu", Range::kPositive, "[N s/m]");
  s.max_tangential_force_n = r.number_or("max_tangential_force", s.max_tangential_force_n, Range::kPositive);
  r.finish();
  if (!mu) return std::nullopt;
  s.mu_n_s_per_m = *mu;
  return s;
}

std::optional<SceneDescription::Impact> read_impact(const toml::table& table, const std::string& path,
                                                    ErrorList& errors, ScalarKind scalar) {
  TableReader r(table, path, errors, scalar);
  SceneDescription::Impact i;
  const auto recoil = r.required_number("recoil_gain", Range::kAny, "[N/m]");
  const auto oscillation = r.required_number("oscillation_gain", Range::kAny, "[N/m]");
  const auto duration = r.required_number("duration", Range::kPositive, "[s]");
  const auto frequency = r.required_number("frequency", Range::kPositive, "[Hz]");
  i.min_impact_speed_m_per_s = r.number_or("min_impact_speed", i.min_impact_speed_m_per_s, Range::kNonNegative);
  i.rearm_distance_m = r.number_or("rearm_distance", i.rearm_distance_m, Range::kNonNegative);
  if (const auto sine = r.optional_string("sine")) {
    i.sine = parse_sine_method(*sine);
    if (!i.sine) {
      r.error("sine", fmt::format("unknown sine method '{}' (library, polynomial or table)", *sine));
    } else if (*i.sine == SineMethod::kLibrary && scalar == ScalarKind::kQ16_16) {
      r.error("sine", "'library' needs a floating-point scalar; use 'polynomial' or 'table' for q16.16");
    }
  }
  if (duration && frequency && scalar == ScalarKind::kQ16_16 && !representable<Q16_16>(*duration * *frequency)) {
    r.error("frequency", fmt::format("frequency x duration = {} turns is outside the Q16.16 range",
                                     *duration * *frequency));
  }
  r.finish();
  if (!recoil || !oscillation || !duration || !frequency) return std::nullopt;
  i.recoil_gain_n_per_m = *recoil;
  i.oscillation_gain_n_per_m = *oscillation;
  i.duration_s = *duration;
  i.frequency_hz = *frequency;
  return i;
}

void read_surface(const toml::table& table, std::size_t number, ErrorList& errors, ScalarKind scalar,
                  SceneDescription& scene) {
  const std::string path = fmt::format("surface[{}]", number);
  TableReader r(table, path, errors, scalar);
  SceneDescription::Surface s;
  s.line = r.line();
  const auto plane = read_plane(r);
  const auto stiffness = r.required_number("stiffness", Range::kPositive, "[N/m]");
  s.damping_n_s_per_m = r.number_or("damping", 0.0, Range::kNonNegative);
  const toml::table* friction = r.optional_table("friction");
  const toml::table* slippery = r.optional_table("slippery");
  const toml::table* impact = r.optional_table("impact");
  if (friction != nullptr && slippery != nullptr) {
    errors.add(slippery->source().begin.line, path,
               "has both [surface.friction] and [surface.slippery]: they contradict each other "
               "(friction opposes motion, the slippery surface pushes along it); keep one");
  }
  if (friction != nullptr) s.friction = read_friction(*friction, path + ".friction", errors, scalar);
  if (slippery != nullptr) s.slippery = read_slippery(*slippery, path + ".slippery", errors, scalar);
  if (impact != nullptr) s.impact = read_impact(*impact, path + ".impact", errors, scalar);
  r.finish();
  if (!plane || !stiffness) return;
  s.plane = *plane;
  s.stiffness_n_per_m = *stiffness;
  scene.surfaces.push_back(s);
}

void read_cliff(const toml::table& table, std::size_t number, ErrorList& errors, ScalarKind scalar,
                SceneDescription& scene) {
  TableReader r(table, fmt::format("cliff[{}]", number), errors, scalar);
  SceneDescription::Cliff c;
  c.line = r.line();
  const auto ground = read_plane(r);
  const auto axis = unit_vector(r, "axis");
  const auto gap_min = r.required_number("gap_min", Range::kAny, "[m]");
  const auto gap_max = r.required_number("gap_max", Range::kAny, "[m]");
  const auto stiffness = r.required_number("stiffness", Range::kPositive, "[N/m]");
  c.damping_n_s_per_m = r.number_or("damping", 0.0, Range::kNonNegative);
  const auto threshold = r.required_number("speed_threshold", Range::kPositive, "[m/s]");
  c.tau_s = r.number_or("tau", c.tau_s, Range::kNonNegative);
  c.rearm_height_m = r.number_or("rearm_height", c.rearm_height_m, Range::kNonNegative);
  c.fall_force_n = r.number_or("fall_force", c.fall_force_n, Range::kNonNegative);
  if (ground && axis && std::abs(dot(ground->normal, *axis)) > 1e-6) {
    r.error("axis", fmt::format("must be perpendicular to the normal (|axis.normal| = {:.3g} > 1e-6 after "
                                "normalising)", std::abs(dot(ground->normal, *axis))));
  }
  if (gap_min && gap_max && !(*gap_min < *gap_max)) {
    r.error("gap_max", fmt::format("must be greater than gap_min ({} >= {})", *gap_min, *gap_max));
  }
  r.finish();
  if (!ground || !axis || !gap_min || !gap_max || !stiffness || !threshold) return;
  c.ground = *ground;
  c.axis = *axis;
  c.gap_min_m = *gap_min;
  c.gap_max_m = *gap_max;
  c.stiffness_n_per_m = *stiffness;
  c.speed_threshold_m_per_s = *threshold;
  scene.cliffs.push_back(c);
}

Result<SceneDescription> describe(const toml::table& root, ErrorList& errors, ScalarKind scalar,
                                  std::string_view source_name) {
  SceneDescription scene;
  scene.source = std::string(source_name);
  TableReader r(root, "", errors, scalar);
  scene.name = r.optional_string("name").value_or(std::filesystem::path(scene.source).stem().string());
  if (const toml::table* device = r.optional_table("device")) read_device(*device, errors, scalar, scene);
  const auto surfaces = r.array_of_tables("surface");
  const auto cliffs = r.array_of_tables("cliff");
  if (surfaces.size() > RuntimeScene<double>::kMaxSurfaces) {
    errors.add(surfaces[RuntimeScene<double>::kMaxSurfaces]->source().begin.line, "surface",
               fmt::format("{} surfaces, more than the {} a scene holds", surfaces.size(),
                           RuntimeScene<double>::kMaxSurfaces));
  }
  if (cliffs.size() > RuntimeScene<double>::kMaxCliffs) {
    errors.add(cliffs[RuntimeScene<double>::kMaxCliffs]->source().begin.line, "cliff",
               fmt::format("{} cliffs, more than the {} a scene holds", cliffs.size(),
                           RuntimeScene<double>::kMaxCliffs));
  }
  for (std::size_t i = 0; i < surfaces.size(); ++i) read_surface(*surfaces[i], i + 1, errors, scalar, scene);
  for (std::size_t i = 0; i < cliffs.size(); ++i) read_cliff(*cliffs[i], i + 1, errors, scalar, scene);
  r.finish();
  if (!errors.empty()) return Error{errors.text()};

  // File order across both kinds: their forces add in this order (spec §0).
  for (std::size_t i = 0; i < scene.surfaces.size(); ++i) scene.order.push_back({SceneDescription::Kind::kSurface, i});
  for (std::size_t i = 0; i < scene.cliffs.size(); ++i) scene.order.push_back({SceneDescription::Kind::kCliff, i});
  const auto line_of = [&scene](const SceneDescription::Entry& e) {
    return e.kind == SceneDescription::Kind::kSurface ? scene.surfaces[e.index].line : scene.cliffs[e.index].line;
  };
  std::stable_sort(scene.order.begin(), scene.order.end(),
                   [&](const auto& a, const auto& b) { return line_of(a) < line_of(b); });
  return scene;
}

}  // namespace

Result<SceneDescription> load_scene_file(const std::string& path, ScalarKind scalar) {
  ErrorList errors(path);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Error{fmt::format("{}: no such scene file{}\n", path,
                             std::filesystem::exists(path, ec) ? " (it is not a regular file)" : "")};
  }
  const auto root = parse_toml_file(path, errors);
  if (!root) return Error{errors.text()};
  return describe(*root, errors, scalar, path);
}

Result<SceneDescription> parse_scene(std::string_view text, std::string_view source_name, ScalarKind scalar) {
  ErrorList errors{std::string(source_name)};
  const auto root = parse_toml_text(text, errors);
  if (!root) return Error{errors.text()};
  return describe(*root, errors, scalar, source_name);
}

ControllerConfig controller_config(const SceneDescription& scene, double period_s) {
  ControllerConfig config;
  config.limits = scene.limits;
  config.velocity_cutoff_hz = scene.velocity_cutoff_hz;
  config.period_s = period_s;
  return config;
}

ServoConfig servo_config(const SceneDescription& scene, double period_s) {
  ServoConfig config;
  config.controller = controller_config(scene, period_s);
  config.safety = scene.safety;
  return config;
}

template <Scalar S>
RuntimeScene<S> make_runtime_scene(const SceneDescription& scene, std::optional<SineMethod> sine) {
  const auto plane = [](const SceneDescription::Plane& p) {
    return Plane<S>{vec_cast<S>(p.point_m), vec_cast<S>(p.normal)};
  };
  RuntimeScene<S> runtime;
  for (const auto& entry : scene.order) {
    if (entry.kind == SceneDescription::Kind::kSurface) {
      const auto& d = scene.surfaces[entry.index];
      typename RuntimeScene<S>::SurfaceEffect::Params p;
      p.plane = plane(d.plane);
      p.wall = {scalar_cast<S>(d.stiffness_n_per_m), scalar_cast<S>(d.damping_n_s_per_m)};
      if (d.friction) {
        p.tangential.kind = AnyTangential<S>::Kind::kFriction;
        p.tangential.friction = {scalar_cast<S>(d.friction->viscous_n_s_per_m), scalar_cast<S>(d.friction->coulomb),
                                 scalar_cast<S>(d.friction->regularization_speed_m_per_s)};
      } else if (d.slippery) {
        p.tangential.kind = AnyTangential<S>::Kind::kSlippery;
        p.tangential.slippery = {scalar_cast<S>(d.slippery->mu_n_s_per_m),
                                 scalar_cast<S>(d.slippery->max_tangential_force_n)};
      }
      if (d.impact) {
        const auto& i = *d.impact;
        p.impact.enabled = true;
        p.impact.law = {scalar_cast<S>(i.recoil_gain_n_per_m), scalar_cast<S>(i.oscillation_gain_n_per_m),
                        scalar_cast<S>(i.duration_s), scalar_cast<S>(i.frequency_hz),
                        scalar_cast<S>(i.min_impact_speed_m_per_s), scalar_cast<S>(i.rearm_distance_m),
                        sine.value_or(i.sine.value_or(default_sine_method<S>()))};
        if (!sine_method_available<S>(p.impact.law.sine)) p.impact.law.sine = default_sine_method<S>();
      }
      static_cast<void>(runtime.add_surface(p));  // capacity was checked at load
    } else {
      const auto& d = scene.cliffs[entry.index];
      typename RuntimeScene<S>::CliffEffect::Params p;
      p.ground = plane(d.ground);
      p.axis = vec_cast<S>(d.axis);
      p.gap_min_m = scalar_cast<S>(d.gap_min_m);
      p.gap_max_m = scalar_cast<S>(d.gap_max_m);
      p.wall = {scalar_cast<S>(d.stiffness_n_per_m), scalar_cast<S>(d.damping_n_s_per_m)};
      p.speed_threshold_m_per_s = scalar_cast<S>(d.speed_threshold_m_per_s);
      p.tau_s = scalar_cast<S>(d.tau_s);
      p.rearm_height_m = scalar_cast<S>(d.rearm_height_m);
      p.fall_force_n = scalar_cast<S>(d.fall_force_n);
      static_cast<void>(runtime.add_cliff(p));
    }
  }
  return runtime;
}

template RuntimeScene<double> make_runtime_scene<double>(const SceneDescription&, std::optional<SineMethod>);
template RuntimeScene<float> make_runtime_scene<float>(const SceneDescription&, std::optional<SineMethod>);
template RuntimeScene<Q16_16> make_runtime_scene<Q16_16>(const SceneDescription&, std::optional<SineMethod>);

}  // namespace toonforce
