// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/world_sim.hpp"

#include <signal.h>
#include <string.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <algorithm>
#include <array>
#include <iterator>
#include <memory>

#include <fmt/format.h>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/control/supervisor.hpp"
#include "toonforce/control/world.hpp"
#include "toonforce/control/world_frame.hpp"
#include "toonforce/sim/world_trace.hpp"
#include "toonforce/host_sim/sim_device.hpp"
#include "toonforce/host_sim/sim_driver.hpp"

namespace toonforce {

namespace {

/// A simulated device of a world, whose cable may be pulled at a time: from then on it answers
/// nothing and gives no force, while its hand and handle go on moving (the simulated time goes
/// on: every write still advances the plant, with zero force).
class WorldSimDevice {
 public:
  WorldSimDevice(host_sim::SimDevice device, std::optional<double> fail_at_s) noexcept
      : device_(std::move(device)), fail_at_s_(fail_at_s) {}
  DeviceStatus read(DeviceReading& reading) noexcept {
    const DeviceStatus status = device_.read(reading);
    return failed() ? DeviceStatus::kDisconnected : status;
  }
  DeviceStatus write(const Vec3<double>& force_n) noexcept {
    if (failed()) {
      static_cast<void>(device_.write({}));
      return DeviceStatus::kDisconnected;
    }
    return device_.write(force_n);
  }
  bool failed() const noexcept { return fail_at_s_ && device_.time_s() >= *fail_at_s_ - 1e-12; }
  host_sim::SimDevice& sim() noexcept { return device_; }

 private:
  host_sim::SimDevice device_;
  std::optional<double> fail_at_s_;
};

struct Prepared {
  WorldDescription world;
  std::vector<HandScriptFile> hands;            ///< in device order
  std::vector<SimulatedWorldDevice> simulated;  ///< in device order
  double period_s = 1e-3;
  std::int64_t ticks = 0;
};

template <std::size_t N>
Result<WorldSimSummary> run(Prepared& p, const WorldSimOptions& options) {
  using SimWorld = World<WorldSimDevice, RuntimeScene<double>, N>;
  std::vector<WorldSimDevice> devices;
  devices.reserve(N);  // the world keeps pointers to them: no reallocation after this
  for (std::size_t i = 0; i < N; ++i) {
    auto device = host_sim::SimDevice::create(p.simulated[i].params, p.hands[i].intent,
                                              {options.integrator, options.substeps, p.period_s}, options.seed + i);
    if (!device) return Error{fmt::format("device {}: {}", p.world.devices[i].name, device.error())};
    std::optional<double> fail_at;
    if (options.fail && options.fail->first == p.world.devices[i].name) fail_at = options.fail->second;
    devices.emplace_back(std::move(device).value(), fail_at);
  }
  // Each device's scene: the effects that act on it (`devices`, every one by default).
  std::vector<RuntimeScene<double>> scenes;
  for (std::size_t i = 0; i < N; ++i) scenes.push_back(make_runtime_scene<double>(p.world.scene_for(i)));
  std::array<typename SimWorld::Member, N> members = [&]<std::size_t... I>(std::index_sequence<I...>) {
    return std::array<typename SimWorld::Member, N>{
        typename SimWorld::Member{&devices[I], scenes[I], p.world.devices[I].frame, p.simulated[I].config}...};
  }
  (std::make_index_sequence<N>{});
  WorldConfig config = world_config(p.world);
  if (const std::string bad = check(config, N); !bad.empty())
    return Error{fmt::format("{}: {}", options.scene_path, bad)};
  auto world = std::make_unique<SimWorld>(members, config);

  const std::vector<std::string> columns = world_columns(p.world);
  std::unique_ptr<WorldTrace> trace;
  if (!options.trace_path.empty()) {
    auto opened = WorldTrace::open(options.trace_path, columns, "--trace");
    if (!opened) return Error{opened.error()};
    trace = std::move(opened.value());
  }
  if (options.rows != nullptr) options.rows->begin(columns, p.ticks);
  WorldSimSummary summary;
  summary.scene_name = p.world.scene.name;
  for (std::size_t i = 0; i < N; ++i) {
    summary.devices.push_back({p.world.devices[i].name, p.hands[i].script.name, 0.0, 0, 0, 0, {}});
  }
  std::vector<double> row;
  WorldFrame frame;
  const auto record = [&](std::int64_t k, const WorldStatus<N>& status) {
    fill_world_frame(*world, status, k, p.period_s, frame);
    world_row(frame, row);
    bool forced = false;
    for (std::size_t i = 0; i < N; ++i) {
      const WorldDeviceFrame& f = frame.device[i];
      WorldSimDeviceSummary& d = summary.devices[i];
      d.peak_force_n = std::max(d.peak_force_n, std::sqrt(dot(f.force_n, f.force_n)));
      if (f.faults != 0) ++d.fault_ticks;
      d.latched = f.latched;
      d.state = f.state;
      d.final_hip_m = f.hip_m;
      forced = forced || f.force_n != Vec3<double>{};
    }
    summary.coupling_imbalance_n = std::max(summary.coupling_imbalance_n, coupling_imbalance_n(frame));
    if (frame.has_ball) summary.final_ball_m = frame.ball_m;
    if (frame.held && !summary.held_at_s) {
      summary.held_at_s = frame.t_s;
      summary.held_by = frame.held_by < N ? p.world.devices[frame.held_by].name : "";
    } else if (frame.held && forced) {
      ++summary.forced_while_held;  // from the tick after the hold began
    }
    if (trace) trace->write(row);
    if (options.rows != nullptr) options.rows->row(row);
  };
  const auto stopped = [&options] { return options.stop != nullptr && options.stop->load() != 0; };
  std::int64_t k = 0;
  for (; k < p.ticks && !stopped(); ++k) record(k, world->tick(k));
  if (k < p.ticks && stopped()) {
    summary.stop_signal = options.stop->load();
    world->shutdown(k);
    record(k, shutdown_status(*world));
  }
  summary.ticks = k;
  summary.duration_s = static_cast<double>(k) * p.period_s;
  if (trace && !trace->close()) {
    return Error{
        fmt::format("--trace {}: writing failed: {}", options.trace_path, std::strerror(errno != 0 ? errno : EIO))};
  }
  return summary;
}

}  // namespace

SimulatedWorldDevice simulated_device(const WorldDeviceEntry& device, host_sim::DevicePreset for_sim, double period_s) {
  const host_sim::DevicePreset preset = device.backend == "omni"     ? host_sim::DevicePreset::kOmni
                                        : device.backend == "falcon" ? host_sim::DevicePreset::kFalcon
                                                                     : for_sim;
  SimulatedWorldDevice out{host_sim::device_params(preset), {}};
  out.config = with_device(servo_config(device.settings, period_s), host_sim::device_info(out.params, period_s));
  return out;
}

Result<std::pair<std::string, std::string>> parse_named_script(const std::string& text) {
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == text.size()) {
    return Error{fmt::format("--script {}: a world scene takes one hand script per device, as NAME=FILE "
                             "(the device's name in the scene's [[device]] table)",
                             text)};
  }
  return std::pair{text.substr(0, eq), text.substr(eq + 1)};
}

Result<WorldSimSummary> run_world_sim(const WorldSimOptions& options) {
  if (!(options.rate_hz > 0.0) || !std::isfinite(options.rate_hz)) {
    return Error{fmt::format("--rate must be a positive number of Hz (got {})", options.rate_hz)};
  }
  if (options.duration_s && !(*options.duration_s > 0.0 && *options.duration_s <= 86400.0)) {
    return Error{fmt::format("--duration must be in (0, 86400] s (got {})", *options.duration_s)};
  }
  for (const auto& [name, script] : options.scripts) {
    std::error_code ec;
    if (options.trace_path != "-" && !options.trace_path.empty() &&
        (std::filesystem::equivalent(options.trace_path, script, ec) ||
         std::filesystem::equivalent(options.trace_path, options.scene_path, ec))) {
      return Error{fmt::format("--trace {} is one of the inputs: it would be overwritten; choose another file",
                               options.trace_path)};
    }
  }
  Prepared p;
  auto world =
      options.scene_text ? parse_world(*options.scene_text, options.scene_path) : load_world_file(options.scene_path);
  if (!world) return Error{world.error()};
  p.world = std::move(world).value();
  p.period_s = 1.0 / options.rate_hz;
  // One hand script per device, named; none twice, none for a device the world lacks.
  std::string problems;
  p.hands.resize(p.world.devices.size());
  std::vector<bool> given(p.world.devices.size(), false);
  for (const auto& [name, path] : options.scripts) {
    const std::size_t i = p.world.device_index(name);
    if (i == p.world.devices.size()) {
      std::string names;
      for (const auto& d : p.world.devices) names += (names.empty() ? "" : ", ") + d.name;
      problems +=
          fmt::format("--script {}={}: the scene has no device '{}' (its devices: {})\n", name, path, name, names);
      continue;
    }
    if (given[i]) {
      problems += fmt::format("--script {}: device '{}' is given a hand script twice\n", name, name);
      continue;
    }
    given[i] = true;
    const auto text = options.script_texts.find(name);
    auto hand = text != options.script_texts.end() ? parse_hand_script(text->second, path) : load_hand_script(path);
    if (!hand) {
      problems += hand.error();
      if (problems.back() != '\n') problems += '\n';
      continue;
    }
    p.hands[i] = std::move(hand).value();
  }
  for (std::size_t i = 0; i < given.size(); ++i) {
    if (!given[i]) {
      problems += fmt::format("device '{}' has no hand script: give --script {}=FILE (one per device of {})\n",
                              p.world.devices[i].name, p.world.devices[i].name, options.scene_path);
    }
  }
  if (options.fail && p.world.device_index(options.fail->first) == p.world.devices.size()) {
    problems += fmt::format("--fail {}: the scene has no such device\n", options.fail->first);
  }
  if (!problems.empty()) return Error{problems};
  // Each device's loop: its own [device] keys, completed by the simulated device's figures.
  double longest_s = 0.0;
  for (std::size_t i = 0; i < p.world.devices.size(); ++i) {
    const WorldDeviceEntry& d = p.world.devices[i];
    p.simulated.push_back(simulated_device(d, options.device, p.period_s));
    if (const std::string bad = check_servo_config(p.simulated.back().config); !bad.empty()) {
      return Error{fmt::format("{}:{}: device '{}': the servo configuration does not work:\n{}", options.scene_path,
                               d.line, d.name, bad)};
    }
    longest_s = std::max(longest_s, p.hands[i].intent.duration_s());
  }
  const double duration_s = options.duration_s.value_or(longest_s);
  p.ticks = std::llround(duration_s / p.period_s);
  if (p.ticks < 1) return Error{"nothing to simulate: give --duration (the hand scripts last no time)"};
  switch (p.world.devices.size()) {
    case 1: return run<1>(p, options);
    case 2: return run<2>(p, options);
    case 3: return run<3>(p, options);
    case 4: return run<4>(p, options);
    default:
      return Error{fmt::format("{}: {} devices; a world has 1 to {}", options.scene_path, p.world.devices.size(),
                               kMaxWorldDevices)};
  }
}

std::string format_world_sim_summary(const WorldSimSummary& s, const WorldSimOptions& options) {
  std::string text = fmt::format("world   {} ({}); {} devices; {:g} Hz\n", s.scene_name, options.scene_path,
                                 s.devices.size(), options.rate_hz);
  text += fmt::format("ran     {} ticks = {:.6g} s simulated\n", s.ticks, s.duration_s);
  for (const WorldSimDeviceSummary& d : s.devices) {
    std::string latched;
    for (const Fault f : kAllFaults) {
      if ((d.latched & static_cast<std::uint32_t>(f)) != 0)
        latched += fmt::format("{}{}", latched.empty() ? "" : ",", fault_name(f));
    }
    text += fmt::format("device  {} (hand {}): peak force {:.4g} N; faults {} ticks; {} at the end{}; HIP at "
                        "[{:.4g}, {:.4g}, {:.4g}] m\n",
                        d.name, d.script, d.peak_force_n, d.fault_ticks, to_string(static_cast<LoopState>(d.state)),
                        latched.empty() ? "" : fmt::format(" (latched: {})", latched), d.final_hip_m.x, d.final_hip_m.y,
                        d.final_hip_m.z);
  }
  text += fmt::format("between couplings: largest |sum of the forces on their two ends| {:.3g} N\n",
                      s.coupling_imbalance_n);
  if (s.final_ball_m) {
    text += fmt::format("ball    at [{:.4g}, {:.4g}, {:.4g}] m at the end\n", s.final_ball_m->x, s.final_ball_m->y,
                        s.final_ball_m->z);
  }
  if (s.held_at_s) {
    text += fmt::format("stop    at t = {:.6g} s device '{}' latched a fault: every device held at zero force from "
                        "the next tick ({} ticks after that with any force)\n",
                        *s.held_at_s, s.held_by, s.forced_while_held);
  }
  if (s.stop_signal != 0) {
    const char* abbrev = sigabbrev_np(s.stop_signal);
    text += fmt::format("stopped by {}: the last row is the shut-down tick (zero force on every device)\n",
                        abbrev != nullptr ? fmt::format("SIG{}", abbrev) : fmt::format("signal {}", s.stop_signal));
  }
  if (options.trace_path != "-" && !options.trace_path.empty()) text += fmt::format("trace   {}\n", options.trace_path);
  return text;
}

}  // namespace toonforce
