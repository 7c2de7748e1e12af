// SPDX-License-Identifier: Apache-2.0
// `toonforce bringup falcon` (see falcon_bringup.hpp). References: FALCON.md §1 (USB), §2
// (firmware), §3 (one reply per command), §4 (homing), §5 (kinematics, frame, forces).
#include "toonforce/bringup/falcon_bringup.hpp"

#include <time.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <functional>

#include <fmt/format.h>

#include "toonforce/config/falcon_calibration_file.hpp"
#include "toonforce/hal/falcon/calibration.hpp"
#include "toonforce/hal/falcon/driver.hpp"
#include "toonforce/hal/falcon/firmware.hpp"
#include "toonforce/hal/falcon/frames.hpp"
#include "toonforce/hal/falcon/ftdi.hpp"
#include "toonforce/hal/falcon/usb.hpp"

namespace toonforce::bringup {

bool step_selected(std::string_view step, const std::vector<std::string>& only, const std::vector<std::string>& skip) {
  const auto named = [step](const std::vector<std::string>& list) {
    return std::find(list.begin(), list.end(), step) != list.end();
  };
  return (only.empty() || named(only)) && !named(skip);
}

namespace {

using falcon::FalconDriver;
using falcon::Mat3;

constexpr double kPeriodS = 1e-3;  // the host paces the Falcon at 1 kHz (FALCON.md §3)
constexpr double kGravity = 9.81;  // [m/s^2]

/// Arms are numbered from the top, clockwise seen from the front (FALCON.md §5 "Frame").
constexpr const char* kArmName[] = {"arm 1 (top)", "arm 2 (right)", "arm 3 (left)"};
constexpr std::uint8_t kHomedBit[] = {falcon::kHomedArm1, falcon::kHomedArm2, falcon::kHomedArm3};

// The encoders step: what a sweep to the workspace limits must show. A sweep over the central
// +-40 mm of each axis turns every arm by well over 600 counts (IK of FALCON.md §5); half of
// that is demanded, and an encoder that moved less than kDeadSpanCounts while another moved
// ten times as much is dead (or its cable is).
constexpr int kNeededSpanCounts = 300;
constexpr int kDeadSpanCounts = 20;
constexpr double kNeededSpanM = 0.050;

class AbortRequested {};

/// The 1 kHz exchange with the Falcon, and waits that keep it running.
class Session {
 public:
  Session(FalconDriver& driver, Operator& person, const FalconBringupOptions& options)
      : d_(driver), person_(person), o_(options) {
    clock_gettime(CLOCK_MONOTONIC, &next_);
  }

  /// One tick: read (collects the reply to the last command), `force` out [N, scene frame].
  DeviceStatus step(const Vec3<double>& force = {}) {
    status_ = d_.read(reading_);
    const bool usable = status_ == DeviceStatus::kOk;
    (void)d_.write(usable ? force : Vec3<double>{});
    pace();
    return status_;
  }
  /// Read only; the caller writes (the motors step decides its force on what it just read).
  DeviceStatus read() {
    status_ = d_.read(reading_);
    return status_;
  }
  void write(const Vec3<double>& force) {
    (void)d_.write(force);
    pace();
  }
  void pace() {
    ++ticks_;
    if (!o_.paced) return;
    next_.tv_nsec += static_cast<long>(kPeriodS * 1e9);
    while (next_.tv_nsec >= 1000000000L) {
      next_.tv_nsec -= 1000000000L;
      ++next_.tv_sec;
    }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next_, nullptr);
  }
  /// Zero force for `seconds`.
  void idle(double seconds, const std::function<Vec3<double>()>& force = {}) {
    for (int i = 0; i < ticks(seconds); ++i) step(force ? force() : Vec3<double>{});
  }

  enum class End { kCondition, kPerson, kTimeout };
  /// Runs the device (with `force` each tick) until `done()` holds, the person says it is
  /// done, or `timeout_s`; throws AbortRequested when the person aborts.
  End wait(const Request& request, double timeout_s, const std::function<bool()>& done,
           const std::function<Vec3<double>()>& force = {}) {
    person_.begin(request);
    const int limit = ticks(timeout_s);
    for (int i = 0; i < limit; ++i) {
      step(force ? force() : Vec3<double>{});
      if (done && done()) return End::kCondition;
      switch (person_.poll(request)) {
        case Progress::kDone: return End::kPerson;
        case Progress::kAbort: throw AbortRequested{};
        case Progress::kWaiting: break;
      }
    }
    return End::kTimeout;
  }
  /// A wait that only the person ends (Enter); false on timeout. A script either answers it
  /// (--answer ID=done) or never will: it is not waited for.
  bool confirm(const Request& request, const std::function<Vec3<double>()>& force = {}) {
    return wait(request, person_.interactive() ? o_.person_timeout_s : kPeriodS, {}, force) == End::kPerson;
  }

  static int ticks(double seconds) { return std::max(1, static_cast<int>(std::lround(seconds / kPeriodS))); }

  FalconDriver& driver() { return d_; }
  Operator& person() { return person_; }
  const DeviceReading& reading() const { return reading_; }
  DeviceStatus status() const { return status_; }
  std::int64_t tick_count() const { return ticks_; }

 private:
  FalconDriver& d_;
  Operator& person_;
  const FalconBringupOptions& o_;
  DeviceReading reading_{};
  DeviceStatus status_ = DeviceStatus::kNotReady;
  timespec next_{};
  std::int64_t ticks_ = 0;
};

StepReport make_step(std::string id, std::string title) {
  StepReport s;
  s.id = std::move(id);
  s.title = std::move(title);
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

std::string homed_axes(std::uint8_t mask, bool homed) {
  std::string out;
  for (std::size_t i = 0; i < 3; ++i) {
    if (((mask & kHomedBit[i]) != 0) != homed) continue;
    out += (out.empty() ? "" : ", ") + std::string(kArmName[i]);
  }
  return out.empty() ? "none" : out;
}

// ---- the steps -------------------------------------------------------------------------------

StepReport homing(Session& io, const FalconBringupOptions& o) {
  StepReport s = make_step("homing", "Homing");
  FalconDriver& d = io.driver();
  io.idle(0.01);
  if (d.homed()) return pass(s, "already homed: the encoders count from the homed position (FALCON.md §4)");
  const Request request{"falcon.homing",
                        "Home the Falcon: pull the grip all the way out toward you until it stops, then push it "
                        "straight back in. The LED turns from red to green when all three axes are homed."};
  const auto end = io.wait(request, o.homing_timeout_s, [&] { return d.homed(); });
  measure(s, "time", fmt::format("{:.2f}", static_cast<double>(io.tick_count()) * kPeriodS), "s since start");
  if (d.homed()) return pass(s, "all three axes report homed; the LED is green");
  const std::uint8_t mask = d.last_status().homed_mask();
  measure(s, "homed flags", fmt::format("0x{:02X}", mask));
  if (d.stats().replies == 0) {
    return fail(s, "the Falcon answered no command while waiting: " + d.last_error(),
                "check the USB cable and the power supply, then run the bring-up again");
  }
  const std::string why = end == Session::End::kTimeout ? fmt::format("after {:.0f} s", o.homing_timeout_s)
                                                        : std::string("when you said it was done");
  if (mask == 0) {
    return fail(s, fmt::format("no axis reported homed {} (homed flags 0x00)", why),
                "pull the grip all the way out until it stops, then push it straight in, holding it at its "
                "centre; if the LED never turns green, power-cycle the Falcon, reload its firmware and try "
                "again; if it still never homes, its homing sensors are at fault");
  }
  return fail(s,
              fmt::format("homing never completed {}: {} reported homed, {} never did (homed flags 0x{:02X})", why,
                          homed_axes(mask, true), homed_axes(mask, false), mask),
              fmt::format("the sensor of {} does not report: pull the grip out and push it in again, straight along "
                          "its axis; if that axis still never reports homed, its homing sensor or its cable is at "
                          "fault and the Falcon cannot be used until it is repaired",
                          homed_axes(mask, false)));
}

StepReport encoders(Session& io, const FalconBringupOptions& o) {
  StepReport s = make_step("encoders", "Encoders and workspace");
  FalconDriver& d = io.driver();
  std::array<int, 3> lo{};
  std::array<int, 3> hi{};
  Vec3<double> p_lo{1, 1, 1};
  Vec3<double> p_hi{-1, -1, -1};
  std::int64_t samples = 0;
  std::int64_t poses = 0;
  bool first = true;
  const auto track = [&] {
    if (d.stats().replies == 0 || !d.homed()) return;
    const auto& e = d.last_status().encoder;
    for (std::size_t i = 0; i < 3; ++i) {
      lo[i] = first ? e[i] : std::min(lo[i], static_cast<int>(e[i]));
      hi[i] = first ? e[i] : std::max(hi[i], static_cast<int>(e[i]));
    }
    first = false;
    ++samples;
    if (io.status() == DeviceStatus::kOk) {
      ++poses;
      const Vec3<double> p = io.reading().position_m;
      p_lo = {std::min(p_lo.x, p.x), std::min(p_lo.y, p.y), std::min(p_lo.z, p.z)};
      p_hi = {std::max(p_hi.x, p.x), std::max(p_hi.y, p.y), std::max(p_hi.z, p.z)};
    }
  };
  const auto spans_enough = [&] {
    for (std::size_t i = 0; i < 3; ++i) {
      if (hi[i] - lo[i] < kNeededSpanCounts) return false;
    }
    return p_hi.x - p_lo.x >= kNeededSpanM && p_hi.y - p_lo.y >= kNeededSpanM && p_hi.z - p_lo.z >= kNeededSpanM;
  };
  const Request request{"falcon.encoders",
                        "Move the grip slowly to every limit of its workspace: all the way left and right, up "
                        "and down, in and out, and into the corners. The step ends by itself once every arm "
                        "has turned far enough (or press Enter)."};
  io.wait(request, o.sweep_timeout_s, [&] {
    track();
    return spans_enough();
  });
  std::array<int, 3> span{};
  for (std::size_t i = 0; i < 3; ++i) {
    span[i] = samples > 0 ? hi[i] - lo[i] : 0;
    measure(s, fmt::format("encoder {} range", i + 1), fmt::format("{} .. {} ({} counts)", lo[i], hi[i], span[i]));
  }
  const Vec3<double> reach = samples > 0 ? p_hi - p_lo : Vec3<double>{};
  measure(s, "reach x (left-right)", fmt::format("{:.1f}", reach.x * 1e3), "mm");
  measure(s, "reach y (in-out)", fmt::format("{:.1f}", reach.y * 1e3), "mm");
  measure(s, "reach z (up-down)", fmt::format("{:.1f}", reach.z * 1e3), "mm");
  measure(s, "converged poses", fmt::format("{} of {}", poses, samples));

  const int widest = *std::max_element(span.begin(), span.end());
  for (std::size_t i = 0; i < 3; ++i) {
    if (span[i] < kDeadSpanCounts && widest >= 10 * kDeadSpanCounts) {
      const std::size_t mover = static_cast<std::size_t>(std::max_element(span.begin(), span.end()) - span.begin());
      return fail(s,
                  fmt::format("the encoder of {} does not count: it stayed within {} counts ({} .. {}) while {} "
                              "turned {} counts",
                              kArmName[i], span[i], lo[i], hi[i], kArmName[mover], widest),
                  fmt::format("check the encoder cable of {} inside the Falcon; if it is seated, the encoder is "
                              "faulty. Do not run forces: the position (and so every force) would be wrong",
                              kArmName[i]));
    }
  }
  if (samples == 0) return fail(s, "no reading from the Falcon: " + d.last_error(), "run the bring-up again");
  if (!spans_enough()) {
    std::string short_of;
    for (std::size_t i = 0; i < 3; ++i) {
      if (span[i] < kNeededSpanCounts)
        short_of += fmt::format("{}{} turned {} counts", short_of.empty() ? "" : "; ", kArmName[i], span[i]);
    }
    for (const auto& [name, r] :
         {std::pair{"left-right", reach.x}, std::pair{"in-out", reach.y}, std::pair{"up-down", reach.z}}) {
      if (r < kNeededSpanM) short_of += fmt::format("{}{:.0f} mm {}", short_of.empty() ? "" : "; ", r * 1e3, name);
    }
    return fail(s,
                fmt::format("the sweep did not reach far enough ({}; each arm must turn {} counts and the grip "
                            "travel {:.0f} mm along each axis)",
                            short_of, kNeededSpanCounts, kNeededSpanM * 1e3),
                "run the step again and move the grip to its limits in every direction; if one arm never turns "
                "far, check that nothing blocks it");
  }
  if (poses * 100 < samples * 99) {
    s.outcome = Outcome::kWarn;
    s.finding = fmt::format("every encoder counts, but the position estimate failed on {} of {} readings",
                            samples - poses, samples);
    s.next = "an encoder may miss counts: move slowly and run the step again; if it persists, check the encoder cables";
    return s;
  }
  return pass(s, fmt::format("every encoder counts (ranges {}, {}, {} counts) and the grip reached {:.0f} x {:.0f} x "
                             "{:.0f} mm with a converged position estimate",
                             span[0], span[1], span[2], reach.x * 1e3, reach.y * 1e3, reach.z * 1e3));
}

/// The force [N, scene frame] at the grip that makes torque `tau` [N m] on the motors at the
/// driver's last pose: F = J^-T tau (tau = J^T F, kinematics.hpp).
bool force_for_torque(FalconDriver& d, const Vec3<double>& tau, Vec3<double>& force_scene) {
  Mat3 j;
  if (!falcon::position_jacobian(falcon::FalconGeometry{}, d.position_falcon_m(), j)) return false;
  Mat3 jt;
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) jt(r, c) = j(c, r);
  }
  Mat3 inv;
  if (!falcon::invert(jt, inv)) return false;
  const Vec3<double> f{inv(0, 0) * tau.x + inv(0, 1) * tau.y + inv(0, 2) * tau.z,
                       inv(1, 0) * tau.x + inv(1, 1) * tau.y + inv(1, 2) * tau.z,
                       inv(2, 0) * tau.x + inv(2, 1) * tau.y + inv(2, 2) * tau.z};
  force_scene = falcon::falcon_force_to_scene(f);
  return true;
}

StepReport motors(Session& io, const FalconBringupOptions& o) {
  StepReport s = make_step("motors", "Motor direction");
  FalconDriver& d = io.driver();
  if (!io.confirm({"falcon.motors.hold",
                   fmt::format("Hold the grip lightly at the centre of the workspace, with your fingertips: each "
                               "motor will push it briefly ({:.2f} s, about 1 N), one after the other. Press Enter "
                               "when you hold it.",
                               o.pulse_s)})) {
    s.outcome = Outcome::kSkipped;
    s.finding = "nobody confirmed holding the grip";
    s.next = "run the step again and press Enter once you hold the grip lightly";
    return s;
  }
  io.idle(0.2);
  // A joint torque turns its own arm its way for any passive hold (a hand, a spring): the
  // joint-space compliance J^-1 K^-1 J^-T has a positive diagonal. Torque tau > 0 is word < 0
  // (word = -k tau, FALCON.md §5), and theta1 (so the count) grows with its arm.
  for (std::size_t i = 0; i < 3; ++i) {
    if (io.status() != DeviceStatus::kOk) {
      return fail(s, "the Falcon is not ready for forces: " + d.last_error(), "fix that, then run the step again");
    }
    const int c0 = d.last_status().encoder[i];
    Vec3<double> tau{};
    (i == 0 ? tau.x : i == 1 ? tau.y : tau.z) = o.pulse_torque_n_m;
    int moved = 0;
    for (int t = 0; t < Session::ticks(o.pulse_s); ++t) {
      const DeviceStatus st = io.read();
      const int delta = d.last_status().encoder[i] - c0;
      moved = std::abs(delta) > std::abs(moved) ? delta : moved;
      if (delta <= -o.min_motion_counts) {
        io.write({});  // zero force this very tick
        io.idle(0.3);
        measure(s, fmt::format("{} moved", kArmName[i]), fmt::format("{}", delta), "counts");
        return fail(s,
                    fmt::format("{} turned the wrong way: a torque that should turn it forward turned it {} counts "
                                "back. Its motor is wired backwards (or its encoder counts backwards). Forces were "
                                "set to zero at once",
                                kArmName[i], -delta),
                    fmt::format("do not run forces on this Falcon: every force would push the wrong way. Check the "
                                "motor connector of {} (its two leads swapped) and the encoder cable of that arm",
                                kArmName[i]));
      }
      Vec3<double> f{};
      if (st != DeviceStatus::kOk || !force_for_torque(d, tau, f)) {
        io.write({});
        io.idle(0.3);
        return fail(s, "the pose was lost during the pulse: " + d.last_error(), "run the step again");
      }
      io.write(f);
    }
    io.idle(0.3);  // zero force; let the arm come back
    measure(s, fmt::format("{} moved", kArmName[i]), fmt::format("{}", moved), "counts");
    if (moved < o.min_motion_counts) {
      return fail(s,
                  fmt::format("{} did not move under its pulse ({} counts; at least {} expected)", kArmName[i], moved,
                              o.min_motion_counts),
                  fmt::format("hold the grip more lightly and run the step again; if {} still does not move, check its "
                              "motor, its cable and the power supply (the motors need the Falcon's own supply)",
                              kArmName[i]));
    }
  }
  return pass(s, "each arm turned the way its motor pushed it");
}

/// Holds the grip where it is with a PI position loop [scene frame]; force() is this tick's.
class Hold {
 public:
  explicit Hold(const Vec3<double>& target) : target_(target), last_(target) {}
  Vec3<double> force(const DeviceReading& r, bool ok) {
    if (!ok) return {};
    const Vec3<double> error = target_ - r.position_m;
    const Vec3<double> v = (r.position_m - last_) * (1.0 / kPeriodS);
    velocity_ = velocity_ + (v - velocity_) * 0.2;  // ~35 Hz low-pass: counts are coarse
    last_ = r.position_m;
    integral_ = integral_ + error * (kKi * kPeriodS);
    const double n = norm(integral_);
    if (n > kMaxIntegralN) integral_ = integral_ * (kMaxIntegralN / n);
    const Vec3<double> f = error * kKp - velocity_ * kKd + integral_;
    history_[count_++ % history_.size()] = f;
    return f;
  }
  /// The mean force [N] of the last `n` ticks (n <= 4096).
  Vec3<double> mean(std::size_t n) const {
    n = std::min({n, count_, history_.size()});
    Vec3<double> sum{};
    for (std::size_t k = 0; k < n; ++k) sum = sum + history_[(count_ - 1 - k) % history_.size()];
    return n > 0 ? sum * (1.0 / static_cast<double>(n)) : sum;
  }
  double error_m(const DeviceReading& r) const { return norm(target_ - r.position_m); }

 private:
  // Gains for a 0.1-0.6 kg grip-plus-weight at 1 kHz with one tick of delay: well damped, and
  // still so with a device 3 times stronger than the constant in use believes.
  static constexpr double kKp = 300.0;   // [N/m]
  static constexpr double kKd = 4.0;     // [N s/m]
  static constexpr double kKi = 3000.0;  // [N/(m s)]
  static constexpr double kMaxIntegralN = 6.0;
  Vec3<double> target_;
  Vec3<double> last_;
  Vec3<double> velocity_{};
  Vec3<double> integral_{};
  std::array<Vec3<double>, 4096> history_{};
  std::size_t count_ = 0;
};

StepReport force_constant(Session& io, const FalconBringupOptions& o, const std::string& serial) {
  StepReport s = make_step("force", "Force constant");
  FalconDriver& d = io.driver();
  Operator& person = io.person();
  const double k_used = d.motor_scale().words_per_n_m;
  measure(s, "constant in use", fmt::format("{:.6g}", k_used), "words / (N m)");
  measure(s, "from", d.calibration_source());
  const auto method =
      person.ask({"falcon.force.method", "How will you measure the force? 'weight' (hang a known mass from the grip), "
                                         "'spring-scale' (pull against the grip with one), or 'skip':"});
  if (!method || *method == "skip") {
    s.outcome = Outcome::kSkipped;
    s.finding = method ? "skipped on request" : "needs a person with a known weight or a spring scale";
    s.next = "run `toonforce bringup falcon --only force` with a 100-500 g weight or a spring scale";
    return s;
  }
  const auto number = [&](const Request& r, double lo, double hi) -> std::optional<double> {
    const auto text = person.ask(r);
    if (!text) return std::nullopt;
    try {
      std::size_t used = 0;
      const double v = std::stod(*text, &used);
      if (used == text->size() && std::isfinite(v) && v >= lo && v <= hi) return v;
    } catch (const std::exception&) {
    }
    return std::nullopt;
  };
  double ratio = 0.0;  // k_true / k_used: how much more force the driver had to ask for
  falcon::FalconCalibration c;
  c.serial = serial;
  c.date = utc_now();
  if (*method == "weight") {
    const auto mass =
        number({"falcon.force.mass_kg", "Mass of the weight, in kg (0.05 to 0.6; 200 g is good):"}, 0.05, 0.6);
    if (!mass)
      return fail(s, "no usable mass was given (0.05 to 0.6 kg)", "run the step again and give the mass in kg");
    io.idle(0.05);
    Hold hold(io.reading().position_m);
    const auto holding = [&] { return hold.force(io.reading(), io.status() == DeviceStatus::kOk); };
    if (!io.confirm({"falcon.force.release", "Let go of the grip: the Falcon now holds it where it is. Press Enter."},
                    holding)) {
      io.idle(0.2);
      return fail(s, "nobody confirmed letting go of the grip", "run the step again");
    }
    io.idle(o.hold_s, holding);
    const Vec3<double> f0 = hold.mean(static_cast<std::size_t>(Session::ticks(o.hold_s / 2)));
    if (!io.confirm({"falcon.force.hang",
                     "Hang the weight from the grip's centre (by a string), let go, and keep it from swinging. "
                     "Press Enter."},
                    holding)) {
      io.idle(0.2);
      return fail(s, "nobody confirmed hanging the weight", "run the step again");
    }
    io.idle(o.hold_s, holding);
    const Vec3<double> f1 = hold.mean(static_cast<std::size_t>(Session::ticks(o.hold_s / 2)));
    const double error = hold.error_m(io.reading());
    const bool saturated = io.reading().force_limited;
    (void)io.confirm({"falcon.force.unhang", "Take the weight off and hold the grip. Press Enter."}, holding);
    io.idle(0.2);
    const double weight_n = *mass * kGravity;
    const double lift_n = f1.z - f0.z;  // scene +z is up
    measure(s, "weight", fmt::format("{:.4g}", weight_n), "N");
    measure(s, "force asked to hold it", fmt::format("{:.4g}", lift_n), "N");
    if (error > 0.005 || saturated || !(lift_n > 0.05 * weight_n)) {
      return fail(
          s,
          fmt::format("the Falcon could not hold the weight still (it ended {:.1f} mm from where it was held{})",
                      error * 1e3, saturated ? ", at the limit of its motors" : ""),
          "use a lighter weight (100-200 g), hung at the grip's centre, and keep it from swinging");
    }
    ratio = lift_n / weight_n;
    c.method = "weight";
    c.reference_force_n = weight_n;
    c.measured_force_n = lift_n;
    c.note = fmt::format("{:.3g} kg held by the PI loop; force asked with {:.6g} words per N m", *mass, k_used);
  } else if (*method == "spring-scale") {
    constexpr double kPushN = 2.0;
    const auto push = [&] { return Vec3<double>{0.0, 0.0, kPushN}; };
    if (!io.confirm({"falcon.force.spring",
                     "The grip now pushes up with what the driver takes for 2 N. Hook the spring scale to the "
                     "grip's centre and pull straight down until the grip floats where it is. Press Enter while "
                     "you hold it there."},
                    push)) {
      io.idle(0.2);
      return fail(s, "nobody confirmed the spring scale", "run the step again");
    }
    const auto reading = number({"falcon.force.spring_n", "What does the scale read, in newtons?"}, 0.1, 20.0);
    io.idle(0.2);
    if (!reading) return fail(s, "no usable scale reading was given (0.1 to 20 N)", "run the step again");
    ratio = kPushN / *reading;
    c.method = "spring-scale";
    c.reference_force_n = *reading;
    c.measured_force_n = kPushN;
    c.note = fmt::format("2 N asked with {:.6g} words per N m; the scale read {:.4g} N", k_used, *reading);
  } else {
    return fail(s, fmt::format("'{}' is not a method (weight, spring-scale or skip)", *method), "run the step again");
  }
  c.words_per_n_m = k_used * ratio;
  const double given_per_asked = 1.0 / ratio;
  measure(s, "measured constant", fmt::format("{:.6g}", c.words_per_n_m), "words / (N m)");
  measure(s, "force given / force asked", fmt::format("{:.3f}", given_per_asked));
  if (c.words_per_n_m < falcon::kMinWordsPerNewtonMetre || c.words_per_n_m > falcon::kMaxWordsPerNewtonMetre) {
    return fail(s, fmt::format("the measured constant, {:.6g} words per N m, is implausible", c.words_per_n_m),
                "check the mass or the scale reading and run the step again");
  }
  const std::string path =
      o.calibration_out.empty() ? falcon::default_falcon_calibration_path(serial) : o.calibration_out;
  if (path.empty()) return fail(s, "no place to write the calibration (no HOME)", "give --calibration-out FILE");
  auto written = falcon::write_falcon_calibration(path, c);
  if (!written) return fail(s, written.error(), "give a writable --calibration-out FILE");
  measure(s, "written to", path);
  if (std::abs(given_per_asked - 1.0) <= 0.10) {
    return pass(s,
                fmt::format("the Falcon gives {:.2f} times the force asked: the constant in use holds (within 10 %); "
                            "the measurement, {:.6g} words per N m, is written to {}",
                            given_per_asked, c.words_per_n_m, path));
  }
  s.outcome = Outcome::kWarn;
  s.finding = fmt::format("the Falcon gives {:.2f} times the force it is asked for: its constant is {:.6g} words per "
                          "N m, not the {:.6g} in use ({})",
                          given_per_asked, c.words_per_n_m, k_used, d.calibration_source());
  s.next =
      fmt::format("written to {}: `toonforce run --device falcon` reads it from now on for this Falcon (serial {}). "
                  "Forces were {} than scenes asked until now",
                  path, serial.empty() ? "?" : serial, given_per_asked > 1.0 ? "stronger" : "weaker");
  return s;
}

StepReport timing(Session& io, const FalconBringupOptions& o) {
  StepReport s = make_step("timing", "USB round trip at 1 kHz");
  FalconDriver& d = io.driver();
  HistogramBuilder rtt(50.0, 100);  // 50 us buckets to 5 ms
  rtt.reserve(static_cast<std::size_t>(o.timing_ticks));
  const falcon::FalconStats before = d.stats();
  using Clock = std::chrono::steady_clock;
  Clock::time_point sent = Clock::now();
  DeviceReading r;
  for (int k = 0; k < o.timing_ticks; ++k) {
    const std::uint64_t replies = d.stats().replies;
    (void)d.read(r);
    const Clock::time_point got = Clock::now();
    if (d.stats().replies > replies && k > 0) {
      rtt.add(std::chrono::duration<double, std::micro>(got - sent).count());
    }
    (void)d.write({});
    sent = Clock::now();
    io.pace();
  }
  const falcon::FalconStats after = d.stats();
  const Histogram h = rtt.build();
  const std::uint64_t lost = (after.timeouts - before.timeouts) + (after.protocol_errors - before.protocol_errors);
  s.histogram = h;
  measure(s, "exchanges", fmt::format("{}", o.timing_ticks));
  measure(s, "replies", fmt::format("{}", after.replies - before.replies));
  measure(s, "without a reply", fmt::format("{}", lost));
  measure(s, "garbled bytes", fmt::format("{}", after.garbled_bytes - before.garbled_bytes));
  measure(s, "round trip median / p99 / max", fmt::format("{:.0f} / {:.0f} / {:.0f}", h.p50, h.p99, h.max), "us");
  measure(s, "paced at 1 kHz", o.paced ? "yes" : "no (as fast as the device answers)");
  if (lost * 100 > static_cast<std::uint64_t>(o.timing_ticks)) {
    return fail(s, fmt::format("{} of {} commands got no reply: {}", lost, o.timing_ticks, d.last_error()),
                "plug the Falcon directly into the computer (no hub), check its power supply, and close any other "
                "program that talks to it");
  }
  pass(s, fmt::format("{} replies to {} commands; round trip median {:.0f} us, p99 {:.0f} us, max {:.0f} us",
                      after.replies - before.replies, o.timing_ticks, h.p50, h.p99, h.max));
  if (o.paced && h.p99 > 1000.0) {
    s.next = "the round trip's p99 is above the 1 ms period: a 1 kHz loop will miss deadlines. Plug the Falcon "
             "directly (no hub) and check the host with `toonforce doctor`";
  }
  return s;
}

StepReport buttons(Session& io, const FalconBringupOptions& o) {
  StepReport s = make_step("buttons", "Grip buttons");
  struct Button {
    std::uint8_t bit;
    const char* id;
    const char* name;
  };
  // FALCON.md §3: bits of status byte 13, on the four-button grip.
  constexpr Button kButtons[] = {{falcon::kButtonPlus, "plus", "far right (+)"},
                                 {falcon::kButtonForward, "forward", "centre-forward"},
                                 {falcon::kButtonCentre, "centre", "centre (circle)"},
                                 {falcon::kButtonMinus, "minus", "far left (-)"}};
  for (const Button& b : kButtons) {
    std::uint32_t seen = 0;
    const auto end =
        io.wait({fmt::format("falcon.button.{}", b.id), fmt::format("Press and hold the {} button.", b.name)},
                o.button_timeout_s, [&] {
                  const std::uint32_t now = io.driver().last_status().buttons();
                  if (now != 0) seen = now;
                  return now != 0;
                });
    if (end != Session::End::kCondition) {
      return fail(s, fmt::format("the {} button was never seen pressed", b.name),
                  "check that the grip is pushed fully onto the Falcon (it is removable) and press the button firmly; "
                  "if it still is not seen, the grip or its contacts are at fault");
    }
    io.idle(0.05);
    seen = io.driver().last_status().buttons();
    if (seen != b.bit) {
      return fail(s,
                  fmt::format("pressing the {} button, the Falcon reported buttons 0x{:X} instead of 0x{:X}", b.name,
                              seen, b.bit),
                  "press only that button; if another one is reported, the grip is not the four-button grip toonforce "
                  "knows (FALCON.md §3) or its wiring differs");
    }
    io.wait({fmt::format("falcon.button.{}.release", b.id), "Let go of it."}, o.button_timeout_s,
            [&] { return io.driver().last_status().buttons() == 0; });
    measure(s, b.name, "seen");
  }
  return pass(s, "each of the four buttons was reported alone, as pressed");
}

StepReport leds(Session& io) {
  StepReport s = make_step("leds", "LED");
  FalconDriver& d = io.driver();
  struct Colour {
    std::uint8_t bit;
    const char* name;
  };
  constexpr Colour kColours[] = {{falcon::kLedRed, "red"}, {falcon::kLedGreen, "green"}, {falcon::kLedBlue, "blue"}};
  std::string wrong;
  for (const Colour& c : kColours) {
    d.set_led(c.bit);
    io.idle(0.3);
    const auto answer = io.person().ask(
        {fmt::format("falcon.led.{}", c.name), fmt::format("Is the Falcon's LED {} now? [y/n]", c.name)});
    const auto yes = answer ? parse_yes_no(*answer) : std::nullopt;
    if (!yes) {
      d.set_led(0);
      s.outcome = Outcome::kSkipped;
      s.finding = "needs a person to look at the LED";
      s.next = "run the step interactively";
      return s;
    }
    measure(s, c.name, *yes ? "seen" : "NOT seen");
    if (!*yes) wrong += (wrong.empty() ? "" : ", ") + std::string(c.name);
  }
  d.set_led(0);
  io.idle(0.05);
  if (!wrong.empty()) {
    s.outcome = Outcome::kWarn;
    s.finding = fmt::format("the LED did not show {}", wrong);
    s.next = "the firmware answers, so the LED or its wiring is at fault; forces are not affected, but the LED will "
             "not say red (not homed) and green (homed) reliably";
    return s;
  }
  return pass(s, "red, green and blue each showed");
}

class UsbAccess final : public FalconAccess {
 public:
  FalconDetection detect() override {
    FalconDetectOptions o;
    o.probe_firmware = false;  // the firmware step probes
    return detect_falcons(o);
  }
  Result<std::unique_ptr<falcon::FalconTransport>> open(const FalconOptions& options) override {
    return falcon::open_falcon_transport(options);
  }
};

}  // namespace

std::unique_ptr<FalconAccess> usb_falcon_access() { return std::make_unique<UsbAccess>(); }

Report run_falcon_bringup(FalconAccess& access, Operator& person, const FalconBringupOptions& o) {
  Report report;
  report.device = "Novint Falcon";
  report.started_utc = utc_now();
  report.toonforce_version = o.toonforce_version;
  const bool unattended = !person.interactive();
  // Steps that need a person run unattended only when named (falcon_bringup.hpp).
  const auto needs_person = [](std::string_view id) { return id != "found" && id != "firmware" && id != "timing"; };
  const auto wanted = [&](std::string_view id) {
    if (!step_selected(id, o.only, o.skip)) return false;
    return !(unattended && needs_person(id) && o.only.empty());
  };
  std::string stopped_by;
  const auto add = [&](StepReport s) {
    person.say(fmt::format("[{}] {}: {}", to_string(s.outcome), s.title, s.finding));
    if (!s.next.empty()) person.say("       what to do: " + s.next);
    if (s.outcome == Outcome::kFail && stopped_by.empty()) stopped_by = s.title;
    report.steps.push_back(std::move(s));
  };
  const auto not_run = [&](const char* id, const char* title) {
    StepReport s = make_step(id, title);
    if (!stopped_by.empty()) {
      s.finding = "not run: " + stopped_by + " failed";
    } else if (!step_selected(id, o.only, o.skip)) {
      s.finding = "not asked for";
    } else {
      s.finding = "needs a person: a non-interactive run skips it unless named with --only";
    }
    report.steps.push_back(std::move(s));
  };

  // ---- found ----
  StepReport found = make_step("found", "Found and may be opened");
  const FalconDetection detection = access.detect();
  const DetectedDevice* chosen = nullptr;
  if (!o.falcon.serial.empty()) {
    for (const auto& dev : detection.devices) {
      if (dev.serial == o.falcon.serial) chosen = &dev;
    }
  } else if (o.falcon.index < detection.devices.size()) {
    chosen = &detection.devices[o.falcon.index];
  }
  for (const auto& p : detection.prerequisites) {
    if (!p.ok) measure(found, p.name, p.detail + (p.fix.empty() ? "" : " (fix: " + p.fix + ")"));
  }
  std::unique_ptr<falcon::FalconTransport> transport;
  std::string serial;
  if (detection.devices.empty()) {
    fail(found, "no Novint Falcon found on USB (vendor 0403, product cb48)",
         "check that its power supply is plugged in and its USB cable connected, directly rather than through a hub; "
         "`lsusb -d 0403:cb48` should list it");
  } else if (chosen == nullptr) {
    fail(found,
         o.falcon.serial.empty() ? fmt::format("Falcon number {} was asked for, but {} are connected", o.falcon.index,
                                               detection.devices.size())
                                 : fmt::format("no Falcon with serial number {} among the {} connected",
                                               o.falcon.serial, detection.devices.size()),
         "`toonforce devices` lists them with their serial numbers");
  } else if (!chosen->can_open) {
    fail(found, fmt::format("the Falcon at {} cannot be opened by this user: {}", chosen->location, chosen->problem),
         chosen->fix);
  } else {
    auto opened = access.open(o.falcon);
    if (!opened) {
      fail(found, opened.error(), "see the message; `toonforce devices` checks permissions");
    } else {
      transport = std::move(opened.value());
      serial = chosen->serial;
      report.target = fmt::format("{}{}", serial.empty() ? "" : "serial " + serial + ", ", chosen->location);
      measure(found, "location", chosen->location);
      measure(found, "serial", serial.empty() ? "(none)" : serial);
      pass(found,
           fmt::format("found at {}{} and opened", chosen->location, serial.empty() ? "" : ", serial " + serial));
    }
  }
  add(std::move(found));  // opening is needed by every later step, so it always runs

  // ---- firmware ----
  std::unique_ptr<FalconDriver> driver;
  if (stopped_by.empty()) {
    StepReport s = make_step("firmware", "Firmware");
    const auto mode = falcon::ftdi::enter_normal_mode(*transport);
    const falcon::FirmwareProbe probe =
        mode == falcon::TransportStatus::kOk ? falcon::probe_firmware(*transport) : falcon::FirmwareProbe{false, mode};
    if (probe.transport != falcon::TransportStatus::kOk) {
      fail(s,
           fmt::format("USB error ({}) while asking the Falcon whether its firmware runs",
                       falcon::to_string(probe.transport)),
           "unplug the Falcon's USB cable and power, plug them back in, and run the bring-up again");
    } else if (probe.loaded) {
      pass(s, "firmware runs: the Falcon answers commands");
    } else if (o.falcon.firmware_path.empty()) {
      fail(s, "no firmware runs on the Falcon (it loses it at every power-up)",
           "run the bring-up with --firmware FILE, or `toonforce falcon firmware FILE`, where FILE comes from a "
           "Novint or nVent driver install (docs/FALCON.md, \"Firmware\")");
    } else {
      auto image = falcon::read_firmware_file(o.falcon.firmware_path);
      if (!image) {
        fail(s, image.error(), "give one of the known firmware images (docs/FALCON.md, \"Firmware\")");
      } else {
        auto loaded = falcon::load_firmware(*transport, image.value(), o.falcon.firmware);
        if (!loaded) {
          fail(s, loaded.error(), "power-cycle the Falcon and run the bring-up again");
        } else {
          measure(s, "loaded", image.value().name);
          measure(s, "tries", fmt::format("{}", loaded.value().attempts));
          pass(s, fmt::format("loaded {} in {} {}; it answers commands", image.value().name, loaded.value().attempts,
                              loaded.value().attempts == 1 ? "try" : "tries"));
        }
      }
    }
    if (s.outcome == Outcome::kPass) {
      auto calibration =
          resolve_falcon_calibration(o.falcon.calibration_path, serial, &falcon::read_falcon_calibration);
      if (!calibration) {
        fail(s, calibration.error(), "fix or remove the calibration file, or measure it again with the force step");
      } else {
        FalconOptions options = o.falcon;
        options.motor.words_per_n_m = calibration.value().calibration.words_per_n_m;
        options.calibration_source = calibration.value().source;
        measure(s, "force constant in use", calibration.value().source);
        driver = std::make_unique<FalconDriver>(std::move(transport), options, "Novint Falcon (" + report.target + ")");
      }
    }
    add(std::move(s));
  } else {
    not_run("firmware", "Firmware");
  }

  // ---- the steps on the running Falcon ----
  if (driver) {
    Session io(*driver, person, o);
    struct DeviceStep {
      const char* id;
      const char* title;
      std::function<StepReport()> run;
    };
    const std::vector<DeviceStep> steps{
        {"homing", "Homing", [&] { return homing(io, o); }},
        {"encoders", "Encoders and workspace", [&] { return encoders(io, o); }},
        {"motors", "Motor direction", [&] { return motors(io, o); }},
        {"force", "Force constant", [&] { return force_constant(io, o, serial); }},
        {"timing", "USB round trip at 1 kHz", [&] { return timing(io, o); }},
        {"buttons", "Grip buttons", [&] { return buttons(io, o); }},
        {"leds", "LED", [&] { return leds(io); }},
    };
    for (const DeviceStep& step : steps) {
      // Positions (and so forces) need homing: steps after it wait for a homed Falcon.
      const bool needs_homed = std::string_view(step.id) != "timing" && std::string_view(step.id) != "leds" &&
                               std::string_view(step.id) != "homing";
      if (!stopped_by.empty() || !wanted(step.id)) {
        not_run(step.id, step.title);
        continue;
      }
      if (needs_homed && !driver->homed()) {
        StepReport s = make_step(step.id, step.title);
        add(fail(s, "the Falcon is not homed, and this step needs positions",
                 "run the homing step first (it is in the "
                 "default set)"));
        continue;
      }
      try {
        add(step.run());
      } catch (const AbortRequested&) {
        io.idle(0.05);
        StepReport s = make_step(step.id, step.title);
        add(fail(s, "stopped by the person at the device; forces are off", "run the bring-up again when ready"));
      }
    }
    io.idle(0.01);  // the last command is zero force
  } else {
    for (const auto& [id, title] : {std::pair{"homing", "Homing"}, std::pair{"encoders", "Encoders and workspace"},
                                    std::pair{"motors", "Motor direction"}, std::pair{"force", "Force constant"},
                                    std::pair{"timing", "USB round trip at 1 kHz"},
                                    std::pair{"buttons", "Grip buttons"}, std::pair{"leds", "LED"}}) {
      not_run(id, title);
    }
  }
  return report;
}

}  // namespace toonforce::bringup
