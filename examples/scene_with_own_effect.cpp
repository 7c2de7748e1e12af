// SPDX-License-Identifier: Apache-2.0
// Embedding toonforce, 3 of 3: an effect written here (a slick magnet) used from a scene file
// by its key, next to the library's own effects, with nothing in the library edited to admit it.
//
//   scene_with_own_effect SCENE.toml HAND.toml [--trace OUT.csv]
//
// The effect carries what the rest of the stack needs from it (toonforce/effects/effect.hpp):
//   - its scene-file table and keys, with units, ranges and defaults (`schema()`), and a check
//     across keys (`check()`): the library's scene-file reader reads `[[magnet]]` tables with
//     them and names file, line and key in its errors (try scenes/magnet_typo.toml);
//   - the part of it that injects energy by design, its slick part (`kActiveSlots`, reported
//     through `ActiveForce` every tick): the servo loop's passivity controller holds what each
//     capture injects to the scene's `passivity_budget`;
//   - what it shows (`kValues`, `describe()`): the loop's telemetry carries `magnet1.captured`
//     and `magnet1.distance`, the trace gets those columns, and `toonforce view OUT.csv` shows
//     them live beside the library's.
//
// The run: the scene file read with the library's kinds plus Magnet, the servo loop (every
// safety stage on) on the simulated Falcon held by the hand of HAND.toml, in simulated time;
// then the same run again with the passivity controller off, to show what the budget held back.
// Exit status 0 when the magnet caught the handle, its slick part stayed within the budget with the
// controller and went beyond it without; 1 when not; 2 when the files or arguments are wrong.
//
// Build against an installed toonforce (examples/README.md).
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_reader.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/host_sim/sim_device.hpp"
#include "toonforce/trace/telemetry_trace.hpp"

namespace {

using toonforce::ActiveForce;
using toonforce::Scalar;
using toonforce::TickInput;
using toonforce::Vec3;

/// A slick magnet. Within `radius` of `centre` a spring pulls the handle to the centre and the
/// handle is "captured"; from there to twice the radius the pull fades linearly to zero, so the
/// force is continuous everywhere. While captured, the handle is slick to move: a negative
/// damping of `slick` pushes it along its own motion (the paper's super-slippery surface, in a
/// ball), so a captured handle zips toward wherever the hand takes it. That part pushes energy
/// into the hand by design, so it is reported as an active part and the loop's passivity
/// controller holds each capture to the scene's budget.
///
/// A template on the scalar like the library's laws: the reader fills Magnet<double>::Params
/// from the file, and the run-time scene takes Magnet<S> for whatever scalar the loop runs in.
template <Scalar S>
struct Magnet {
  using Scalar = S;
  struct Params {
    Vec3<S> centre_m;
    S stiffness_n_per_m{};
    S radius_m{};
    S slick_n_s_per_m{};
  };
  struct State {
    bool captured = false;
  };

  static constexpr std::string_view kKey = "magnet";  // [[magnet]] in a scene file
  // The slick part uses the velocity; a magnet without one needs none (needs() below), so a
  // scene of such magnets runs no velocity estimator at all.
  static constexpr toonforce::Needs kNeeds = toonforce::Needs::kVelocity;
  static constexpr std::size_t kActiveSlots = 1;  // the slick part
  static constexpr std::array<toonforce::ValueInfo, 2> kValues{{
      {"captured", "", "1 while the handle is within the radius"},
      {"distance", "m", "from the centre"},
  }};

  /// The `[[magnet]]` table: every key with its unit, range and default (or required).
  static constexpr auto schema() {
    using namespace toonforce::schema;
    return fields(vector("centre", &Params::centre_m, "m"),
                  number("stiffness", &Params::stiffness_n_per_m, "N/m", Range::kPositive),
                  number("radius", &Params::radius_m, "m", Range::kPositive),
                  number("slick", &Params::slick_n_s_per_m, "N s/m", Range::kNonNegative, 0.0));
  }
  /// Across keys (in double, as the file gives them): a slick part stronger than the pull can
  /// hold would fling the handle out of the magnet it is supposed to decorate: at the rim the
  /// pull (stiffness x radius) must outweigh it at 0.5 m/s, a brisk hand.
  static void check(const Params& p, toonforce::schema::Problems& problems, toonforce::ScalarKind) {
    const double rim_pull_n = toonforce::to_double(p.stiffness_n_per_m) * toonforce::to_double(p.radius_m);
    if (toonforce::to_double(p.slick_n_s_per_m) * 0.5 >= rim_pull_n) {
      problems.add("slick", "x 0.5 m/s must be below the pull at the rim, stiffness x radius [N] =", rim_pull_n);
    }
  }
  static constexpr toonforce::Needs needs(const Params& p) noexcept {
    return p.slick_n_s_per_m > S{} ? toonforce::Needs::kVelocity : toonforce::Needs::kNone;
  }
  /// A magnet that is not slick injects nothing: it asks the passivity stage for no slot.
  static constexpr std::size_t active_slots(const Params& p) noexcept { return p.slick_n_s_per_m > S{} ? 1 : 0; }

  static Vec3<S> force(const Params& p, State& s, const TickInput<S>& in, ActiveForce<S>* active) noexcept {
    const Vec3<S> to_centre = p.centre_m - in.position_m;
    const S distance_m = norm(to_centre);
    const bool captured = distance_m <= p.radius_m;
    const bool new_capture = captured && !s.captured;
    s.captured = captured;

    Vec3<S> pull{};
    if (captured) {
      pull = to_centre * p.stiffness_n_per_m;
    } else if (distance_m < p.radius_m + p.radius_m) {
      pull = to_centre * (p.stiffness_n_per_m * (p.radius_m + p.radius_m - distance_m) / p.radius_m);
    }
    if (!(p.slick_n_s_per_m > S{})) return pull;  // no active slot was given to this one

    const Vec3<S> slick = captured ? in.velocity_m_per_s * p.slick_n_s_per_m : Vec3<S>{};
    active[0] = {slick, captured, new_capture};  // one episode per capture
    return pull + slick;
  }

  /// The values the loop's telemetry, the trace and the viewer show; true while captured.
  static bool describe(const Params& p, const State& s, const TickInput<S>& in, double* values) noexcept {
    values[0] = s.captured ? 1.0 : 0.0;
    values[1] = toonforce::to_double(norm(p.centre_m - in.position_m));
    return s.captured;
  }
};
static_assert(toonforce::FileEffect<Magnet<double>>);
static_assert(toonforce::FileEffect<Magnet<toonforce::Q16_16>>);

// The library's effect kinds and this program's: a scene file may use any of them.
using SceneFile = toonforce::SceneFileOf<toonforce::RuntimeSurface, toonforce::CartoonCliff, Magnet>;
using RunScene = toonforce::RuntimeSceneOf<double, toonforce::RuntimeSurface, toonforce::CartoonCliff, Magnet>;
using Loop = toonforce::ServoLoop<toonforce::host_sim::SimDevice, RunScene>;

constexpr double kPeriodS = 1e-3;  // 1 kHz, the Falcon's rate

/// What one run showed, from each tick's telemetry frame.
struct Outcome {
  std::int64_t captures = 0;    ///< ticks on which magnet1.captured went 0 -> 1
  double captured_s = 0.0;      ///< time spent captured [s]
  double peak_episode_j = 0.0;  ///< the largest active-part episode energy [J]
  double peak_force_n = 0.0;
  double peak_tick_injection_j = 0.0;  ///< the most the slick part did in one tick, slick |v|^2 T [J]
  std::int64_t damped_ticks = 0;       ///< ticks the passivity controller damped
  bool latched = false;
  std::string trace_error;  ///< a trace that could not be written
};

Outcome run(const SceneFile& file, const toonforce::HandScriptFile& hand, const toonforce::ServoConfig& config,
            toonforce::TraceWriter* trace) {
  const double slick_n_s_per_m = file.of<Magnet>().front().slick_n_s_per_m;
  namespace hs = toonforce::host_sim;
  Outcome out;
  hs::PlantOptions plant;
  plant.period_s = kPeriodS;
  auto device = hs::SimDevice::create(hs::falcon_params(), hand.intent, plant);
  if (!device) {
    out.trace_error = "simulated device: " + device.error();
    out.latched = true;
    return out;
  }
  // The loop holds the scene in fixed capacity: allocate it once, here, not on the stack.
  auto loop = std::make_unique<Loop>(std::move(device.value()), toonforce::make_runtime_scene<double>(file), config);
  const std::vector<std::string> names = toonforce::effect_value_names(loop->scene());
  std::size_t captured_column = names.size();
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == "magnet1.captured") captured_column = i;
  }

  const auto ticks = static_cast<std::int64_t>(std::llround((hand.intent.duration_s() + 0.2) / kPeriodS));
  toonforce::TelemetryFrame frame;
  bool was_captured = false;
  for (std::int64_t k = 0; k < ticks; ++k) {
    static_cast<void>(loop->tick(k));
    loop->fill_frame(frame);  // outside the tick: the loop itself stays allocation- and I/O-free
    const bool captured = captured_column < frame.value_count && frame.values[captured_column] > 0.5;
    if (captured && !was_captured) ++out.captures;
    if (captured) {
      out.captured_s += kPeriodS;
      const double injected_j = slick_n_s_per_m * dot(frame.velocity_m_per_s, frame.velocity_m_per_s) * kPeriodS;
      out.peak_tick_injection_j = std::max(out.peak_tick_injection_j, injected_j);
    }
    was_captured = captured;
    out.peak_episode_j = std::max(out.peak_episode_j, frame.episode_energy_j);
    out.peak_force_n = std::max(out.peak_force_n, std::sqrt(dot(frame.force_n, frame.force_n)));
    if (frame.damping_n.x != 0.0 || frame.damping_n.y != 0.0 || frame.damping_n.z != 0.0) ++out.damped_ticks;
    if (trace != nullptr && !toonforce::write_frame(*trace, frame, frame.value_count, false)) {
      out.trace_error = "cannot write " + trace->path();
      trace = nullptr;
    }
  }
  static_cast<void>(loop->shutdown(ticks));  // zero force, as at the end of any run
  out.latched = static_cast<bool>(loop->latched());
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  const char* files[2] = {nullptr, nullptr};
  int file_count = 0;
  std::string trace_path;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--trace") == 0 && i + 1 < argc) {
      trace_path = argv[++i];
    } else if (argv[i][0] != '-' && file_count < 2) {
      files[file_count++] = argv[i];
    } else {
      file_count = 3;
    }
  }
  if (file_count != 2) {
    std::fprintf(stderr, "usage: %s SCENE.toml HAND.toml [--trace OUT.csv]\n", argv[0]);
    return 2;
  }

  // Start-up: everything that can fail, fails here with a message naming file, line and key.
  auto scene = toonforce::read_scene_file<toonforce::RuntimeSurface, toonforce::CartoonCliff, Magnet>(files[0]);
  if (!scene) {
    std::fprintf(stderr, "%s", scene.error().c_str());
    return 2;
  }
  auto hand = toonforce::load_hand_script(files[1]);
  if (!hand) {
    std::fprintf(stderr, "%s\n", hand.error().c_str());
    return 2;
  }
  const SceneFile& file = scene.value();
  const toonforce::ServoConfig config = toonforce::servo_config(file, kPeriodS);
  if (const std::string problems = toonforce::check_servo_config(config); !problems.empty()) {
    std::fprintf(stderr, "%s: %s", files[0], problems.c_str());
    return 2;
  }
  if (file.of<Magnet>().empty()) {
    std::fprintf(stderr, "%s: no [[magnet]] table: nothing for this example to show\n", files[0]);
    return 2;
  }
  const Magnet<double>::Params& magnet = file.of<Magnet>().front();
  if (!(magnet.slick_n_s_per_m > 0.0) || !config.safety.passivity.controller) {
    std::fprintf(stderr,
                 "%s: this example shows the passivity budget on the magnet's slick part: give the first "
                 "magnet a slick and leave passivity_controller on\n",
                 files[0]);
    return 2;
  }

  std::unique_ptr<toonforce::TraceWriter> trace;
  if (!trace_path.empty()) {
    auto names = toonforce::effect_value_names(toonforce::make_runtime_scene<double>(file));
    auto opened = toonforce::TraceWriter::open(trace_path, toonforce::telemetry_columns(names, false));
    if (!opened) {
      std::fprintf(stderr, "%s\n", opened.error().c_str());
      return 2;
    }
    trace = std::move(opened.value());
  }

  std::printf("scene '%s': %zu surface(s), %zu cliff(s), %zu magnet(s); hand '%s'; passivity budget %.4g J\n",
              file.name.c_str(), file.of<toonforce::RuntimeSurface>().size(), file.of<toonforce::CartoonCliff>().size(),
              file.of<Magnet>().size(), hand.value().script.name.c_str(), config.safety.passivity.budget_j);
  const Outcome held = run(file, hand.value(), config, trace.get());
  toonforce::ServoConfig off = config;
  off.safety.passivity.controller = false;
  const Outcome unbudgeted = run(file, hand.value(), off, nullptr);
  if (!held.trace_error.empty() || !unbudgeted.trace_error.empty()) {
    std::fprintf(stderr, "%s%s\n", held.trace_error.c_str(), unbudgeted.trace_error.c_str());
    return 2;
  }
  if (trace && !trace->close()) {
    std::fprintf(stderr, "cannot write %s\n", trace_path.c_str());
    return 2;
  }

  const double budget_j = config.safety.passivity.budget_j;
  std::printf("captured %lld time(s), %.3f s in all; peak force %.2f N\n", static_cast<long long>(held.captures),
              held.captured_s, held.peak_force_n);
  std::printf("slick episode energy, peak: %.4f J with the passivity controller (%lld ticks damped), %.4f J without\n",
              held.peak_episode_j, static_cast<long long>(held.damped_ticks), unbudgeted.peak_episode_j);
  if (trace)
    std::printf("trace: %s (%zu rows; toonforce view %s)\n", trace_path.c_str(), trace->rows(), trace_path.c_str());

  // The controller acts on the excess it has measured: the work of a tick is booked on the
  // next one and damped on the one after, so an episode may pass its budget by what the slick
  // part injects in two ticks (Hannaford and Ryu's observer is one sample late by design).
  const double allowed_j = budget_j + 2.0 * held.peak_tick_injection_j;
  std::printf("allowed: the budget + two ticks of the slick part's largest power = %.4f J\n", allowed_j);
  bool ok = true;
  const auto expect = [&](bool condition, const char* what) {
    std::printf("  %-60s %s\n", what, condition ? "ok" : "NO");
    ok = ok && condition;
  };
  expect(held.captures > 0, "the magnet caught the handle");
  expect(held.peak_episode_j <= allowed_j, "its slick part stayed within the budget with the controller");
  expect(unbudgeted.peak_episode_j > allowed_j, "and went beyond it without (the budget did the holding)");
  expect(!held.latched && !unbudgeted.latched, "no safety fault latched");
  return ok ? 0 : 1;
}
