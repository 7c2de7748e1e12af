// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Where Q16.16 saturates (docs/performance/fixed-point.md): the
/// largest servo rate and scene values the load-time guards accept, found by asking the guards
/// themselves (fixed_point::max_rate, and the scene loader by bisection), so the map is what
/// `replay`, `sim`, `run` and `check` enforce. Arithmetic only: nothing is timed or run.

#include <string>

namespace toonforce::report {

/// The map as Markdown tables.
std::string fixed_point_map_markdown();

}  // namespace toonforce::report
