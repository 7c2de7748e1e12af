// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/figures.hpp"

#include <array>
#include <filesystem>

#include <fmt/format.h>

#include "toonforce/sim/data_dir.hpp"

namespace toonforce {

namespace {

// The scenes are the bundled Falcon-class ones; the hand scripts were written for the figures
// (each says why its speeds and forces). Durations leave time to see the aftermath.
constexpr std::array<FigureSpec, 6> kFigures{{
    {"fig1_realistic", "scenes/realistic_friction.toml", "scenes/hands/stroke.toml", 1.6, "stroke",
     "Figure 1 (left): a stroke across realistic friction slows the hand down"},
    {"fig1_slippery", "scenes/slippery.toml", "scenes/hands/stroke.toml", 1.6, "stroke",
     "Figure 1 (right): on the super-slippery surface the stroke speeds up"},
    {"fig3_wall", "scenes/wall.toml", "scenes/hands/strike.toml", 1.0, "wall",
     "Figure 3 (top): striking a penalty wall"},
    {"fig3_cartoon_wall", "scenes/cartoon_wall.toml", "scenes/hands/strike.toml", 1.0, "wall",
     "Figure 3 (bottom): the cartoon wall throws the stylus back and shakes it"},
    {"fig4_fast", "scenes/cliff.toml", "scenes/hands/cross_fast.toml", 1.3, "cliff",
     "Figure 4 (bottom): crossing the gap decisively, the ground holds"},
    {"fig4_slow", "scenes/cliff.toml", "scenes/hands/cross_slow.toml", 1.4, "cliff",
     "Figure 4 (top): slowing down over the gap, the character falls"},
}};

}  // namespace

std::span<const FigureSpec> figure_specs() noexcept { return kFigures; }

std::string figures_root(const std::string& given) {
  if (!given.empty()) return given;
  std::error_code ec;
  if (std::filesystem::is_directory("scenes/hands", ec)) return ".";
  if (const std::string installed = installed_data_dir();
      !installed.empty() && std::filesystem::is_directory(std::filesystem::path(installed) / "scenes/hands", ec)) {
    return installed;
  }
  return build_source_dir();
}

SimOptions figure_sim_options(const FigureSpec& spec, const std::string& root) {
  SimOptions options;
  options.scene_path = (std::filesystem::path(root) / spec.scene).string();
  options.script_path = (std::filesystem::path(root) / spec.script).string();
  options.duration_s = spec.duration_s;
  options.device = host_sim::DevicePreset::kFalcon;
  options.integrator = host_sim::Integrator::kRk4;
  options.substeps = 4;
  options.rate_hz = 1000.0;
  options.seed = 1;
  options.plot_kind = std::string(spec.plot_kind);
  options.plot_title = std::string(spec.title);
  return options;
}

Result<FigureRun> run_figure(const FigureSpec& spec, const std::string& root) {
  const SimOptions options = figure_sim_options(spec, root);
  auto scene = load_scene_file(options.scene_path, options.scalar);
  if (!scene) return Error{scene.error()};
  auto hand = load_hand_script(options.script_path);
  if (!hand) return Error{hand.error()};
  auto session = SimSession::create(scene.value(), hand.value(), sim_config(options));
  if (!session) return Error{session.error()};
  const std::int64_t ticks = session->ticks_for(spec.duration_s);
  FigureRun run;
  run.value_names = session->value_names();
  run.scene = std::move(scene).value();
  run.records.reserve(static_cast<std::size_t>(ticks));
  for (std::int64_t k = 0; k < ticks; ++k) run.records.push_back(session->step());
  return run;
}

Result<std::vector<std::string>> run_figures(const FiguresOptions& options) {
  if (options.format != "png" && options.format != "svg") {
    return Error{fmt::format("--format must be png or svg (got '{}')", options.format)};
  }
  const std::string root = figures_root(options.root);
  std::error_code ec;
  std::filesystem::create_directories(options.out_dir, ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory: {}", options.out_dir, ec.message())};
  std::vector<std::string> lines;
  lines.push_back(fmt::format("scenes and hand scripts from {}", root));
  for (const FigureSpec& spec : kFigures) {
    SimOptions sim = figure_sim_options(spec, root);
    const std::filesystem::path out(options.out_dir);
    sim.trace_path = (out / fmt::format("{}.csv", spec.name)).string();
    if (options.plot) sim.plot_path = (out / fmt::format("{}.{}", spec.name, options.format)).string();
    auto summary = run_sim(sim);
    if (!summary) return Error{fmt::format("{}: {}", spec.name, summary.error())};
    lines.push_back(fmt::format("{:<18} {} ticks, peak force {:.3g} N, contact {} ticks, impacts {}, cliff falls {}"
                                " -> {}{}",
                                spec.name, summary->ticks, summary->peak_force_n, summary->ticks_in_contact,
                                summary->impacts, summary->cliff_falls, sim.trace_path,
                                options.plot ? fmt::format(", {}", sim.plot_path) : std::string()));
  }
  return lines;
}

}  // namespace toonforce
