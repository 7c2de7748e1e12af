// SPDX-License-Identifier: Apache-2.0
// `toonforce bringup gpio` (see gpio_bringup.hpp).
#include "toonforce/bringup/gpio_bringup.hpp"

#include <time.h>

#include <cmath>
#include <functional>

#include <fmt/format.h>

#include "toonforce/bringup/falcon_bringup.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/hal/gpio/gpio_session.hpp"

namespace toonforce::bringup {
namespace {

class AbortRequested {};

/// The device of the e-stop and enable steps: the HIP where the step puts it, and the force
/// the loop wrote last.
struct Bench {
  Vec3<double> position_m{0.0, 0.0, 0.01};
  Vec3<double> written_n{};
};
struct BenchDevice {
  Bench* bench;
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = bench->position_m;
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>& f) noexcept {
    bench->written_n = f;
    return DeviceStatus::kOk;
  }
};
static_assert(ServoDevice<BenchDevice>);

// A floor at z = 0, 200 N/m: 5 mm into it asks 1 N, well inside any device's limits.
constexpr const char* kBenchScene =
    "name = \"bring-up bench\"\n[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 200.0\n";
constexpr Vec3<double> kInFloor{0.0, 0.0, -0.005};

using Loop = ServoLoop<BenchDevice, RuntimeScene<double>, gpio::GpioPins>;

class Clock {
 public:
  Clock(double rate_hz, bool paced) : period_ns_(static_cast<long>(std::lround(1e9 / rate_hz))), paced_(paced) {
    clock_gettime(CLOCK_MONOTONIC, &next_);
  }
  void wait_next() {
    ++k_;
    if (!paced_) return;
    next_.tv_nsec += period_ns_;
    while (next_.tv_nsec >= 1000000000L) {
      next_.tv_nsec -= 1000000000L;
      ++next_.tv_sec;
    }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next_, nullptr);
  }
  std::int64_t k() const { return k_; }

 private:
  long period_ns_;
  bool paced_;
  timespec next_{};
  std::int64_t k_ = 0;
};

StepReport make_step(const char* id, const char* title) {
  StepReport s;
  s.id = id;
  s.title = title;
  return s;
}
StepReport& fail(StepReport& s, std::string finding, std::string next) {
  s.outcome = Outcome::kFail;
  s.finding = std::move(finding);
  s.next = std::move(next);
  return s;
}
StepReport& pass(StepReport& s, std::string finding) {
  s.outcome = Outcome::kPass;
  s.finding = std::move(finding);
  return s;
}
void measure(StepReport& s, std::string name, std::string value, std::string unit = {}) {
  s.measurements.push_back({std::move(name), std::move(value), std::move(unit)});
}

enum class End { kCondition, kPerson, kTimeout };

/// Runs `tick` at the rate until `done()`, the person's Enter, or the timeout.
End wait(Operator& person, Clock& clock, const Request& r, double seconds, double rate_hz,
         const std::function<void()>& tick, const std::function<bool()>& done) {
  person.begin(r);
  const auto limit = static_cast<std::int64_t>(seconds * rate_hz);
  for (std::int64_t i = 0; i < limit; ++i) {
    tick();
    clock.wait_next();
    if (done && done()) return End::kCondition;
    switch (person.poll(r)) {
      case Progress::kDone: return End::kPerson;
      case Progress::kAbort: throw AbortRequested{};
      case Progress::kWaiting: break;
    }
  }
  return End::kTimeout;
}

StepReport tick_pin(Operator& person, gpio::GpioPins& pins, const GpioBringupOptions& o) {
  StepReport s = make_step("tick", "Tick pin");
  Clock clock(o.rate_hz, o.paced);
  const double expected_hz = o.rate_hz / 2.0;  // one toggle per tick: a full period every two
  const std::uint32_t errors_before = pins.tick.write_errors();
  const End end = wait(person, clock,
                       {"gpio.tick", fmt::format("The tick pin now toggles once per tick at {:.0f} Hz: put a scope or "
                                                 "frequency counter on it (expect a square wave of {:.0f} Hz). Press "
                                                 "Enter once you have read it.",
                                                 o.rate_hz, expected_hz)},
                       o.person_timeout_s, o.rate_hz, [&] { pins.tick.toggle(); }, {});
  const std::uint32_t errors = pins.tick.write_errors() - errors_before;
  measure(s, "toggles", fmt::format("{}", clock.k()));
  measure(s, "write errors", fmt::format("{}", errors));
  if (errors > 0) {
    return fail(s, fmt::format("{} of {} writes to the tick pin failed", errors, clock.k()),
                "check the line with `gpioinfo`: another program may have taken it, or the chip went away");
  }
  const auto answer =
      end == End::kPerson
          ? person.ask({"gpio.tick.frequency_hz", "What frequency did you read on the tick pin, in Hz?"})
          : std::nullopt;
  if (!answer) {
    s.outcome = Outcome::kSkipped;
    s.finding = fmt::format("the pin toggled {} times without an error, but nobody read its frequency", clock.k());
    s.next = "run the step with a scope on the pin";
    return s;
  }
  double hz = 0.0;
  try {
    hz = std::stod(*answer);
  } catch (const std::exception&) {
    return fail(s, fmt::format("'{}' is not a frequency", *answer), "run the step again and give it in Hz");
  }
  measure(s, "frequency read", fmt::format("{:.1f}", hz), "Hz");
  measure(s, "expected", fmt::format("{:.1f}", expected_hz), "Hz");
  if (std::abs(hz - expected_hz) > o.frequency_tolerance * expected_hz) {
    return fail(s, fmt::format("the tick pin shows {:.1f} Hz, not {:.1f} Hz", hz, expected_hz),
                hz < 1.0 ? "nothing toggles where you measured: probe the line the --tick-pin option names (its "
                           "offset on the chip, not the header pin number; docs/GPIO.md)"
                         : "the scope may be on another line, or the loop is not keeping its rate: check the host "
                           "with `toonforce doctor`");
  }
  return pass(s, fmt::format("the tick pin shows {:.1f} Hz, half the loop's {:.0f} Hz", hz, o.rate_hz));
}

/// The servo loop on the bench device, engaged and pushing 1 N out of the floor.
struct Rig {
  Bench bench;
  Loop loop;
  Rig(const RuntimeScene<double>& scene, const ServoConfig& config, const gpio::GpioPins& pins)
      : loop(BenchDevice{&bench}, scene, config, pins) {}
};

Result<ServoConfig> bench_config(double rate_hz, SceneDescription& scene) {
  auto d = parse_scene(kBenchScene, "bring-up bench", ScalarKind::kDouble);
  if (!d) return Error{d.error()};
  scene = d.value();
  ServoConfig c = servo_config(scene, 1.0 / rate_hz);
  c.limits.has_max_force = true;
  c.limits.max_force_n = 2.0;
  c.safety.soft_start_s = 0.1;
  c.safety.has_max_velocity = false;
  c.safety.thermal.continuous_force_n = 0.0;
  c.safety.passivity.controller = false;
  if (auto problem = check_servo_config(c); !problem.empty()) return Error{problem};
  return c;
}

/// Engages the loop (from above the floor, as `run` engages) and pushes into the floor until the
/// force is full; false if it never gets there (the e-stop or enable already cut it).
bool engage(Rig& rig, Clock& clock, std::int64_t& k) {
  rig.bench.position_m = {0.0, 0.0, 0.01};
  for (int i = 0; i < 50; ++i, clock.wait_next()) rig.loop.tick(k++);
  rig.bench.position_m = kInFloor;
  for (int i = 0; i < 400; ++i, clock.wait_next()) {
    rig.loop.tick(k++);
    if (rig.loop.state() == LoopState::kActive && rig.bench.written_n.z > 0.9) return true;
  }
  return false;
}

StepReport estop(Operator& person, const gpio::GpioPins& pins, const GpioBringupOptions& o) {
  StepReport s = make_step("estop", "Emergency stop");
  SceneDescription scene;
  auto config = bench_config(o.rate_hz, scene);
  if (!config) return fail(s, config.error(), "report this as a bug");
  gpio::GpioPins test_pins = pins;
  const PinLevel before = test_pins.estop.read();
  measure(s, "released reads",
          before == PinLevel::kInactive ? "released"
          : before == PinLevel::kActive ? "ENGAGED"
                                        : "error");
  if (before == PinLevel::kError) {
    return fail(s, "the e-stop line cannot be read",
                "check the line with `gpioinfo`; see docs/GPIO.md for permissions");
  }
  if (before == PinLevel::kActive) {
    return fail(s, "the e-stop reads engaged although nobody pressed it",
                "its polarity is the other way round: add :active-low to --estop-pin (or remove it). A normally-closed "
                "switch between the line and ground reads low while released (docs/GPIO.md)");
  }
  // The e-stop alone: an enable switch (its own step) would keep the loop idle unless held.
  gpio::GpioPins estop_pins = pins;
  estop_pins.enable = gpio::GpioEnablePin{};
  Rig rig(make_runtime_scene<double>(scene), config.value(), estop_pins);
  Clock clock(o.rate_hz, o.paced);
  std::int64_t k = 0;
  if (!engage(rig, clock, k)) return fail(s, "the loop never engaged on the bench", "report this as a bug");
  // The tick the loop sees the e-stop, and the force it wrote in that tick.
  std::int64_t seen_at = -1;
  double force_before = 0.0;
  double force_then = -1.0;
  const End end = wait(
      person, clock, {"gpio.estop.press", "Press the emergency stop, and keep it pressed."}, o.person_timeout_s,
      o.rate_hz,
      [&] {
        const double before_n = rig.bench.written_n.z;
        const TickStatus st = rig.loop.tick(k);
        if (seen_at < 0 && st.faults.has(Fault::kEstop)) {
          seen_at = k;
          force_before = before_n;
          force_then = rig.bench.written_n.z;
        }
        ++k;
      },
      [&] { return seen_at >= 0; });
  if (seen_at < 0) {
    return fail(
        s,
        end == End::kPerson ? "you pressed the e-stop, but the loop never saw it" : "the e-stop was never seen pressed",
        "check the wiring and the line the --estop-pin option names (its offset on the chip); if it is the "
        "right line, its polarity may be inverted (:active-low)");
  }
  measure(s, "force before", fmt::format("{:.3f}", force_before), "N");
  measure(s, "force in the tick the e-stop was seen", fmt::format("{:.3f}", force_then), "N");
  if (force_then != 0.0) {
    return fail(s, fmt::format("the loop saw the e-stop but still wrote {:.3f} N in that tick", force_then),
                "report this as a bug");
  }
  // Latched: released, it stays off until re-armed; a re-arm while pressed is refused.
  rig.loop.request_rearm();
  rig.loop.tick(k++);
  clock.wait_next();
  const bool refused_while_pressed = rig.loop.last_status().rearm_refused;
  wait(
      person, clock, {"gpio.estop.release", "Release the emergency stop."}, o.person_timeout_s, o.rate_hz,
      [&] { rig.loop.tick(k++); }, [&] { return rig.loop.pins().estop.read() == PinLevel::kInactive; });
  const bool still_off = rig.bench.written_n.z == 0.0 && rig.loop.state() == LoopState::kFaulted;
  // Re-armed, the loop engages again as at start: only where the scene force is small (the
  // bench leaves the floor and comes back).
  rig.loop.request_rearm();
  const bool rearmed = engage(rig, clock, k);
  measure(s, "re-arm refused while pressed", refused_while_pressed ? "yes" : "no");
  measure(s, "off after release until re-armed", still_off ? "yes" : "no");
  measure(s, "force back after re-arm", rearmed ? "yes" : "no");
  if (!refused_while_pressed || !still_off || !rearmed) {
    return fail(s,
                "the e-stop cut the force, but the latch did not behave: re-arm refused while pressed " +
                    std::string(refused_while_pressed ? "yes" : "no") + ", off after release " +
                    (still_off ? "yes" : "no") + ", back after re-arm " + (rearmed ? "yes" : "no"),
                "release the e-stop fully before re-arming; if the line bounces, check the switch");
  }
  return pass(s, fmt::format("zero force in the tick the loop saw the e-stop ({:.2f} N before); latched until released "
                             "and re-armed",
                             force_before));
}

StepReport enable(Operator& person, const gpio::GpioPins& pins, const GpioBringupOptions& o) {
  StepReport s = make_step("enable", "Enable switch");
  SceneDescription scene;
  auto config = bench_config(o.rate_hz, scene);
  if (!config) return fail(s, config.error(), "report this as a bug");
  Rig rig(make_runtime_scene<double>(scene), config.value(), pins);
  Clock clock(o.rate_hz, o.paced);
  std::int64_t k = 0;
  wait(
      person, clock, {"gpio.enable.press", "Press and hold the enable switch."}, o.person_timeout_s, o.rate_hz,
      [&] { rig.loop.tick(k++); }, [&] { return rig.loop.pins().enable.read() == PinLevel::kActive; });
  if (!engage(rig, clock, k)) {
    return fail(s, "with the enable switch held, the force never came on",
                "check the line the --enable-pin option names and its polarity (:active-low; docs/GPIO.md)");
  }
  std::int64_t released_at = -1;
  double force_then = -1.0;
  const End end = wait(
      person, clock, {"gpio.enable.release", "Let go of the enable switch."}, o.person_timeout_s, o.rate_hz,
      [&] {
        rig.loop.tick(k);
        if (released_at < 0 && rig.loop.state() == LoopState::kIdle) {
          released_at = k;
          force_then = rig.bench.written_n.z;
        }
        ++k;
      },
      [&] { return released_at >= 0; });
  if (released_at < 0) {
    return fail(
        s, end == End::kPerson ? "you let go, but the loop still saw the switch held" : "letting go was never seen",
        "check the wiring; the polarity may be inverted (:active-low)");
  }
  measure(s, "force in the tick the release was seen", fmt::format("{:.3f}", force_then), "N");
  if (force_then != 0.0)
    return fail(s, fmt::format("{:.3f} N written in the tick of the release", force_then), "report this as a bug");
  wait(
      person, clock, {"gpio.enable.press.again", "Press and hold the enable switch again."}, o.person_timeout_s,
      o.rate_hz, [&] { rig.loop.tick(k++); }, [&] { return rig.loop.pins().enable.read() == PinLevel::kActive; });
  if (!engage(rig, clock, k))
    return fail(s, "the force did not come back when the switch was held again", "check the switch");
  return pass(s, "zero force in the tick the switch was let go, and the force back once it was held again");
}

}  // namespace

Report run_gpio_bringup(Operator& person, const GpioBringupOptions& o) {
  Report report;
  report.device = "GPIO lines";
  report.started_utc = utc_now();
  report.toonforce_version = o.toonforce_version;
  std::string stopped_by;
  const auto add = [&](StepReport s) {
    person.say(fmt::format("[{}] {}: {}", to_string(s.outcome), s.title, s.finding));
    if (!s.next.empty()) person.say("       what to do: " + s.next);
    if (s.outcome == Outcome::kFail && stopped_by.empty()) stopped_by = s.title;
    report.steps.push_back(std::move(s));
  };
  const auto skipped = [&](const char* id, const char* title, std::string why) {
    StepReport s = make_step(id, title);
    s.finding = stopped_by.empty() ? std::move(why) : "not run: " + stopped_by + " failed";
    report.steps.push_back(std::move(s));
  };

  StepReport lines = make_step("lines", "Lines open");
  std::optional<gpio::GpioSession> session;
  if (o.pins.empty()) {
    fail(lines, "no GPIO line was given",
         "name the lines as `toonforce run` takes them: --tick-pin, --estop-pin, --enable-pin (docs/GPIO.md)");
  } else {
    auto opened = gpio::open_gpio(o.pins);
    if (!opened) {
      fail(lines, opened.error(), "fix each line as the message says (docs/GPIO.md)");
    } else {
      session.emplace(std::move(opened.value()));
      for (const auto& line : session->summary()) measure(lines, "line", line);
      report.target = fmt::format("{} line(s)", session->summary().size());
      pass(lines, fmt::format("{} line(s) opened as `toonforce run` opens them", session->summary().size()));
    }
  }
  add(std::move(lines));
  const bool unattended = !person.interactive();
  const struct {
    const char* id;
    const char* title;
    bool configured;
    const char* option;
  } steps[] = {{"tick", "Tick pin", !o.pins.tick_pin.empty(), "--tick-pin"},
               {"estop", "Emergency stop", !o.pins.estop_pin.empty(), "--estop-pin"},
               {"enable", "Enable switch", !o.pins.enable_pin.empty(), "--enable-pin"}};
  for (const auto& step : steps) {
    if (!stopped_by.empty() || !session) {
      skipped(step.id, step.title, "not run");
      continue;
    }
    if (!step_selected(step.id, o.only, o.skip)) {
      skipped(step.id, step.title, "not asked for");
      continue;
    }
    if (!step.configured) {
      skipped(step.id, step.title, fmt::format("no {} given", step.option));
      continue;
    }
    if (unattended && o.only.empty()) {
      skipped(step.id, step.title, "needs a person: a non-interactive run skips it unless named with --only");
      continue;
    }
    gpio::GpioPins pins = session->pins();
    try {
      const std::string_view id = step.id;
      add(id == "tick" ? tick_pin(person, pins, o) : id == "estop" ? estop(person, pins, o) : enable(person, pins, o));
    } catch (const AbortRequested&) {
      StepReport s = make_step(step.id, step.title);
      add(fail(s, "stopped by the person", "run the bring-up again when ready"));
    }
  }
  return report;
}

}  // namespace toonforce::bringup
