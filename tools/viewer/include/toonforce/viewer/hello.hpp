#pragma once
/// The first message a page gets (JSON): what it is looking at. The scene's geometry (surfaces,
/// cliffs with their gaps, from the scene file the run loaded), the frame columns, the run's
/// rate and source, and the names of the fault, limit and loop-state bits, so the page has no
/// copy of them to go stale. Start-up code only.

#include <optional>
#include <string>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce::viewer {

struct HelloInfo {
  std::string source;        ///< "run", "sim" or "trace"
  std::string title;         ///< shown in the page's header
  double rate_hz = 0.0;      ///< servo rate (0: unknown)
  bool live = true;          ///< frames arrive as the run goes (false: a recording)
  std::string pacing;        ///< how sim time relates to wall time (sim only), for the page
  const SceneDescription* scene = nullptr;  ///< none: the page shows the HIP only
  std::optional<Vec3<double>> workspace_min_m, workspace_max_m;  ///< the device's, if known
};

std::string make_hello(const HelloInfo& info);

}  // namespace toonforce::viewer
