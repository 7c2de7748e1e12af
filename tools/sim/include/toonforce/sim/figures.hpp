// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce figures` (interfaces.md): the paper's figures regenerated on the host simulation
/// from committed scenes and hand scripts, each as NAME.csv (the sim trace) and NAME.png:
///   fig1_realistic, fig1_slippery   a stroke across realistic friction / the super-slippery
///                                   surface (paper §4.1, figure 1)
///   fig3_wall, fig3_cartoon_wall    a strike on a penalty wall / the cartoon wall (§4.2,
///                                   figures 2-3)
///   fig4_fast, fig4_slow            crossing the cartoon cliff fast / slowing down over it
///                                   (§4.3, figure 4)
/// Surfaces are horizontal (normal +z, ground at z = 0); strokes and crossings go along +x.
/// All run on the Falcon-class device at 1 kHz with RK4 and 4 sub-steps, seed 1.

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/sim/sim_run.hpp"

namespace toonforce {

struct FigureSpec {
  std::string_view name;
  std::string_view scene;   ///< relative to the data root
  std::string_view script;  ///< relative to the data root
  double duration_s;
  std::string_view plot_kind;
  std::string_view title;
};

std::span<const FigureSpec> figure_specs() noexcept;

/// The directory holding scenes/ (the current one if it has scenes/hands, else the installed
/// data of an installed binary (data_dir.hpp), else the source tree this binary was built
/// from), or `given` if not empty.
std::string figures_root(const std::string& given = {});

/// The options `toonforce sim` would need to produce a figure's trace.
SimOptions figure_sim_options(const FigureSpec& spec, const std::string& root);

/// One figure's scenario, tick by tick (tests assert on it).
struct FigureRun {
  std::vector<SimRecord> records;
  std::vector<std::string> value_names;  ///< of SimRecord::frame.values
  SceneDescription scene;
  /// A record's value by name (value_of).
  double value(std::size_t tick, std::string_view name) const noexcept {
    return value_of(records[tick], value_names, name);
  }
};

/// Runs one figure's scenario and returns every tick's record.
Result<FigureRun> run_figure(const FigureSpec& spec, const std::string& root);

struct FiguresOptions {
  std::string out_dir = "docs/figures";
  std::string root;            ///< empty: figures_root()
  std::string format = "png";  ///< png or svg
  bool plot = true;
};

/// Writes every figure's trace and plot into out_dir; returns a line saying where the scenes came
/// from, then one summary line per figure.
Result<std::vector<std::string>> run_figures(const FiguresOptions& options);

}  // namespace toonforce
