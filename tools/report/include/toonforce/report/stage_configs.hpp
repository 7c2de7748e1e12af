// SPDX-License-Identifier: Apache-2.0
// The servo settings the figures run the whole loop with (header-only: `toonforce-lab report`'s
// workloads and the microcontroller images' generator, tools/mcu/host/mcu_gen.cpp, take the
// same numbers from here).
#pragma once

#include "toonforce/config/scene_file.hpp"

namespace toonforce::report {

/// The scene file's settings with every stage of the loop on: the clamp and the rate limit
/// (the file's values, else 8 N and 2000 N/s), a +-60 mm workspace, the velocity limit, a
/// thermal model at half the clamp and the passivity controller.
inline ServoConfig every_stage_config(const SceneDescription& desc, double rate_hz) {
  ServoConfig c = servo_config(desc, 1.0 / rate_hz);
  c.limits.has_max_force = true;
  c.limits.max_force_n = desc.limits.has_max_force ? desc.limits.max_force_n : 8.0;
  c.limits.has_max_force_rate = true;
  c.limits.max_force_rate_n_per_s = desc.limits.has_max_force_rate ? desc.limits.max_force_rate_n_per_s : 2000.0;
  c.safety.has_workspace = true;
  c.safety.workspace_min_m = {-0.06, -0.06, -0.06};
  c.safety.workspace_max_m = {0.06, 0.06, 0.06};
  c.safety.has_max_velocity = true;
  c.safety.thermal.continuous_force_n = 0.5 * c.limits.max_force_n;
  c.safety.passivity.controller = true;
  return c;
}

/// every_stage_config, tuned so that every stage's expensive branch is reachable within a
/// strike of a search (workloads.cpp, search_path) and within the scripted motions: a 0.1 s
/// soft start, a thermal model at half the clamp with a 50 ms time constant (derates within
/// a strike of hard contact), a passivity budget of 0.1 mJ (the active effects exceed it
/// within a few ticks of contact, so the controller damps).
inline ServoConfig search_config(const SceneDescription& desc, double rate_hz) {
  ServoConfig c = every_stage_config(desc, rate_hz);
  c.safety.soft_start_s = 0.1;
  c.safety.thermal.time_constant_s = 0.05;
  c.safety.passivity.budget_j = 1e-4;
  return c;
}

}  // namespace toonforce::report
