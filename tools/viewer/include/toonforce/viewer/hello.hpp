// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The first message a page gets (JSON): what it is looking at. The scene (scene_json.hpp: every
/// effect of the file the run loaded, with its parameters), the frame columns (the effects'
/// values among them), the run's rate and source, and the names of the fault, limit and
/// loop-state bits, so the page has no copy of them to go stale. Start-up code only.

#include <optional>
#include <string>

#include <vector>

#include "toonforce/math/vec3.hpp"

namespace toonforce::viewer {

struct HelloInfo {
  std::string source;                      ///< "run", "sim" or "trace"
  std::string title;                       ///< shown in the page's header
  double rate_hz = 0.0;                    ///< servo rate (0: unknown)
  bool live = true;                        ///< frames arrive as the run goes (false: a recording)
  std::string pacing;                      ///< how sim time relates to wall time (sim only), for the page
  std::string scene_json;                  ///< scene_json(); empty: none, the page shows the HIP only
  std::vector<std::string> effect_values;  ///< the names of the frames' effect value columns
  /// A world (world_view.hpp): its columns (WorldViewMap::columns, instead of the one-device
  /// frame's) and world_json(); empty for one device.
  std::vector<std::string> world_columns;
  std::string world_json;
  std::optional<Vec3<double>> workspace_min_m, workspace_max_m;  ///< the device's, if known
};

std::string make_hello(const HelloInfo& info);

}  // namespace toonforce::viewer
