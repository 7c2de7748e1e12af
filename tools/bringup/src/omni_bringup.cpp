// SPDX-License-Identifier: Apache-2.0
// `toonforce bringup omni` (see omni_bringup.hpp). References: OMNI.md §2 (the HD API),
// install_check.hpp (the install), omni_device.hpp (calibration, cap, frame).
#include "toonforce/bringup/omni_bringup.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <thread>

#include <fmt/format.h>

#include "toonforce/bringup/falcon_bringup.hpp"
#include "toonforce/hal/omni/hd_api.hpp"
#include "toonforce/hal/omni/install_check.hpp"
#include "toonforce/hal/omni/touch_detect.hpp"

namespace toonforce::bringup {
namespace {

class AbortRequested {};

constexpr std::size_t kMaxPeriods = 20000;

/// What the servo thread does for the bring-up: zero force, or a pulse along one direction
/// that it cuts itself the tick the stylus moves the wrong way. Shared with the main thread
/// through atomics only (set the fields, then publish `mode` with release).
struct Probe {
  enum Mode : int { kIdle = 0, kPulse = 1 };
  OmniDevice* device = nullptr;
  std::atomic<int> mode{kIdle};
  Vec3<double> pulse_n{};  // written before mode = kPulse
  Vec3<double> start_m{};
  int pulse_ticks = 0;
  double min_motion_m = 0.0;
  std::atomic<int> ticks_left{0};
  std::atomic<bool> wrong_way{false};
  std::atomic<double> moved_m{0.0};  // along the pulse, signed, largest magnitude seen
  bool started = false;
  // Periods for the timing step.
  std::array<double, kMaxPeriods> periods_s{};
  std::atomic<std::size_t> recorded{0};
  std::atomic<std::size_t> record_limit{kMaxPeriods};  // the step's tick count: not one more
  std::atomic<bool> recording{false};
  std::atomic<std::uint64_t> ticks{0};

  static TickVerdict tick(void* self, const ClockedTick& clock) noexcept {
    auto& p = *static_cast<Probe*>(self);
    DeviceReading r;
    const DeviceStatus s = p.device->read(r);
    p.ticks.fetch_add(1, std::memory_order_relaxed);
    if (p.recording.load(std::memory_order_acquire)) {
      const std::size_t n = p.recorded.load(std::memory_order_relaxed);
      if (n < p.record_limit.load(std::memory_order_relaxed)) {
        p.periods_s[n] = clock.dt_s;
        p.recorded.store(n + 1, std::memory_order_release);
      }
    }
    Vec3<double> force{};
    if (p.mode.load(std::memory_order_acquire) == kPulse && s == DeviceStatus::kOk) {
      if (!p.started) {
        p.start_m = r.position_m;
        p.started = true;
      }
      const double length = norm(p.pulse_n);
      const double along = dot(r.position_m - p.start_m, p.pulse_n) / length;
      if (std::abs(along) > std::abs(p.moved_m.load(std::memory_order_relaxed))) {
        p.moved_m.store(along, std::memory_order_relaxed);
      }
      if (along <= -p.min_motion_m) {
        p.wrong_way.store(true, std::memory_order_release);  // zero force this very tick
        p.ticks_left.store(0, std::memory_order_release);
        p.mode.store(kIdle, std::memory_order_release);
      } else if (p.ticks_left.fetch_sub(1, std::memory_order_acq_rel) > 0) {
        force = p.pulse_n;
      } else {
        p.mode.store(kIdle, std::memory_order_release);
      }
    }
    (void)p.device->write(force);
    return TickVerdict::kContinue;
  }
};

class Session {
 public:
  Session(OmniDevice& d, Probe& probe, Operator& person, const OmniBringupOptions& o)
      : d_(d), probe_(probe), person_(person), o_(o) {}

  enum class End { kCondition, kPerson, kTimeout };
  /// Waits (the device runs on its own clock) until `done()`, the person's Enter, or `timeout_s`
  /// of the device's ticks; throws AbortRequested on the person's abort.
  End wait(const Request& r, double timeout_s, const std::function<bool()>& done) {
    person_.begin(r);
    const std::uint64_t start = probe_.ticks.load();
    const auto limit = static_cast<std::uint64_t>(timeout_s / period_s());
    const auto wall_limit = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s * 2 + 1);
    while (true) {
      if (done && done()) return End::kCondition;
      switch (person_.poll(r)) {
        case Progress::kDone: return End::kPerson;
        case Progress::kAbort: throw AbortRequested{};
        case Progress::kWaiting: break;
      }
      if (probe_.ticks.load() - start >= limit) return End::kTimeout;
      if (!d_.running()) return End::kTimeout;
      // A scheduler that stalls (or a manual one nobody steps) must not hang the bring-up.
      if (o_.poll_interval_s > 0 && std::chrono::steady_clock::now() > wall_limit) return End::kTimeout;
      if (o_.poll_interval_s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(o_.poll_interval_s));
    }
  }
  /// Waits until the device has run `ticks` more ticks.
  void run_ticks(std::uint64_t ticks) {
    const std::uint64_t target = probe_.ticks.load() + ticks;
    wait({"omni.running", "(the device runs)"}, static_cast<double>(ticks + 10) * period_s() * 4,
         [&] { return probe_.ticks.load() >= target; });
  }
  double period_s() const { return 1.0 / o_.omni.scheduler_rate_hz; }
  OmniDevice& device() { return d_; }
  Probe& probe() { return probe_; }
  Operator& person() { return person_; }

 private:
  OmniDevice& d_;
  Probe& probe_;
  Operator& person_;
  const OmniBringupOptions& o_;
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

StepReport calibration(Session& io, const OmniBringupOptions& o) {
  StepReport s = make_step("calibration", "Calibration");
  OmniDevice& d = io.device();
  const auto calibrated = [&] {
    const OmniStatus st = d.status();
    return st.frames > 0 && st.phase != OmniPhase::kCalibrating;
  };
  io.run_ticks(2);
  if (calibrated()) return pass(s, "hdCheckCalibration says OK: forces may come on");
  const int style = d.limits().calibration_style;
  const char* what = style == hd::kCalibrationAuto
                         ? "Move the stylus slowly through the whole workspace, to its limits "
                           "in every direction, until the device is calibrated."
                     : style == hd::kCalibrationEncoderReset
                         ? "This device calibrates by encoder reset when it is opened: hold the arm in its reset "
                           "pose (all links at right angles) and run the bring-up again."
                         : "Put the stylus in the inkwell (its holder on the base) and leave it there a moment.";
  io.wait({"omni.calibration", what}, o.calibration_timeout_s, calibrated);
  const OmniStatus st = d.status();
  measure(s, "calibration style",
          style == hd::kCalibrationAuto           ? "auto"
          : style == hd::kCalibrationInkwell      ? "inkwell"
          : style == hd::kCalibrationEncoderReset ? "encoder reset"
                                                  : "none reported");
  measure(s, "calibration errors", fmt::format("{}", st.calibration_errors));
  if (calibrated()) return pass(s, "calibrated: hdCheckCalibration says OK");
  return fail(s, "the device is still not calibrated: " + d.last_error(),
              style == hd::kCalibrationInkwell
                  ? "put the stylus in the inkwell and keep it there until the device is calibrated; if it never is, "
                    "check the inkwell switch with the vendor's Touch_Diagnostic"
                  : "do what the finding says, then run the step again");
}

StepReport workspace(Session& io, const OmniBringupOptions& o) {
  StepReport s = make_step("workspace", "Encoders and workspace");
  OmniDevice& d = io.device();
  const OmniLimits& l = d.limits();
  Vec3<double> lo{1, 1, 1};
  Vec3<double> hi{-1, -1, -1};
  std::uint64_t seen = 0;
  const Vec3<double> usable = l.usable_workspace_max_m - l.usable_workspace_min_m;
  const double fraction = 0.6;  // of the usable workspace, along each axis
  const auto enough = [&] {
    // Held after a force error (a fast sweep trips the library's velocity limit) the position
    // still reads right; only an uncalibrated one does not.
    const OmniStatus st = d.status();
    if (st.frames > 0 && st.phase != OmniPhase::kCalibrating && st.phase != OmniPhase::kStopped) {
      const Vec3<double> p = st.position_m;
      lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
      hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
      ++seen;
    }
    const Vec3<double> reach = hi - lo;
    return seen > 0 && reach.x >= fraction * usable.x && reach.y >= fraction * usable.y &&
           reach.z >= fraction * usable.z;
  };
  io.wait({"omni.workspace",
           "Move the stylus slowly to every limit of the workspace: left and right, up and down, toward you and "
           "away. The step ends by itself once it has reached far enough (or press Enter)."},
          o.sweep_timeout_s, enough);
  const Vec3<double> reach = seen > 0 ? hi - lo : Vec3<double>{};
  measure(s, "reach x (left-right)", fmt::format("{:.0f} of {:.0f}", reach.x * 1e3, usable.x * 1e3), "mm");
  measure(s, "reach y (in-out)", fmt::format("{:.0f} of {:.0f}", reach.y * 1e3, usable.y * 1e3), "mm");
  measure(s, "reach z (up-down)", fmt::format("{:.0f} of {:.0f}", reach.z * 1e3, usable.z * 1e3), "mm");
  if (enough())
    return pass(s, fmt::format("the stylus reached {:.0f} x {:.0f} x {:.0f} mm of the usable workspace", reach.x * 1e3,
                               reach.y * 1e3, reach.z * 1e3));
  return fail(s,
              fmt::format("the stylus reached only {:.0f} x {:.0f} x {:.0f} mm; {:.0f} % of the usable workspace "
                          "({:.0f} x {:.0f} x {:.0f} mm) along each axis was expected",
                          reach.x * 1e3, reach.y * 1e3, reach.z * 1e3, fraction * 100, usable.x * 1e3, usable.y * 1e3,
                          usable.z * 1e3),
              "run the step again and move the stylus to its limits; if an axis never reaches far, the device's "
              "calibration is wrong (put it in the inkwell) or a joint is blocked");
}

StepReport motors(Session& io, const OmniBringupOptions& o) {
  StepReport s = make_step("motors", "Motor direction");
  Probe& p = io.probe();
  if (io.wait({"omni.motors.hold",
               fmt::format("Hold the stylus lightly at the centre of the workspace, with your fingertips: the device "
                           "will push it briefly ({:.2f} s, {:.1f} N) right, away and up, one after the other. Press "
                           "Enter when you hold it.",
                           o.pulse_s, o.pulse_force_n)},
              // A script either answers it (--answer omni.motors.hold=done) or never will.
              io.person().interactive() ? o.person_timeout_s : io.period_s(), {}) != Session::End::kPerson) {
    s.outcome = Outcome::kSkipped;
    s.finding = "nobody confirmed holding the stylus";
    s.next = "run the step again and press Enter once you hold the stylus lightly";
    return s;
  }
  const struct {
    Vec3<double> direction;
    const char* name;
  } kAxes[] = {{{1, 0, 0}, "right (+x)"}, {{0, 1, 0}, "away from you (+y)"}, {{0, 0, 1}, "up (+z)"}};
  const auto ticks = static_cast<int>(std::lround(o.pulse_s / io.period_s()));
  for (const auto& axis : kAxes) {
    p.pulse_n = axis.direction * o.pulse_force_n;
    p.min_motion_m = o.min_motion_m;
    p.started = false;
    p.moved_m.store(0.0);
    p.wrong_way.store(false);
    p.ticks_left.store(ticks);
    p.mode.store(Probe::kPulse, std::memory_order_release);
    io.wait({"omni.motors.pulse", "(a pulse)"}, o.pulse_s * 4 + 1.0,
            [&] { return p.mode.load(std::memory_order_acquire) == Probe::kIdle; });
    p.mode.store(Probe::kIdle, std::memory_order_release);
    io.run_ticks(static_cast<std::uint64_t>(std::lround(0.3 / io.period_s())));
    const double moved = p.moved_m.load();
    measure(s, fmt::format("pushed {}", axis.name), fmt::format("{:+.2f}", moved * 1e3), "mm");
    if (p.wrong_way.load()) {
      return fail(s,
                  fmt::format("pushed {}, the stylus moved {:.1f} mm the other way; forces were set to zero at once",
                              axis.name, -moved * 1e3),
                  "do not run scenes on this device: its forces are reversed along that axis. Check the device's "
                  "configuration in Touch_Setup and its calibration (the inkwell), then run the step again");
    }
    if (moved < o.min_motion_m) {
      return fail(s, fmt::format("pushed {}, the stylus did not move ({:.2f} mm)", axis.name, moved * 1e3),
                  "hold the stylus more lightly and run the step again; if it still does not move, forces may be "
                  "disabled (calibration, warm motors) or the motors unpowered");
    }
  }
  return pass(s, "the stylus moved the way each pulse pushed it");
}

StepReport timing(Session& io, const OmniBringupOptions& o) {
  StepReport s = make_step("timing", "Scheduler rate");
  Probe& p = io.probe();
  const std::size_t wanted = std::min<std::size_t>(static_cast<std::size_t>(std::max(o.timing_ticks, 1)), kMaxPeriods);
  const std::uint32_t overruns_before = io.device().status().overruns;
  p.recorded.store(0);
  // The scheduler may tick again between the wait seeing `wanted` and recording stopping: the
  // probe stops itself at `wanted`, so the step reports the ticks it asked for.
  p.record_limit.store(wanted, std::memory_order_relaxed);
  p.recording.store(true, std::memory_order_release);
  io.wait({"omni.timing", "(measuring the scheduler's period)"}, static_cast<double>(wanted) * io.period_s() * 4 + 1.0,
          [&] { return p.recorded.load(std::memory_order_acquire) >= wanted; });
  p.recording.store(false, std::memory_order_release);
  const std::size_t n = p.recorded.load(std::memory_order_acquire);
  HistogramBuilder periods(50.0, 100);
  for (std::size_t i = 1; i < n; ++i) periods.add(p.periods_s[i] * 1e6);  // the first has no predecessor
  const Histogram h = periods.build();
  const std::uint32_t overruns = io.device().status().overruns - overruns_before;
  s.histogram = h;
  measure(s, "scheduler rate", fmt::format("{:.0f}", o.omni.scheduler_rate_hz), "Hz");
  measure(s, "ticks", fmt::format("{}", n));
  measure(s, "overruns", fmt::format("{}", overruns));
  measure(s, "period median / p99 / max", fmt::format("{:.0f} / {:.0f} / {:.0f}", h.p50, h.p99, h.max), "us");
  if (n < wanted) {
    return fail(s, fmt::format("the scheduler ran only {} of {} ticks: {}", n, wanted, io.device().last_error()),
                "see `toonforce doctor`; the device or its driver stopped the scheduler");
  }
  if (overruns * 100 > n) {
    s.outcome = Outcome::kWarn;
    s.finding = fmt::format("{} of {} ticks overran their period", overruns, n);
    s.next = "a quieter or real-time host (`toonforce doctor`), or a lower --rate";
    return s;
  }
  return pass(s,
              fmt::format("{} ticks; period median {:.0f} us, p99 {:.0f} us; {} overruns", n, h.p50, h.p99, overruns));
}

StepReport buttons(Session& io, const OmniBringupOptions& o) {
  StepReport s = make_step("buttons", "Stylus buttons");
  OmniDevice& d = io.device();
  constexpr struct {
    std::uint32_t bit;
    const char* id;
    const char* name;
  } kButtons[] = {{1U, "1", "first (front, HD_DEVICE_BUTTON_1)"}, {2U, "2", "second (back, HD_DEVICE_BUTTON_2)"}};
  for (const auto& b : kButtons) {
    std::uint32_t seen = 0;
    const auto end =
        io.wait({fmt::format("omni.button.{}", b.id), fmt::format("Press and hold the {} stylus button.", b.name)},
                o.button_timeout_s, [&] {
                  seen = d.status().buttons;
                  return seen != 0;
                });
    if (end != Session::End::kCondition) {
      return fail(s, fmt::format("the {} button was never seen pressed", b.name),
                  "press it firmly; check it with the vendor's Touch_Diagnostic");
    }
    if (seen != b.bit) {
      return fail(s, fmt::format("pressing the {} button, the device reported buttons 0x{:X}", b.name, seen),
                  "press only that button; the buttons may be swapped in the device's configuration");
    }
    io.wait({fmt::format("omni.button.{}.release", b.id), "Let go of it."}, o.button_timeout_s,
            [&] { return d.status().buttons == 0; });
    measure(s, b.name, "seen");
  }
  return pass(s, "both stylus buttons were reported alone, as pressed");
}

}  // namespace

Report run_omni_bringup(Operator& person, const OmniBringupOptions& o) {
  Report report;
  report.device = "Phantom Omni / 3D Systems Touch";
  report.started_utc = utc_now();
  report.toonforce_version = o.toonforce_version;
  const bool unattended = !person.interactive();
  const auto needs_person = [](std::string_view id) { return id != "found" && id != "driver" && id != "timing"; };
  std::string stopped_by;
  const auto add = [&](StepReport s) {
    person.say(fmt::format("[{}] {}: {}", to_string(s.outcome), s.title, s.finding));
    if (!s.next.empty()) person.say("       what to do: " + s.next);
    if (s.outcome == Outcome::kFail && stopped_by.empty()) stopped_by = s.title;
    report.steps.push_back(std::move(s));
  };
  const auto not_run = [&](const char* id, const char* title) {
    StepReport s = make_step(id, title);
    s.finding = !stopped_by.empty()                  ? "not run: " + stopped_by + " failed"
                : !step_selected(id, o.only, o.skip) ? std::string("not asked for")
                                                     : std::string("needs a person: a non-interactive run skips "
                                                                   "it unless named with --only");
    report.steps.push_back(std::move(s));
  };

  // found
  StepReport found = make_step("found", "Found and may be opened");
  const Prerequisite library = openhaptics_prerequisite(o.omni.library_path);
  std::string install_fixes;
  for (const auto& f : check_openhaptics_install(OpenHapticsHost::this_process())) {
    if (!f.prerequisite.ok) {
      measure(found, f.prerequisite.name, f.prerequisite.detail);
      install_fixes += (install_fixes.empty() ? "" : "; ") + f.prerequisite.fix;
    }
  }
  std::unique_ptr<OmniDevice> device;
  if (!library.ok) {
    fail(found, library.detail, library.fix + (install_fixes.empty() ? "" : "; " + install_fixes));
  } else {
    auto opened = open_omni(o.omni);
    if (!opened) {
      fail(found, opened.error(),
           install_fixes.empty() ? "see the message; `toonforce devices` checks the node's "
                                   "permission"
                                 : install_fixes);
    } else {
      device = std::move(opened).value();
      report.target = device->info().name;
      pass(found, "opened " + device->info().name);
    }
  }
  add(std::move(found));

  if (device) {
    StepReport driver = make_step("driver", "Driver and limits");
    const OmniLimits& l = device->limits();
    measure(driver, "device", device->info().name);
    measure(driver, "peak force (HD_NOMINAL_MAX_FORCE)", fmt::format("{:.3g}", l.max_force_n), "N");
    measure(driver, "continuous force",
            l.max_continuous_force_n > 0 ? fmt::format("{:.3g}", l.max_continuous_force_n) : "not reported",
            l.max_continuous_force_n > 0 ? "N" : "");
    measure(driver, "force cap in use", fmt::format("{:.3g} ({})", l.force_cap_n, l.force_cap_source), "N");
    measure(driver, "hdDisableDevice on close", device->disables_device_on_close() ? "yes" : "no (FireWire stack)");
    pass(driver,
         fmt::format("{}; forces capped at {:.3g} N ({})", device->info().name, l.force_cap_n, l.force_cap_source));
    if (l.max_continuous_force_n <= 0) {
      driver.outcome = Outcome::kWarn;
      driver.next =
          "the device reports no continuous force: the cap is its peak force; give --omni-max-force to lower it";
    }
    add(std::move(driver));

    Probe probe;
    probe.device = device.get();
    auto started = device->start(&Probe::tick, &probe);
    if (!started) {
      StepReport s = make_step("calibration", "Calibration");
      add(fail(s, started.error(), "see the message; `toonforce doctor` checks the host"));
    }
    Session io(*device, probe, person, o);
    const struct {
      const char* id;
      const char* title;
      std::function<StepReport()> run;
    } steps[] = {{"calibration", "Calibration", [&] { return calibration(io, o); }},
                 {"workspace", "Encoders and workspace", [&] { return workspace(io, o); }},
                 {"motors", "Motor direction", [&] { return motors(io, o); }},
                 {"timing", "Scheduler rate", [&] { return timing(io, o); }},
                 {"buttons", "Stylus buttons", [&] { return buttons(io, o); }}};
    for (const auto& step : steps) {
      const bool wanted =
          step_selected(step.id, o.only, o.skip) && !(unattended && needs_person(step.id) && o.only.empty());
      if (!stopped_by.empty() || !wanted) {
        not_run(step.id, step.title);
        continue;
      }
      const bool needs_calibration = std::string_view(step.id) == "workspace" || std::string_view(step.id) == "motors";
      if (needs_calibration && device->status().phase == OmniPhase::kCalibrating) {
        StepReport s = make_step(step.id, step.title);
        add(fail(s, "the device is not calibrated, and this step needs positions: " + device->last_error(),
                 "run the calibration step first (it is in the default set)"));
        continue;
      }
      try {
        add(step.run());
      } catch (const AbortRequested&) {
        probe.mode.store(Probe::kIdle);
        StepReport s = make_step(step.id, step.title);
        add(fail(s, "stopped by the person at the device; forces are off", "run the bring-up again when ready"));
      }
    }
    probe.mode.store(Probe::kIdle);
    device->request_stop();
    // A manual scheduler (tests) runs the closing frame when the person next steps it.
    io.wait({"omni.stopping", "(stopping)"}, 1.0, [&] { return !device->running(); });
    device->stop();
  } else {
    for (const auto& [id, title] :
         {std::pair{"driver", "Driver and limits"}, std::pair{"calibration", "Calibration"},
          std::pair{"workspace", "Encoders and workspace"}, std::pair{"motors", "Motor direction"},
          std::pair{"timing", "Scheduler rate"}, std::pair{"buttons", "Stylus buttons"}}) {
      not_run(id, title);
    }
  }
  return report;
}

}  // namespace toonforce::bringup
