#include "toonforce/config/scene_file.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "toonforce/config/scene_reader.hpp"

namespace toonforce {

namespace {

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

void read_device(const toml::table& table, ErrorList& errors, ScalarKind scalar, SceneSettings& scene) {
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

}  // namespace

namespace scene_reader {

void read_settings(TableReader& root, SceneSettings& settings) {
  if (auto name = root.optional_string("name")) settings.name = std::move(*name);
  if (const toml::table* device = root.optional_table("device")) {
    read_device(*device, root.errors(), root.scalar(), settings);
  }
}

void check_scene(const std::vector<SceneEntry>&, std::size_t values, const std::string& file, ErrorList& errors) {
  if (values > kMaxEffectValues) {
    errors.add(1, "", fmt::format("{}: its effects show {} values, more than the {} a telemetry frame carries; "
                                  "split the scene", file, values, kMaxEffectValues));
  }
}

}  // namespace scene_reader

Result<SceneDescription> load_scene_file(const std::string& path, ScalarKind scalar) {
  return read_scene_file<RuntimeSurface, CartoonCliff>(path, scalar);
}

Result<SceneDescription> parse_scene(std::string_view text, std::string_view source_name, ScalarKind scalar) {
  return read_scene<RuntimeSurface, CartoonCliff>(text, source_name, scalar);
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
