// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/sim_run.hpp"

#include "toonforce/sim/plausibility.hpp"

#include <signal.h>
#include <string.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>
#include <cmath>
#include <thread>

#include <fmt/format.h>

#include "toonforce/sim/plot.hpp"
#include "toonforce/sim/sim_trace.hpp"
#include "toonforce/control/supervisor.hpp"

namespace toonforce {

void add_to_summary(SimSummary& s, const SimRecord& r, const SummaryColumns& columns) {
  const TelemetryFrame& f = r.frame;
  ++s.ticks;
  const double magnitude = std::sqrt(dot(f.force_n, f.force_n));
  if (magnitude > s.peak_force_n) {
    s.peak_force_n = magnitude;
    s.peak_force_t_s = f.t_s;
  }
  if (f.in_contact) ++s.ticks_in_contact;
  for (const std::size_t i : columns.impact_times) {
    if (i < f.value_count && f.values[i] == 0.0) ++s.impacts;
  }
  s.last_cliff_states.resize(columns.cliff_states.size(), 0.0);
  for (std::size_t c = 0; c < columns.cliff_states.size(); ++c) {
    const std::size_t i = columns.cliff_states[c];
    if (i >= f.value_count) continue;
    if (f.values[i] == 1.0 && s.last_cliff_states[c] == 0.0) ++s.cliff_falls;
    s.last_cliff_states[c] = f.values[i];
  }
  const auto limited = [&f](Limit l) { return (f.limits & static_cast<std::uint8_t>(l)) != 0; };
  if (limited(Limit::kRateLimited)) ++s.rate_limited;
  if (limited(Limit::kClamped)) ++s.clamped;
  if (limited(Limit::kEngaging)) ++s.engaging_ticks;
  if (limited(Limit::kSoftStart)) ++s.soft_start_ticks;
  if (limited(Limit::kPassivity)) ++s.passivity_ticks;
  if (f.faults != 0) ++s.fault_ticks;
  s.fault_bits |= f.faults;
  s.last_state = f.state;
}

SimConfig sim_config(const SimOptions& options) {
  SimConfig config;
  config.device = host_sim::device_params(options.device);
  if (options.sensor_noise_m) config.device.sensor_noise_m = *options.sensor_noise_m;
  config.plant.integrator = options.integrator;
  config.plant.substeps = options.substeps;
  config.plant.period_s = 1.0 / options.rate_hz;
  config.seed = options.seed;
  config.scalar = options.scalar;
  return config;
}

Result<SimSummary> run_sim(const SimOptions& options) {
  if (!(options.rate_hz > 0.0) || !std::isfinite(options.rate_hz)) {
    return Error{fmt::format("--rate must be a positive number of Hz (got {})", options.rate_hz)};
  }
  if (options.duration_s && !(*options.duration_s > 0.0 && std::isfinite(*options.duration_s))) {
    return Error{fmt::format("--duration must be a positive number of seconds (got {})", *options.duration_s)};
  }
  if (options.duration_s && *options.duration_s > kMaxSimDurationS) {
    return Error{fmt::format("--duration {:g}: over the maximum of {:g} s simulated (one day)", *options.duration_s,
                             kMaxSimDurationS)};
  }
  if (options.sine == SineMethod::kLibrary && options.scalar == ScalarKind::kQ16_16) {
    return Error{"--sine library needs a floating-point scalar; use polynomial or table with q16.16"};
  }
  // Outputs, before anything is opened for writing: never one of the inputs, and a plot in a
  // format the plotter writes (refused now, not after the run).
  for (const auto& [output, flag] :
       {std::pair{options.trace_path, "--trace"}, std::pair{options.plot_path, "--plot"}}) {
    for (const auto& [input, what] :
         {std::pair{options.scene_path, "the scene"}, std::pair{options.script_path, "the hand script"}}) {
      std::error_code ec;
      if (!output.empty() && output != "-" && std::filesystem::equivalent(output, input, ec) && !ec) {
        return Error{
            fmt::format("{} {} is {} ({}): it would be overwritten; choose another file", flag, output, what, input)};
      }
    }
  }
  if (!options.plot_path.empty()) {
    const std::string ext = std::filesystem::path(options.plot_path).extension().string();
    if (ext != ".png" && ext != ".svg") {
      return Error{fmt::format("--plot {}: the plot is written as .png or .svg (got '{}')", options.plot_path, ext)};
    }
    if (options.trace_path == "-" || options.trace_path.empty()) {
      return Error{"--plot needs the trace in a file, not on standard output"};
    }
  }
  // A warning goes to standard error, or to the caller's list (the Python module's warnings).
  const auto warn = [&options](std::string message) {
    if (options.warnings == nullptr) {
      // The plausibility report's warnings are one line each; the trace's room warning ends in its own.
      std::fputs(fmt::format("toonforce: warning: {}{}", message, message.ends_with('\n') ? "" : "\n").c_str(), stderr);
      return;
    }
    while (!message.empty() && message.back() == '\n') message.pop_back();
    options.warnings->push_back(std::move(message));
  };
  auto scene = options.scene_text ? parse_scene(*options.scene_text, options.scene_path, options.scalar)
                                  : load_scene_file(options.scene_path, options.scalar);
  if (!scene) return Error{scene.error()};
  if (std::string empty = empty_scene_problem(scene.value(), options.scene_path);
      !empty.empty() && !options.allow_empty) {
    return Error{std::move(empty)};
  }
  {
    // The plausibility report's warnings, before anything runs.
    const PlausibilityReport plausible =
        check_plausibility(scene.value(), options.scene_path, sim_config(options).device, options.rate_hz);
    if (!plausible.warnings.empty()) {
      std::string text;
      for (const std::string& w : plausible.warnings) text += fmt::format("toonforce: warning: {}\n", w);
      if (options.strict) return Error{text + "--strict: the simulation does not start with a warning"};
      for (const std::string& w : plausible.warnings) warn(w);
    }
  }
  if (const std::string bad = fixed_point::check_rate(options.rate_hz, options.scalar, scene.value()); !bad.empty()) {
    return Error{fmt::format("--rate {}", bad)};  // `toonforce sim` refuses it earlier, exit 2
  }
  if (options.sine) override_sine(scene.value(), *options.sine);
  auto hand = options.script_text ? parse_hand_script(*options.script_text, options.script_path)
                                  : load_hand_script(options.script_path);
  if (!hand) return Error{hand.error()};
  auto session = SimSession::create(scene.value(), hand.value(), sim_config(options));
  if (!session) return Error{session.error()};

  const double duration_s = options.duration_s.value_or(hand->intent.duration_s());
  const std::int64_t ticks = session->ticks_for(duration_s);
  if (!options.duration_s && duration_s > kMaxSimDurationS) {
    return Error{fmt::format("{}: the hand script lasts {:g} s, over the maximum of {:g} s simulated (one day); "
                             "give a shorter --duration",
                             options.script_path, duration_s, kMaxSimDurationS)};
  }
  if (ticks < 1) {
    return Error{fmt::format("nothing to simulate: {} s is less than one tick at {} Hz (give --duration)", duration_s,
                             options.rate_hz)};
  }
  // The trace file, unless the rows go only to the caller's sink (empty trace_path).
  std::unique_ptr<TraceWriter> trace;
  const std::vector<std::string> extra_columns = sim_trace_columns(session->value_names());
  if (!options.trace_path.empty()) {
    auto opened = TraceWriter::open(options.trace_path, extra_columns);
    if (!opened) return Error{opened.error()};
    trace = std::move(opened.value());
    trace->limit_size(options.max_output_bytes);
    // About 8 bytes a value (shortest round-trip text, many columns repeat a short value).
    const std::uint64_t expected = static_cast<std::uint64_t>(ticks) * trace->columns().size() * 8U;
    const std::string room = trace_room_warning(options.trace_path, expected, options.max_output_bytes);
    if (!room.empty()) warn(room);
  }
  if (options.rows != nullptr) options.rows->begin(extra_columns, ticks);
  const std::size_t values = session->value_names().size();
  const SummaryColumns columns = SummaryColumns::of(session->value_names());

  SimSummary summary;
  summary.scene_name = scene->name;
  summary.script_name = hand->script.name;
  summary.device_name = std::string(session->config().device.name);
  summary.script_duration_s = hand->intent.duration_s();
  const auto& device = session->config().device;
  const auto inside = [&device](const Vec3<double>& p) {
    return p.x >= device.workspace_min_m.x && p.x <= device.workspace_max_m.x && p.y >= device.workspace_min_m.y &&
           p.y <= device.workspace_max_m.y && p.z >= device.workspace_min_m.z && p.z <= device.workspace_max_m.z;
  };
  // Paced for the viewer: each tick waits until its simulated time has come on the wall clock
  // (this thread is the simulation's own, not a real-time loop; the trace is unchanged).
  const bool paced = options.sink != nullptr && options.pace > 0.0;
  const auto wall_start = std::chrono::steady_clock::now();
  const auto stopped = [&options] { return options.stop != nullptr && options.stop->load() != 0; };
  std::int64_t k = 0;
  // One row's numbers, for the file and the sink alike (the sink's arrays are the file's doubles).
  TraceRow row;
  const auto write = [&](const SimRecord& record) {
    const bool fits = sim_record_row(row, record, values);  // a sim row always fits (13 columns of its own)
    if (options.rows != nullptr && fits) options.rows->row(row);
    if (!trace || !summary.trace_error.empty() || (fits && trace->write(row.core, row.extras()))) return;
    summary.trace_error =
        trace->size_limit_reached()
            ? fmt::format("stopped at t = {:.6g} s: it reached --max-output {} (give a larger one, or 0 for no limit)",
                          record.frame.t_s, describe_bytes(options.max_output_bytes))
            : fmt::format("writing failed at t = {:.6g} s: {}", record.frame.t_s,
                          std::strerror(errno != 0 ? errno : EIO));
    std::fputs(fmt::format("toonforce: {}: {}; nothing more is written, the simulation goes on\n", options.trace_path,
                           summary.trace_error)
                   .c_str(),
               stderr);
  };
  for (; k < ticks && !stopped(); ++k) {
    const SimRecord record = session->step();
    write(record);
    add_to_summary(summary, record, columns);
    if (!inside(record.true_position_m)) ++summary.ticks_outside_workspace;
    if (options.sink != nullptr) {
      options.sink->publish(record.frame);
      if (paced) {
        // In slices, so that a stop is heard within one even at a slow pace.
        const auto due = wall_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                          std::chrono::duration<double>(record.frame.t_s / options.pace));
        while (!stopped()) {
          const auto now = std::chrono::steady_clock::now();
          if (now >= due) break;
          std::this_thread::sleep_for(
              std::min<std::chrono::steady_clock::duration>(due - now, std::chrono::milliseconds(20)));
        }
      }
    }
  }
  if (k < ticks && stopped()) {
    // Stopped early: the loop's shut-down tick (zero force) is the trace's last row, as in `run`.
    summary.stop_signal = options.stop->load();
    const SimRecord record = session->shutdown();
    write(record);
    add_to_summary(summary, record, columns);
    if (options.sink != nullptr) options.sink->publish(record.frame);
  }
  if (options.sink != nullptr) options.sink->finish();
  summary.duration_s = static_cast<double>(k) * session->config().plant.period_s;
  summary.final_position_m = session->device().plant().position_m();
  summary.device_work_j = session->device().plant().device_work_j();
  if (trace && !trace->close() && summary.trace_error.empty()) {
    summary.trace_error = fmt::format("writing its end failed: {}", std::strerror(errno != 0 ? errno : EIO));
  }

  if (!options.plot_path.empty() && summary.trace_error.empty() && summary.stop_signal == 0) {
    PlotRequest request{
        options.trace_path,
        options.plot_path,
        options.plot_kind,
        options.plot_title.empty() ? fmt::format("{} / {}", scene->name, hand->script.name) : options.plot_title,
        {}};
    // A cliff across x on a horizontal ground: the plot can draw its gap and threshold.
    if (!scene->of<CartoonCliff>().empty()) {
      const auto& c = scene->of<CartoonCliff>().front();
      if (std::abs(c.axis.x - 1.0) < 1e-9 && std::abs(c.ground.normal.z - 1.0) < 1e-9) {
        request.extra_args = {"--gap", fmt::format("{}", c.ground.point_m.x + c.gap_min_m),
                              fmt::format("{}", c.ground.point_m.x + c.gap_max_m), "--threshold",
                              fmt::format("{}", c.speed_threshold_m_per_s)};
      }
    }
    auto plotted = plot_trace(request);
    if (!plotted) return Error{plotted.error()};
  }
  return summary;
}

std::string format_sim_summary(const SimSummary& s, const SimOptions& options) {
  std::string text;
  text += fmt::format("scene   {} ({}); hand script {} ({}, {:.6g} s)\n", s.scene_name, options.scene_path,
                      s.script_name, options.script_path, s.script_duration_s);
  text += fmt::format("device  {}; {} integrator, {} sub-steps per tick; {:g} Hz; scalar {}\n", s.device_name,
                      host_sim::integrator_name(options.integrator), options.substeps, options.rate_hz,
                      scalar_kind_name(options.scalar));
  text += fmt::format("ran     {} ticks = {:.6g} s simulated; in contact {} ticks\n", s.ticks, s.duration_s,
                      s.ticks_in_contact);
  text += fmt::format("forces  peak {:.4g} N at t = {:.6g} s; the device did {:.4g} J of work on the hand\n",
                      s.peak_force_n, s.peak_force_t_s, s.device_work_j);
  text += fmt::format("effects impacts triggered {}; cliff falls {}\n", s.impacts, s.cliff_falls);
  text += fmt::format("safety  engaging {} ticks, soft start {} ticks, passivity damping {} ticks, rate-limited {} "
                      "ticks, clamped {} ticks, faults {} ticks; loop {} at the end\n",
                      s.engaging_ticks, s.soft_start_ticks, s.passivity_ticks, s.rate_limited, s.clamped, s.fault_ticks,
                      to_string(static_cast<LoopState>(s.last_state)));
  text += fmt::format("end     handle at [{:.4g}, {:.4g}, {:.4g}] m\n", s.final_position_m.x, s.final_position_m.y,
                      s.final_position_m.z);
  if (s.ticks_outside_workspace > 0) {
    text += fmt::format("note    the handle was outside the device's workspace for {} ticks: the simulated device "
                        "has no end stops, a real one would have stopped it\n",
                        s.ticks_outside_workspace);
  }
  if (s.stop_signal != 0) {
    const char* abbrev = sigabbrev_np(s.stop_signal);
    text += fmt::format("stopped by {} after {:.6g} s simulated: the last trace row is the loop's shut-down tick "
                        "(zero force)\n",
                        abbrev != nullptr ? fmt::format("SIG{}", abbrev) : fmt::format("signal {}", s.stop_signal),
                        s.duration_s);
  }
  if (!s.trace_error.empty()) {
    text += fmt::format("trace   {}: INCOMPLETE, {}\n", options.trace_path, s.trace_error);
  } else if (options.trace_path != "-") {
    text += fmt::format("trace   {}\n", options.trace_path);
  }
  if (!options.plot_path.empty()) text += fmt::format("plot    {}\n", options.plot_path);
  return text;
}

}  // namespace toonforce
