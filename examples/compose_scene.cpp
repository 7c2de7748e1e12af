// SPDX-License-Identifier: Apache-2.0
// Embedding toonforce, 1 of 3: a scene composed at compile time from a library effect (a
// penalty-wall floor) and an effect written here (a magnetic detent), run by the servo loop on
// the simulated Falcon with a simulated hand holding it, in simulated time.
//
// The hand moves the handle near the detent and holds it there, then presses it into the
// floor away from the detent. In each hold the handle settles where the springs balance, which
// this program computes by hand and compares with the simulation:
//   near the detent (hand spring k_h toward r, detent k_d toward c):  x = (k_h r + k_d c) / (k_h + k_d)
//   on the floor (hand toward r below it, wall k_w):                  z = k_h r_z / (k_h + k_w)
// up to the band the device's Coulomb friction f_c leaves: |error| <= f_c / (sum of stiffnesses),
// plus one encoder step. Exit status 0 when both agree, 1 otherwise.
//
// Build against an installed toonforce (examples/README.md):
//   cmake -S examples -B build-examples -DCMAKE_PREFIX_PATH=/usr/local && cmake --build build-examples
#include <array>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>

#include "toonforce/control/servo_loop.hpp"
#include "toonforce/effects/penalty_wall.hpp"
#include "toonforce/effects/scene.hpp"
#include "toonforce/effects/surface.hpp"
#include "toonforce/host_sim/sim_device.hpp"

namespace {

using toonforce::Vec3;

/// A magnetic detent: inside `radius_m` of `centre_m` a spring pulls the handle to the centre;
/// from there to twice the radius the pull fades linearly to zero, so the force is continuous
/// everywhere (a force that jumps when the handle crosses a boundary does work on the hand).
///
/// An effect is a type with Scalar, Params, State, kNeeds, kKey and a static noexcept force()
/// (the Effect concept, toonforce/effects/effect.hpp), and what it shows in traces and the
/// viewer (kValues, describe()). force() runs on every servo tick, so like the library's laws
/// it allocates nothing, throws nothing and calls nothing. (scene_with_own_effect.cpp goes on:
/// its own effect in a scene file.)
struct Detent {
  using Scalar = double;
  struct Params {
    Vec3<double> centre_m;
    double stiffness_n_per_m = 0.0;
    double radius_m = 0.0;
  };
  struct State {};  // a detent remembers nothing between ticks
  static constexpr std::string_view kKey = "detent";
  static constexpr toonforce::Needs kNeeds = toonforce::Needs::kNone;  // position only: no velocity estimate
  static constexpr std::array<toonforce::ValueInfo, 1> kValues{{{"distance", "m", "from the centre"}}};

  static Vec3<double> force(const Params& p, State&, const toonforce::TickInput<double>& in) noexcept {
    const Vec3<double> to_centre = p.centre_m - in.position_m;
    const double distance_m = std::sqrt(dot(to_centre, to_centre));
    if (distance_m <= p.radius_m) return to_centre * p.stiffness_n_per_m;
    if (distance_m >= 2.0 * p.radius_m) return {};
    return to_centre * (p.stiffness_n_per_m * (2.0 * p.radius_m - distance_m) / p.radius_m);
  }
  static bool describe(const Params& p, const State&, const toonforce::TickInput<double>& in, double* values) noexcept {
    const Vec3<double> to_centre = p.centre_m - in.position_m;
    values[0] = std::sqrt(dot(to_centre, to_centre));
    return values[0] <= p.radius_m;
  }
};
static_assert(toonforce::Effect<Detent>);

using Floor = toonforce::Surface<toonforce::PenaltyWall<double>>;
using DetentScene = toonforce::Scene<Floor, Detent>;

constexpr double kPeriodS = 1e-3;  // 1 kHz, the Falcon's rate
constexpr double kWallStiffness = 1500.0;
constexpr double kDetentStiffness = 300.0;
constexpr double kDetentRadius = 0.005;
const Vec3<double> kDetentCentre{0.0, 0.0, 0.010};  // 10 mm above the floor
const Vec3<double> kNearDetent{0.004, 0.0, 0.012};  // where the hand aims while near it
const Vec3<double> kIntoFloor{0.030, 0.0, -0.010};  // 30 mm aside, 10 mm into the floor

/// The hand: starts at rest on the detent's centre (no force there, so the loop engages at
/// once), moves near it and holds, then moves away, pressing into the floor, and holds.
std::optional<toonforce::host_sim::HandIntent> plan_hand() {
  using toonforce::host_sim::HandSegment;
  using toonforce::host_sim::SegmentKind;
  toonforce::host_sim::HandScript script;
  script.name = "detent, then floor";
  script.start_m = kDetentCentre;
  HandSegment near;
  near.kind = SegmentKind::kMove;
  near.to_m = kNearDetent;
  near.duration_s = 0.5;
  HandSegment hold;
  hold.kind = SegmentKind::kHold;
  hold.duration_s = 2.5;  // the loop's 1 s soft start is over long before the end
  HandSegment away = near;
  away.to_m = kIntoFloor;
  away.duration_s = 1.0;
  script.segments = {near, hold, away, hold};
  toonforce::host_sim::PlanError error;
  auto intent = toonforce::host_sim::HandIntent::plan(script, error);
  if (!intent)
    std::fprintf(stderr, "hand script: segment %zu: %s: %s\n", error.segment, error.key.c_str(), error.problem.c_str());
  return intent;
}

/// Runs the loop from tick `from` to `to` and returns the mean handle position the device
/// reported over the last `average_ticks`.
template <class Loop>
Vec3<double> run_and_average(Loop& loop, std::int64_t from, std::int64_t to, std::int64_t average_ticks) {
  Vec3<double> sum{};
  for (std::int64_t k = from; k < to; ++k) {
    static_cast<void>(loop.tick(k));
    if (k >= to - average_ticks) sum += loop.device().plant().position_m();
  }
  return sum * (1.0 / static_cast<double>(average_ticks));
}

bool report(const char* what, double got_m, double expected_m, double tolerance_m) {
  const bool ok = std::fabs(got_m - expected_m) <= tolerance_m;
  std::printf("  %-22s %8.3f mm  expected %8.3f mm  (+- %.3f)  %s\n", what, got_m * 1e3, expected_m * 1e3,
              tolerance_m * 1e3, ok ? "ok" : "DIFFERENT");
  return ok;
}

}  // namespace

int main() {
  namespace hs = toonforce::host_sim;
  const auto hand = plan_hand();
  if (!hand) return 1;
  const hs::DeviceParams falcon = hs::falcon_params();
  hs::PlantOptions plant;
  plant.period_s = kPeriodS;
  auto device = hs::SimDevice::create(falcon, *hand, plant);
  if (!device) {
    std::fprintf(stderr, "simulated device: %s\n", device.error().c_str());
    return 1;
  }

  Floor::Params floor{};
  floor.plane = {{0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}};
  floor.wall.stiffness_n_per_m = kWallStiffness;
  const DetentScene scene(floor, Detent::Params{kDetentCentre, kDetentStiffness, kDetentRadius});

  // The servo loop's settings: the safety layer's documented defaults, the device's force
  // limit, and a force-rate limit as the bundled Falcon scenes use.
  toonforce::ServoConfig config;
  config.period_s = kPeriodS;
  config.limits.has_max_force = true;
  config.limits.max_force_n = falcon.max_force_n;
  config.limits.has_max_force_rate = true;
  config.limits.max_force_rate_n_per_s = 2000.0;
  if (const std::string problems = toonforce::check_servo_config(config); !problems.empty()) {
    std::fprintf(stderr, "servo configuration: %s", problems.c_str());
    return 1;
  }
  toonforce::ServoLoop<hs::SimDevice, DetentScene> loop(std::move(device.value()), scene, config);

  const auto ticks = [](double s) { return static_cast<std::int64_t>(std::llround(s / kPeriodS)); };
  const std::int64_t average = ticks(0.5);  // the last half second of each hold
  const Vec3<double> at_detent = run_and_average(loop, 0, ticks(3.0), average);
  const Vec3<double> on_floor = run_and_average(loop, ticks(3.0), ticks(6.5), average);

  const double k_hand = hand->impedance().stiffness_n_per_m;
  const double coulomb_n = falcon.coulomb_n;
  const double step_m = falcon.encoder_step_m;
  const Vec3<double> expect_detent =
      (kNearDetent * k_hand + kDetentCentre * kDetentStiffness) * (1.0 / (k_hand + kDetentStiffness));
  const double expect_floor_z = k_hand * kIntoFloor.z / (k_hand + kWallStiffness);
  const double detent_band = coulomb_n / (k_hand + kDetentStiffness) + step_m;
  const double floor_band = coulomb_n / (k_hand + kWallStiffness) + step_m;

  std::printf("scene: floor (k = %.0f N/m) + detent (k = %.0f N/m at z = %.0f mm); hand k = %.0f N/m; "
              "%s at %.0f Hz\n",
              kWallStiffness, kDetentStiffness, kDetentCentre.z * 1e3, k_hand, std::string(falcon.name).c_str(),
              1.0 / kPeriodS);
  std::printf("held near the detent (the hand aims at x = %.0f mm, z = %.0f mm):\n", kNearDetent.x * 1e3,
              kNearDetent.z * 1e3);
  bool ok = report("x", at_detent.x, expect_detent.x, detent_band);
  ok = report("z", at_detent.z, expect_detent.z, detent_band) && ok;
  std::printf("pressed into the floor (the hand aims at z = %.0f mm):\n", kIntoFloor.z * 1e3);
  ok = report("z", on_floor.z, expect_floor_z, floor_band) && ok;
  std::printf("  floor force %.2f N; loop state %s, faults %s\n", -kWallStiffness * on_floor.z,
              toonforce::to_string(loop.state()), loop.latched() ? "latched" : "none");
  ok = ok && !loop.latched();
  static_cast<void>(loop.shutdown(loop.last_tick() + 1));  // zero force, as at the end of any run
  return ok ? 0 : 1;
}
