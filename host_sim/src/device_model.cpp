// SPDX-License-Identifier: Apache-2.0
#include "toonforce/host_sim/device_model.hpp"

namespace toonforce::host_sim {

std::string_view device_preset_name(DevicePreset preset) noexcept {
  switch (preset) {
    case DevicePreset::kFalcon: return "falcon";
    case DevicePreset::kOmni: return "omni";
  }
  return "?";
}

std::optional<DevicePreset> parse_device_preset(std::string_view name) noexcept {
  if (name == "falcon") return DevicePreset::kFalcon;
  if (name == "omni") return DevicePreset::kOmni;
  return std::nullopt;
}

// The reasoning behind each value is in the header, next to the declaration.
DeviceParams falcon_params() noexcept {
  DeviceParams p;
  p.name = "simulated Novint Falcon";
  p.mass_kg = 0.15;
  p.damping_n_s_per_m = 0.1;
  p.coulomb_n = 0.2;
  p.max_force_n = 8.0;
  p.encoder_step_m = 20e-6;
  p.force_step_n = 8.0 / 4095.0;
  p.io_delay_ticks = 1;
  p.nominal_rate_hz = 1000.0;
  p.workspace_min_m = {-0.05, -0.05, -0.05};
  p.workspace_max_m = {0.05, 0.05, 0.05};
  return p;
}

DeviceParams omni_params() noexcept {
  DeviceParams p;
  p.name = "simulated Phantom Omni";
  p.mass_kg = 0.045;
  p.damping_n_s_per_m = 0.05;
  p.coulomb_n = 0.26;
  p.max_force_n = 3.3;
  p.encoder_step_m = 2.0 * 3.14159265358979323846 * 0.13335 / 15000.0;
  p.force_step_n = 3.3 / 2047.0;
  p.io_delay_ticks = 1;
  p.nominal_rate_hz = 1000.0;
  p.workspace_min_m = {-0.08, -0.035, -0.06};
  p.workspace_max_m = {0.08, 0.035, 0.06};
  return p;
}

DeviceParams device_params(DevicePreset preset) noexcept {
  return preset == DevicePreset::kOmni ? omni_params() : falcon_params();
}

}  // namespace toonforce::host_sim
