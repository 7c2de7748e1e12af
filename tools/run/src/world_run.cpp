// SPDX-License-Identifier: Apache-2.0
#include "toonforce/run/world_run.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <memory>
#include <utility>

#include <fmt/format.h>

#include "toonforce/config/falcon_calibration_file.hpp"
#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/control/clock_bridge.hpp"
#include "toonforce/control/guardian.hpp"
#include "toonforce/control/process_split.hpp"
#include "toonforce/control/world.hpp"
#include "toonforce/control/world_session.hpp"
#include "toonforce/host_sim/sim_driver.hpp"
#include "toonforce/sim/check.hpp"
#include "toonforce/sim/world_sim.hpp"
#include "toonforce/sim/world_trace.hpp"
#include "toonforce/trace/json.hpp"
#include "toonforce/trace/trace_writer.hpp"

namespace toonforce {
namespace {

/// A simulated device whose cable is pulled after `fail_after_reads` reads (`--fail`): from then
/// on it answers nothing and takes no force (each write still gives the plant zero force, so
/// its hand and handle go on moving in time).
class PulledCable final : public DeviceDriver {
 public:
  PulledCable(std::unique_ptr<DeviceDriver> inner, std::int64_t fail_after_reads)
      : inner_(std::move(inner)), fail_after_reads_(fail_after_reads) {}
  DeviceStatus read(DeviceReading& reading) noexcept override {
    const DeviceStatus status = inner_->read(reading);
    ++reads_;
    return failed() ? DeviceStatus::kDisconnected : status;
  }
  DeviceStatus write(const Vec3<double>& force_n) noexcept override {
    if (failed()) {
      static_cast<void>(inner_->write({}));
      return DeviceStatus::kDisconnected;
    }
    return inner_->write(force_n);
  }
  void emergency_zero() noexcept override { inner_->emergency_zero(); }
  const DeviceInfo& info() const noexcept override { return inner_->info(); }
  std::string last_error() const override { return failed() ? "its cable was pulled (--fail)" : inner_->last_error(); }

 private:
  bool failed() const noexcept { return reads_ > fail_after_reads_; }
  std::unique_ptr<DeviceDriver> inner_;
  std::int64_t fail_after_reads_;
  std::int64_t reads_ = 0;
};

struct Opened {
  /// Devices behind a bridge (ClockBridge): destroyed after their bridges (declared first).
  std::vector<std::unique_ptr<DeviceDriver>> bridged;
  std::vector<std::unique_ptr<DeviceDriver>> drivers;  ///< in device order
  std::vector<WorldRunDevice> devices;
};

WorldRunDevice named(const std::string& name, const std::string& backend, const std::string& driver,
                     const std::string& script) {
  WorldRunDevice d;
  d.name = name;
  d.backend = backend;
  d.device_name = driver;
  d.script = script;
  return d;
}

/// Every device of the world, opened as options.device says; nothing is left open on an error.
Result<Opened> open_world_devices(const WorldDescription& world, const RunOptions& options) {
  Opened out;
  std::string problems;
  // One hand script per simulated device, named; none twice, none for a device the world lacks.
  std::vector<std::string> scripts(world.devices.size());
  for (const auto& [name, path] : options.world_scripts) {
    const std::size_t i = world.device_index(name);
    if (i == world.devices.size()) {
      std::string names;
      for (const auto& d : world.devices) names += (names.empty() ? "" : ", ") + d.name;
      problems +=
          fmt::format("--script {}={}: the scene has no device '{}' (its devices: {})\n", name, path, name, names);
    } else if (!scripts[i].empty()) {
      problems += fmt::format("--script {}: device '{}' is given a hand script twice\n", name, name);
    } else {
      scripts[i] = path;
    }
  }
  if (options.world_fail && world.device_index(options.world_fail->first) == world.devices.size()) {
    problems += fmt::format("--fail {}: the scene has no such device\n", options.world_fail->first);
  }
  const auto preset = host_sim::parse_device_preset(options.sim_device);
  if (!preset) problems += fmt::format("--sim-device {}: unknown device model (falcon or omni)\n", options.sim_device);
  std::size_t falcons = 0;
  std::size_t omnis = 0;
  for (const WorldDeviceEntry& d : world.devices) {
    falcons += options.device == "scene" && d.backend == "falcon";
    omnis += options.device == "scene" && d.backend == "omni";
  }
  // Omnis to bridge once every device is open: OpenHaptics initialises each device before its
  // one scheduler starts, and the first bridge's run starts it.
  struct PendingOmni {
    std::size_t index;  // in out.drivers
    OmniDevice* omni;   // owned by out.bridged
    double max_force_age_s;
    std::string who;
  };
  std::vector<PendingOmni> pending;
  for (std::size_t i = 0; i < world.devices.size() && problems.empty(); ++i) {
    const WorldDeviceEntry& d = world.devices[i];
    const bool simulated = options.device == "sim" || d.backend == "sim";
    const std::string who = fmt::format("{}:{}: device '{}'", options.scene_path, d.line, d.name);
    if (!simulated && !scripts[i].empty()) {
      problems += fmt::format("--script {}={}: device '{}' is a {} (backend), not simulated; --device sim simulates "
                              "every device\n",
                              d.name, scripts[i], d.name, d.backend);
      break;
    }
    if (!simulated && options.world_fail && options.world_fail->first == d.name) {
      problems += fmt::format("--fail {}: only a simulated device's cable can be pulled\n", d.name);
      break;
    }
    std::unique_ptr<DeviceDriver> driver;
    if (simulated) {
      std::optional<host_sim::HandIntent> intent;
      if (scripts[i].empty()) {
        intent = host_sim::HandIntent::holding({0.0, 0.0, 0.01});
      } else {
        const auto text = options.world_script_texts.find(d.name);
        auto script = text != options.world_script_texts.end() ? parse_hand_script(text->second, scripts[i])
                                                               : load_hand_script(scripts[i]);
        if (!script) {
          problems += script.error();
          break;
        }
        if (std::string bad = hand_script_length_problem(scripts[i], script->intent.duration_s()); !bad.empty()) {
          problems += bad + "\n";
          break;
        }
        intent = std::move(script->intent);
      }
      host_sim::PlantOptions plant;
      plant.period_s = 1.0 / options.rate_hz;
      plant.substeps = std::max(1, static_cast<int>(std::ceil(4000.0 / options.rate_hz)));
      const SimulatedWorldDevice model = simulated_device(d, *preset, plant.period_s);
      auto sim = host_sim::SimDriver::create(model.params, std::move(*intent), plant, options.seed + i);
      if (!sim) {
        problems += fmt::format("{}: {}\n", who, sim.error());
        break;
      }
      driver = std::move(sim.value());
      if (options.world_fail && options.world_fail->first == d.name) {
        const auto reads = static_cast<std::int64_t>(std::llround(options.world_fail->second * options.rate_hz));
        driver = std::make_unique<PulledCable>(std::move(driver), reads);
      }
      out.devices.push_back(named(d.name, "sim", driver->info().name, scripts[i]));
    } else if (d.backend == "falcon") {
      if (falcons > 1 && d.select.empty()) {
        problems += fmt::format("{}: the world has {} Falcons: give each its `select`, the serial number `toonforce "
                                "devices` lists\n",
                                who, falcons);
        break;
      }
      FalconOptions falcon = options.falcon;
      falcon.serial = d.select;
      falcon.read_calibration = &falcon::read_falcon_calibration;
      auto opened = open_falcon(falcon);
      if (!opened) {
        problems += fmt::format("{}: {}\n", who, opened.error());
        break;
      }
      driver = std::move(opened.value());
      out.devices.push_back(named(d.name, "falcon", driver->info().name, ""));
    } else {
      if (omnis > 1 && d.select.empty()) {
        problems += fmt::format("{}: the world has {} Omnis: give each its `select = \"<device name>\"`, the name "
                                "Touch_Setup configured it with (OpenHaptics opens several devices by name)\n",
                                who, omnis);
        break;
      }
      OmniOptions omni = options.omni;
      omni.device_name = d.select;
      omni.scheduler_rate_hz = options.rate_hz;
      auto opened = open_omni(omni);
      if (!opened) {
        problems += fmt::format("{}: {}\n", who, opened.error());
        break;
      }
      const double period_s = 1.0 / options.rate_hz;
      const ServoConfig own = servo_config(d.settings, period_s);
      const double max_age_s = static_cast<double>(std::max<std::int64_t>(own.safety.watchdog_periods, 3)) * period_s;
      pending.push_back(PendingOmni{out.drivers.size(), opened.value().get(), max_age_s, who});
      out.devices.push_back(named(d.name, "omni", "", ""));  // named after its bridge, below
      out.bridged.push_back(std::move(opened.value()));
      out.drivers.push_back(nullptr);  // its bridge, below
      continue;
    }
    out.drivers.push_back(std::move(driver));
  }
  // OpenHaptics clocks each Omni from its one servo thread; the world ticks on the host's clock:
  // a bridge per Omni lets each go on at its own rate (control/clock_bridge.hpp). The first
  // bridge's run starts the scheduler, every further one joins it.
  for (const PendingOmni& p : pending) {
    if (!problems.empty()) break;
    auto bridge = ClockBridge::start(*p.omni, p.max_force_age_s);
    if (!bridge) {
      problems += fmt::format("{}: {}\n", p.who, bridge.error());
      break;
    }
    out.drivers[p.index] = std::move(bridge.value());
    out.devices[p.index].device_name = out.drivers[p.index]->info().name;
  }
  if (!problems.empty()) return Error{problems};
  return out;
}

/// The frames of a world run, on the session's writer thread: trace rows, per-device fault
/// messages, counts.
class WorldRunConsumer {
 public:
  WorldRunConsumer(const WorldDescription& world, WorldTrace* trace, WorldRowSink* rows, std::FILE* messages,
                   WorldRunSummary& summary, guardian::SharedPage* page)
      : world_(world),
        trace_(trace),
        rows_(rows),
        messages_(messages),
        summary_(summary),
        page_(page),
        latched_(world.devices.size(), 0) {}

  void consume(const WorldFrame& f) {
    ++summary_.frames_written;
    bool forced = false;
    bool any_latched = false;
    for (std::size_t i = 0; i < summary_.devices.size() && i < f.devices; ++i) {
      const WorldDeviceFrame& d = f.device[i];
      WorldRunDevice& s = summary_.devices[i];
      s.peak_force_n = std::max(s.peak_force_n, std::sqrt(dot(d.force_n, d.force_n)));
      if (d.faults != 0) ++s.fault_ticks;
      s.fault_bits |= d.faults;
      if (has(d.limits, Limit::kDeviceLimited)) ++s.device_limited_ticks;
      s.latched_at_end = d.latched;
      forced = forced || d.force_n != Vec3<double>{};
      any_latched = any_latched || d.latched != 0;
      const std::uint32_t added = d.latched & ~latched_[i];
      if (added != 0) {
        fmt::print(messages_, "t = {:.3f} s: device '{}': fault latched: {}; its force off until re-armed{}\n", f.t_s,
                   s.name, describe_faults(added), interactive_ ? " (type r and Enter)" : "");
        std::fflush(messages_);
      }
      latched_[i] = d.latched;
    }
    if (f.held && !held_) {
      fmt::print(messages_, "t = {:.3f} s: one stop: every device held at zero force (started by device '{}')\n", f.t_s,
                 f.held_by < summary_.devices.size() ? summary_.devices[f.held_by].name : "?");
      std::fflush(messages_);
    }
    if (held_ && !f.held && !any_latched) {
      fmt::print(messages_, "t = {:.3f} s: re-armed\n", f.t_s);
      std::fflush(messages_);
      ++summary_.rearms;
    }
    if (f.held && !summary_.held_at_s) {
      summary_.held_at_s = f.t_s;
      summary_.held_by = f.held_by < summary_.devices.size() ? summary_.devices[f.held_by].name : "";
    } else if (f.held && held_ && forced) {
      ++summary_.forced_while_held;
    }
    held_ = f.held;
    summary_.coupling_imbalance_n = std::max(summary_.coupling_imbalance_n, coupling_imbalance_n(f));
    if (rows_ != nullptr || (trace_ != nullptr && !write_failed_)) world_row(f, row_);
    if (rows_ != nullptr) rows_->row(row_);
    if (trace_ != nullptr && !write_failed_) {
      if (!trace_->write(row_)) trace_failed(f);
      // With a guardian, the trace goes to the file every 20 ms of loop time: if this process
      // dies, the guardian ends the trace after what the file holds.
      if (!write_failed_ && page_ != nullptr && f.t_s - flushed_t_s_ >= 0.02) {
        flushed_t_s_ = f.t_s;
        if (!trace_->flush()) trace_failed(f);
      }
    }
  }
  void finish() {}
  void set_interactive(bool interactive) noexcept { interactive_ = interactive; }
  std::uint64_t trace_limit_bytes = 0;

 private:
  void trace_failed(const WorldFrame& f) {
    write_failed_ = true;
    if (trace_->size_limit_reached()) {
      summary_.trace_error = fmt::format("stopped at t = {:.3f} s: it reached --max-output {} (give a larger one, or 0 "
                                         "for no limit)",
                                         f.t_s, describe_bytes(trace_limit_bytes));
    } else {
      summary_.trace_error =
          fmt::format("writing failed at t = {:.3f} s: {}", f.t_s, std::strerror(errno != 0 ? errno : EIO));
    }
    fmt::print(messages_, "t = {:.3f} s: the trace {}: nothing more is written, the run goes on\n", f.t_s,
               summary_.trace_error);
    std::fflush(messages_);
  }
  const WorldDescription& world_;
  WorldTrace* trace_;
  WorldRowSink* rows_;
  std::FILE* messages_;
  WorldRunSummary& summary_;
  guardian::SharedPage* page_;
  std::vector<std::uint32_t> latched_;
  std::vector<double> row_;
  bool held_ = false;
  bool write_failed_ = false;
  bool interactive_ = false;
  double flushed_t_s_ = 0.0;
};

template <std::size_t N>
Result<WorldRunSummary> run_world_of(const RunOptions& options, const WorldDescription& world, Opened& opened,
                                     DeviceGroup& group) {
  // Live (the world's stages take scene updates) in every run: one atomic load a tick when no
  // control protocol sends any (docs/performance/world.md); one instantiation per size.
  using RunWorld = World<DriverRef, RuntimeScene<double>, N, kLiveStages>;
  const double period_s = 1.0 / options.rate_hz;
  std::vector<DriverRef> refs;
  refs.reserve(N);  // the world keeps pointers to them: no reallocation after this
  std::vector<ServoConfig> configs;
  for (std::size_t i = 0; i < N; ++i) {
    refs.emplace_back(*opened.drivers[i]);
    const WorldDeviceEntry& d = world.devices[i];
    configs.push_back(with_device(servo_config(d.settings, period_s), opened.drivers[i]->info()));
    if (const std::string bad = check_servo_config(configs.back()); !bad.empty()) {
      return Error{fmt::format("{}:{}: device '{}': the servo configuration does not work:\n{}", options.scene_path,
                               d.line, d.name, bad)};
    }
  }
  // Each device's scene: the effects that act on it (`devices`, every one by default).
  std::vector<RuntimeScene<double>> scenes;
  for (std::size_t i = 0; i < N; ++i) scenes.push_back(make_runtime_scene<double>(world.scene_for(i)));
  const auto members = [&]<std::size_t... I>(std::index_sequence<I...>) {
    return std::array<typename RunWorld::Member, N>{
        typename RunWorld::Member{&refs[I], scenes[I], world.devices[I].frame, configs[I]}...};
  }
  (std::make_index_sequence<N>{});
  WorldConfig config = world_config(world);
  if (const std::string bad = check(config, N); !bad.empty())
    return Error{fmt::format("{}: {}", options.scene_path, bad)};
  auto run_world_object = std::make_unique<RunWorld>(members, config);
  WorldMailbox<RuntimeScene<double>>* mailbox = options.live != nullptr ? options.live->of_world : nullptr;
  if (mailbox != nullptr) run_world_object->listen(*mailbox);

  WorldRunSummary summary;
  summary.scene_name = world.scene.name;
  summary.devices = opened.devices;
  summary.couplings = world.couplings.size();
  summary.has_ball = world.ball.has_value();
  std::unique_ptr<WorldTrace> trace;
  if (!options.trace_path.empty()) {
    auto file = WorldTrace::open(options.trace_path, world_columns(world), "--trace");
    if (!file) return Error{file.error()};
    trace = std::move(file.value());
    trace->limit_size(options.max_output_bytes);
  }
  // The heartbeat watchdog outside the loop: the most patient of the devices' own.
  std::int64_t watchdog = 0;
  for (const ServoConfig& c : configs) watchdog = std::max(watchdog, c.safety.watchdog_periods);
  const SessionOptions session = session_options(options, watchdog);
  if (options.world_rows != nullptr) options.world_rows->begin(world_columns(world), session.realtime.deadlines);
  WorldRunConsumer consumer(world, trace.get(), options.world_rows, options.messages, summary, options.guardian);
  consumer.set_interactive(options.interactive && isatty(STDIN_FILENO) != 0);
  consumer.trace_limit_bytes = options.max_output_bytes;
  auto report = run_world(*run_world_object, group, consumer, session);
  after_session(options);
  if (!report) return Error{report.error()};
  summary.report = std::move(report->report);
  summary.frames_dropped = report->frames_dropped;
  if (mailbox != nullptr) {
    summary.live = true;
    summary.updates_applied = run_world_object->loop(0).updates_applied();
    summary.updates_refused = run_world_object->updates_refused();
  }
  for (std::size_t i = 0; i < N; ++i) {
    if (auto* bridge = dynamic_cast<ClockBridge*>(opened.drivers[i].get())) {
      bridge->stop();  // its thread's last tick writes zero; then its measures are whole
      WorldRunDevice& d = summary.devices[i];
      d.bridged = true;
      d.reading_age = bridge->reading_age().summary();
      d.force_age = bridge->force_age().summary();
      d.stale_force_ticks = bridge->stale_force_ticks();
    }
  }
  if (trace && !trace->close() && summary.trace_error.empty()) {
    summary.trace_error = fmt::format("writing its end failed: {}", std::strerror(errno != 0 ? errno : EIO));
  }
  return summary;
}

}  // namespace

Result<WorldRunSummary> run_world_servo(const RunOptions& options) {
  if (const std::string bad = run_options_problem(options); !bad.empty()) return Error{bad};
  if (options.device != "sim" && options.device != "scene") {
    return Error{fmt::format("--device {}: {} is a world scene ([[device]] tables), which names its devices: "
                             "--device scene opens each as its table says (backend, select), --device sim simulates "
                             "every one",
                             options.device, options.scene_path)};
  }
  if (options.scalar != ScalarKind::kDouble) {
    return Error{fmt::format("--scalar {}: a world runs in double (q16.16 and float are for one-device scenes)",
                             scalar_kind_name(options.scalar))};
  }
  if (options.world_fail && !(options.world_fail->second >= 0.0 && std::isfinite(options.world_fail->second))) {
    return Error{fmt::format("--fail {}@{}: the time must be >= 0 seconds", options.world_fail->first,
                             options.world_fail->second)};
  }
  // No output may replace an input.
  for (const auto& [output, flag] :
       {std::pair{options.trace_path, "--trace"}, std::pair{options.stats_json_path, "--stats-json"}}) {
    std::vector<std::string> inputs{options.scene_path};
    for (const auto& [name, path] : options.world_scripts) inputs.push_back(path);
    for (const std::string& input : inputs) {
      std::error_code ec;
      if (!output.empty() && output != "-" && std::filesystem::equivalent(output, input, ec) && !ec) {
        return Error{fmt::format("{} {} is an input of the run ({}): it would be overwritten; choose another file",
                                 flag, output, input)};
      }
    }
  }
  auto loaded =
      options.scene_text ? parse_world(*options.scene_text, options.scene_path) : load_world_file(options.scene_path);
  if (!loaded) return Error{loaded.error()};
  const WorldDescription& world = loaded.value();
  {
    // `check`'s report of the world, per device in its own frame, before anything opens.
    CheckOptions check;
    check.scene_path = options.scene_path;
    check.scene_text = options.scene_text;
    if (const auto preset = host_sim::parse_device_preset(options.sim_device)) check.device = *preset;
    check.rate_hz = options.rate_hz;
    check.allow_empty = options.allow_empty;
    check.strict = options.strict;
    const CheckReport report = check_scene(check);
    std::string errors;
    for (const std::string& e : report.errors) errors += e + (e.empty() || e.back() != '\n' ? "\n" : "");
    if (!errors.empty()) return Error{errors};
    std::string text;
    for (const std::string& w : report.warnings) text += fmt::format("warning: {}\n", w);
    if (!text.empty() && options.strict) return Error{text + "--strict: the run does not start with a warning"};
    if (!text.empty()) fmt::print(options.messages, "{}", text);
  }
  if (options.guardian != nullptr && !wait_for_guardian(*options.guardian, 10.0)) {
    return Error{"the guardian process did not start watching (it said why above): no device was opened"};
  }
  auto opened = open_world_devices(world, options);
  if (!opened) return Error{opened.error()};
  std::vector<DeviceDriver*> drivers;
  std::vector<std::string> names;
  for (std::size_t i = 0; i < opened->drivers.size(); ++i) {
    drivers.push_back(opened->drivers[i].get());
    names.push_back(world.devices[i].name);
  }
  auto group = DeviceGroup::create(drivers, names);
  if (!group) return Error{group.error()};
  if (options.guardian != nullptr) {  // from here until the loop ends, the guardian zeroes every device it can reach
    guardian::SharedPage& page = *options.guardian;
    page.zero_count = static_cast<std::uint32_t>(std::min(drivers.size(), guardian::kMaxGuardedDevices));
    for (std::size_t i = 0; i < page.zero_count; ++i) page.zeros[i] = drivers[i]->external_zero();
    page.period_ns = static_cast<std::int64_t>(std::llround(1e9 / options.rate_hz));
    page.phase.store(static_cast<std::uint32_t>(guardian::Phase::kDeviceOpen), std::memory_order_release);
  }
  Result<WorldRunSummary> result = Error{std::string()};
  switch (drivers.size()) {
    case 1: result = run_world_of<1>(options, world, opened.value(), *group.value()); break;
    case 2: result = run_world_of<2>(options, world, opened.value(), *group.value()); break;
    case 3: result = run_world_of<3>(options, world, opened.value(), *group.value()); break;
    case 4: result = run_world_of<4>(options, world, opened.value(), *group.value()); break;
    default:
      result = Error{
          fmt::format("{}: {} devices; a world has 1 to {}", options.scene_path, drivers.size(), kMaxWorldDevices)};
  }
  if (options.guardian != nullptr) options.guardian->loop_ended.store(1, std::memory_order_release);
  return result;
}

std::string format_world_run_summary(const WorldRunSummary& s, const RunOptions& o) {
  std::string text = fmt::format("world    {} ({}): {} device(s), {} coupling(s){}\n", s.scene_name, o.scene_path,
                                 s.devices.size(), s.couplings, s.has_ball ? ", a ball" : "");
  for (const WorldRunDevice& d : s.devices) {
    text += fmt::format("device   {}: {} ({}){}\n", d.name, d.backend, d.device_name,
                        d.script.empty() ? "" : fmt::format(", hand {}", d.script));
  }
  text += format_run_timing(s.report, o.rate_hz);
  for (const WorldRunDevice& d : s.devices) {
    text += fmt::format("device   {}: peak force {:.3f} N; ", d.name, d.peak_force_n);
    if (d.fault_bits == 0) {
      text += "faults none";
    } else {
      text += fmt::format("{} tick(s) with faults ({}); latched at the end: {}", d.fault_ticks,
                          describe_faults(d.fault_bits),
                          d.latched_at_end == 0 ? "none" : describe_faults(d.latched_at_end));
    }
    if (d.device_limited_ticks > 0) {
      text += fmt::format("; could not give the force asked in {} tick(s)", d.device_limited_ticks);
    }
    text += "\n";
    if (d.bridged) {
      const auto ms = [](std::int64_t ns) { return static_cast<double>(ns) * 1e-6; };
      text +=
          fmt::format("clocks   {}: on its own servo thread; reading age median {:.3f} ms, p99 {:.3f}, max {:.3f} "
                      "(when the world used it); force age median {:.3f} ms, p99 {:.3f}, max {:.3f} (when the "
                      "device applied it); {} device tick(s) zeroed a force too old\n",
                      d.name, ms(d.reading_age.median_ns), ms(d.reading_age.p99_ns), ms(d.reading_age.max_ns),
                      ms(d.force_age.median_ns), ms(d.force_age.p99_ns), ms(d.force_age.max_ns), d.stale_force_ticks);
    }
  }
  if (s.couplings > 0) {
    text += fmt::format("between  couplings: largest |sum of the forces on their two ends| {:.3g} N\n",
                        s.coupling_imbalance_n);
  }
  if (s.held_at_s) {
    text += fmt::format("stop     at t = {:.4f} s device '{}' latched a fault: every device held at zero force ({} "
                        "frame(s) after that with any force); re-armed {} time(s)\n",
                        *s.held_at_s, s.held_by, s.forced_while_held, s.rearms);
  }
  if (s.live) {
    text += fmt::format("live     {} scene update(s) applied (each on every device at once), {} refused{}\n",
                        s.updates_applied, s.updates_refused,
                        s.updates_refused > 0 ? " (they failed the loop's checks: docs/spec/live-scenes.md)" : "");
  }
  text += format_run_trace(o.trace_path, s.trace_error, s.frames_written, s.frames_dropped);
  return text;
}

std::string world_stats_json(const WorldRunSummary& s, const RunOptions& o) {
  const RunReport& r = s.report;
  std::string out = "{\n";
  out += fmt::format("  \"world\": true,\n  \"scene\": {},\n  \"scene_file\": {},\n", json_string(s.scene_name),
                     json_string(o.scene_path));
  out += fmt::format("  \"rate_hz\": {},\n  \"duration_s\": {},\n  \"elapsed_s\": {},\n", o.rate_hz, o.duration_s,
                     r.elapsed_s);
  out += fmt::format("  \"ticks\": {},\n  \"missed\": {},\n  \"watchdog_trips\": {},\n  \"stop_signal\": {},\n",
                     r.ticks, r.missed, r.watchdog_trips, r.stop_signal);
  out += fmt::format("  \"frames_written\": {},\n  \"frames_dropped\": {},\n", s.frames_written, s.frames_dropped);
  out += fmt::format("  \"coupling_imbalance_n\": {},\n", s.coupling_imbalance_n);
  out += fmt::format("  \"held_at_s\": {},\n  \"held_by\": {},\n  \"forced_while_held\": {},\n  \"rearms\": {},\n",
                     s.held_at_s ? fmt::format("{}", *s.held_at_s) : "null", json_string(s.held_by),
                     s.forced_while_held, s.rearms);
  if (s.live) {
    out +=
        fmt::format("  \"updates_applied\": {},\n  \"updates_refused\": {},\n", s.updates_applied, s.updates_refused);
  }
  out += "  \"devices\": [";
  for (std::size_t i = 0; i < s.devices.size(); ++i) {
    const WorldRunDevice& d = s.devices[i];
    out +=
        fmt::format("{}\n    {{\"name\": {}, \"backend\": {}, \"device_name\": {}, \"peak_force_n\": {}, "
                    "\"fault_ticks\": {}, \"fault_bits\": {}, \"faults\": {}, \"latched_at_end\": {}, "
                    "\"device_limited_ticks\": {}{}}}",
                    i == 0 ? "" : ",", json_string(d.name), json_string(d.backend), json_string(d.device_name),
                    d.peak_force_n, d.fault_ticks, d.fault_bits, json_string(describe_faults(d.fault_bits)),
                    d.latched_at_end, d.device_limited_ticks,
                    d.bridged ? fmt::format(", \"reading_age_us\": {}, \"force_age_us\": {}, \"stale_force_ticks\": {}",
                                            json_latency(d.reading_age), json_latency(d.force_age), d.stale_force_ticks)
                              : std::string());
  }
  out += "\n  ],\n";
  out += fmt::format("  \"realtime\": {{\"sched_fifo\": {}, \"priority\": {}, \"memory_locked\": {}, \"cpu\": {}, "
                     "\"notes\": {}}},\n",
                     r.setup.fifo, r.setup.priority, r.setup.memory_locked, r.setup.cpu, json_string(r.setup.notes));
  out += fmt::format("  \"wake_latency_us\": {},\n", json_latency(r.wake.summary()));
  out += fmt::format("  \"compute_us\": {},\n", json_latency(r.compute.summary()));
  out += fmt::format("  \"slack_us\": {}\n", json_latency(r.slack.summary()));
  out += "}\n";
  return out;
}

}  // namespace toonforce
