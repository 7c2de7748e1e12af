// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/documents.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "toonforce/control/passivity_bound.hpp"
#include "toonforce/report/paths.hpp"
#include "toonforce/report/process.hpp"
#include "toonforce/report/staged_outputs.hpp"
#include "toonforce/report/template.hpp"
#include "toonforce/report/templates.hpp"

namespace toonforce::report {

namespace fs = std::filesystem;

std::string merge_generated(const std::string& existing, const std::string& generated, std::string_view begin_marker,
                            std::string_view end_marker) {
  const std::string begin(begin_marker);
  const std::string end(end_marker);
  const std::string block =
      begin + "\n" + generated + (generated.empty() || generated.back() == '\n' ? "" : "\n") + end;
  const auto b = existing.find(begin);
  const auto e = b == std::string::npos ? std::string::npos : existing.find(end, b);
  if (b == std::string::npos || e == std::string::npos) {
    std::string out = existing;
    if (!out.empty() && out.back() != '\n') out += '\n';
    if (!out.empty()) out += '\n';
    return out + block + "\n";
  }
  return existing.substr(0, b) + block + existing.substr(e + end.size());
}

std::string adopt_earlier_markers(std::string text, std::string_view begin_marker, std::string_view end_marker) {
  // The earlier spelling: the marker without the program's "-lab".
  const auto earlier = [](std::string_view marker) {
    std::string m(marker);
    if (const auto at = m.find("-lab "); at != std::string::npos) m.erase(at, 4);
    return m;
  };
  const std::string old_begin = earlier(begin_marker);
  const std::string old_end = earlier(end_marker);
  if (old_begin == begin_marker || text.find(begin_marker) != std::string::npos) return text;
  const auto b = text.find(old_begin);
  if (b == std::string::npos) return text;
  const auto e = text.find(old_end, b);
  if (e == std::string::npos) return text;
  // The end first, so that the begin's position still holds.
  text.replace(e, old_end.size(), end_marker);
  text.replace(b, old_begin.size(), begin_marker);
  return text;
}

namespace {

Result<std::string> read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::string();
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// Plots `kind` (tools/plot_report.py) from `csv` (a staged path) into `target`, staged with
/// the step's other outputs.
Result<bool> plot(StagedOutputs& outputs, const std::string& kind, const fs::path& csv, const fs::path& target,
                  const std::vector<std::string>& options = {}) {
  auto staged = outputs.stage(target);
  if (!staged) return Error{staged.error()};
  std::vector<std::string> argv{"/usr/bin/python3", plot_report_script(), kind, csv.string(), staged->string()};
  argv.insert(argv.end(), options.begin(), options.end());
  auto status = run_process(argv);
  if (!status) return Error{fmt::format("plot: {} (install python3-matplotlib: tools/setup-deps)", status.error())};
  if (status.value() != 0)
    return Error{fmt::format("plot: `{}` failed with status {}", shell_line(argv), status.value())};
  return true;
}

Result<std::string> stability_document(const StabilityReport& s, const std::string& command,
                                       const std::string& plot_dir) {
  // Where the delay-aware bound is exact and where it only bounds: against
  // Colgate and Schenkel's b_req of the same discrete law, computed here.
  SampledLoop delayed_damped_wall;
  delayed_damped_wall.delay_ticks = 1;
  delayed_damped_wall.stiffness_n_per_m = 1000.0;
  delayed_damped_wall.velocity_feedback_n_s_per_m = -0.2;  // a wall damping B = 0.2 N s/m
  return render(templates::stability_md,
                {{"command", command},
                 {"b_req_delayed_damped_wall", fmt::format("{:.2f}", required_damping_n_s_per_m(delayed_damped_wall))},
                 {"bound_delayed_damped_wall", fmt::format("{:.2f}", damping_needed_n_s_per_m(1000.0, 1e-3, 1, 0.2))},
                 {"stability_tables", stability_markdown(s, plot_dir)}});
}

Result<std::string> performance_section(const LatencyReport& latency, const std::string& command) {
  return render(templates::performance_latency_md,
                {{"command", command},
                 {"ticks_option", latency.ticks == 10'000'000 ? "" : fmt::format(" --ticks {}", latency.ticks)},
                 {"latency_tables", latency_markdown(latency)},
                 {"ticks", fmt::format("{}", latency.ticks)}});
}

Result<std::string> precision_section(const PrecisionReport& precision, const std::string& command,
                                      const std::string& plot_dir) {
  // The command that made these figures (report precision --docs passes its own line), and
  // the default one.
  const bool own = command.rfind("toonforce-lab report precision", 0) == 0;
  return render(templates::performance_precision_md,
                {{"command", command},
                 {"precision_command",
                  own ? command
                      : fmt::format("toonforce-lab report precision --docs docs{}",
                                    precision.options.drift_hours == PrecisionOptions{}.drift_hours
                                        ? ""
                                        : fmt::format(" --drift-hours {:g}", precision.options.drift_hours))},
                 {"precision_tables", precision_markdown(precision, plot_dir)}});
}

}  // namespace

Result<std::vector<std::string>> write_stability_documents(const DocumentsOptions& options, const Progress& progress) {
  const fs::path out = options.out_dir;
  const fs::path figures = out / "report";
  std::error_code ec;
  fs::create_directories(figures, ec);
  if (ec) return Error{fmt::format("cannot create {}: {}", figures.string(), ec.message())};
  const std::string plot_dir = "report";  // relative to the documents
  auto stability = run_stability(options.stability, progress);
  if (!stability) return Error{stability.error()};
  StagedOutputs outputs;
  for (const auto& map : stability->maps) {
    auto csv = outputs.write(figures / (map.name + ".csv"), stability_csv(map));
    if (!csv) return Error{csv.error()};
    if (options.plot) {
      std::vector<std::string> args{"--title", map.title, "--xlabel", map.x_label, "--ylabel", map.y_label};
      if (!map.log_x) args.emplace_back("--linear-x");
      if (!map.log_y) args.emplace_back("--linear-y");
      if (auto p = plot(outputs, "stability", csv.value(), figures / (map.name + ".png"), args); !p)
        return Error{p.error()};
    }
  }
  const fs::path stability_md = out / "STABILITY.md";
  auto document = stability_document(stability.value(), options.command_line, plot_dir);
  if (!document) return Error{document.error()};
  if (auto w = outputs.write(stability_md, document.value()); !w) return Error{w.error()};
  return outputs.commit();
}

Result<std::vector<std::string>> write_documents(const DocumentsOptions& options, const Progress& progress) {
  std::vector<std::string> written;
  const fs::path out = options.out_dir;
  const fs::path figures = out / "report";
  std::error_code ec;
  fs::create_directories(figures, ec);
  if (ec) return Error{fmt::format("cannot create {}: {}", figures.string(), ec.message())};
  const std::string plot_dir = "report";  // relative to the documents

  LatencyOptions latency_options = options.latency;
  latency_options.root = options.root;
  auto latency = run_latency(latency_options, progress);
  if (!latency) return Error{latency.error()};

  PrecisionOptions precision_options = options.precision;
  precision_options.root = options.root;
  auto precision = run_precision(precision_options, progress);
  if (!precision) return Error{precision.error()};

  const fs::path performance = out / kLatencyDocument;
  fs::create_directories(performance.parent_path(), ec);
  if (ec) return Error{fmt::format("cannot create {}: {}", performance.parent_path().string(), ec.message())};
  auto existing = read_file(performance);
  if (!existing) return Error{existing.error()};
  std::string text = adopt_earlier_markers(existing.value(), kBeginMarker, kEndMarker);
  if (text.empty()) text = templates::performance_head_md.text;
  const auto section = performance_section(latency.value(), options.command_line);
  if (!section) return Error{section.error()};
  {
    StagedOutputs outputs;
    if (auto w = outputs.write(performance, merge_generated(text, section.value())); !w) return Error{w.error()};
    if (auto c = outputs.commit(); !c) return Error{c.error()};
  }
  written.push_back(performance.string());
  auto precision_written =
      write_precision_documents(precision.value(), options.out_dir, options.command_line, options.plot);
  if (!precision_written) return Error{precision_written.error()};
  written.insert(written.end(), precision_written->begin(), precision_written->end());

  auto stability = write_stability_documents(options, progress);
  if (!stability) return Error{stability.error()};
  written.insert(written.end(), stability->begin(), stability->end());
  return written;
}

Result<std::vector<std::string>> write_latency_documents(const LatencyReport& latency, const std::string& out_dir,
                                                         const std::string& command_line) {
  const fs::path performance = fs::path(out_dir) / kLatencyDocument;
  std::error_code ec;
  fs::create_directories(performance.parent_path(), ec);
  if (ec) return Error{fmt::format("cannot create {}: {}", performance.parent_path().string(), ec.message())};
  auto existing = read_file(performance);
  if (!existing) return Error{existing.error()};
  std::string text = adopt_earlier_markers(existing.value(), kBeginMarker, kEndMarker);
  if (text.empty()) text = templates::performance_head_md.text;
  const auto section = performance_section(latency, command_line);
  if (!section) return Error{section.error()};
  StagedOutputs outputs;
  if (auto w = outputs.write(performance, merge_generated(text, section.value())); !w) return Error{w.error()};
  return outputs.commit();
}

Result<std::vector<std::string>> write_precision_documents(const PrecisionReport& precision, const std::string& out_dir,
                                                           const std::string& command_line, bool with_plots) {
  const fs::path out = out_dir;
  const fs::path figures = out / "report";
  std::error_code ec;
  fs::create_directories(figures, ec);
  if (ec) return Error{fmt::format("cannot create {}: {}", figures.string(), ec.message())};
  StagedOutputs outputs;
  const fs::path precision_csv_path = figures / "precision.csv";
  const fs::path drift_csv_path = figures / "drift.csv";
  const fs::path convergence_csv_path = figures / "convergence.csv";
  const fs::path closed_loop_csv_path = figures / "closed_loop.csv";
  std::vector<fs::path> staged;
  for (const auto& [path, text] :
       {std::pair{precision_csv_path, precision_csv(precision)}, std::pair{drift_csv_path, drift_csv(precision)},
        std::pair{convergence_csv_path, convergence_csv(precision)},
        std::pair{closed_loop_csv_path, closed_loop_csv(precision)}}) {
    auto w = outputs.write(path, text);
    if (!w) return Error{w.error()};
    staged.push_back(w.value());
  }
  if (with_plots) {
    if (auto p = plot(outputs, "work-precision", staged[0], figures / "work_precision.png"); !p)
      return Error{p.error()};
    if (!precision.drift.empty()) {
      if (auto p = plot(outputs, "drift", staged[1], figures / "drift.png"); !p) return Error{p.error()};
    }
    if (!precision.closed_loop.empty()) {
      if (auto p = plot(outputs, "closed-loop", staged[3], figures / "closed_loop.png"); !p) return Error{p.error()};
    }
  }
  const fs::path performance = out / kPrecisionDocument;
  fs::create_directories(performance.parent_path(), ec);
  if (ec) return Error{fmt::format("cannot create {}: {}", performance.parent_path().string(), ec.message())};
  auto existing = read_file(performance);
  if (!existing) return Error{existing.error()};
  // Its own markers, and the main block's, after whose end a first precision block goes.
  std::string text = adopt_earlier_markers(
      adopt_earlier_markers(existing.value(), kPrecisionBeginMarker, kPrecisionEndMarker), kBeginMarker, kEndMarker);
  // The plots are in <out>/report/, one level up from the page.
  const auto rendered = precision_section(precision, command_line, "../report");
  if (!rendered) return Error{rendered.error()};
  const std::string& section = rendered.value();
  if (text.find(kPrecisionBeginMarker) == std::string::npos) {
    // First time: the block goes right after the main generated block (or at the end).
    const auto e = text.find(kEndMarker);
    const std::string block =
        std::string(kPrecisionBeginMarker) + "\n" + section + std::string(kPrecisionEndMarker) + "\n";
    if (e == std::string::npos) {
      text = merge_generated(text, section, kPrecisionBeginMarker, kPrecisionEndMarker);
    } else {
      const std::size_t at = e + kEndMarker.size();
      text = text.substr(0, at) + "\n\n" + block + text.substr(at + (at < text.size() && text[at] == '\n' ? 1 : 0));
    }
  } else {
    text = merge_generated(text, section, kPrecisionBeginMarker, kPrecisionEndMarker);
  }
  if (auto w = outputs.write(performance, text); !w) return Error{w.error()};
  return outputs.commit();
}

Result<std::vector<std::string>> write_mcu_documents(const McuReport& mcu, const std::string& out_dir) {
  const fs::path out = out_dir;
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) return Error{fmt::format("cannot create {}: {}", out.string(), ec.message())};
  const fs::path performance = out / kMcuDocument;
  fs::create_directories(performance.parent_path(), ec);
  if (ec) return Error{fmt::format("cannot create {}: {}", performance.parent_path().string(), ec.message())};
  auto existing = read_file(performance);
  if (!existing) return Error{existing.error()};
  std::string text = adopt_earlier_markers(existing.value(), kMcuBeginMarker, kMcuEndMarker);
  if (text.empty())
    text = templates::performance_head_md.text;  // report all into a new directory starts with this block
  const auto begins = text.find(kMcuBeginMarker);
  // Once each, begin before end: anything else is a hand edit to look at, not to guess about.
  const auto ends = text.find(kMcuEndMarker);
  const bool twice = (begins != std::string::npos && text.find(kMcuBeginMarker, begins + 1) != std::string::npos) ||
                     (ends != std::string::npos && text.find(kMcuEndMarker, ends + 1) != std::string::npos);
  if (twice || (begins == std::string::npos) != (ends == std::string::npos) ||
      (begins != std::string::npos && ends < begins)) {
    return Error{fmt::format("{}: the markers {} and {} must be there once each, in that order, or not at all",
                             performance.string(), kMcuBeginMarker, kMcuEndMarker)};
  }
  if (begins == std::string::npos) {
    if (!text.empty() && text.back() != '\n') text += '\n';
    text += (text.empty() ? "" : "\n") + std::string("## Microcontroller\n");
  }
  StagedOutputs outputs;
  if (auto w = outputs.write(performance, merge_generated(text, mcu_markdown(mcu), kMcuBeginMarker, kMcuEndMarker));
      !w) {
    return Error{w.error()};
  }
  return outputs.commit();
}

}  // namespace toonforce::report
