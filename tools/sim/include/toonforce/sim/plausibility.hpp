// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The plausibility report: a scene's numbers against what the chosen device
/// can do, before anything runs. `toonforce check` prints it whole; `run` and `sim` print its
/// warnings at the start, and refuse to start on one under `--strict`.
///
/// The stability bound is the one the stability maps draw (control/passivity_bound.hpp: b >
/// (1 + 2 d) K T / 2 + |B|, with the device model's damping b and I/O delay d), twice: on the
/// device alone (a handle let go) and held by a hand of the hand scripts' default damping (8 N
/// s/m, host_sim/hand_script.hpp, Tsuji et al. 1995). Over the first, a wall or a slippery
/// surface relies on the hand and on the passivity controller: a note while that controller is
/// on, a warning when it is off. Over the second it is a warning whatever: it can buzz even in a
/// firm hand. The device's force and workspace limits come from the same device model
/// (host_sim/device_model.hpp), the one `sim` simulates and `run` uses for the device class.

#include <string>
#include <vector>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/host_sim/device_model.hpp"

namespace toonforce {

/// The hand damping the "held" bound assumes [N s/m]: the hand scripts' default.
inline constexpr double kHeldHandDampingNsPerM = 8.0;

struct PlausibilityReport {
  std::vector<std::string> notes;     ///< what the scene's numbers are compared with, and findings within limits
  std::vector<std::string> warnings;  ///< outside the device's limits, each with its numbers
};

/// `scene` (loaded from `scene_path`) on `device` at `rate_hz`.
PlausibilityReport check_plausibility(const SceneDescription& scene, const std::string& scene_path,
                                      const host_sim::DeviceParams& device, double rate_hz);

}  // namespace toonforce
