#include "toonforce/run/run.hpp"

#include <poll.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include <fmt/format.h>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/hal/gpio/gpio_session.hpp"
#include "toonforce/host_sim/sim_driver.hpp"
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

/// 16384 frames: 1.6 s of telemetry at 10 kHz, 16 s at 1 kHz, before the writer must catch up.
using TelemetryRing = SpscRing<TelemetryFrame, 16384>;

void sleep_ms(int ms) noexcept {
  timespec ts{0, static_cast<long>(ms) * 1'000'000L};
  nanosleep(&ts, nullptr);
}

/// One servo tick per period, telemetry out through the ring. Everything here runs on the
/// servo thread: no allocation, no lock, no blocking.
template <Scalar S, class PinsT>
class ServoTask final : public PeriodicTask {
 public:
  using Loop = ServoLoop<DriverRef, RuntimeScene<S>, PinsT>;
  ServoTask(Loop& loop, TelemetryRing& ring) : loop_(loop), ring_(ring) {}

  void tick(std::int64_t k) noexcept override { static_cast<void>(loop_.tick(k)); }
  void publish(std::int64_t, const TickTiming& timing) noexcept override {
    loop_.fill_frame(frame_);
    frame_.timing = timing;
    missed_ = timing.missed_total;
    static_cast<void>(ring_.push(frame_));  // a full ring drops and counts, never waits
  }
  void shutdown(std::int64_t k) noexcept override {
    static_cast<void>(loop_.shutdown(k));  // zero force before anything else
    loop_.fill_frame(frame_);
    frame_.timing = TickTiming{};
    frame_.timing.missed_total = missed_;
    // The run is over: the last frame (force zero) may wait for the writer, up to a second.
    for (int i = 0; i < 1000; ++i) {
      if (ring_.try_push(frame_)) return;
      sleep_ms(1);
    }
    static_cast<void>(ring_.push(frame_));
  }

 private:
  Loop& loop_;
  TelemetryRing& ring_;
  TelemetryFrame frame_{};
  std::int64_t missed_ = 0;
};

/// The writer thread: trace rows, fault messages, counts.
struct Writer {
  TelemetryRing& ring;
  TraceWriter* trace;
  std::FILE* messages;
  TelemetrySink* sink;
  bool interactive;
  std::atomic<bool> finished{false};
  RunSummary& summary;
  bool write_failed = false;

  void run() {
    TelemetryFrame f;
    std::uint32_t latched = 0;
    for (;;) {
      if (!ring.pop(f)) {
        if (finished.load(std::memory_order_acquire)) {
          if (!ring.pop(f)) break;
        } else {
          sleep_ms(2);
          continue;
        }
      }
      ++summary.frames_written;
      if (f.faults != 0) ++summary.fault_ticks;
      summary.fault_bits |= f.faults;
      summary.peak_force_n = std::max(summary.peak_force_n, std::sqrt(dot(f.force_n, f.force_n)));
      if (f.latched != latched) {
        const std::uint32_t added = f.latched & ~latched;
        if (added != 0) {
          fmt::print(messages, "t = {:.3f} s: fault latched: {}; force off until re-armed{}\n", f.t_s,
                     describe_faults(added), interactive ? " (type r and Enter)" : "");
        } else if (f.latched == 0) {
          fmt::print(messages, "t = {:.3f} s: re-armed\n", f.t_s);
          ++summary.rearms;
        }
        std::fflush(messages);
        latched = f.latched;
      }
      summary.latched_at_end = f.latched;
      if (trace != nullptr && !write_frame(*trace, f)) write_failed = true;
      if (sink != nullptr) sink->publish(f);  // fan-out here, never in the servo thread
    }
    if (sink != nullptr) sink->finish();
  }
};

/// Reads 'r' (re-arm) and 'q' (stop) lines from a terminal while the run lasts.
template <class Loop>
void read_commands(Loop& loop, std::atomic<int>& stop, const std::atomic<bool>& finished) {
  char buffer[64];
  while (!finished.load(std::memory_order_acquire) && stop.load() == 0) {
    pollfd in{STDIN_FILENO, POLLIN, 0};
    if (poll(&in, 1, 100) <= 0 || (in.revents & POLLIN) == 0) continue;
    const ssize_t n = ::read(STDIN_FILENO, buffer, sizeof buffer);
    if (n <= 0) return;  // end of input
    for (ssize_t i = 0; i < n; ++i) {
      if (buffer[i] == 'r') loop.request_rearm();
      if (buffer[i] == 'q') {
        int expected = 0;
        stop.compare_exchange_strong(expected, kStopByUser);
      }
    }
  }
}

std::atomic<int> g_stop{0};

void zero_driver(void* driver) noexcept { static_cast<DeviceDriver*>(driver)->emergency_zero(); }

template <Scalar S, class PinsT>
Result<RunSummary> run_as(const RunOptions& options, const SceneDescription& scene, DeviceDriver& driver,
                          PinsT& pins) {
  const double period_s = 1.0 / options.rate_hz;
  const ServoConfig config = with_device(servo_config(scene, period_s), driver.info());
  if (const std::string problems = check_servo_config(config); !problems.empty()) {
    return Error{fmt::format("{}: the servo configuration does not work:\n{}", options.scene_path, problems)};
  }
  RunSummary summary;
  summary.scene_name = scene.name;
  summary.surfaces = scene.surfaces.size();
  summary.cliffs = scene.cliffs.size();
  summary.device_name = driver.info().name;

  std::unique_ptr<TraceWriter> trace;
  if (!options.trace_path.empty()) {
    auto opened = TraceWriter::open(options.trace_path, telemetry_columns());
    if (!opened) return Error{opened.error()};
    trace = std::move(opened.value());
  }
  // Everything the servo thread touches is allocated here, before it starts.
  using Loop = ServoLoop<DriverRef, RuntimeScene<S>, PinsT>;
  auto loop = std::make_unique<Loop>(DriverRef(driver), make_runtime_scene<S>(scene), config, pins);
  auto ring = std::make_unique<TelemetryRing>();
  ServoTask<S, PinsT> task(*loop, *ring);

  RealtimeOptions rt;
  rt.rate_hz = options.rate_hz;
  rt.deadlines = options.duration_s > 0.0 ? static_cast<std::int64_t>(std::llround(options.duration_s * options.rate_hz)) : 0;
  rt.priority = options.priority;
  rt.cpu = options.cpu;
  rt.allow_non_realtime = options.allow_non_realtime;
  rt.lock_memory = options.lock_memory;
  rt.watchdog_periods = config.safety.watchdog_periods;
  const EmergencyZero emergency{zero_driver, &driver};

  g_stop.store(0);
  if (options.handle_signals) install_signal_handlers(g_stop, emergency);
  const bool interactive = options.interactive && isatty(STDIN_FILENO) != 0;
  Writer writer{*ring, trace.get(), options.messages, options.sink, interactive, {}, summary};
  std::thread writer_thread([&writer] { writer.run(); });
  std::atomic<bool> finished{false};
  std::thread command_thread;
  if (interactive) {
    fmt::print(options.messages, "running; type q and Enter (or Ctrl-C) to stop, r and Enter to re-arm after a fault\n");
    command_thread = std::thread([&] { read_commands(*loop, g_stop, finished); });
  }

  auto* clocked = driver.info().self_clocked ? dynamic_cast<OmniDevice*>(&driver) : nullptr;
  auto report = clocked != nullptr ? run_device_clocked(task, *clocked, rt.deadlines, rt.lock_memory, g_stop)
                                   : run_realtime(task, rt, emergency, g_stop);
  finished.store(true);
  writer.finished.store(true, std::memory_order_release);
  writer_thread.join();
  if (command_thread.joinable()) command_thread.join();
  if (options.handle_signals) restore_signals();
  if (!report) return Error{report.error()};

  summary.report = std::move(report.value());
  summary.frames_dropped = ring->dropped();
  if (trace && !trace->close()) writer.write_failed = true;
  if (writer.write_failed) return Error{fmt::format("{}: writing the trace failed (disk full?)", options.trace_path)};
  return summary;
}

std::string json_latency(const LatencySummary& s) {
  const auto us = [](std::int64_t ns) { return static_cast<double>(ns) * 1e-3; };
  return fmt::format(
      "{{\"count\": {}, \"min\": {:.3f}, \"median\": {:.3f}, \"p99\": {:.3f}, \"p99_9\": {:.3f}, \"max\": {:.3f}, \"below_zero\": {}, "
      "\"overflow\": {}}}",
      s.count, us(s.min_ns), us(s.median_ns), us(s.p99_ns), us(s.p999_ns), us(s.max_ns), s.below_zero, s.overflow);
}

std::string stop_reason(int signal) {
  if (signal == 0) return "";
  if (signal == kStopByUser) return "stopped by the user";
  return fmt::format("stopped by {}", signal == 2 ? "SIGINT" : signal == 15 ? "SIGTERM" : fmt::format("signal {}", signal));
}

}  // namespace

namespace {

std::int64_t monotonic_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);  // vDSO: no system call
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// What the vendor's servo thread needs: the task, where to count, when to stop.
struct ClockedRun {
  PeriodicTask& task;
  RunReport& report;
  std::int64_t deadlines;
  const std::atomic<int>& stop;
  std::int64_t last_tick = -1;
  std::int64_t missed = 0;
};

TickVerdict clocked_tick(void* context, const ClockedTick& clock) noexcept {
  auto& run = *static_cast<ClockedRun*>(context);
  if (run.last_tick >= 0 && clock.tick > run.last_tick + 1) run.missed += clock.tick - run.last_tick - 1;
  run.last_tick = clock.tick;
  if (run.stop.load(std::memory_order_relaxed) != 0 || (run.deadlines > 0 && run.report.ticks >= run.deadlines)) {
    run.task.shutdown(clock.tick);  // zero force inside the frame, then the device stops
    return TickVerdict::kStop;
  }
  const std::int64_t start = monotonic_ns();
  run.task.tick(clock.tick);
  const std::int64_t compute = monotonic_ns() - start;
  const auto period_ns = static_cast<std::int64_t>(std::llround(clock.period_s * 1e9));
  TickTiming timing;
  timing.wake_latency_ns = run.report.ticks == 0 ? 0 : static_cast<std::int64_t>(std::llround(clock.dt_s * 1e9)) - period_ns;
  timing.compute_ns = compute;
  timing.slack_ns = period_ns - compute;
  timing.missed_total = run.missed;
  run.report.wake.record(timing.wake_latency_ns);
  run.report.compute.record(timing.compute_ns);
  run.report.slack.record(timing.slack_ns);
  ++run.report.ticks;
  run.task.publish(clock.tick, timing);
  return TickVerdict::kContinue;
}

}  // namespace

Result<RunReport> run_device_clocked(PeriodicTask& task, OmniDevice& device, std::int64_t deadlines, bool lock_memory,
                                     const std::atomic<int>& stop) {
  RunReport report;
  report.setup.priority = -1;  // the vendor's scheduler thread: its priority is not ours to set
  report.setup.notes = "wake-up latency here is the jitter of the device scheduler's period\n";
  if (lock_memory) {
    report.setup.memory_locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
    if (!report.setup.memory_locked) report.setup.notes += "mlockall refused: memory not locked\n";
  }
  ClockedRun run{task, report, deadlines, stop};
  const std::int64_t begin = monotonic_ns();
  auto started = device.start(&clocked_tick, &run);
  if (!started) return Error{started.error()};
  while (device.running()) static_cast<void>(device.wait_until_stopped(std::chrono::milliseconds(100)));
  device.stop();
  report.elapsed_s = static_cast<double>(monotonic_ns() - begin) * 1e-9;
  report.missed = run.missed;
  report.stop_signal = stop.load();
  const bool we_stopped = stop.load() != 0 || (deadlines > 0 && report.ticks >= deadlines);
  if (const std::string why = device.last_error(); !we_stopped && !why.empty()) {
    report.setup.notes += fmt::format("the device stopped the run: {}\n", why);
  }
  return report;
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
    if (!preset) return Error{fmt::format("--sim-device {}: unknown device model (falcon or omni)", options.sim_device)};
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
    auto driver = host_sim::SimDriver::create(host_sim::device_params(*preset), std::move(*intent), plant, options.seed);
    if (!driver) return Error{driver.error()};
    return std::unique_ptr<DeviceDriver>(std::move(driver.value()));
  }
  if (options.device == "falcon") return open_falcon(options.falcon);
  if (options.device == "omni") {
    OmniOptions omni = options.omni;
    omni.scheduler_rate_hz = options.rate_hz;
    auto device = open_omni(omni);
    if (!device) return Error{device.error()};
    return std::unique_ptr<DeviceDriver>(std::move(device.value()));
  }
  return Error{fmt::format("--device {}: unknown device (sim, falcon or omni)", options.device)};
}

Result<RunSummary> run_servo(const RunOptions& options) {
  if (!(options.rate_hz >= 500.0 && options.rate_hz <= 10000.0)) {
    return Error{fmt::format("--rate {}: the servo rate must be within 500..10000 Hz", options.rate_hz)};
  }
  if (!(options.duration_s >= 0.0) || !std::isfinite(options.duration_s)) {
    return Error{fmt::format("--duration {}: must be >= 0 seconds (0: until stopped)", options.duration_s)};
  }
  auto scene = load_scene_file(options.scene_path, options.scalar);
  if (!scene) return Error{scene.error()};
  auto device = open_device(options);
  if (!device) return Error{device.error()};
  DeviceDriver& driver = *device.value();
  // The GPIO pins are opened (and checked) before the loop starts; without GPIO options the
  // loop is built with NullPins and runs no GPIO code at all.
  auto result = gpio::with_gpio_pins(options.gpio, [&](auto& pins) -> Result<RunSummary> {
    switch (options.scalar) {
#if TOONFORCE_FIRMWARE
      case ScalarKind::kQ16_16: return run_as<Q16_16>(options, scene.value(), driver, pins);
      case ScalarKind::kDouble:
      case ScalarKind::kFloat: break;
    }
    return Error{fmt::format("--scalar {}: this is a firmware build (TOONFORCE_FIRMWARE=ON): the servo loop is "
                             "compiled for q16.16 only",
                             scalar_kind_name(options.scalar))};
#else
      case ScalarKind::kDouble: return run_as<double>(options, scene.value(), driver, pins);
      case ScalarKind::kFloat: return run_as<float>(options, scene.value(), driver, pins);
      case ScalarKind::kQ16_16: return run_as<Q16_16>(options, scene.value(), driver, pins);
    }
    return Error{"unknown scalar type"};
#endif
  });
  if (!result) return Error{result.error()};
  return std::move(result.value());
}

std::string format_run_summary(const RunSummary& s, const RunOptions& o) {
  const RunReport& r = s.report;
  std::string text;
  text += fmt::format("scene    {} ({}): {} surface(s), {} cliff(s); scalar {}\n", s.scene_name, o.scene_path, s.surfaces,
                      s.cliffs, scalar_kind_name(o.scalar));
  text += fmt::format("device   {} ({})\n", o.device, s.device_name);
  std::string rt = r.setup.priority < 0 ? "the device's own servo thread (its scheduler sets the priority)"
                   : r.setup.fifo     ? fmt::format("SCHED_FIFO {}", r.setup.priority)
                                      : "NOT real-time (normal scheduling)";
  rt += r.setup.memory_locked ? ", memory locked" : ", memory not locked";
  rt += r.setup.cpu >= 0 ? fmt::format(", pinned to CPU {}", r.setup.cpu) : ", not pinned";
  text += fmt::format("realtime {}\n", rt);
  std::string notes = r.setup.notes;
  while (!notes.empty() && notes.back() == '\n') notes.pop_back();
  if (!notes.empty()) text += fmt::format("note     {}\n", notes);
  const std::string why = stop_reason(r.stop_signal);
  text += fmt::format("run      {} ticks at {} Hz over {:.3f} s{}; {} deadline(s) missed; watchdog trips {}\n", r.ticks,
                      o.rate_hz, r.elapsed_s, why.empty() ? "" : " (" + why + ")", r.missed, r.watchdog_trips);
  text += "timing   [us]             min   median      p99    p99.9      max\n";
  const auto row = [&text](std::string_view name, const LatencySummary& l) {
    const auto us = [](std::int64_t ns) { return static_cast<double>(ns) * 1e-3; };
    text += fmt::format("         {:<16}{:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f}\n", name, us(l.min_ns),
                        us(l.median_ns), us(l.p99_ns), us(l.p999_ns), us(l.max_ns));
  };
  row("wake-up latency", r.wake.summary());
  row("compute", r.compute.summary());
  row("slack", r.slack.summary());
  text += fmt::format("forces   peak {:.3f} N\n", s.peak_force_n);
  if (s.fault_bits == 0) {
    text += "faults   none\n";
  } else {
    text += fmt::format("faults   {} tick(s) with faults ({}); re-armed {} time(s); latched at the end: {}\n",
                        s.fault_ticks, describe_faults(s.fault_bits), s.rearms,
                        s.latched_at_end == 0 ? "none" : describe_faults(s.latched_at_end));
  }
  if (!o.trace_path.empty()) {
    text += fmt::format("trace    {}: {} rows, {} frame(s) dropped (telemetry ring full)\n", o.trace_path,
                        s.frames_written, s.frames_dropped);
  } else if (s.frames_dropped != 0) {
    text += fmt::format("telemetry {} frame(s) dropped (ring full)\n", s.frames_dropped);
  }
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
  out += fmt::format("  \"ticks\": {},\n  \"missed\": {},\n  \"watchdog_trips\": {},\n  \"stop_signal\": {},\n", r.ticks,
                     r.missed, r.watchdog_trips, r.stop_signal);
  out += fmt::format("  \"frames_written\": {},\n  \"frames_dropped\": {},\n", s.frames_written, s.frames_dropped);
  out += fmt::format("  \"fault_ticks\": {},\n  \"fault_bits\": {},\n  \"latched_at_end\": {},\n  \"rearms\": {},\n",
                     s.fault_ticks, s.fault_bits, s.latched_at_end, s.rearms);
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
    out += fmt::format("{}\"{}\": {}", first ? "" : ", ", static_cast<std::int64_t>(i) * r.wake.bin_ns() / 1000, bins[i]);
    first = false;
  }
  out += "}\n}\n";
  return out;
}

}  // namespace toonforce
