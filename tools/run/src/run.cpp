// SPDX-License-Identifier: Apache-2.0
#include "toonforce/run/run.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <utility>

#include <fmt/format.h>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/control/servo_session.hpp"
#include "toonforce/hal/gpio/gpio_session.hpp"
#include "toonforce/host_sim/sim_driver.hpp"
#include "toonforce/sim/plausibility.hpp"
#include "toonforce/config/falcon_calibration_file.hpp"
#include "toonforce/control/guardian.hpp"
#include "toonforce/control/process_split.hpp"
#include "toonforce/trace/json.hpp"
#include "toonforce/trace/telemetry_trace.hpp"

namespace toonforce {

ScalarKind RunOptions::default_run_scalar() noexcept {
#if TOONFORCE_FIRMWARE
  return ScalarKind::kQ16_16;
#else
  return ScalarKind::kDouble;
#endif
}

namespace {

/// The frames of a run, on the session's writer thread: trace rows, fault messages, counts,
/// the live viewer.
class RunConsumer final : public FrameConsumer {
 public:
  RunConsumer(TraceWriter* trace, std::size_t values, std::FILE* messages, TelemetrySink* sink, RunSummary& summary,
              guardian::SharedPage* page)
      : trace_(trace), values_(values), messages_(messages), sink_(sink), summary_(summary), page_(page) {}

  void consume(const TelemetryFrame& f) override {
    ++summary_.frames_written;
    if (f.faults != 0) ++summary_.fault_ticks;
    if (has(f.limits, Limit::kDeviceLimited)) ++summary_.device_limited_ticks;
    summary_.fault_bits |= f.faults;
    summary_.peak_force_n = std::max(summary_.peak_force_n, std::sqrt(dot(f.force_n, f.force_n)));
    if (f.latched != latched_) {
      const std::uint32_t added = f.latched & ~latched_;
      if (added != 0) {
        fmt::print(messages_, "t = {:.3f} s: fault latched: {}; force off until re-armed{}\n", f.t_s,
                   describe_faults(added), interactive_ ? " (type r and Enter)" : "");
      } else if (f.latched == 0) {
        fmt::print(messages_, "t = {:.3f} s: re-armed\n", f.t_s);
        ++summary_.rearms;
      }
      std::fflush(messages_);
      latched_ = f.latched;
    }
    summary_.latched_at_end = f.latched;
    if (trace_ != nullptr && !write_failed && !write_frame(*trace_, f, values_, true)) trace_failed(f);
    if (sink_ != nullptr) sink_->publish(f);  // fan-out here, never in the servo thread
    if (page_ != nullptr) {
      guardian::publish_frame(*page_, f);
      // With a guardian, the trace goes to the file every 20 ms of loop time: if this process
      // dies, the guardian ends the trace after what the file holds (guardian.hpp).
      if (trace_ != nullptr && !write_failed && f.t_s - flushed_t_s_ >= 0.02) {
        flushed_t_s_ = f.t_s;
        if (!trace_->flush()) trace_failed(f);
      }
    }
  }
  /// A row or a flush failed: said at once; the loop goes on (its force never depends on the
  /// trace), unwritten.
  void trace_failed(const TelemetryFrame& f) {
    write_failed = true;
    if (trace_->size_limit_reached()) {
      summary_.trace_error = fmt::format("stopped at t = {:.3f} s: it reached --max-output {} (give a larger one, or 0 "
                                         "for no limit)",
                                         f.t_s, describe_bytes(trace_limit_bytes));
      fmt::print(messages_,
                 "t = {:.3f} s: the trace reached --max-output {}: nothing more is written, the run goes on\n", f.t_s,
                 describe_bytes(trace_limit_bytes));
    } else {
      summary_.trace_error =
          fmt::format("writing failed at t = {:.3f} s: {}", f.t_s, std::strerror(errno != 0 ? errno : EIO));
      fmt::print(messages_,
                 "t = {:.3f} s: the trace cannot be written ({}): nothing more is written, the run goes on\n", f.t_s,
                 std::strerror(errno != 0 ? errno : EIO));
    }
    std::fflush(messages_);
  }
  void finish() override {
    if (sink_ != nullptr) sink_->finish();
  }
  void set_interactive(bool interactive) noexcept { interactive_ = interactive; }

  bool write_failed = false;
  std::uint64_t trace_limit_bytes = 0;  ///< for the message when the trace reaches it

 private:
  TraceWriter* trace_;
  std::size_t values_;
  std::FILE* messages_;
  TelemetrySink* sink_;
  RunSummary& summary_;
  guardian::SharedPage* page_;
  double flushed_t_s_ = 0.0;
  std::uint32_t latched_ = 0;
  bool interactive_ = false;
};

template <Scalar S, LoopStages kStages, class PinsT>
Result<RunSummary> run_as(const RunOptions& options, const SceneDescription& scene, DeviceDriver& driver, PinsT& pins) {
  const double period_s = 1.0 / options.rate_hz;
  const ServoConfig config = with_device(servo_config(scene, period_s), driver.info());
  if (const std::string problems = check_servo_config(config); !problems.empty()) {
    return Error{fmt::format("{}: the servo configuration does not work:\n{}", options.scene_path, problems)};
  }
  RunSummary summary;
  summary.scene_name = scene.name;
  summary.surfaces = scene.of<RuntimeSurface>().size();
  summary.cliffs = scene.of<CartoonCliff>().size();
  summary.device_name = driver.info().name;

  // Everything the servo thread touches is allocated here, before it starts.
  const RuntimeScene<S> runtime = make_runtime_scene<S>(scene);
  const std::vector<std::string> values = effect_value_names(runtime);
  std::unique_ptr<TraceWriter> trace;
  if (!options.trace_path.empty()) {
    auto opened = TraceWriter::open(options.trace_path, telemetry_columns(values, true));
    if (!opened) return Error{opened.error()};
    trace = std::move(opened.value());
    trace->limit_size(options.max_output_bytes);
    // About 8 bytes a value; a run until stopped has no expected size (the limit alone).
    const std::uint64_t expected =
        options.duration_s > 0.0 ? static_cast<std::uint64_t>(std::llround(options.duration_s * options.rate_hz)) *
                                       trace->columns().size() * 8U
                                 : 0U;
    const std::string room = trace_room_warning(options.trace_path, expected, options.max_output_bytes);
    if (!room.empty()) fmt::print(options.messages, "warning: {}", room);
  }
  using Loop = ServoLoop<DriverRef, RuntimeScene<S>, PinsT, kStages>;
  auto loop = std::make_unique<Loop>(DriverRef(driver), runtime, config, pins);
  if constexpr (kStages.live) {
    auto* mailbox = options.live->template of<S>();
    if (mailbox == nullptr) return Error{"live scene: no mailbox for the run's scalar type"};
    loop->listen(*mailbox);
    summary.live = true;
  }

  const SessionOptions session = session_options(options, config.safety.watchdog_periods);
  RunConsumer consumer(trace.get(), values.size(), options.messages, options.sink, summary, options.guardian);
  consumer.set_interactive(options.interactive && isatty(STDIN_FILENO) != 0);
  consumer.trace_limit_bytes = options.max_output_bytes;

  auto report = run_loop(*loop, driver, consumer, session);
  after_session(options);
  if (!report) return Error{report.error()};
  summary.report = std::move(report->report);
  summary.frames_dropped = report->frames_dropped;
  if constexpr (kStages.live) {
    summary.updates_applied = loop->updates_applied();
    summary.updates_refused = loop->updates_refused();
  }
  if (trace && !trace->close() && summary.trace_error.empty()) {
    summary.trace_error = fmt::format("writing its end failed: {}", std::strerror(errno != 0 ? errno : EIO));
  }
  return summary;
}

std::string stop_reason(int signal) {
  if (signal == 0) return "";
  if (signal == kStopByUser) return "stopped by the user";
  return fmt::format("stopped by {}", signal_name(signal));
}

}  // namespace

std::string json_latency(const LatencySummary& s) {
  const auto us = [](std::int64_t ns) { return static_cast<double>(ns) * 1e-3; };
  return fmt::format(
      "{{\"count\": {}, \"min\": {:.3f}, \"median\": {:.3f}, \"p99\": {:.3f}, \"p99_9\": {:.3f}, \"max\": {:.3f}, \"below_zero\": {}, "
      "\"overflow\": {}}}",
      s.count, us(s.min_ns), us(s.median_ns), us(s.p99_ns), us(s.p999_ns), us(s.max_ns), s.below_zero, s.overflow);
}

std::string describe_faults(std::uint32_t bits) {
  std::string out;
  for (const Fault f : kAllFaults) {
    if ((bits & static_cast<std::uint32_t>(f)) != 0) out += fmt::format("{}{}", out.empty() ? "" : ", ", fault_name(f));
  }
  return out;
}

Result<std::unique_ptr<DeviceDriver>> open_device(const RunOptions& options) {
  if (options.device == "sim") {
    const auto preset = host_sim::parse_device_preset(options.sim_device);
    if (!preset)
      return Error{fmt::format("--sim-device {}: unknown device model (falcon or omni)", options.sim_device)};
    std::optional<host_sim::HandIntent> intent;
    if (options.hand_script_path.empty()) {
      intent = host_sim::HandIntent::holding({0.0, 0.0, 0.01});
    } else {
      auto script = load_hand_script(options.hand_script_path);
      if (!script) return Error{script.error()};
      intent = std::move(script->intent);
    }
    // RK4 with about 4 sub-steps per millisecond: the step the host simulation's tests check.
    host_sim::PlantOptions plant;
    plant.period_s = 1.0 / options.rate_hz;
    plant.substeps = std::max(1, static_cast<int>(std::ceil(4000.0 / options.rate_hz)));
    auto driver =
        host_sim::SimDriver::create(host_sim::device_params(*preset), std::move(*intent), plant, options.seed);
    if (!driver) return Error{driver.error()};
    return std::unique_ptr<DeviceDriver>(std::move(driver.value()));
  }
  if (options.device == "falcon") {
    FalconOptions falcon = options.falcon;
    falcon.read_calibration = &falcon::read_falcon_calibration;  // the file format is this layer's
    return open_falcon(falcon);
  }
  if (options.device == "omni") {
    OmniOptions omni = options.omni;
    omni.scheduler_rate_hz = options.rate_hz;
    auto device = open_omni(omni);
    if (!device) return Error{device.error()};
    return std::unique_ptr<DeviceDriver>(std::move(device.value()));
  }
  return Error{fmt::format("--device {}: unknown device (sim, falcon or omni)", options.device)};
}

std::string run_options_problem(const RunOptions& options) {
  if (!(options.rate_hz >= 500.0 && options.rate_hz <= 10000.0)) {
    return fmt::format("--rate {}: the servo rate must be within 500..10000 Hz", options.rate_hz);
  }
  if (!(options.duration_s >= 0.0) || !std::isfinite(options.duration_s)) {
    return fmt::format("--duration {}: must be >= 0 seconds (0: until stopped)", options.duration_s);
  }
  // The maximum first: a tick count of 1e16 s does not fit an integer (it read as "less than
  // one tick").
  if (options.duration_s > kMaxRunDurationS) {
    return fmt::format("--duration {:g}: over the maximum of {:g} s (30 days; 0 runs until stopped)",
                       options.duration_s, kMaxRunDurationS);
  }
  if (options.duration_s > 0.0 && std::llround(options.duration_s * options.rate_hz) < 1) {
    return fmt::format("--duration {:g}: less than one tick at {:g} Hz (allowed: 0, until stopped, or {:g} .. {:g} s)",
                       options.duration_s, options.rate_hz, 1.0 / options.rate_hz, kMaxRunDurationS);
  }
  return {};
}

Result<RunSummary> run_servo(const RunOptions& options) {
  if (const std::string bad = run_options_problem(options); !bad.empty()) return Error{bad};
  // No output may replace an input: both are checked before anything is opened for writing.
  for (const auto& [output, flag] :
       {std::pair{options.trace_path, "--trace"}, std::pair{options.stats_json_path, "--stats-json"}}) {
    for (const auto& [input, what] :
         {std::pair{options.scene_path, "the scene"}, std::pair{options.hand_script_path, "the hand script"}}) {
      std::error_code ec;
      if (!output.empty() && output != "-" && !input.empty() && std::filesystem::equivalent(output, input, ec) && !ec) {
        return Error{
            fmt::format("{} {} is {} ({}): it would be overwritten; choose another file", flag, output, what, input)};
      }
    }
  }
  auto scene = options.scene_text ? parse_scene(*options.scene_text, options.scene_path, options.scalar)
                                  : load_scene_file(options.scene_path, options.scalar);
  if (!scene) return Error{scene.error()};
  if (std::string empty = empty_scene_problem(scene.value(), options.scene_path);
      !empty.empty() && !options.allow_empty) {
    return Error{std::move(empty)};
  }
  {
    // The plausibility report's warnings, before the device is opened, for
    // the device class's model: the simulated one, or the Falcon's or the Omni's.
    const auto preset = options.device == "sim" ? host_sim::parse_device_preset(options.sim_device)
                                                : host_sim::parse_device_preset(options.device);
    if (preset) {
      const PlausibilityReport plausible =
          check_plausibility(scene.value(), options.scene_path, host_sim::device_params(*preset), options.rate_hz);
      std::string text;
      for (const std::string& w : plausible.warnings) text += fmt::format("warning: {}\n", w);
      if (!text.empty() && options.strict) return Error{text + "--strict: the run does not start with a warning"};
      if (!text.empty()) fmt::print(options.messages, "{}", text);
    }
  }
  // Before the device opens: a rate whose 1/dt-based quantities Q16.16 cannot hold.
  if (const std::string bad = fixed_point::check_rate(options.rate_hz, options.scalar, scene.value()); !bad.empty()) {
    return Error{fmt::format("--rate {}", bad)};
  }
  // The guardian watches before the device opens, or the device is not opened at all.
  if (options.guardian != nullptr && !wait_for_guardian(*options.guardian, 10.0)) {
    return Error{"the guardian process did not start watching (it said why above): the device was not opened"};
  }
  auto device = open_device(options);
  if (!device) return Error{device.error()};
  DeviceDriver& driver = *device.value();
  if (options.guardian != nullptr) {  // from here until the loop ends, the guardian zeroes if this process dies
    options.guardian->zeros[0] = driver.external_zero();
    options.guardian->zero_count = 1;
    options.guardian->period_ns = static_cast<std::int64_t>(std::llround(1e9 / options.rate_hz));
    options.guardian->phase.store(static_cast<std::uint32_t>(guardian::Phase::kDeviceOpen), std::memory_order_release);
  }
  // The GPIO pins are opened (and checked) before the loop starts; without GPIO options the
  // loop is built with NullPins and runs no GPIO code at all.
  auto result = gpio::with_gpio_pins(options.gpio, [&](auto& pins) -> Result<RunSummary> {
    return with_scalar(
        options.scalar,
        [&]<Scalar S>() {
          // The live stage only when asked for (--control): a run without it pays nothing.
          return options.live != nullptr ? run_as<S, kLiveStages>(options, scene.value(), driver, pins)
                                         : run_as<S, kEveryStage>(options, scene.value(), driver, pins);
        },
        [](ScalarKind kind) -> Result<RunSummary> {
          return Error{fmt::format("--scalar {}: this is a firmware build (TOONFORCE_FIRMWARE=ON): the servo loop is "
                                   "compiled for q16.16 only",
                                   scalar_kind_name(kind))};
        });
  });
  if (options.guardian != nullptr) {  // the loop ended or never started: the device closes as usual
    options.guardian->loop_ended.store(1, std::memory_order_release);
  }
  if (!result) return Error{result.error()};
  return std::move(result.value());
}

SessionOptions session_options(const RunOptions& options, std::int64_t watchdog_periods) {
  SessionOptions session;
  session.realtime.rate_hz = options.rate_hz;
  session.realtime.deadlines =
      options.duration_s > 0.0 ? static_cast<std::int64_t>(std::llround(options.duration_s * options.rate_hz)) : 0;
  session.realtime.priority = options.priority;
  session.realtime.cpu = options.cpu;
  session.realtime.allow_non_realtime = options.allow_non_realtime;
  session.realtime.lock_memory = options.lock_memory;
  session.realtime.watchdog_periods = watchdog_periods;
  if (options.guardian != nullptr) {
    session.realtime.heartbeat = &options.guardian->heartbeat;
    session.realtime.ended = &options.guardian->loop_ended;  // at the shut-down tick, not after the writer
  }
  session.handle_signals = options.handle_signals;
  session.interactive = options.interactive;
  session.messages = options.messages;
  session.pending_stop = options.early_stop;
  return session;
}

void after_session(const RunOptions& options) {
  if (options.guardian == nullptr) return;
  // The loop commanded zero force on its way out (its shut-down tick, which told the guardian):
  // the guardian stands down. Said again here for a run that ended before its first tick.
  options.guardian->loop_ended.store(1, std::memory_order_release);
  if (getppid() != options.guardian->guardian_pid) {
    fmt::print(options.messages,
               "the guardian process (pid {}) ended during the run: the loop stopped with zero force\n",
               options.guardian->guardian_pid);
  }
}

std::string format_run_trace(const std::string& trace_path, const std::string& trace_error,
                             std::uint64_t frames_written, std::uint64_t frames_dropped) {
  if (!trace_path.empty() && !trace_error.empty())
    return fmt::format("trace    {}: INCOMPLETE, {}\n", trace_path, trace_error);
  if (!trace_path.empty()) {
    return fmt::format("trace    {}: {} rows, {} frame(s) dropped (telemetry ring full)\n", trace_path, frames_written,
                       frames_dropped);
  }
  if (frames_dropped != 0) return fmt::format("telemetry {} frame(s) dropped (ring full)\n", frames_dropped);
  return {};
}

std::string format_run_timing(const RunReport& r, double rate_hz) {
  std::string text;
  std::string rt = r.setup.priority < 0 ? "the device's own servo thread (its scheduler sets the priority)"
                   : r.setup.fifo       ? fmt::format("SCHED_FIFO {}", r.setup.priority)
                                        : "NOT real-time (normal scheduling)";
  rt += r.setup.memory_locked ? ", memory locked" : ", memory not locked";
  rt += r.setup.cpu >= 0 ? fmt::format(", pinned to CPU {}", r.setup.cpu) : ", not pinned";
  text += fmt::format("realtime {}\n", rt);
  std::string notes = r.setup.notes;
  while (!notes.empty() && notes.back() == '\n') notes.pop_back();
  if (!notes.empty()) text += fmt::format("note     {}\n", notes);
  const std::string why = stop_reason(r.stop_signal);
  // Two watchdogs, named apart ("watchdog trips 0" stood beside a latched watchdog
  // fault): the heartbeat thread outside the loop, which zeroes the device when the loop
  // stalls, and the loop's own gap check, a fault in the "faults" line.
  text += fmt::format("run      {} ticks at {} Hz over {:.3f} s{}; {} deadline(s) missed; heartbeat watchdog "
                      "(outside the loop) tripped {} time(s)\n",
                      r.ticks, rate_hz, r.elapsed_s, why.empty() ? "" : " (" + why + ")", r.missed, r.watchdog_trips);
  text += "timing   [us]             min   median      p99    p99.9      max\n";
  const auto row = [&text](std::string_view name, const LatencySummary& l) {
    const auto us = [](std::int64_t ns) { return static_cast<double>(ns) * 1e-3; };
    text += fmt::format("         {:<16}{:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f}\n", name, us(l.min_ns),
                        us(l.median_ns), us(l.p99_ns), us(l.p999_ns), us(l.max_ns));
  };
  row("wake-up latency", r.wake.summary());
  row("compute", r.compute.summary());
  row("slack", r.slack.summary());
  return text;
}

std::string format_run_summary(const RunSummary& s, const RunOptions& o) {
  const RunReport& r = s.report;
  std::string text;
  text += fmt::format("scene    {} ({}): {} surface(s), {} cliff(s); scalar {}\n", s.scene_name, o.scene_path,
                      s.surfaces, s.cliffs, scalar_kind_name(o.scalar));
  text += fmt::format("device   {} ({})\n", o.device, s.device_name);
  text += format_run_timing(r, o.rate_hz);
  text += fmt::format("forces   peak {:.3f} N\n", s.peak_force_n);
  if (s.live) {
    text += fmt::format("live     {} scene update(s) applied, {} refused{}\n", s.updates_applied, s.updates_refused,
                        s.updates_refused > 0 ? " (they failed the loop's checks: docs/spec/live-scenes.md)" : "");
  }
  if (s.device_limited_ticks > 0) {
    text += fmt::format("device   could not give the force asked in {} tick(s): its force envelope is smaller "
                        "there (`toonforce falcon envelope`); the hand felt less than the scene\n",
                        s.device_limited_ticks);
  }
  if (s.fault_bits == 0) {
    text += "faults   none\n";
  } else {
    text += fmt::format("faults   {} tick(s) with faults ({}); re-armed {} time(s); latched at the end: {}\n",
                        s.fault_ticks, describe_faults(s.fault_bits), s.rearms,
                        s.latched_at_end == 0 ? "none" : describe_faults(s.latched_at_end));
  }
  text += format_run_trace(o.trace_path, s.trace_error, s.frames_written, s.frames_dropped);
  return text;
}

std::string stats_json(const RunSummary& s, const RunOptions& o) {
  const RunReport& r = s.report;
  std::string out = "{\n";
  out += fmt::format("  \"device\": {},\n  \"device_name\": {},\n", json_string(o.device), json_string(s.device_name));
  out += fmt::format("  \"scene\": {},\n  \"scene_file\": {},\n", json_string(s.scene_name), json_string(o.scene_path));
  out += fmt::format("  \"scalar\": {},\n  \"rate_hz\": {},\n  \"duration_s\": {},\n  \"elapsed_s\": {},\n",
                     json_string(scalar_kind_name(o.scalar)), o.rate_hz, o.duration_s, r.elapsed_s);
  out += fmt::format(
      "  \"realtime\": {{\"sched_fifo\": {}, \"priority\": {}, \"memory_locked\": {}, \"cpu\": {}, \"notes\": {}}},\n",
      r.setup.fifo, r.setup.priority, r.setup.memory_locked, r.setup.cpu, json_string(r.setup.notes));
  out += fmt::format("  \"ticks\": {},\n  \"missed\": {},\n  \"watchdog_trips\": {},\n  \"stop_signal\": {},\n",
                     r.ticks, r.missed, r.watchdog_trips, r.stop_signal);
  out += fmt::format("  \"frames_written\": {},\n  \"frames_dropped\": {},\n", s.frames_written, s.frames_dropped);
  out += fmt::format("  \"fault_ticks\": {},\n  \"fault_bits\": {},\n  \"latched_at_end\": {},\n  \"rearms\": {},\n",
                     s.fault_ticks, s.fault_bits, s.latched_at_end, s.rearms);
  out += fmt::format("  \"device_limited_ticks\": {},\n", s.device_limited_ticks);
  out += fmt::format("  \"updates_applied\": {},\n  \"updates_refused\": {},\n", s.updates_applied, s.updates_refused);
  out += fmt::format("  \"faults\": {},\n", json_string(describe_faults(s.fault_bits)));
  out += fmt::format("  \"wake_latency_us\": {},\n", json_latency(r.wake.summary()));
  out += fmt::format("  \"compute_us\": {},\n", json_latency(r.compute.summary()));
  out += fmt::format("  \"slack_us\": {},\n", json_latency(r.slack.summary()));
  // The wake-up latency histogram itself (1 us bins, non-empty ones), for the benchmark.
  out += "  \"wake_latency_histogram_us\": {";
  bool first = true;
  const auto& bins = r.wake.counts();
  for (std::size_t i = 0; i < bins.size(); ++i) {
    if (bins[i] == 0) continue;
    out +=
        fmt::format("{}\"{}\": {}", first ? "" : ", ", static_cast<std::int64_t>(i) * r.wake.bin_ns() / 1000, bins[i]);
    first = false;
  }
  out += "}\n}\n";
  return out;
}

}  // namespace toonforce
