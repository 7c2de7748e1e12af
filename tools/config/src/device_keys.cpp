// SPDX-License-Identifier: Apache-2.0
#include "toonforce/config/device_keys.hpp"

#include <array>

#include <fmt/format.h>

#include "toonforce/config/scene_file.hpp"

namespace toonforce {

namespace {

using T = DeviceKeyType;

// The [device] keys (interfaces.md "[device] keys", effects.md §6 for what each stage does),
// in the order they are read. The defaults are SceneSettings{}'s.
constexpr std::array kDeviceKeys{
    DeviceKey{.key = "max_force",
              .unit = "N",
              .range = Range::kPositive,
              .default_text = "none: the device's nominal maximum",
              .doc = "the clamp: the force is at most the smaller of this and the device's nominal maximum",
              .number = [](SceneSettings& s) { return &s.limits.max_force_n; },
              .present = [](SceneSettings& s) { return &s.limits.has_max_force; }},
    DeviceKey{.key = "max_force_rate",
              .unit = "N/s",
              .range = Range::kPositive,
              .default_text = "none",
              .doc = "the force-rate limit: the commanded force changes by at most this per second",
              .number = [](SceneSettings& s) { return &s.limits.max_force_rate_n_per_s; },
              .present = [](SceneSettings& s) { return &s.limits.has_max_force_rate; }},
    DeviceKey{.key = "velocity_cutoff",
              .unit = "Hz",
              .range = Range::kPositive,
              .doc = "cut-off of the velocity estimator (effects.md §0)",
              .number = [](SceneSettings& s) { return &s.velocity_cutoff_hz; }},
    DeviceKey{.key = "engage_force",
              .unit = "N",
              .range = Range::kPositive,
              .doc = "forces come on (after start, enable, re-arm) only once the scene force here is below this",
              .number = [](SceneSettings& s) { return &s.safety.engage_force_n; }},
    DeviceKey{.key = "soft_start",
              .unit = "s",
              .range = Range::kNonNegative,
              .doc = "linear ramp from 0 after engaging and after every fault; 0 = none",
              .number = [](SceneSettings& s) { return &s.safety.soft_start_s; }},
    DeviceKey{.key = "max_velocity",
              .unit = "m/s",
              .range = Range::kPositive,
              .doc = "force off above this HIP speed",
              .number = [](SceneSettings& s) { return &s.safety.max_velocity_m_per_s; }},
    DeviceKey{.key = "workspace_min",
              .type = T::kBox,
              .unit = "m",
              .upper_key = "workspace_max",
              .default_text = "the device's workspace",
              .doc = "force off outside this box",
              .present = [](SceneSettings& s) { return &s.safety.has_workspace; },
              .lower = [](SceneSettings& s) { return &s.safety.workspace_min_m; },
              .upper = [](SceneSettings& s) { return &s.safety.workspace_max_m; }},
    DeviceKey{.key = "watchdog_periods",
              .type = T::kWholeNumber,
              .min_whole = 1,
              .doc = "a gap of more periods between ticks latches a fault (and the heartbeat watchdog "
                     "zeroes the force)",
              .whole = [](SceneSettings& s) { return &s.safety.watchdog_periods; }},
    DeviceKey{.key = "device_timeout_periods",
              .type = T::kWholeNumber,
              .min_whole = 1,
              .doc = "failed device exchanges in a row that latch a fault",
              .whole = [](SceneSettings& s) { return &s.safety.device_timeout_periods; }},
    DeviceKey{.key = "continuous_force",
              .unit = "N",
              .range = Range::kPositive,
              .default_text = "the device's continuous force (no thermal model when neither says)",
              .doc = "the force the motors bear indefinitely: the thermal derating's floor",
              .number = [](SceneSettings& s) { return &s.safety.thermal.continuous_force_n; }},
    DeviceKey{.key = "thermal_time_constant",
              .unit = "s",
              .range = Range::kPositive,
              .doc = "time constant of the first-order motor thermal model",
              .number = [](SceneSettings& s) { return &s.safety.thermal.time_constant_s; }},
    DeviceKey{.key = "thermal_derate_start",
              .range = Range::kNonNegative,
              .below = 1.0,
              .has_below = true,
              .below_why = "1 is the rated temperature",
              .doc = "predicted temperature (1 = rated) where the clamp starts derating toward continuous_force",
              .number = [](SceneSettings& s) { return &s.safety.thermal.derate_start; }},
    DeviceKey{.key = "passivity_controller",
              .type = T::kFlag,
              .doc = "damp the energy the active effects (slippery surface, impact transient) inject beyond "
                     "their budget",
              .flag = [](SceneSettings& s) { return &s.safety.passivity.controller; }},
    DeviceKey{.key = "passivity_budget",
              .unit = "J",
              .range = Range::kPositive,
              .doc = "the energy budget per active effect and contact or transient",
              .number = [](SceneSettings& s) { return &s.safety.passivity.budget_j; }},
    DeviceKey{.key = "passivity_max_damping",
              .unit = "N s/m",
              .range = Range::kPositive,
              .doc = "the passivity controller's largest damping",
              .number = [](SceneSettings& s) { return &s.safety.passivity.max_damping_n_s_per_m; }},
};

void read_number(TableReader& r, const DeviceKey& k, SceneSettings& s) {
  const auto v = r.optional_number(k.key, k.range);
  if (!v) return;
  if (k.has_below && *v >= k.below) {
    r.error(k.key, fmt::format("must be below {} (got {}): {}", k.below, *v, k.below_why));
    return;
  }
  *k.number(s) = *v;
  if (k.present != nullptr) *k.present(s) = true;
}

void read_box(TableReader& r, const DeviceKey& k, SceneSettings& s) {
  const std::string unit = fmt::format("[{}]", k.unit);
  const auto lo = r.optional_vec3(k.key, unit);
  const auto hi = r.optional_vec3(k.upper_key, unit);
  if (lo.has_value() != hi.has_value()) {
    r.error(lo ? k.key : k.upper_key, fmt::format("needs {} and {} together", k.key, k.upper_key));
  } else if (lo && hi) {
    if (!(lo->x < hi->x && lo->y < hi->y && lo->z < hi->z)) {
      r.error(k.upper_key, fmt::format("must be greater than {} on every axis", k.key));
    } else {
      *k.present(s) = true;
      *k.lower(s) = *lo;
      *k.upper(s) = *hi;
    }
  }
}

std::string range_text(const DeviceKey& k) {
  switch (k.type) {
    case T::kWholeNumber: return fmt::format("whole number >= {}", k.min_whole);
    case T::kFlag: return "true or false";
    case T::kBox: return "[x, y, z] each; both or neither; min < max on every axis";
    case T::kNumber: break;
  }
  if (k.has_below) {
    switch (k.range) {
      case Range::kPositive: return fmt::format("in (0, {})", k.below);
      case Range::kNonNegative: return fmt::format("in [0, {})", k.below);
      case Range::kNonPositive:
      case Range::kAny: return fmt::format("< {}", k.below);
    }
  }
  switch (k.range) {
    case Range::kPositive: return "> 0";
    case Range::kNonNegative: return ">= 0";
    case Range::kNonPositive: return "<= 0";
    case Range::kAny: break;
  }
  return "any number";
}

std::string default_text(const DeviceKey& k) {
  SceneSettings defaults;
  if (k.present != nullptr && !*k.present(defaults)) return std::string(k.default_text);
  switch (k.type) {
    case T::kNumber:
      if (*k.number(defaults) == 0.0 && !k.default_text.empty()) return std::string(k.default_text);
      return fmt::format("{}", *k.number(defaults));
    case T::kWholeNumber: return fmt::format("{}", *k.whole(defaults));
    case T::kFlag: return *k.flag(defaults) ? "true" : "false";
    case T::kBox: break;
  }
  return std::string(k.default_text);
}

}  // namespace

std::span<const DeviceKey> device_keys() noexcept { return kDeviceKeys; }

void read_device_keys(TableReader& r, SceneSettings& s) {
  for (const DeviceKey& k : kDeviceKeys) {
    switch (k.type) {
      case T::kNumber: read_number(r, k, s); break;
      case T::kWholeNumber: *k.whole(s) = r.optional_integer(k.key, k.min_whole).value_or(*k.whole(s)); break;
      case T::kFlag: *k.flag(s) = r.optional_bool(k.key).value_or(*k.flag(s)); break;
      case T::kBox: read_box(r, k, s); break;
    }
  }
}

std::string device_keys_markdown() {
  std::string out = "| key | value | unit | default | what it does |\n| --- | --- | --- | --- | --- |\n";
  for (const DeviceKey& k : kDeviceKeys) {
    const std::string key =
        k.type == T::kBox ? fmt::format("`{}`, `{}`", k.key, k.upper_key) : fmt::format("`{}`", k.key);
    out += fmt::format("| {} | {} | {} | {} | {} |\n", key, range_text(k), k.unit.empty() ? "-" : k.unit,
                       default_text(k), k.doc);
  }
  return out;
}

}  // namespace toonforce
