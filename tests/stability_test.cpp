// SPDX-License-Identifier: Apache-2.0
// The extreme cases of our stability checklist (docs/STABILITY.md), each with the safety
// layer on: the servo loop (ServoLoop: engage, soft start, velocity limit, workspace, watchdog,
// passivity observer and controller, thermal model, force-rate limit, clamp last; configured
// as `toonforce run --device sim` configures it, so the thermal model is inert: the simulated
// device's continuous force is its peak) on the host simulation's
// device (host_sim::SimDevice: mass, damping, friction, encoder and DAC steps, I/O delay,
// saturation) held by a simulated hand. Every test checks the same properties: the commanded
// force stays within the clamp, the energy stays bounded, nothing becomes NaN, and the loop
// recovers or re-arms as designed. Counts and simulated quantities only; no time is measured.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/passivity_bound.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/host_sim/sim_device.hpp"
#include "toonforce/report/scenario.hpp"
#include "toonforce/report/stability.hpp"

namespace toonforce {
namespace {

using host_sim::DeviceParams;
using host_sim::HandImpedance;
using host_sim::HandIntent;
using host_sim::HandScript;
using host_sim::HandSegment;
using host_sim::SegmentKind;
using host_sim::SimDevice;

constexpr double kPeriodS = 1e-3;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

/// What a test makes the device report instead of the truth, tick by tick.
struct Injection {
  std::function<bool(std::int64_t tick, Vec3<double>& position)> reading;  ///< true: replaced
};

/// The simulated device behind the loop's device seam, with readings a test may replace.
struct TestDevice {
  SimDevice* sim;
  Injection* inject;
  std::int64_t* exchanges;
  DeviceStatus read(DeviceReading& r) noexcept {
    const DeviceStatus s = sim->read(r);
    if (inject->reading) {
      Vec3<double> p = r.position_m;
      if (inject->reading(*exchanges, p)) r.position_m = p;
    }
    return s;
  }
  DeviceStatus write(const Vec3<double>& f) noexcept {
    ++*exchanges;
    return sim->write(f);
  }
};
static_assert(ServoDevice<TestDevice>);

/// A hand holding at `aim` with `impedance`, pressing with `press_n` along -normal, or
/// following `segments` after that.
HandIntent hand(const Vec3<double>& aim, const HandImpedance& impedance, double press_n = 0.0,
                std::vector<HandSegment> segments = {}) {
  HandScript script;
  script.name = "test";
  script.start_m = aim;
  script.impedance = impedance;
  if (segments.empty()) {
    HandSegment hold;
    hold.kind = SegmentKind::kHold;
    hold.duration_s = 1e4;
    hold.force_ramp_s = 0.0;
    if (press_n > 0.0) hold.force_n = press_n;
    segments.push_back(hold);
  }
  script.segments = std::move(segments);
  host_sim::PlanError error;
  auto planned = HandIntent::plan(script, error);
  EXPECT_TRUE(planned) << error.key << ": " << error.problem;
  return std::move(*planned);
}

constexpr HandImpedance kFirmHand{0.1, 300.0, 15.0};  // scenes/hands/strike.toml
constexpr HandImpedance kRelaxedHand{0.1, 100.0, 2.0};
constexpr HandImpedance kNoHand{0.0, 0.0, 0.0};  // only a press force, if any

std::string floor_toml(double stiffness, const std::string& device_extra = "", const std::string& surface_extra = "") {
  return "[device]\nmax_force = 8.0\nmax_force_rate = 2000.0\nsoft_start = 0.2\n" + device_extra +
         "[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nstiffness = " + std::to_string(stiffness) +
         "\n" + surface_extra;
}

std::string bundled(const char* name) {
  std::FILE* f = std::fopen((std::string(TOONFORCE_SOURCE_DIR) + "/scenes/" + name + ".toml").c_str(), "rb");
  EXPECT_NE(f, nullptr) << name;
  std::string text;
  char buffer[4096];
  std::size_t n = 0;
  while (f != nullptr && (n = std::fread(buffer, 1, sizeof buffer, f)) > 0) text.append(buffer, n);
  if (f != nullptr) std::fclose(f);
  return text;
}

template <Scalar S>
constexpr ScalarKind kind_of() {
  return kIsFixed<S> ? ScalarKind::kQ16_16 : std::same_as<S, float> ? ScalarKind::kFloat : ScalarKind::kDouble;
}

/// The servo loop with its whole safety layer on a simulated device, as `toonforce run
/// --device sim` builds it (servo_config(scene) completed by the device: with_device).
/// What the first surface and the first cliff of a loop's scene show after its last tick.
struct Shown {
  bool in_contact = false;
  double impact_time_s = std::numeric_limits<double>::quiet_NaN();  ///< surface1.impact_t
  int cliff_state = -1;                                             ///< cliff1.state (-1: no cliff)
};

template <class Loop>
Shown shown(const Loop& loop) {
  std::vector<double> values(loop.scene().value_count());
  Shown out;
  out.in_contact = loop.describe(values.data());
  bool surface = false;
  bool cliff = false;
  for (std::size_t i = 0; i < loop.scene().effect_count(); ++i) {
    const EffectInfo e = loop.scene().effect_info(i);
    if (e.key == "surface" && !surface) {
      surface = true;
      out.impact_time_s = values[e.value_offset + 1];
    }
    if (e.key == "cliff" && !cliff) {
      cliff = true;
      out.cliff_state = static_cast<int>(values[e.value_offset]);
    }
  }
  return out;
}

template <Scalar S = double>
class Rig {
 public:
  Rig(const std::string& scene_toml, const DeviceParams& device, HandIntent intent, double period_s = kPeriodS,
      const std::function<void(ServoConfig&)>& tweak = {}, int substeps = 4)
      : period_s_(period_s) {
    auto scene = parse_scene(scene_toml, "test.toml", kind_of<S>());
    EXPECT_TRUE(scene) << scene.error();
    description_ = scene.value();
    auto sim = SimDevice::create(device, std::move(intent), {host_sim::Integrator::kExact, substeps, period_s});
    EXPECT_TRUE(sim) << sim.error();
    sim_ = std::make_unique<SimDevice>(std::move(sim).value());
    DeviceInfo info;
    info.name = "simulated";
    info.max_force_n = device.max_force_n;
    info.max_continuous_force_n = device.max_force_n;  // as host_sim::SimDriver: no thermal limit
    info.workspace_min_m = device.workspace_min_m;
    info.workspace_max_m = device.workspace_max_m;
    config_ = with_device(servo_config(description_, period_s), info);
    if (tweak) tweak(config_);
    EXPECT_EQ(check_servo_config(config_), "");
    loop_ = std::make_unique<ServoLoop<TestDevice, RuntimeScene<S>>>(TestDevice{sim_.get(), &injection_, &exchanges_},
                                                                     make_runtime_scene<S>(description_), config_);
  }

  /// One tick at the next integer time; `gap` > 1: the loop missed gap - 1 ticks, during
  /// which the device held the last force (as a real device holds its last command).
  TickStatus tick(std::int64_t gap = 1) {
    for (std::int64_t i = 1; i < gap; ++i) {
      DeviceReading ignored;
      static_cast<void>(sim_->read(ignored));
      static_cast<void>(sim_->write(to_double(loop_->force())));
    }
    k_ += gap;
    const TickStatus s = loop_->tick(k_);
    const Vec3<double> f = to_double(loop_->force());
    const bool finite = std::isfinite(f.x) && std::isfinite(f.y) && std::isfinite(f.z) &&
                        is_finite(sim_->plant().position_m()) && is_finite(sim_->plant().velocity_m_per_s());
    if (!finite) ++non_finite_;
    max_force_ = std::max(max_force_, norm(f));
    max_speed_ = std::max(max_speed_, norm(sim_->plant().velocity_m_per_s()));
    return s;
  }
  void run_for(double seconds) {
    const auto n = static_cast<std::int64_t>(std::llround(seconds / period_s_));
    for (std::int64_t i = 0; i < n; ++i) tick();
  }

  double time_s() const { return sim_->time_s(); }
  const host_sim::Plant& plant() const { return sim_->plant(); }
  SimDevice& sim() { return *sim_; }
  ServoLoop<TestDevice, RuntimeScene<S>>& loop() { return *loop_; }
  Injection& injection() { return injection_; }
  Vec3<double> force() const { return to_double(loop_->force()); }
  double max_force() const { return max_force_; }
  double max_speed() const { return max_speed_; }
  std::int64_t non_finite() const { return non_finite_; }
  const ServoConfig& config() const { return config_; }
  /// Kinetic energy of handle and hand plus the hand's spring about its aim [J].
  double energy() const { return sim_->plant().mechanical_energy_j(time_s()); }

 private:
  double period_s_;
  SceneDescription description_;
  std::unique_ptr<SimDevice> sim_;
  Injection injection_;
  std::int64_t exchanges_ = 0;
  ServoConfig config_;
  std::unique_ptr<ServoLoop<TestDevice, RuntimeScene<S>>> loop_;
  std::int64_t k_ = -1;
  double max_force_ = 0.0;
  double max_speed_ = 0.0;
  std::int64_t non_finite_ = 0;
};

/// The Falcon-class device without Coulomb friction and with the given viscous damping.
DeviceParams falcon_with_damping(double damping_n_s_per_m) {
  DeviceParams d = host_sim::falcon_params();
  d.damping_n_s_per_m = damping_n_s_per_m;
  d.coulomb_n = 0.0;
  return d;
}

bool running_normally(LoopState s) { return s == LoopState::kActive || s == LoopState::kRamping; }

// ---- 1. stiffness through and beyond 2b/T ------------------------------------------------

/// Peak-to-peak of the commanded force and of the handle's true position along z over the
/// last `window_s` of a run (after `settle_s`), and the largest energy in that window.
struct Swing {
  double force_n = 0.0;
  double position_m = 0.0;
  double energy_j = 0.0;
};

Swing swing_after(Rig<>& rig, double settle_s, double window_s) {
  rig.run_for(settle_s);
  double f_lo = kInf;
  double f_hi = -kInf;
  double x_lo = kInf;
  double x_hi = -kInf;
  Swing out;
  const auto n = static_cast<int>(std::llround(window_s / rig.config().period_s));
  for (int i = 0; i < n; ++i) {
    rig.tick();
    f_lo = std::min(f_lo, rig.force().z);
    f_hi = std::max(f_hi, rig.force().z);
    x_lo = std::min(x_lo, rig.plant().position_m().z);
    x_hi = std::max(x_hi, rig.plant().position_m().z);
    out.energy_j = std::max(out.energy_j, rig.energy());
  }
  out.force_n = f_hi - f_lo;
  out.position_m = x_hi - x_lo;
  return out;
}

TEST(ExtremeCases, StiffWallsSettleInsideTheDelayAwareBoundAndTheSafetyLayerHoldsTheLimitCycleBeyondIt) {
  // The Falcon-class device (20 um encoder, DAC steps, one tick of I/O delay, 8 N) without
  // Coulomb friction (which would hide a limit cycle), held by the relaxed hand aiming 2 mm
  // into a penalty wall. The hand's damping adds to the device's, and the delay enters the
  // bound (control/passivity_bound.hpp, Diolaiti et al. 2006): K_p = 2 (b + b_hand) / (3 T).
  const DeviceParams base = falcon_with_damping(0.0);
  const double q = base.encoder_step_m;
  for (const double period : {1e-3, 0.5e-3, 0.25e-3}) {
    for (const double device_damping : {0.0, 0.1}) {
      const double k_bound =
          stiffest_passive_wall_n_per_m(device_damping + kRelaxedHand.damping_n_s_per_m, period, base.io_delay_ticks);
      for (const double factor : {0.25, 0.5, 2.0, 8.0}) {
        const double k = factor * k_bound;
        SCOPED_TRACE(testing::Message() << "T " << period << " s, b " << device_damping << ", K " << k << " N/m ("
                                        << factor << " K_p)");
        Rig<> rig(floor_toml(k), falcon_with_damping(device_damping), hand({0, 0, -0.002}, kRelaxedHand), period);
        rig.sim().set_state({0, 0, 0.002}, {0, 0, 0});
        const Swing last = swing_after(rig, 3.0, 1.0);
        // The loop's linear model in contact (report::SampledLoop: device and hand, the delay;
        // no quantisation or clamp) agrees with the bound on which side each K is.
        report::SampledLoop linear;
        linear.mass_kg = base.mass_kg + kRelaxedHand.mass_kg;
        linear.damping_n_s_per_m = device_damping + kRelaxedHand.damping_n_s_per_m;
        linear.spring_n_per_m = kRelaxedHand.stiffness_n_per_m;
        linear.period_s = period;
        linear.delay_ticks = base.io_delay_ticks;
        linear.stiffness_n_per_m = k;
        const auto rho = report::loop_spectral_radius(linear);
        ASSERT_TRUE(rho) << rho.error();
        EXPECT_EQ(rho.value() < 1.0, factor < 1.0) << "rho " << rho.value();
        EXPECT_EQ(rig.non_finite(), 0);
        EXPECT_LE(rig.max_force(), 8.0 + 1e-9);
        EXPECT_FALSE(rig.loop().latched());
        EXPECT_TRUE(running_normally(rig.loop().state())) << to_string(rig.loop().state());
        if (factor < 1.0) {
          // Half the bound or less: the loop settles, and what is left over the last second is
          // the quantisation's dither, one encoder count either way (2 q of position, 2 K q of
          // force, plus two DAC steps), not a limit cycle. (Closer to the bound, at 0.9 K_p,
          // the lightly damped loop is kept ringing by the quantisation error at 5-9 counts:
          // stable, but not settled, so it is not asserted here.)
          EXPECT_LE(last.position_m, 2.0 * q + 1e-9);
          EXPECT_LE(last.force_n, 2.0 * k * q + 2.0 * base.force_step_n + 1e-9);
        } else {
          // Beyond it the linear loop is unstable (rho > 1 above) and what grows is held by the
          // clamp at 8 N (not by the force-rate limit: without it the runs at T = 1 and 0.5 ms
          // are the same, and at 0.25 ms the cycle is smaller). Stated requirement: a buzz the hand feels, not a
          // throw: under 1 cm peak to peak and 10 mJ (handle and hand, 0.25 kg, at 0.28 m/s).
          // Without the clamp the wall at 8 K_p and T = 0.25 ms swings 75 mm with 0.4 J.
          EXPECT_LE(last.position_m, 0.01);
          EXPECT_LE(last.energy_j, 0.010);
        }
      }
    }
  }
}

// ---- 2. negative virtual damping (the slippery surface) ---------------------------------

/// The most energy the slippery surface's episode (slot 0) held while a relaxed hand strokes
/// 8 cm across it at `stroke_speed` pressing with `press_n`, with the passivity controller on
/// or off.
template <Scalar S = double>
double stroked_episode_energy(const std::string& scene, const DeviceParams& device, double stroke_speed, double press_n,
                              bool controller) {
  HandSegment stroke;
  stroke.kind = SegmentKind::kStroke;
  stroke.to_m = {0.04, 0.0, -0.001};
  stroke.speed_m_per_s = stroke_speed;
  stroke.force_n = press_n;
  HandSegment hold;
  hold.kind = SegmentKind::kHold;
  hold.duration_s = 0.5;
  hold.force_n = press_n;
  auto rig =
      std::make_unique<Rig<S>>(scene, device, hand({-0.04, 0, -0.001}, kRelaxedHand, 0.0, {stroke, hold}), kPeriodS,
                               [controller](ServoConfig& c) { c.safety.passivity.controller = controller; });
  rig->sim().set_state({-0.04, 0, 0.002}, {0, 0, 0});  // above the floor: the loop engages at once
  const double rate = rig->config().limits.max_force_rate_n_per_s;
  double worst = 0.0;
  Vec3<double> previous{};
  const auto ticks = static_cast<int>(std::llround((0.08 / stroke_speed + 0.6) / kPeriodS));
  for (int i = 0; i < ticks; ++i) {
    const TickStatus s = rig->tick();
    worst = std::max(worst, rig->loop().passivity().controller().episode_energy(0).to_double());
    // The force-rate limit holds on every tick, damping included, except for a cut to zero
    // (a fault: over-speed, outside the workspace), which bypasses it by design.
    if (!s.faults) {
      EXPECT_LE(norm(rig->force() - previous), rate * kPeriodS + 1e-9) << "tick " << i;
    } else {
      EXPECT_EQ(norm(rig->force()), 0.0);
    }
    previous = rig->force();
  }
  EXPECT_EQ(rig->non_finite(), 0);
  EXPECT_LE(rig->max_force(), rig->config().limits.max_force_n + 1e-9);
  EXPECT_LE(rig->max_speed(), rig->config().safety.max_velocity_m_per_s);
  EXPECT_FALSE(rig->loop().latched());
  EXPECT_TRUE(running_normally(rig->loop().state()));
  return worst;
}

/// What the passivity controller may let through beyond the budget: the slippery surface's
/// power mu v^2 at 1.5 times the stroke speed, for the velocity filter's time constant (50 Hz:
/// 3.2 ms) and two ticks: it damps the excess it has measured, on the filtered velocity.
double passivity_slack(double mu, double stroke_speed) {
  const double v = 1.5 * stroke_speed;
  return mu * v * v * (1.0 / (2.0 * 3.14159265358979 * 50.0) + 2.0 * kPeriodS);
}

TEST(ExtremeCases, SlipperyGainNearAndAboveTheDevicesDampingIsHeldToItsEnergyBudget) {
  const double device_damping = 0.1;
  const double hand_damping = kRelaxedHand.damping_n_s_per_m;
  constexpr double kBudgetJ = 0.002;
  constexpr double kStroke = 0.1;
  // mu from half to eight times the damping of device and hand (b - K T / 2 with K = 0 along
  // the surface), all under passivity_max_damping (control/passivity.hpp: above it the
  // controller cannot keep up at low speeds, by design).
  for (const double factor : {0.5, 1.0, 2.0, 8.0}) {
    const double mu = factor * (device_damping + hand_damping);
    SCOPED_TRACE(testing::Message() << "mu " << mu << " N s/m");
    const std::string scene =
        floor_toml(1500.0, "passivity_budget = " + std::to_string(kBudgetJ) + "\npassivity_max_damping = 20.0\n",
                   "  [surface.slippery]\n  mu = " + std::to_string(mu) + "\n");
    const double held = stroked_episode_energy(scene, falcon_with_damping(device_damping), kStroke, 1.0, true);
    EXPECT_LE(held, kBudgetJ + passivity_slack(mu, kStroke));
    if (factor >= 2.0) {
      // Without the controller the same stroke injects far more: the controller did the work.
      const double free = stroked_episode_energy(scene, falcon_with_damping(device_damping), kStroke, 1.0, false);
      EXPECT_GT(free, 2.0 * (kBudgetJ + passivity_slack(mu, kStroke)));
    }
  }
}

// ---- 3. impact at the device's top speed --------------------------------------------------

TEST(ExtremeCases, AnImpactAtTopSpeedIsClampedPushedBackOutAndItsRecoilBudgeted) {
  // Just under the velocity limit (1.2 m/s, the fastest the loop renders) and above it.
  for (const double speed : {1.15, 1.6}) {
    SCOPED_TRACE(testing::Message() << "impact at " << speed << " m/s");
    Rig<> rig(bundled("cartoon_wall"), host_sim::falcon_params(), hand({0, 0, -0.003}, kFirmHand), kPeriodS,
              [](ServoConfig& c) { c.safety.soft_start_s = 0.0; });
    rig.sim().set_state({0, 0, 0.004}, {0, 0, 0});
    rig.run_for(0.3);  // engaged above the floor, then resting on it where the hand holds it
    rig.sim().set_state({0, 0, 0.004}, {0, 0, -speed});  // thrown at the floor from 4 mm
    double deepest = 0.0;
    double worst_episode = 0.0;
    const double budget = rig.config().safety.passivity.budget_j;
    const double start_energy = rig.energy();
    double most_energy = 0.0;
    for (int i = 0; i < 2000; ++i) {
      rig.tick();
      deepest = std::min(deepest, rig.plant().position_m().z);
      worst_episode = std::max(worst_episode, rig.loop().passivity().controller().episode_energy(1).to_double());
      most_energy = std::max(most_energy, rig.energy());
    }
    EXPECT_EQ(rig.non_finite(), 0);
    // The recoil asks for v_i d (k_r + k_osc) = 100 N and more: the clamp holds it at 8 N.
    EXPECT_LE(rig.max_force(), 8.0 + 1e-9);
    EXPECT_GT(rig.max_force(), 7.9);
    // A half-space has no far side to pop through; the handle stops within a few cm and is
    // pushed back to where the hand and the wall balance.
    EXPECT_GT(deepest, -0.03);
    const double rest_z = -0.003 * kFirmHand.stiffness_n_per_m / (kFirmHand.stiffness_n_per_m + 1500.0);
    EXPECT_NEAR(rig.plant().position_m().z, rest_z, 2e-4);
    // The transient's energy is held to its budget (one tick of clamped force as slack), and
    // the mechanical energy never exceeds the strike's plus that budget.
    EXPECT_LE(worst_episode, budget + 8.0 * speed * kPeriodS);
    EXPECT_LE(most_energy, start_energy + budget + 0.05);
    EXPECT_FALSE(rig.loop().latched());
    EXPECT_TRUE(running_normally(rig.loop().state()));
  }
}

// ---- 4. chattering: wall boundary, cliff threshold, corner ------------------------------

TEST(ExtremeCases, RestingOnTheWallBoundaryWithSensorNoiseNeitherRetriggersNorBuzzes) {
  DeviceParams device = host_sim::falcon_params();
  device.sensor_noise_m = 10e-6;  // readings flip in and out of contact every few ticks
  Rig<> rig(bundled("cartoon_wall"), device, hand({0, 0, 0}, kFirmHand));
  int triggers = 0;
  int in_contact = 0;
  int out_of_contact = 0;
  for (int i = 0; i < 3000; ++i) {
    rig.tick();
    const Shown d = shown(rig.loop());
    if (d.impact_time_s == 0.0) ++triggers;
    (d.in_contact ? in_contact : out_of_contact)++;
  }
  EXPECT_GT(in_contact, 100);  // it really chatters across the boundary
  EXPECT_GT(out_of_contact, 100);
  EXPECT_EQ(triggers, 0);  // noise is far below min_impact_speed
  EXPECT_EQ(rig.non_finite(), 0);
  EXPECT_LT(rig.max_force(), 0.5);  // 1500 N/m times a few noise steps
  EXPECT_LT(std::abs(rig.plant().position_m().z), 2e-4);
  EXPECT_LT(norm(rig.plant().velocity_m_per_s()), 0.01);
  EXPECT_TRUE(running_normally(rig.loop().state()));
}

TEST(ExtremeCases, LingeringAtTheCliffsSpeedThresholdFallsOnceAndNeverChatters) {
  for (const double speed : {0.08 * 0.97, 0.08, 0.08 * 1.03}) {
    SCOPED_TRACE(testing::Message() << "crossing at " << speed << " m/s");
    HandSegment cross;
    cross.kind = SegmentKind::kCross;
    cross.to_m = {0.04, 0.0, -0.0015};
    cross.speed_m_per_s = speed;
    cross.force_n = 2.0;
    cross.stop = false;
    Rig<> rig(bundled("cliff"), host_sim::falcon_params(), hand({-0.03, 0, -0.0015}, kFirmHand, 0.0, {cross}));
    rig.sim().set_state({-0.03, 0, 0.002}, {0, 0, 0});
    int falls = 0;
    int rises_below_ground = 0;
    int previous = -1;
    for (int i = 0; i < 1500; ++i) {
      rig.tick();
      const int state = shown(rig.loop()).cliff_state;
      if (previous == 0 && state == 1) ++falls;
      if (previous == 1 && state == 0 && rig.plant().position_m().z < 0.0) ++rises_below_ground;
      previous = state;
    }
    EXPECT_LE(falls, 1);
    EXPECT_EQ(rises_below_ground, 0);  // a surface never appears with the HIP inside it
    EXPECT_EQ(rig.non_finite(), 0);
    EXPECT_LE(rig.max_force(), 8.0 + 1e-9);
    EXPECT_FALSE(rig.loop().latched());
  }
}

TEST(ExtremeCases, PressingIntoACornerOfTwoWallsStaysClampedAndCalm) {
  // A floor (normal +z) and a wall at x = 0 (normal -x) meet along the y axis; the hand aims
  // 5 mm into both with a firm grip.
  const std::string corner =
      floor_toml(1500.0) + "[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [-1.0, 0.0, 0.0]\nstiffness = 1500.0\n";
  Rig<> rig(corner, host_sim::falcon_params(), hand({0.005, 0, -0.005}, kFirmHand));
  rig.sim().set_state({-0.01, 0, 0.01}, {0, 0, 0});
  rig.run_for(3.0);
  EXPECT_EQ(rig.non_finite(), 0);
  EXPECT_LE(rig.max_force(), 8.0 + 1e-9);
  const Vec3<double> f = rig.force();
  EXPECT_LT(f.x, -0.5);  // both walls push out of the corner
  EXPECT_GT(f.z, 0.5);
  EXPECT_LT(norm(rig.plant().velocity_m_per_s()), 1e-3);
  EXPECT_TRUE(running_normally(rig.loop().state()));
}

// ---- 5. timing faults -----------------------------------------------------------------------

TEST(ExtremeCases, TimingFaultsKeepTheForceWithinItsRateLimitAndAStallZeroesItUntilReArmed) {
  Rig<> rig(floor_toml(1500.0), host_sim::falcon_params(), hand({0, 0, -0.003}, kFirmHand));
  rig.sim().set_state({0, 0, 0.002}, {0, 0, 0});
  rig.run_for(0.5);
  ASSERT_EQ(rig.loop().state(), LoopState::kActive);
  const double rate = rig.config().limits.max_force_rate_n_per_s;
  std::vector<std::int64_t> gaps;
  for (int i = 0; i < 200; ++i) gaps.push_back(1 + (i * 7919) % 3);  // jitter: 1, 2 or 3 periods
  gaps.push_back(2);                                                 // one missed tick
  for (int i = 0; i < 500; ++i) gaps.push_back(2);                   // sustained 2T
  for (int i = 0; i < 10; ++i) gaps.push_back(5);                    // a burst of late ticks
  for (int i = 0; i < 200; ++i) gaps.push_back(1);
  Vec3<double> previous = rig.force();
  for (const std::int64_t gap : gaps) {
    const TickStatus s = rig.tick(gap);
    ASSERT_FALSE(s.faults.has(Fault::kWatchdog)) << "gap " << gap;
    const Vec3<double> f = rig.force();
    EXPECT_LE(norm(f - previous), rate * static_cast<double>(gap) * kPeriodS + 1e-9);
    previous = f;
  }
  EXPECT_EQ(rig.loop().state(), LoopState::kActive);
  EXPECT_GT(norm(rig.force()), 0.5);  // still pressing on the wall

  // A stall beyond the watchdog (30 periods): zero force at once, latched, until re-armed.
  TickStatus s = rig.tick(rig.config().safety.watchdog_periods + 5);
  EXPECT_TRUE(s.faults.has(Fault::kWatchdog));
  EXPECT_EQ(norm(rig.force()), 0.0);
  for (int i = 0; i < 100; ++i) {
    s = rig.tick();
    EXPECT_EQ(s.state, LoopState::kFaulted);
    EXPECT_EQ(norm(rig.force()), 0.0);
  }
  // Re-armed with the handle pushed into the wall by the hand: the loop waits to engage (a
  // force would throw the handle) ...
  rig.loop().request_rearm();
  s = rig.tick();
  EXPECT_FALSE(rig.loop().latched());
  rig.run_for(0.2);
  EXPECT_EQ(rig.loop().state(), LoopState::kEngaging);
  EXPECT_EQ(norm(rig.force()), 0.0);
  // ... until the handle is out of the wall; then it ramps in and renders the wall again.
  rig.sim().set_state({0, 0, 0.002}, {0, 0, 0});
  rig.run_for(1.0);
  EXPECT_EQ(rig.loop().state(), LoopState::kActive);
  EXPECT_GT(norm(rig.force()), 0.5);
  EXPECT_EQ(rig.non_finite(), 0);
  EXPECT_LE(rig.max_force(), 8.0 + 1e-9);
}

// ---- 6. sensor faults -------------------------------------------------------------------------

TEST(ExtremeCases, SensorFaultsGiveZeroForceOrStayBoundedAndTheLoopRecovers) {
  {  // A coarse encoder (0.2 mm, ten Falcon counts) under a stiff wall.
    DeviceParams coarse = host_sim::falcon_params();
    coarse.encoder_step_m = 2e-4;
    Rig<> rig(floor_toml(1500.0), coarse, hand({0, 0, -0.003}, kFirmHand));
    rig.sim().set_state({0, 0, 0.002}, {0, 0, 0});
    rig.run_for(3.0);
    EXPECT_EQ(rig.non_finite(), 0);
    EXPECT_LE(rig.max_force(), 8.0 + 1e-9);
    EXPECT_LT(norm(rig.plant().velocity_m_per_s()), 0.05);
    EXPECT_TRUE(running_normally(rig.loop().state()));
  }
  {  // A slow approach: the velocity estimate is next to zero; the impact must not fire.
    HandSegment creep;
    creep.kind = SegmentKind::kStrike;
    creep.to_m = {0, 0, -0.003};
    creep.speed_m_per_s = 0.002;
    creep.ramp_s = 0.05;
    Rig<> rig(bundled("cartoon_wall"), host_sim::falcon_params(), hand({0, 0, 0.002}, kFirmHand, 0.0, {creep}));
    int triggers = 0;
    for (int i = 0; i < 4000; ++i) {
      rig.tick();
      if (shown(rig.loop()).impact_time_s == 0.0) ++triggers;
    }
    EXPECT_EQ(triggers, 0);
    EXPECT_TRUE(shown(rig.loop()).in_contact);
    EXPECT_EQ(rig.non_finite(), 0);
  }
  {  // A laggy velocity filter (5 Hz) under the slippery surface: the passivity controller
     // still holds the energy it injects to the budget.
    HandSegment stroke;
    stroke.kind = SegmentKind::kStroke;
    stroke.to_m = {0.04, 0.0, -0.001};
    stroke.speed_m_per_s = 0.1;
    stroke.force_n = 1.0;
    const std::string scene =
        floor_toml(1500.0, "velocity_cutoff = 5.0\npassivity_budget = 0.02\n", "  [surface.slippery]\n  mu = 4.0\n");
    Rig<> rig(scene, host_sim::falcon_params(), hand({-0.04, 0, -0.001}, kRelaxedHand, 0.0, {stroke}));
    rig.sim().set_state({-0.04, 0, 0.002}, {0, 0, 0});
    double worst_episode = 0.0;
    for (int i = 0; i < 1500; ++i) {
      rig.tick();
      worst_episode = std::max(worst_episode, rig.loop().passivity().controller().episode_energy(0).to_double());
    }
    EXPECT_LE(worst_episode, 0.02 + 2.0 * 0.3 * kPeriodS);
    EXPECT_EQ(rig.non_finite(), 0);
  }
  {  // NaN and Inf readings: exactly zero force on those ticks, then back through the ramp.
    Rig<> rig(floor_toml(1500.0), host_sim::falcon_params(), hand({0, 0, -0.003}, kFirmHand));
    rig.sim().set_state({0, 0, 0.002}, {0, 0, 0});
    rig.run_for(0.5);
    ASSERT_EQ(rig.loop().state(), LoopState::kActive);
    const std::int64_t start = static_cast<std::int64_t>(std::llround(rig.time_s() / kPeriodS));
    rig.injection().reading = [start](std::int64_t tick, Vec3<double>& p) {
      if (tick == start + 3) p.z = kNaN;
      if (tick == start + 7) p.x = kInf;
      if (tick == start + 8) p = {-kInf, kNaN, kInf};
      return tick >= start + 3 && tick <= start + 8 && (tick == start + 3 || tick >= start + 7);
    };
    int zero_ticks = 0;
    for (int i = 0; i < 12; ++i) {
      const TickStatus s = rig.tick();
      if (s.faults.has(Fault::kNonFiniteInput)) {
        EXPECT_EQ(norm(rig.force()), 0.0);
        ++zero_ticks;
      }
    }
    EXPECT_EQ(zero_ticks, 3);
    rig.injection().reading = nullptr;
    rig.run_for(1.0);
    EXPECT_EQ(rig.loop().state(), LoopState::kActive);
    EXPECT_FALSE(rig.loop().latched());
    EXPECT_GT(norm(rig.force()), 0.5);
    EXPECT_EQ(rig.non_finite(), 0);
  }
}

// ---- 7. saturation ------------------------------------------------------------------------------

TEST(ExtremeCases, OnAClampedOmniThePassivityControllerStillHoldsTheSlipperyBudget) {
  // The Omni's 3.3 N clamp is below what the scene asks (a 3 N press on the wall and the
  // slippery force of a fast stroke): the passivity controller's damping is clamped along with
  // the scene force (direction kept), and must still hold the budget.
  constexpr double kBudgetJ = 0.002;
  constexpr double kStroke = 0.4;
  constexpr double kMu = 4.0;
  const std::string scene =
      floor_toml(800.0, "passivity_budget = " + std::to_string(kBudgetJ) + "\npassivity_max_damping = 5.0\n",
                 "  [surface.slippery]\n  mu = 4.0\n  max_tangential_force = 5.0\n");
  const DeviceParams omni = host_sim::omni_params();
  int clamped = 0;
  {
    // Count the clamped ticks of the controlled run.
    HandSegment stroke;
    stroke.kind = SegmentKind::kStroke;
    stroke.to_m = {0.04, 0.0, -0.001};
    stroke.speed_m_per_s = kStroke;
    stroke.force_n = 3.0;
    Rig<> rig(scene, omni, hand({-0.04, 0, -0.001}, kRelaxedHand, 0.0, {stroke}));
    ASSERT_DOUBLE_EQ(rig.config().limits.max_force_n, 3.3);  // the device's is smaller
    rig.sim().set_state({-0.04, 0, 0.002}, {0, 0, 0});
    for (int i = 0; i < 800; ++i) {
      const TickStatus s = rig.tick();
      if ((s.limits & static_cast<std::uint8_t>(Limit::kClamped)) != 0) ++clamped;
    }
  }
  EXPECT_GT(clamped, 10);
  const double held = stroked_episode_energy(scene, omni, kStroke, 3.0, true);
  const double free = stroked_episode_energy(scene, omni, kStroke, 3.0, false);
  EXPECT_LE(held, kBudgetJ + passivity_slack(kMu, kStroke));
  EXPECT_GT(free, 2.0 * (kBudgetJ + passivity_slack(kMu, kStroke)));
}

// ---- 8. number formats ----------------------------------------------------------------------------

TEST(ExtremeCases, FixedPointRangeEndsSaturateWithAFaultAndStayBounded) {
  Rig<Q16_16> rig(floor_toml(1500.0), host_sim::falcon_params(), hand({0, 0, -0.003}, kFirmHand));
  rig.sim().set_state({0, 0, 0.002}, {0, 0, 0});
  rig.run_for(0.5);
  ASSERT_EQ(rig.loop().state(), LoopState::kActive);
  // Readings at and beyond the ends of Q16.16 (+-32768 m) for a few ticks.
  const std::int64_t start = static_cast<std::int64_t>(std::llround(rig.time_s() / kPeriodS));
  rig.injection().reading = [start](std::int64_t tick, Vec3<double>& p) {
    if (tick < start + 1 || tick > start + 6) return false;
    p = tick % 2 == 0 ? Vec3<double>{40000.0, -32767.9, 1e9} : Vec3<double>{-40000.0, 32767.99, -1e9};
    return true;
  };
  int saturated = 0;
  for (int i = 0; i < 8; ++i) {
    const TickStatus s = rig.tick();
    if (s.faults.has(Fault::kFixedSaturation)) ++saturated;
  }
  EXPECT_GT(saturated, 0);
  EXPECT_LE(rig.max_force(), 8.0 + 1e-3);
  rig.injection().reading = nullptr;
  rig.run_for(1.5);  // the velocity estimate settles, the loop ramps back in
  EXPECT_EQ(rig.loop().state(), LoopState::kActive);
  EXPECT_FALSE(rig.loop().latched());
  EXPECT_GT(norm(rig.force()), 0.5);
  EXPECT_EQ(rig.non_finite(), 0);
}

TEST(ExtremeCases, TheObserverAccumulatesAnHourOfWorkExactlyInQ16) {
  // Q32.32 (math/wide.hpp): the work F.dx of each tick is exact, and so is its sum over an
  // hour at 1 kHz. The reference is independent of the observer: the same samples' raw Q16.16
  // integers multiplied and summed in int64 (2^-32 J units; the sum stays below 2^53, so its
  // conversion to double is exact too). The samples vary every tick (a fixed increment would
  // let N x (one increment) agree with a wrong accumulator), forces up to 8 N and
  // displacements up to 1 mm per tick, of both signs.
  PassivityObserver<Q16_16> fixed;
  PassivityObserver<double> floating;
  std::int64_t exact_raw = 0;  // 2^-32 J
  double magnitude_j = 0.0;    // sum of |F.dx|, for double's rounding bound
  std::uint64_t state = 0x9E3779B97F4A7C15u;
  const auto next = [&state](std::int32_t half_range) {           // uniform in [-half_range, half_range]
    state = state * 6364136223846793005u + 1442695040888963407u;  // Knuth's MMIX LCG
    const auto span = static_cast<std::uint64_t>(2 * half_range + 1);
    return static_cast<std::int32_t>(static_cast<std::int64_t>((state >> 33) % span) - half_range);
  };
  constexpr std::int32_t kForceRaw = 8 * 65536;  // 8 N
  constexpr std::int32_t kStepRaw = 66;          // 1 mm = 65.5 counts of 2^-16 m
  constexpr std::int64_t kTicks = 3'600'000;
  for (std::int64_t i = 0; i < kTicks; ++i) {
    Vec3<Q16_16> f;
    Vec3<Q16_16> dx;
    f.x = Q16_16::from_raw(next(kForceRaw));
    f.y = Q16_16::from_raw(next(kForceRaw));
    f.z = Q16_16::from_raw(next(kForceRaw));
    dx.x = Q16_16::from_raw(next(kStepRaw));
    dx.y = Q16_16::from_raw(next(kStepRaw));
    dx.z = Q16_16::from_raw(next(kStepRaw));
    fixed.observe(f, dx);
    floating.observe(to_double(f), to_double(dx));
    const std::int64_t work = std::int64_t{f.x.raw()} * dx.x.raw() + std::int64_t{f.y.raw()} * dx.y.raw() +
                              std::int64_t{f.z.raw()} * dx.z.raw();
    exact_raw -= work;  // the observer counts the energy absorbed: -F.dx
    magnitude_j += std::abs(static_cast<double>(work)) / 4294967296.0;
  }
  ASSERT_LT(std::abs(exact_raw), std::int64_t{1} << 53);
  const double exact = static_cast<double>(exact_raw) / 4294967296.0;
  EXPECT_NE(exact, 0.0);
  EXPECT_EQ(fixed.energy().to_double(), exact);
  // Double: each addition rounds by at most eps/2 of the running sum (<= the sum of
  // magnitudes), so the error is at most N eps/2 times that sum.
  EXPECT_NEAR(floating.energy().to_double(), exact,
              static_cast<double>(kTicks) * std::numeric_limits<double>::epsilon() * magnitude_j);
}

/// A device that reports the latency report's scripted cartoon-wall path (no physics), for
/// long runs: the loop's forces then repeat with the path's period.
struct ScriptedDevice {
  const std::vector<Vec3<double>>* positions;
  std::int64_t k = 0;
  DeviceStatus read(DeviceReading& r) noexcept {
    r.position_m = (*positions)[static_cast<std::size_t>(k % static_cast<std::int64_t>(positions->size()))];
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>&) noexcept {
    ++k;
    return DeviceStatus::kOk;
  }
};

template <Scalar S>
std::vector<Vec3<double>> scripted_forces(std::int64_t ticks, std::int64_t keep_from) {
  const report::KeyframePath path = report::paper_scenario("cartoon_wall");
  std::vector<Vec3<double>> positions;
  for (int j = 0; j < 1000; ++j) positions.push_back(path.at(j * 1e-3).position_m);
  auto scene = parse_scene(bundled("cartoon_wall"), "cartoon_wall.toml", kind_of<S>());
  EXPECT_TRUE(scene);
  ServoConfig config = servo_config(scene.value(), kPeriodS);
  config.safety.engage_force_n = 100.0;  // engage at once: the path starts wherever it is
  config.safety.soft_start_s = 0.0;
  ServoLoop<ScriptedDevice, RuntimeScene<S>> loop(ScriptedDevice{&positions}, make_runtime_scene<S>(scene.value()),
                                                  config);
  std::vector<Vec3<double>> out;
  for (std::int64_t k = 0; k < ticks; ++k) {
    static_cast<void>(loop.tick(k));
    if (k >= keep_from) out.push_back(to_double(loop.force()));
  }
  return out;
}

TEST(ExtremeCases, DoubleFloatAndQ16RepeatThemselvesExactlyOverAMillionTicks) {
  // 10^6 ticks of the periodic path (1000 ticks per period); keep the second period and the
  // last one. Time is integer ticks and nothing accumulates in the scalar type, so the last
  // period repeats the second exactly, in every scalar type.
  constexpr std::int64_t kTicks = 1'000'000;
  for (const auto& [name, forces] :
       {std::pair{"double", scripted_forces<double>(kTicks, 0)}, std::pair{"float", scripted_forces<float>(kTicks, 0)},
        std::pair{"q16.16", scripted_forces<Q16_16>(kTicks, 0)}}) {
    SCOPED_TRACE(name);
    ASSERT_EQ(forces.size(), static_cast<std::size_t>(kTicks));
    for (std::size_t j = 0; j < 1000; ++j) {
      ASSERT_EQ(forces[1000 + j], forces[static_cast<std::size_t>(kTicks) - 1000 + j]) << "tick " << j;
    }
  }
}

TEST(ExtremeCases, TheSameRunTwiceGivesTheSameBits) {
  const auto run = [] {
    DeviceParams device = host_sim::falcon_params();
    device.sensor_noise_m = 5e-6;  // seeded: part of what must repeat
    Rig<> rig(bundled("cartoon_wall"), device, hand({0, 0, -0.003}, kFirmHand));
    rig.sim().set_state({0, 0, 0.01}, {0, 0, -0.3});
    std::vector<Vec3<double>> forces;
    for (int i = 0; i < 3000; ++i) {
      rig.tick();
      forces.push_back(rig.force());
    }
    return forces;
  };
  const auto a = run();
  const auto b = run();
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3<double>)), 0);
}

// ---- 9. long-run energy -------------------------------------------------------------------------

TEST(ExtremeCases, AnIsolatedPassiveSceneNeverGainsEnergy) {
  // A wall inside the bound (K = 100 < 2 b / T = 200 N/m) on a device with its own damping,
  // pressed by a constant force and nothing else (no hand impedance), starting in contact at
  // the equilibrium depth with some speed: the energy of device plus wall plus press must
  // never grow, tick after tick, for 20 simulated seconds.
  constexpr double kStiffness = 100.0;
  constexpr double kPress = 1.0;
  DeviceParams device = falcon_with_damping(0.1);
  device.encoder_step_m = 0.0;
  device.force_step_n = 0.0;
  device.io_delay_ticks = 0;
  const std::string scene = "[device]\nmax_force = 8.0\nmax_force_rate = 2000.0\nsoft_start = 0.0\n"
                            "engage_force = 5.0\nvelocity_cutoff = 1000000.0\n" +
                            std::string("[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n") +
                            "stiffness = " + std::to_string(kStiffness) + "\n";
  const double depth = kPress / kStiffness;
  Rig<> rig(scene, device, hand({0, 0, -depth}, kNoHand, kPress), kPeriodS, {}, 1);
  rig.sim().set_state({0, 0, -depth}, {0, 0, -0.1});
  const double m = device.mass_kg;
  const auto energy = [&] {
    const Vec3<double> x = rig.plant().position_m();
    const Vec3<double> v = rig.plant().velocity_m_per_s();
    const double d = std::max(0.0, -x.z);
    return 0.5 * m * dot(v, v) + 0.5 * kStiffness * d * d + kPress * x.z;
  };
  double previous = energy();
  const double first = previous;
  int increases = 0;
  for (int i = 0; i < 20000; ++i) {
    rig.tick();
    const double now = energy();
    if (now > previous + 1e-12 + 1e-9 * std::abs(previous)) ++increases;
    previous = now;
  }
  EXPECT_EQ(increases, 0);
  EXPECT_LT(previous, first);
  EXPECT_EQ(rig.loop().state(), LoopState::kActive);
  EXPECT_EQ(rig.non_finite(), 0);
}

}  // namespace
}  // namespace toonforce
