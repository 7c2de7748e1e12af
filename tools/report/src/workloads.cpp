// SPDX-License-Identifier: Apache-2.0
// The measured ticks. This file is compiled with -O3 in every build type (CMakeLists.txt), and
// every function that runs a tick is flattened, so what is timed and counted is the same
// machine code whatever the build.
#include "toonforce/report/workloads.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <utility>

#include <fmt/format.h>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/report/scenario.hpp"
#include "toonforce/report/stage_configs.hpp"
#include "toonforce/report/tsc_clock.hpp"

namespace toonforce::report {

std::string_view level_name(Level level) noexcept {
  switch (level) {
    case Level::kHarness: return "harness";
    case Level::kEffect: return "effect";
    case Level::kSafety: return "safety";
    case Level::kScene: return "scene";
    case Level::kSpecLoop: return "spec-loop";
    case Level::kLoop: return "loop";
  }
  return "?";
}

std::uint64_t CycleHistogram::percentile(double p) const noexcept {
  if (count_ == 0) return 0;
  const auto rank = static_cast<std::uint64_t>(std::ceil(p * static_cast<double>(count_)));
  const std::uint64_t wanted = std::max<std::uint64_t>(rank, 1);
  std::uint64_t seen = 0;
  for (std::size_t i = 0; i < counts_.size(); ++i) {
    seen += counts_[i];
    if (seen >= wanted) return i;
  }
  return max_;  // in the overflow: only the maximum is known exactly
}

double CycleHistogram::mean_in_bins() const noexcept {
  double sum = 0.0;
  std::uint64_t n = 0;
  for (std::size_t i = 0; i < counts_.size(); ++i) {
    sum += static_cast<double>(i) * static_cast<double>(counts_[i]);
    n += counts_[i];
  }
  return n == 0 ? 0.0 : sum / static_cast<double>(n);
}

bool selected(const std::string& id, const std::string& filter) {
  if (filter.empty()) return true;
  std::size_t start = 0;
  while (start <= filter.size()) {
    const std::size_t comma = std::min(filter.find(',', start), filter.size());
    const std::string part = filter.substr(start, comma - start);
    if (!part.empty() && id.find(part) != std::string::npos) return true;
    start = comma + 1;
  }
  return false;
}

/// The one function callgrind counts (--toggle-collect=*measured_tick*): a tick and nothing else.
template <class Work>
[[gnu::noinline, gnu::flatten]] void measured_tick(Work& work) noexcept {
  const auto out = work.tick();
  keep(out);
}

namespace {

template <Scalar S>
constexpr ScalarKind kind_of() noexcept {
  if constexpr (kIsFixed<S>) {
    return ScalarKind::kQ16_16;
  } else if constexpr (std::same_as<S, float>) {
    return ScalarKind::kFloat;
  } else {
    return ScalarKind::kDouble;
  }
}

template <class Work>
class CaseOf final : public TickCase {
 public:
  CaseOf(CaseInfo info, Work work) : TickCase(std::move(info)), initial_(work), work_(std::move(work)) {}

  [[gnu::flatten]] void time(std::uint64_t ticks, CycleHistogram& histogram) noexcept override {
    for (std::uint64_t i = 0; i < ticks; ++i) {
      work_.prepare(next_++);
      const std::uint64_t start = tsc_begin();
      const auto out = work_.tick();
      keep(out);  // the result is complete before the second read
      const std::uint64_t end = tsc_end();
      histogram.add(end - start);
    }
  }
  void run_counted(std::uint64_t ticks, AfterTick after, void* context) noexcept override {
    for (std::uint64_t i = 0; i < ticks; ++i) {
      work_.prepare(next_++);
      measured_tick(work_);
      if (after != nullptr) after(i, context);
    }
  }
  [[gnu::flatten]] void run(std::uint64_t ticks) noexcept override {
    for (std::uint64_t i = 0; i < ticks; ++i) {
      work_.prepare(next_++);
      const auto out = work_.tick();
      keep(out);
    }
  }
  void restart() noexcept override {
    work_ = initial_;
    next_ = 0;
  }

 private:
  Work initial_;
  Work work_;
  std::uint64_t next_ = 0;
};

template <class Work>
std::unique_ptr<TickCase> make_case(CaseInfo info, Work work) {
  return std::make_unique<CaseOf<Work>>(std::move(info), std::move(work));
}

// ---- workloads ------------------------------------------------------------------------------

/// Nothing: what measured_tick() and the two counter reads cost on their own.
struct EmptyWork {
  int value = 0;
  void prepare(std::uint64_t) noexcept {}
  int tick() noexcept { return value; }
};

/// One law on branch inputs; its state is restored before every tick so each tick takes the
/// branch the case names.
template <class E>
struct EffectWork {
  using S = typename E::Scalar;
  typename E::Params params;
  typename E::State initial_state;
  std::vector<TickInput<S>> inputs;
  typename E::State state{};
  const TickInput<S>* in = nullptr;

  void prepare(std::uint64_t i) noexcept {
    state = initial_state;
    in = &inputs[i % inputs.size()];
  }
  Vec3<S> tick() noexcept { return effect::force<E>(params, state, *in, active.data()); }
  std::array<ActiveForce<S>, (effect::kActiveSlots<E> > 0 ? effect::kActiveSlots<E> : 1)> active{};
};

/// The safety stage alone: from a previous output to a new scene force.
template <Scalar S>
struct SafetyWork {
  struct Input {
    ForceSafety<S> primed;  ///< with the previous output already in it
    Vec3<S> force_n;
  };
  std::vector<Input> inputs;
  S rate_hz{};
  ForceSafety<S> safety{};
  const Input* in = nullptr;

  void prepare(std::uint64_t i) noexcept {
    in = &inputs[i % inputs.size()];
    safety = in->primed;
  }
  typename ForceSafety<S>::Output tick() noexcept { return safety.limit(in->force_n, rate_hz); }
};

/// A paper scene's tick: its effects, then the safety stage, on the scenario's inputs (the
/// states carry over from tick to tick, as in a run).
template <class SceneT>
struct SceneWork {
  using S = typename SceneT::Scalar;
  SceneT scene;
  ForceSafety<S> safety;
  std::vector<TickInput<S>> inputs;
  typename SceneT::State state{};
  TickInput<S> current{};

  void prepare(std::uint64_t i) noexcept {
    current = inputs[i % inputs.size()];
    current.now.tick = static_cast<std::int64_t>(i);  // time runs on across passes
  }
  typename ForceSafety<S>::Output tick() noexcept {
    return safety.limit(scene.force(current, state, active.data()), current.rate_hz);
  }
  std::array<ActiveForce<S>, (SceneT::kActiveCapacity > 0 ? SceneT::kActiveCapacity : 1)> active{};
};

/// The whole servo loop tick (read, supervisor, velocity, scene, the safety chain, write) on a
/// scripted device that plays the scenario's positions: with every stage (kLoop), or with
/// effects.md §6's only, as replay runs it (kSpecLoop).
template <class SceneT, LoopStages kStages>
struct LoopWork {
  struct Script {
    const std::vector<Vec3<double>>* samples = nullptr;
    std::size_t next = 0;
  };
  struct ScriptedDevice {
    Script* script;
    DeviceStatus read(DeviceReading& r) noexcept {
      r.position_m = (*script->samples)[script->next];
      r.has_velocity = false;
      return DeviceStatus::kOk;
    }
    DeviceStatus write(const Vec3<double>&) noexcept { return DeviceStatus::kOk; }
  };
  using Loop = ServoLoop<ScriptedDevice, SceneT, NullPins, kStages>;

  LoopWork(SceneT scene, ServoConfig config, std::vector<Vec3<double>> samples)
      : scene_(std::move(scene)),
        config_(config),
        samples_(std::make_shared<std::vector<Vec3<double>>>(std::move(samples))) {
    rebuild();
  }
  LoopWork(const LoopWork& o) : scene_(o.scene_), config_(o.config_), samples_(o.samples_) { rebuild(); }
  LoopWork& operator=(const LoopWork& o) {
    scene_ = o.scene_;
    config_ = o.config_;
    samples_ = o.samples_;
    rebuild();
    return *this;
  }
  std::size_t size() const noexcept { return samples_->size(); }

  void prepare(std::uint64_t i) noexcept {
    script_->next = static_cast<std::size_t>(i % samples_->size());
    k_ = static_cast<std::int64_t>(i);
  }
  TickStatus tick() noexcept { return loop_->tick(k_); }

 private:
  void rebuild() {
    script_ = std::make_unique<Script>();
    script_->samples = samples_.get();
    loop_ = std::make_unique<Loop>(ScriptedDevice{script_.get()}, scene_, config_);
  }
  SceneT scene_;
  ServoConfig config_;
  std::shared_ptr<std::vector<Vec3<double>>> samples_;
  std::unique_ptr<Script> script_;
  std::unique_ptr<Loop> loop_;
  std::int64_t k_ = 0;
};

/// Every stage of the servo loop's safety layer on, as on a Falcon-class device: engage, soft
/// start, velocity limit, workspace, thermal model (continuous force below the clamp),
/// passivity observer and controller, rate limit, clamp.
/// Replay's configuration at a fixed rate: the [device] clamp and rate limit only.
ServoConfig spec_config(const SceneDescription& desc, double rate_hz) { return servo_config(desc, 1.0 / rate_hz); }

// ---- inputs ---------------------------------------------------------------------------------

constexpr double kRateHz = 1000.0;
constexpr std::size_t kBranchInputs = 256;

/// A small deterministic generator: the same inputs on every run and machine.
class Lcg {
 public:
  explicit Lcg(std::uint64_t seed) : state_(seed) {}
  double uniform(double lo, double hi) noexcept {
    state_ = state_ * 6364136223846793005ULL + 1442695040888963407ULL;
    const double u = static_cast<double>(state_ >> 11) / 9007199254740992.0;  // [0, 1)
    return lo + (hi - lo) * u;
  }
  /// A horizontal vector of magnitude in [lo, hi].
  Vec3<double> horizontal(double lo, double hi) noexcept {
    const double angle = uniform(0.0, 6.283185307179586);
    const double m = uniform(lo, hi);
    return {m * std::cos(angle), m * std::sin(angle), 0.0};
  }

 private:
  std::uint64_t state_;
};

template <Scalar S>
TickInput<S> tick_input(const Vec3<double>& x, const Vec3<double>& v, std::int64_t tick) {
  TickInput<S> in{};
  in.position_m = vec_cast<S>(x);
  in.velocity_m_per_s = vec_cast<S>(v);
  in.rate_hz = scalar_cast<S>(kRateHz);
  in.now = Instant{tick, 0};
  in.period_s = 1.0 / kRateHz;
  return in;
}

/// `count` inputs from `make(lcg, i)` -> {x, v, tick}.
template <Scalar S, class Make>
std::vector<TickInput<S>> branch_inputs(std::uint64_t seed, Make make) {
  Lcg lcg(seed);
  std::vector<TickInput<S>> inputs;
  for (std::size_t i = 0; i < kBranchInputs; ++i) inputs.push_back(make(lcg, i));
  return inputs;
}

/// The scenario of a paper scene at 1 kHz, one period, as scene inputs (velocity exact).
template <Scalar S>
std::vector<TickInput<S>> scenario_inputs(std::string_view scene) {
  const KeyframePath path = paper_scenario(scene);
  const auto ticks = static_cast<std::int64_t>(std::llround(path.period_s() * kRateHz));
  std::vector<TickInput<S>> inputs;
  for (std::int64_t k = 0; k < ticks; ++k) {
    const PathPoint p = path.at(static_cast<double>(k) / kRateHz);
    inputs.push_back(tick_input<S>(p.position_m, p.velocity_m_per_s, k));
  }
  return inputs;
}

/// The same scenario as device readings (positions only: the loop estimates velocity).
std::vector<Vec3<double>> scenario_samples(std::string_view scene, double rate_hz = kRateHz) {
  const KeyframePath path = paper_scenario(scene);
  const auto ticks = static_cast<std::int64_t>(std::llround(path.period_s() * rate_hz));
  std::vector<Vec3<double>> samples;
  for (std::int64_t k = 0; k < ticks; ++k) samples.push_back(path.at(static_cast<double>(k) / rate_hz).position_m);
  return samples;
}

/// Inputs constructed to drive the expensive branches of every stage at once,
/// then searched. A search pass is kSearchStrikes strikes of kSearchStrikeTicks ticks at 1 kHz.
/// Each strike starts a fresh loop at the scenario's first point (out of contact: the loop
/// engages there). The first is constructed (below); each other follows a smooth path (cubic
/// Hermite) through random waypoints near the scenario's own points, up to 12 mm off them on
/// each axis (deeper into walls and gaps than the scenario goes: forces of several times the
/// clamp), at random speeds up to 1.25 m/s (past the 1.2 m/s velocity limit now and then). With
/// search_config() (a short soft start, a quick thermal model, a tiny passivity budget) the
/// soft-start ramp, the thermal derating, the passivity controller's damping, the rate limit,
/// the clamp and the effects' own branches are all reachable within one strike, and they
/// coincide on some ticks (the report counts them). Seeded: the same inputs on every machine.
struct SearchPath {
  std::vector<Vec3<double>> position_m;
  std::vector<Vec3<double>> velocity_m_per_s;
};

SearchPath search_path(std::string_view scene) {
  const KeyframePath scenario = paper_scenario(scene);
  Lcg r(0x5EA4C4U + scene.size());
  SearchPath path;
  const auto inside = [](Vec3<double> p) {
    for (double* c : {&p.x, &p.y, &p.z}) *c = std::clamp(*c, -0.055, 0.055);  // the workspace is +-60 mm
    return p;
  };
  constexpr double kStrikeS = static_cast<double>(kSearchStrikeTicks) / kRateHz;
  // Strike 0 is constructed, not random: the largest vectors of normal use, for the Q16.16
  // square root's rounds (one per two bits of its argument). 20 ticks at rest where the
  // scenario starts (the loop engages), then 1 m/s straight down to the workspace's floor
  // (z = -55 mm: the deepest contact there is, several times the clamp's force), then 1 m/s
  // along x to the workspace's edge and back, held deep; under the 1.2 m/s velocity limit.
  {
    const Vec3<double> start = scenario.at(0.0).position_m;
    Vec3<double> p = start;
    Vec3<double> v{};
    double sweep = 1.0;
    for (std::size_t k = 0; k < kSearchStrikeTicks; ++k) {
      if (k >= 20) {
        if (p.z > -0.055 + 1e-12) {
          v = {0.0, 0.0, -1.0};
        } else {
          if (p.x > 0.055 - 1e-12) sweep = -1.0;
          if (p.x < -0.055 + 1e-12) sweep = 1.0;
          v = {sweep, 0.0, 0.0};
        }
        p = inside(p + v * (1.0 / kRateHz));
      }
      path.position_m.push_back(p);
      path.velocity_m_per_s.push_back(v);
    }
  }
  for (std::size_t strike = 1; strike < kSearchStrikes; ++strike) {
    std::vector<Keyframe> keys;
    keys.push_back({0.0, scenario.at(0.0).position_m, {}});
    double t = 0.0;
    while (t < kStrikeS) {
      t += r.uniform(0.01, 0.06);
      const Vec3<double> near = scenario.at(r.uniform(0.0, scenario.period_s() * 0.999)).position_m;
      const Vec3<double> off{r.uniform(-0.012, 0.012), r.uniform(-0.012, 0.012), r.uniform(-0.012, 0.006)};
      const double speed = r.uniform(0.0, 1.25);
      const Vec3<double> dir{r.uniform(-1.0, 1.0), r.uniform(-1.0, 1.0), r.uniform(-1.0, 1.0)};
      const double n = std::sqrt(dir.x * dir.x + dir.y * dir.y + dir.z * dir.z);
      keys.push_back({t, inside(near + off), n > 1e-9 ? dir * (speed / n) : Vec3<double>{}});
    }
    const KeyframePath strike_path(std::move(keys));
    for (std::size_t k = 0; k < kSearchStrikeTicks; ++k) {
      const PathPoint p = strike_path.at(static_cast<double>(k) / kRateHz);
      path.position_m.push_back(inside(p.position_m));
      path.velocity_m_per_s.push_back(p.velocity_m_per_s);
    }
  }
  return path;
}

/// The whole loop on a search path: a fresh loop (engaging, cold thermal model, no episode)
/// at the start of every strike, built outside the counted tick.
template <class SceneT>
struct SearchLoopWork {
  using Device = typename LoopWork<SceneT, kEveryStage>::ScriptedDevice;
  using Script = typename LoopWork<SceneT, kEveryStage>::Script;
  using Loop = ServoLoop<Device, SceneT, NullPins, kEveryStage>;

  SearchLoopWork(SceneT scene, ServoConfig config, std::vector<Vec3<double>> samples)
      : scene_(std::move(scene)),
        config_(config),
        samples_(std::make_shared<std::vector<Vec3<double>>>(std::move(samples))) {
    rebuild();
  }
  SearchLoopWork(const SearchLoopWork& o) : scene_(o.scene_), config_(o.config_), samples_(o.samples_) { rebuild(); }
  SearchLoopWork& operator=(const SearchLoopWork& o) {
    scene_ = o.scene_;
    config_ = o.config_;
    samples_ = o.samples_;
    rebuild();
    return *this;
  }
  std::size_t size() const noexcept { return samples_->size(); }

  void prepare(std::uint64_t i) noexcept {
    const auto at = static_cast<std::size_t>(i % samples_->size());
    if (at % kSearchStrikeTicks == 0) loop_->emplace(Device{script_.get()}, scene_, config_);
    script_->next = at;
    k_ = static_cast<std::int64_t>(i);
  }
  TickStatus tick() noexcept { return (**loop_).tick(k_); }

 private:
  void rebuild() {
    script_ = std::make_unique<Script>();
    script_->samples = samples_.get();
    loop_ = std::make_unique<std::optional<Loop>>();
    loop_->emplace(Device{script_.get()}, scene_, config_);
  }
  SceneT scene_;
  ServoConfig config_;
  std::shared_ptr<std::vector<Vec3<double>>> samples_;
  std::unique_ptr<Script> script_;
  std::unique_ptr<std::optional<Loop>> loop_;
  std::int64_t k_ = 0;
};

template <Scalar S>
std::vector<TickInput<S>> search_inputs(const SearchPath& path) {
  std::vector<TickInput<S>> inputs;
  for (std::size_t k = 0; k < path.position_m.size(); ++k) {
    inputs.push_back(tick_input<S>(path.position_m[k], path.velocity_m_per_s[k], static_cast<std::int64_t>(k)));
  }
  return inputs;
}

struct Loaded {
  SceneDescription wall, friction, slippery, cartoon, cliff;
};

template <Scalar S>
class CaseBuilder {
 public:
  CaseBuilder(const Loaded& loaded, std::vector<std::unique_ptr<TickCase>>& out) : loaded_(loaded), out_(out) {}

  void effects() {
    penalty_wall();
    friction();
    slippery();
    impact();
    cliff();
    safety();
  }

  // (Each scene's name and description as variables of their own, not structured bindings: the
  // lambdas below capture them, which clang 14 does not allow for bindings.)
  void scenes() {
    for (const auto& scene : paper_scenes()) {
      const char* const name = scene.first;
      const SceneDescription* const desc = scene.second;
      const RuntimeScene<S> runtime = make_runtime_scene<S>(*desc);
      auto inputs = scenario_inputs<S>(name);
      const std::size_t ticks = inputs.size();
      with_compiled(name, runtime, [&](const auto& compiled) {
        using Compiled = std::remove_cvref_t<decltype(compiled)>;
        add(Level::kScene, name, "scenario", "compile-time", ticks,
            SceneWork<Compiled>{compiled, ForceSafety<S>(desc->limits), inputs, {}, {}});
      });
      add(Level::kScene, name, "scenario", "runtime", ticks,
          SceneWork<RuntimeScene<S>>{runtime, ForceSafety<S>(desc->limits), std::move(inputs), {}, {}});
    }
  }

  /// The servo loop as replay runs it (effects.md §6 stages only), on the scene file's scene.
  void spec_loops() {
    for (const auto& [name, desc] : paper_scenes()) {
      LoopWork<RuntimeScene<S>, kSpecStages> work(make_runtime_scene<S>(*desc), spec_config(*desc, kRateHz),
                                                  scenario_samples(name));
      const auto ticks = work.size();
      add(Level::kSpecLoop, name, "scenario", "runtime", ticks, std::move(work));
    }
  }

  /// The whole servo loop, every stage on, for the scene composed at compile time and from its file.
  void loops() {
    for (const auto& scene : paper_scenes()) {
      const char* const name = scene.first;
      const SceneDescription* const desc = scene.second;
      const RuntimeScene<S> runtime = make_runtime_scene<S>(*desc);
      const ServoConfig config = every_stage_config(*desc, kRateHz);
      with_compiled(name, runtime, [&](const auto& compiled) {
        using Compiled = std::remove_cvref_t<decltype(compiled)>;
        LoopWork<Compiled, kEveryStage> work(compiled, config, scenario_samples(name));
        const auto ticks = work.size();
        add(Level::kLoop, name, "scenario", "compile-time", ticks, std::move(work));
      });
      LoopWork<RuntimeScene<S>, kEveryStage> work(runtime, config, scenario_samples(name));
      const auto ticks = work.size();
      add(Level::kLoop, name, "scenario", "runtime", ticks, std::move(work));
    }
  }

  /// Effects plus safety, and the whole loop, on the search path (form
  /// "search"; the scene file's run-time scene, the dearer form).
  void scene_searches() {
    for (const auto& [name, desc] : paper_scenes()) {
      auto inputs = search_inputs<S>(search_path(name));
      const std::size_t ticks = inputs.size();
      add(Level::kScene, name, "search", "search", ticks,
          SceneWork<RuntimeScene<S>>{
              make_runtime_scene<S>(*desc), ForceSafety<S>(desc->limits), std::move(inputs), {}, {}});
    }
  }
  void loop_searches() {
    for (const auto& [name, desc] : paper_scenes()) {
      SearchLoopWork<RuntimeScene<S>> work(make_runtime_scene<S>(*desc), search_config(*desc, kRateHz),
                                           search_path(name).position_m);
      const auto ticks = work.size();
      add(Level::kLoop, name, "search", "search", ticks, std::move(work));
    }
  }

 private:
  template <class Work>
  void add(Level level, std::string subject, std::string branch, std::string form, std::size_t ticks, Work work) {
    CaseInfo info;
    info.level = level;
    info.scalar = kind_of<S>();
    info.subject = std::move(subject);
    info.branch = std::move(branch);
    info.form = std::move(form);
    info.ticks_per_pass = ticks;
    info.id = fmt::format("{}/{}/{}/{}", level_name(level), info.subject, scalar_kind_name(info.scalar),
                          info.form.empty() ? info.branch : info.form);
    out_.push_back(make_case(std::move(info), std::move(work)));
  }

  template <class E>
  void effect(std::string subject, std::string branch, typename E::Params params, typename E::State state,
              std::vector<TickInput<S>> inputs) {
    const std::size_t n = inputs.size();
    add(Level::kEffect, std::move(subject), std::move(branch), "", n,
        EffectWork<E>{params, state, std::move(inputs), {}, nullptr});
  }

  static Vec3<double> above(Lcg& r) {
    return {r.uniform(-0.03, 0.03), r.uniform(-0.03, 0.03), r.uniform(0.0005, 0.005)};
  }
  static Vec3<double> inside(Lcg& r) {
    return {r.uniform(-0.03, 0.03), r.uniform(-0.03, 0.03), r.uniform(-0.005, -0.0005)};
  }
  static Vec3<double> any_velocity(Lcg& r) {
    return {r.uniform(-0.2, 0.2), r.uniform(-0.2, 0.2), r.uniform(-0.2, 0.2)};
  }

  void penalty_wall() {
    const auto s =
        make_runtime_scene<S>(loaded_.wall).template params<RuntimeSurface<S>>(0);  // a copy: the scene is a temporary
    using Spring = Surface<SpringWall<S>>;
    const typename Spring::Params spring{s.plane, {s.wall.stiffness_n_per_m, S{}}, {}, {}};
    effect<Spring>("penalty wall", "out of contact", spring, {}, branch_inputs<S>(1, [](Lcg& r, std::size_t) {
                     return tick_input<S>(above(r), any_velocity(r), 0);
                   }));
    effect<Spring>("penalty wall", "in contact", spring, {}, branch_inputs<S>(2, [](Lcg& r, std::size_t) {
                     return tick_input<S>(inside(r), any_velocity(r), 0);
                   }));
    using Damped = Surface<PenaltyWall<S>>;
    const typename Damped::Params damped{s.plane, {s.wall.stiffness_n_per_m, scalar_cast<S>(2.0)}, {}, {}};
    effect<Damped>(
        "penalty wall, damping 2 N s/m", "in contact", damped, {},
        branch_inputs<S>(3, [](Lcg& r, std::size_t) { return tick_input<S>(inside(r), any_velocity(r), 0); }));
  }

  void friction() {
    const auto s = make_runtime_scene<S>(loaded_.friction)
                       .template params<RuntimeSurface<S>>(0);  // a copy: the scene is a temporary
    using F = Surface<SpringWall<S>, RealisticFriction<S>>;
    const typename F::Params p{s.plane, {s.wall.stiffness_n_per_m, S{}}, s.tangential.friction, {}};
    const std::string name = "realistic friction";
    effect<F>(name, "out of contact", p, {}, branch_inputs<S>(4, [](Lcg& r, std::size_t) {
                return tick_input<S>(above(r), r.horizontal(0.0, 0.3), 0);
              }));
    effect<F>(
        name, "in contact, |v_t| < v_reg", p, {}, branch_inputs<S>(5, [](Lcg& r, std::size_t) {
          return tick_input<S>(inside(r), r.horizontal(0.001, 0.018) + Vec3<double>{0, 0, r.uniform(-0.05, 0.05)}, 0);
        }));
    effect<F>(
        name, "in contact, |v_t| > v_reg", p, {}, branch_inputs<S>(6, [](Lcg& r, std::size_t) {
          return tick_input<S>(inside(r), r.horizontal(0.03, 0.3) + Vec3<double>{0, 0, r.uniform(-0.05, 0.05)}, 0);
        }));
  }

  void slippery() {
    const auto s = make_runtime_scene<S>(loaded_.slippery)
                       .template params<RuntimeSurface<S>>(0);  // a copy: the scene is a temporary
    using F = Surface<SpringWall<S>, SuperSlippery<S>>;
    const typename F::Params p{s.plane, {s.wall.stiffness_n_per_m, S{}}, s.tangential.slippery, {}};
    const std::string name = "super-slippery";
    effect<F>(name, "out of contact", p, {}, branch_inputs<S>(7, [](Lcg& r, std::size_t) {
                return tick_input<S>(above(r), r.horizontal(0.0, 1.0), 0);
              }));
    // mu = 4 N s/m, cap 2 N: below 0.5 m/s the force is mu v_t, above it is scaled to the cap.
    effect<F>(name, "in contact, under the cap", p, {}, branch_inputs<S>(8, [](Lcg& r, std::size_t) {
                return tick_input<S>(inside(r), r.horizontal(0.01, 0.45), 0);
              }));
    effect<F>(name, "in contact, capped", p, {}, branch_inputs<S>(9, [](Lcg& r, std::size_t) {
                return tick_input<S>(inside(r), r.horizontal(0.6, 1.5), 0);
              }));
  }

  void impact() {
    const auto s = make_runtime_scene<S>(loaded_.cartoon)
                       .template params<RuntimeSurface<S>>(0);  // a copy: the scene is a temporary
    using F = Surface<SpringWall<S>, NoTangential<S>, ImpactTransient<S>>;
    typename F::Params p{s.plane, {s.wall.stiffness_n_per_m, S{}}, {}, s.impact.law};
    const std::string name = "impact transient";
    using State = typename F::State;
    State armed_out{};
    armed_out.impact.previous_penetration_m = scalar_cast<S>(-0.002);
    effect<F>(name, "armed, out of contact", p, armed_out,
              branch_inputs<S>(10, [](Lcg& r, std::size_t) { return tick_input<S>(above(r), any_velocity(r), 5); }));
    effect<F>(name, "enters and triggers", p, armed_out, branch_inputs<S>(11, [](Lcg& r, std::size_t) {
                return tick_input<S>({r.uniform(-0.03, 0.03), 0.0, r.uniform(-0.001, -0.0001)},
                                     {r.uniform(-0.1, 0.1), 0.0, r.uniform(-0.5, -0.06)}, 5);
              }));
    State running{};
    running.impact.armed = false;
    running.impact.running = true;
    running.impact.trigger = Instant{0, 0};
    running.impact.impact_speed_m_per_s = scalar_cast<S>(0.2);
    running.impact.previous_penetration_m = scalar_cast<S>(0.001);
    for (const SineMethod method : {SineMethod::kLibrary, SineMethod::kPolynomial, SineMethod::kTable}) {
      if (!sine_method_available<S>(method)) continue;
      p.impact.sine = method;
      // t from 1 to 149 ticks into the 150 ms transient: the sine's whole range.
      effect<F>(name, fmt::format("running, in contact ({} sine)", sine_method_name(method)), p, running,
                branch_inputs<S>(12, [](Lcg& r, std::size_t i) {
                  return tick_input<S>(inside(r), any_velocity(r), 1 + static_cast<std::int64_t>(i % 149));
                }));
    }
    p.impact.sine = s.impact.law.sine;
    effect<F>(name, "running, out of contact", p, running, branch_inputs<S>(13, [](Lcg& r, std::size_t i) {
                return tick_input<S>(above(r), any_velocity(r), 1 + static_cast<std::int64_t>(i % 149));
              }));
    effect<F>(name, "ends (t > duration)", p, running, branch_inputs<S>(14, [](Lcg& r, std::size_t i) {
                return tick_input<S>(inside(r), any_velocity(r), 151 + static_cast<std::int64_t>(i % 50));
              }));
    State disarmed = armed_out;
    disarmed.impact.armed = false;
    effect<F>(name, "re-arms out of contact", p, disarmed, branch_inputs<S>(15, [](Lcg& r, std::size_t) {
                return tick_input<S>({r.uniform(-0.03, 0.03), 0.0, r.uniform(0.0011, 0.005)}, any_velocity(r), 5);
              }));
  }

  void cliff() {
    const typename CartoonCliff<S>::Params p = make_runtime_scene<S>(loaded_.cliff).template params<CartoonCliff<S>>(0);
    using C = CartoonCliff<S>;
    const std::string name = "cartoon cliff";
    // Gap x in [0, 0.02]; threshold 0.08 m/s; rearm height 1 mm.
    const auto ledge_x = [](Lcg& r) {
      return r.uniform(0.0, 1.0) < 0.5 ? r.uniform(-0.03, -0.001) : r.uniform(0.021, 0.05);
    };
    const auto fast = [](Lcg& r) {
      return Vec3<double>{r.uniform(0.12, 0.4), r.uniform(-0.05, 0.05), r.uniform(-0.05, 0.05)};
    };
    const auto slow = [](Lcg& r) {
      return Vec3<double>{r.uniform(0.0, 0.04), r.uniform(-0.02, 0.02), r.uniform(-0.02, 0.02)};
    };
    typename C::State supported_fast{scalar_cast<S>(0.2), false};
    typename C::State supported_slow{scalar_cast<S>(0.01), false};
    typename C::State fallen{scalar_cast<S>(0.01), true};
    effect<C>(name, "supported, on a ledge", p, supported_fast, branch_inputs<S>(16, [&](Lcg& r, std::size_t) {
                return tick_input<S>({ledge_x(r), 0.0, r.uniform(-0.003, -0.0002)}, fast(r), 0);
              }));
    effect<C>(name, "supported, over the gap (bridged)", p, supported_fast,
              branch_inputs<S>(17, [&](Lcg& r, std::size_t) {
                return tick_input<S>({r.uniform(0.001, 0.019), 0.0, r.uniform(-0.003, -0.0002)}, fast(r), 0);
              }));
    effect<C>(name, "supported, above the ground", p, supported_fast, branch_inputs<S>(18, [&](Lcg& r, std::size_t) {
                return tick_input<S>({ledge_x(r), 0.0, r.uniform(0.0005, 0.005)}, fast(r), 0);
              }));
    effect<C>(name, "falls (slow in the gap)", p, supported_slow, branch_inputs<S>(19, [&](Lcg& r, std::size_t) {
                return tick_input<S>({r.uniform(0.001, 0.019), 0.0, r.uniform(-0.003, -0.0002)}, slow(r), 0);
              }));
    effect<C>(name, "fallen, in the gap", p, fallen, branch_inputs<S>(20, [&](Lcg& r, std::size_t) {
                return tick_input<S>({r.uniform(0.001, 0.019), 0.0, r.uniform(-0.01, 0.0005)}, slow(r), 0);
              }));
    effect<C>(name, "fallen, under a ledge (side face)", p, fallen, branch_inputs<S>(21, [&](Lcg& r, std::size_t) {
                const double x = r.uniform(0.0, 1.0) < 0.5 ? r.uniform(-0.005, -0.0005) : r.uniform(0.0205, 0.025);
                return tick_input<S>({x, 0.0, r.uniform(-0.01, -0.0005)}, slow(r), 0);
              }));
    effect<C>(name, "fallen, re-supported above a ledge", p, fallen, branch_inputs<S>(22, [&](Lcg& r, std::size_t) {
                return tick_input<S>({ledge_x(r), 0.0, r.uniform(0.0015, 0.005)}, slow(r), 0);
              }));
  }

  void safety() {
    const ForceLimits limits = loaded_.wall.limits;  // 8 N, 2000 N/s: 2 N per 1 ms tick
    const auto primed = [&](const Vec3<double>& previous) {
      ForceSafety<S> s(limits);
      static_cast<void>(s.limit(vec_cast<S>(previous), scalar_cast<S>(1.0)));  // 1 Hz: any step allowed
      return s;
    };
    const auto make = [&](std::uint64_t seed, auto draw) {
      Lcg r(seed);
      SafetyWork<S> w;
      w.rate_hz = scalar_cast<S>(kRateHz);
      for (std::size_t i = 0; i < kBranchInputs; ++i) {
        const auto [previous, next] = draw(r);
        w.inputs.push_back({primed(previous), vec_cast<S>(next)});
      }
      return w;
    };
    const auto along = [](Lcg& r, double lo, double hi) { return r.horizontal(lo, hi); };
    const std::string name = "safety stage (ForceSafety)";
    auto within = make(23, [&](Lcg& r) {
      const Vec3<double> a = along(r, 0.0, 6.0);
      return std::pair{a, a + along(r, 0.0, 1.5)};
    });
    add(Level::kSafety, name, "within the limits", "", within.inputs.size(), std::move(within));
    auto rate = make(24, [&](Lcg& r) {
      const Vec3<double> a = along(r, 0.0, 3.0);
      return std::pair{a, a + along(r, 2.5, 4.0)};
    });
    add(Level::kSafety, name, "rate-limited", "", rate.inputs.size(), std::move(rate));
    auto clamped = make(25, [&](Lcg& r) {
      const Vec3<double> a = along(r, 7.6, 7.9);
      return std::pair{a, a * 1.15};
    });
    add(Level::kSafety, name, "clamped", "", clamped.inputs.size(), std::move(clamped));
    auto both = make(26, [&](Lcg& r) {
      const Vec3<double> a = along(r, 7.0, 7.9);
      return std::pair{a, Vec3<double>{-a.y, a.x, 0.0} * 1.5};
    });
    add(Level::kSafety, name, "rate-limited and clamped", "", both.inputs.size(), std::move(both));
  }

  std::array<std::pair<const char*, const SceneDescription*>, 5> paper_scenes() const {
    return {{{"wall", &loaded_.wall},
             {"realistic_friction", &loaded_.friction},
             {"slippery", &loaded_.slippery},
             {"cartoon_wall", &loaded_.cartoon},
             {"cliff", &loaded_.cliff}}};
  }

  /// Calls `f` with the paper scene `name` composed at compile time from its file's run-time
  /// scene: only its own laws (a spring wall where the file's has no damping).
  template <class F>
  static void with_compiled(std::string_view name, const RuntimeScene<S>& rt, F&& f) {
    if (name == "cliff") {
      f(Scene<CartoonCliff<S>>(rt.template params<CartoonCliff<S>>(0)));
      return;
    }
    const auto& s = rt.template params<RuntimeSurface<S>>(0);
    const typename SpringWall<S>::Params wall{s.wall.stiffness_n_per_m, S{}};
    if (name == "wall") {
      f(Scene<Surface<SpringWall<S>>>({s.plane, wall, {}, {}}));
    } else if (name == "realistic_friction") {
      f(Scene<Surface<SpringWall<S>, RealisticFriction<S>>>({s.plane, wall, s.tangential.friction, {}}));
    } else if (name == "slippery") {
      f(Scene<Surface<SpringWall<S>, SuperSlippery<S>>>({s.plane, wall, s.tangential.slippery, {}}));
    } else {
      f(Scene<Surface<SpringWall<S>, NoTangential<S>, ImpactTransient<S>>>({s.plane, wall, {}, s.impact.law}));
    }
  }

  const Loaded& loaded_;
  std::vector<std::unique_ptr<TickCase>>& out_;
};

Result<SceneDescription> load(const std::string& root, std::string_view name, ScalarKind kind) {
  return load_scene_file(paper_scene_path(root, name), kind);
}

template <Scalar S>
Result<Loaded> load_all(const std::string& root) {
  constexpr ScalarKind kind = kind_of<S>();
  Loaded l;
  SceneDescription* slots[] = {&l.wall, &l.friction, &l.slippery, &l.cartoon, &l.cliff};
  for (std::size_t i = 0; i < kPaperScenes.size(); ++i) {
    auto d = load(root, kPaperScenes[i], kind);
    if (!d) return Error{d.error()};
    *slots[i] = std::move(d).value();
  }
  return l;
}

template <Scalar S>
Result<bool> add_scalar(const std::string& root, std::vector<std::unique_ptr<TickCase>>& effects,
                        std::vector<std::unique_ptr<TickCase>>& scenes,
                        std::vector<std::unique_ptr<TickCase>>& controllers) {
  auto loaded = load_all<S>(root);
  if (!loaded) return Error{loaded.error()};
  CaseBuilder<S>(loaded.value(), effects).effects();
  CaseBuilder<S>(loaded.value(), scenes).scenes();
  CaseBuilder<S>(loaded.value(), scenes).scene_searches();
  CaseBuilder<S>(loaded.value(), controllers).spec_loops();
  CaseBuilder<S>(loaded.value(), controllers).loops();
  CaseBuilder<S>(loaded.value(), controllers).loop_searches();
  return true;
}

template <Scalar S>
std::unique_ptr<TickCase> spec_loop_case(SceneDescription desc, std::string_view scene, double rate_hz,
                                         std::optional<SineMethod> sine) {
  if (sine) override_sine(desc, *sine);
  LoopWork<RuntimeScene<S>, kSpecStages> work(make_runtime_scene<S>(desc), spec_config(desc, rate_hz),
                                              scenario_samples(scene, rate_hz));
  CaseInfo info;
  info.level = Level::kSpecLoop;
  info.scalar = scalar_kind_of<S>();
  info.subject = std::string(scene);
  info.branch = "scenario";
  info.form = "runtime";
  info.ticks_per_pass = work.size();
  info.id = fmt::format("spec-loop/{}/{}/{:g}Hz/{}", scene, scalar_kind_name(info.scalar), rate_hz,
                        sine ? sine_method_name(*sine) : std::string_view("default"));
  return make_case(std::move(info), std::move(work));
}

}  // namespace

Result<std::unique_ptr<TickCase>> make_spec_loop_case(const std::string& root, std::string_view scene,
                                                      ScalarKind scalar, double rate_hz,
                                                      std::optional<SineMethod> sine) {
  auto desc = load(root, scene, scalar);
  if (!desc) return Error{desc.error()};
  return with_scalar(
      scalar,
      [&]<Scalar S>() -> Result<std::unique_ptr<TickCase>> {
        return spec_loop_case<S>(desc.value(), scene, rate_hz, sine);
      },
      [](ScalarKind) -> Result<std::unique_ptr<TickCase>> { return Error{"scalar not built"}; });
}

std::vector<std::vector<Vec3<double>>> search_strikes(std::string_view scene) {
  const SearchPath path = search_path(scene);
  std::vector<std::vector<Vec3<double>>> strikes;
  for (std::size_t at = 0; at < path.position_m.size(); at += kSearchStrikeTicks) {
    const auto first = path.position_m.begin() + static_cast<std::ptrdiff_t>(at);
    strikes.emplace_back(first, first + static_cast<std::ptrdiff_t>(kSearchStrikeTicks));
  }
  return strikes;
}

Result<std::vector<SearchTick>> search_loop_ticks(const std::string& root, std::string_view scene, ScalarKind scalar) {
  auto desc = load(root, scene, scalar);
  if (!desc) return Error{desc.error()};
  return with_scalar(
      scalar,
      [&]<Scalar S>() -> Result<std::vector<SearchTick>> {
        SearchLoopWork<RuntimeScene<S>> work(make_runtime_scene<S>(desc.value()), search_config(desc.value(), kRateHz),
                                             search_path(scene).position_m);
        std::vector<SearchTick> ticks;
        for (std::size_t i = 0; i < work.size(); ++i) {
          work.prepare(i);
          const TickStatus status = work.tick();
          ticks.push_back({status.limits, status.faults.bits()});
        }
        return ticks;
      },
      [](ScalarKind) -> Result<std::vector<SearchTick>> { return Error{"scalar not built"}; });
}

Result<std::vector<std::unique_ptr<TickCase>>> make_cases(const std::string& root) {
  std::vector<std::unique_ptr<TickCase>> cases;
  CaseInfo empty;
  empty.id = "harness/empty";
  empty.level = Level::kHarness;
  empty.subject = "empty tick";
  empty.branch = "measurement overhead";
  empty.ticks_per_pass = 1;
  cases.push_back(make_case(std::move(empty), EmptyWork{}));

  std::vector<std::unique_ptr<TickCase>> effects;
  std::vector<std::unique_ptr<TickCase>> scenes;
  std::vector<std::unique_ptr<TickCase>> controllers;
  for (auto added :
       {add_scalar<double>(root, effects, scenes, controllers), add_scalar<float>(root, effects, scenes, controllers),
        add_scalar<Q16_16>(root, effects, scenes, controllers)}) {
    if (!added) return Error{added.error()};
  }
  for (auto* group : {&effects, &scenes, &controllers}) {
    for (auto& c : *group) cases.push_back(std::move(c));
  }
  return cases;
}

}  // namespace toonforce::report
