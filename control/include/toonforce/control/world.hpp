// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Several devices in one world: each device keeps its own servo loop (ServoLoop, with its own
/// supervisor, HIP sensor and safety chain, configured with that device's limits), and a
/// `World` ticks them together so that forces between the hands can be computed from every
/// HIP of the same tick. One world tick:
///
///   read every device (each loop later takes its reading from here: WorldDevice)
///   -> every HIP into the world frame (DeviceFrame), a velocity for each
///   -> the forces between HIPs (couplings, the shared ball: effects/between.hpp), per device
///   -> each device's loop ticks: its scene (FramedScene: the scene's effects in the world
///      frame, plus the world's force for it) and its whole safety chain, in its device's frame
///   -> one stop: a latched fault on any device holds every device (the policy kAll).
///
/// The world's force for a device enters that device's loop as part of its scene force, so
/// everything the loop does to a scene force applies to it: the non-finite guard, the
/// passivity observer at that device's port, engage and the soft start, the velocity and
/// workspace limits, the rate limit and the clamp at the device's own maximum. The ball's
/// cartoon effects (its slippery surface, its impact) inject energy by design; each is one
/// more active part of the device's scene (WorldShare), so the passivity controller at that
/// device's port budgets it as it budgets the single-device slippery surface and impact.
///
/// The tick is noexcept and allocation-free; its work is linear in the number of devices (and
/// in the couplings). A World holds pointers into itself: it is neither copied nor moved.

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <string>
#include <utility>

#include "toonforce/control/servo_config.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/control/velocity_estimator.hpp"
#include "toonforce/control/world_updates.hpp"
#include "toonforce/effects/between.hpp"
#include "toonforce/effects/scene.hpp"
#include "toonforce/hal/device.hpp"
#include "toonforce/hal/pins.hpp"

namespace toonforce {

/// Where a device's workspace sits in the world: x_world = scale R x_device + offset. R is a
/// rotation (rows orthonormal, determinant +1) and scale > 0. Velocities map with scale R and
/// forces back with scale R^T, so that the power a force delivers is the same in both frames
/// (f_w . v_w = f_w . (s R v_d) = (s R^T f_w) . v_d): the passivity observer's energy at the
/// device's port is the world's.
struct DeviceFrame {
  Vec3<double> offset_m{};
  std::array<Vec3<double>, 3> rotation{{{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}}};  ///< rows
  double scale = 1.0;

  /// A turn by `angle_rad` about the world's z axis (two devices facing each other: pi).
  static DeviceFrame yaw(double angle_rad, const Vec3<double>& offset_m = {}, double scale = 1.0) noexcept {
    return about_z(std::cos(angle_rad), std::sin(angle_rad), offset_m, scale);
  }
  /// The same in degrees, exact at whole quarter turns (cos 90 deg is 0 here, not 6e-17): two
  /// devices facing each other are then mirror images to the last bit.
  static DeviceFrame yaw_degrees(double angle_deg, const Vec3<double>& offset_m = {}, double scale = 1.0) noexcept {
    const double quarter_turns = angle_deg / 90.0;
    if (quarter_turns != std::floor(quarter_turns) || !std::isfinite(quarter_turns)) {
      return yaw(angle_deg * std::numbers::pi / 180.0, offset_m, scale);
    }
    constexpr std::array<std::array<double, 2>, 4> kQuarters{{{1.0, 0.0}, {0.0, 1.0}, {-1.0, 0.0}, {0.0, -1.0}}};
    const auto q = static_cast<std::size_t>(((static_cast<long long>(quarter_turns) % 4) + 4) % 4);
    return about_z(kQuarters[q][0], kQuarters[q][1], offset_m, scale);
  }

  template <Scalar S>
  Vec3<S> rotate(const Vec3<S>& v) const noexcept {
    return {dot(vec_cast<S>(rotation[0]), v), dot(vec_cast<S>(rotation[1]), v), dot(vec_cast<S>(rotation[2]), v)};
  }
  template <Scalar S>
  Vec3<S> rotate_back(const Vec3<S>& v) const noexcept {  // R^T v
    return vec_cast<S>(rotation[0]) * v.x + vec_cast<S>(rotation[1]) * v.y + vec_cast<S>(rotation[2]) * v.z;
  }
  template <Scalar S>
  Vec3<S> position_to_world(const Vec3<S>& x) const noexcept {
    return rotate(x) * scalar_cast<S>(scale) + vec_cast<S>(offset_m);
  }
  template <Scalar S>
  Vec3<S> velocity_to_world(const Vec3<S>& v) const noexcept {
    return rotate(v) * scalar_cast<S>(scale);
  }
  template <Scalar S>
  Vec3<S> force_to_device(const Vec3<S>& f) const noexcept {
    return rotate_back(f) * scalar_cast<S>(scale);
  }
  /// The rotation about z with this cosine and sine, then the offset and scale.
  static DeviceFrame about_z(double c, double s, const Vec3<double>& offset_m, double scale) noexcept {
    DeviceFrame f;
    f.rotation = {{{c, -s, 0.0}, {s, c, 0.0}, {0.0, 0.0, 1.0}}};
    f.offset_m = offset_m;
    f.scale = scale;
    return f;
  }
  /// The identity: the device's frame is the world's.
  bool identity() const noexcept {
    return offset_m == Vec3<double>{} && scale == 1.0 && rotation[0] == Vec3<double>{1.0, 0.0, 0.0} &&
           rotation[1] == Vec3<double>{0.0, 1.0, 0.0} && rotation[2] == Vec3<double>{0.0, 0.0, 1.0};
  }
};

/// Why a frame is refused (empty: accepted): R must be a rotation to 1e-9, scale > 0.
inline std::string check(const DeviceFrame& f) {
  if (!is_finite(f.offset_m)) return "the offset must be finite";
  if (!(std::isfinite(f.scale) && f.scale > 0.0)) return "the scale must be finite and > 0";
  constexpr double kTol = 1e-9;
  for (std::size_t i = 0; i < 3; ++i) {
    if (!is_finite(f.rotation[i])) return "the rotation must be finite";
    for (std::size_t j = 0; j < 3; ++j) {
      const double want = i == j ? 1.0 : 0.0;
      if (std::abs(dot(f.rotation[i], f.rotation[j]) - want) > kTol) {
        return "the rotation's rows must be orthonormal (a rotation, without scale or shear: scale is its own key)";
      }
    }
  }
  const auto& r = f.rotation;
  const double det = r[0].x * (r[1].y * r[2].z - r[1].z * r[2].y) - r[0].y * (r[1].x * r[2].z - r[1].z * r[2].x) +
                     r[0].z * (r[1].x * r[2].y - r[1].y * r[2].x);
  if (det < 0.0) return "the rotation must not mirror (determinant -1): a mirrored device would push the wrong way";
  return "";
}

/// The most active parts the world adds to a device's scene: the ball's slippery surface and
/// its impact transient.
inline constexpr std::size_t kWorldActiveSlots = 2;

/// What the world puts on one device on one tick, in the world frame: the force, and of it the
/// active parts (the first `slots` of `active`, as FramedScene was told), for the passivity
/// controller at the device's port.
template <Scalar S>
struct WorldShare {
  Vec3<S> force_n{};
  std::array<ActiveForce<S>, kWorldActiveSlots> active{};
};

namespace detail {
template <class Inner>
constexpr std::size_t max_effects_of() noexcept {
  if constexpr (requires { Inner::kMaxEffects; }) {
    return Inner::kMaxEffects;
  } else {
    return 0;
  }
}
}  // namespace detail

/// A device's scene as its loop sees it: the scene's effects act in the world frame (the HIP
/// is carried there first), the world's force for this device (`share->force_n`, in the world
/// frame, written by the World before the loop's tick) is added to theirs, and the sum goes
/// back to the device's frame, as do the active parts the passivity controller budgets: the
/// scene's, then the world's `world_slots` (fixed for the loop's life: the controller's slots
/// are laid out once).
template <SceneType Inner>
class FramedScene {
 public:
  using Scalar = typename Inner::Scalar;
  using S = Scalar;
  using State = typename Inner::State;
  static constexpr Needs kNeeds = Inner::kNeeds;
  static constexpr std::size_t kActiveCapacity = Inner::kActiveCapacity + kWorldActiveSlots;
  static constexpr std::size_t kValueCapacity = Inner::kValueCapacity;

  /// A live scene's (LiveSceneType) effects, when Inner is one.
  static constexpr std::size_t kMaxEffects = detail::max_effects_of<Inner>();

  /// Only as room for an update's scene (SceneUpdate): never ticked.
  FramedScene() noexcept = default;
  FramedScene(const Inner& inner, const DeviceFrame& frame, const WorldShare<S>* share,
              std::size_t world_slots = 0) noexcept
      : inner_(inner),
        frame_(frame),
        share_(share),
        world_slots_(world_slots < kWorldActiveSlots ? world_slots : kWorldActiveSlots) {}

  Vec3<S> force(const TickInput<S>& in, State& s, ActiveForce<S>* active) const noexcept {
    return to_device(inner_.force(to_world(in), s, active), active);
  }
  Vec3<S> force(const TickInput<S>& in, const State& from, State& to, ActiveForce<S>* active) const noexcept {
    return to_device(inner_.force(to_world(in), from, to, active), active);
  }
  Needs needs() const noexcept { return inner_.needs(); }
  std::size_t active_slots() const noexcept { return inner_.active_slots() + world_slots_; }
  std::size_t value_count() const noexcept { return inner_.value_count(); }
  bool describe(const State& s, const TickInput<S>& in, double* values) const noexcept {
    return inner_.describe(s, to_world(in), values);
  }
  std::size_t effect_count() const noexcept { return inner_.effect_count(); }
  EffectInfo effect_info(std::size_t i) const noexcept { return inner_.effect_info(i); }

  const Inner& inner() const noexcept { return inner_; }
  const DeviceFrame& frame() const noexcept { return frame_; }
  /// The same device's scene with other effects: where it sits and its share of the world stay.
  FramedScene with_inner(const Inner& inner) const noexcept {
    FramedScene f = *this;
    f.inner_ = inner;
    return f;
  }

  // A live scene (scene_updates.hpp), when its effects are: every call goes to them. An update
  // of a world's device carries effects only (World::take_update builds its scene from this
  // one's frame and share with with_inner), so nothing here reads a frame or a pointer from
  // another's bytes.
  // clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
  // clang-format off
  void carry(const State& from, State& now, const std::int16_t* continues) const noexcept
    requires LiveSceneType<Inner>
  {
    inner_.carry(from, now, continues);
  }
  bool fire(State& s, std::size_t i, std::size_t event, double value, Instant now) const noexcept
    requires LiveSceneType<Inner>
  {
    return inner_.fire(s, i, event, value, now);
  }
  bool assign_checked(const FramedScene& untrusted) noexcept
    requires LiveSceneType<Inner>
  {
    return inner_.assign_checked(untrusted.inner_);
  }
  bool continues_ok(const FramedScene& previous, const std::int16_t* continues) const noexcept
    requires LiveSceneType<Inner>
  {
    return inner_.continues_ok(previous.inner_, continues);
  }
  bool takes_event(std::size_t i, std::size_t event, double value) const noexcept
    requires LiveSceneType<Inner>
  {
    return inner_.takes_event(i, event, value);
  }
  // clang-format on

 private:
  TickInput<S> to_world(const TickInput<S>& in) const noexcept {
    TickInput<S> w = in;
    w.position_m = frame_.position_to_world(in.position_m);
    w.velocity_m_per_s = frame_.velocity_to_world(in.velocity_m_per_s);
    return w;
  }
  Vec3<S> to_device(const Vec3<S>& scene_n, ActiveForce<S>* active) const noexcept {
    const std::size_t scene_slots = inner_.active_slots();
    for (std::size_t j = 0; j < world_slots_; ++j) active[scene_slots + j] = share_->active[j];
    for (std::size_t i = 0; i < scene_slots + world_slots_; ++i)
      active[i].force_n = frame_.force_to_device(active[i].force_n);
    return frame_.force_to_device(scene_n + share_->force_n);
  }

  Inner inner_{};
  DeviceFrame frame_{};
  const WorldShare<S>* share_ = nullptr;
  std::size_t world_slots_ = 0;
};

/// A device of a world: the World reads the real device once a tick (`fetch`), and the
/// device's loop takes that reading (`read`); writes go straight through.
template <ServoDevice Device>
class WorldDevice {
  static_assert(std::same_as<device_scalar_t<Device>, double>, "a world's devices read in double");

 public:
  explicit WorldDevice(Device* device) noexcept : device_(device) {}
  DeviceStatus fetch() noexcept {
    reading_ = DeviceReading{};
    status_ = device_->read(reading_);
    return status_;
  }
  DeviceStatus read(DeviceReading& reading) noexcept {
    reading = reading_;
    return status_;
  }
  DeviceStatus write(const Vec3<double>& force_n) noexcept { return device_->write(force_n); }
  const DeviceReading& reading() const noexcept { return reading_; }
  DeviceStatus status() const noexcept { return status_; }
  Device& device() noexcept { return *device_; }

 private:
  Device* device_;
  DeviceReading reading_{};
  DeviceStatus status_ = DeviceStatus::kNotReady;
};

/// The e-stop input of a world's loop: engaged while the world holds every device.
struct WorldStopPin {
  const std::atomic<bool>* held = nullptr;
  PinLevel read() noexcept { return held->load(std::memory_order_acquire) ? PinLevel::kActive : PinLevel::kInactive; }
};
using WorldPins = Pins<NullTickPin, WorldStopPin, AlwaysActive, NullLights>;

/// What one device's fault does to the others.
enum class StopPolicy : std::uint8_t {
  kAll,   ///< a latched fault (e-stop, watchdog, silent device) on one holds every device at zero force
  kEach,  ///< independent stations: each device stops on its own faults only
};

/// The most couplings a world has (sized at start-up: a fixed array).
inline constexpr std::size_t kMaxCouplings = 8;

struct CouplingSpec {
  std::size_t a = 0;  ///< device indices, a != b
  std::size_t b = 1;
  between::CouplingParams params;
};

struct WorldConfig {
  StopPolicy stop = StopPolicy::kAll;
  std::array<CouplingSpec, kMaxCouplings> couplings{};
  std::size_t coupling_count = 0;
  bool has_ball = false;
  /// The ball, with its optional surface effects (ball.has_slippery, ball.has_impact; both off
  /// by default).
  between::BallParams ball;
  std::uint32_t ball_devices = ~0U;  ///< bit i: device i touches the ball
};

/// Why a world's configuration is refused for `devices` devices (empty: accepted); normalises
/// the ball's wall normal.
inline std::string check(WorldConfig& c, std::size_t devices) {
  if (c.coupling_count > kMaxCouplings) return "at most " + std::to_string(kMaxCouplings) + " couplings";
  for (std::size_t i = 0; i < c.coupling_count; ++i) {
    const CouplingSpec& s = c.couplings[i];
    if (s.a >= devices || s.b >= devices)
      return "coupling " + std::to_string(i + 1) + " names a device the world does not have";
    if (s.a == s.b) return "coupling " + std::to_string(i + 1) + " couples a device with itself";
    if (const std::string why = between::check(s.params); !why.empty()) {
      return "coupling " + std::to_string(i + 1) + ": " + why;
    }
  }
  if (c.has_ball) {
    if (const std::string why = between::check_and_normalise(c.ball); !why.empty()) return "ball: " + why;
  }
  return "";
}

/// The outcome of one world tick.
template <std::size_t N>
struct WorldStatus {
  std::array<TickStatus, N> devices{};
  bool held = false;        ///< every device is held at zero force (one stop)
  std::size_t held_by = N;  ///< the device whose fault started the hold (N: none)
};

namespace detail {
/// A live world's intake and the per-device updates it offers its loops; nothing otherwise.
template <class SceneT, std::size_t N, bool kLive>
struct WorldLive {};
template <class SceneT, std::size_t N>
struct WorldLive<SceneT, N, true> {
  WorldMailbox<SceneT>* mailbox = nullptr;
  WorldIntake<SceneT, N> intake{};
  std::array<SceneUpdate<FramedScene<SceneT>>, N> offered{};
  std::uint64_t applied = 0;
};
}  // namespace detail

/// N devices of one type (a backend, or the DeviceDriver seam for a mix) in one world. With
/// kStages.live (kLiveStages) the world takes scene updates for all its devices at once
/// (world_updates.hpp: listen).
template <ServoDevice Device, SceneType SceneT, std::size_t N, LoopStages kStages = kEveryStage>
class World {
  static_assert(N >= 1 && N <= 32, "1 to 32 devices");
  static_assert(!kStages.live || N <= kMaxWorldUpdateDevices, "a live world has at most 4 devices");

 public:
  using S = typename SceneT::Scalar;
  using Loop = ServoLoop<WorldDevice<Device>, FramedScene<SceneT>, WorldPins, kStages>;

  /// One device of the world: the device (owned by the caller, outliving the world), its
  /// scene (the effects that act on it, in the world frame), where it sits, and its loop's
  /// configuration (its own limits; must pass check_servo_config()). All devices share one
  /// period.
  struct Member {
    Device* device;
    SceneT scene;
    DeviceFrame frame;
    ServoConfig config;
  };

  /// `config` must pass check(config, N); every member's frame check(frame).
  World(const std::array<Member, N>& members, const WorldConfig& config) noexcept
      : World(members, config, std::make_index_sequence<N>{}) {}
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  /// One world tick at integer time k (strictly increasing).
  WorldStatus<N> tick(std::int64_t k) noexcept {
    // A re-arm asked for since the last tick: the hold lets go and every loop re-arms in this
    // tick (its supervisor reads the request), so a device whose fault is gone comes back and
    // one whose fault persists latches again below.
    const std::uint64_t rearms = rearm_requests_.load(std::memory_order_acquire);
    if (rearms != rearms_seen_) {
      rearms_seen_ = rearms;
      held_.store(false, std::memory_order_release);
      for (Loop& loop : loops_) loop.request_rearm();
    }
    if constexpr (kStages.live) offer_update();
    const std::int64_t gap = started_ && k > last_k_ ? k - last_k_ : 1;
    const double dt_s = static_cast<double>(gap) * period_s_;
    const S rate_hz = scalar_cast<S>(1.0 / dt_s);
    for (std::size_t i = 0; i < N; ++i) {
      sense(i, rate_hz);
      // In the world: read this tick, and its loop's force was not cut by a fault last tick (a
      // handle outside its workspace, too fast, a device error, a latched fault). A device that
      // is not takes part in nothing between hands, at either end: the others are not pulled
      // toward a handle whose own force is off (a coupling thrown out of the workspace pulled
      // the other device at its clamp).
      in_world_[i] = known_[i] && !loops_[i].last_status().faults;
    }
    between(dt_s, k);

    WorldStatus<N> status;
    for (std::size_t i = 0; i < N; ++i) status.devices[i] = loops_[i].tick(k);
    if constexpr (kStages.live) {
      if (live_.applied != 0 && live_.mailbox != nullptr) live_.mailbox->report_applied(live_.applied);
    }
    if (config_.stop == StopPolicy::kAll && !held_.load(std::memory_order_relaxed)) {
      for (std::size_t i = 0; i < N; ++i) {
        if ((loops_[i].latched().bits() & kLatchedFaults) != 0) {
          held_by_.store(i, std::memory_order_relaxed);
          held_.store(true, std::memory_order_release);
          break;
        }
      }
    }
    status.held = held_.load(std::memory_order_relaxed);
    status.held_by = status.held ? held_by_.load(std::memory_order_relaxed) : N;
    started_ = true;
    last_k_ = k;
    return status;
  }

  /// A live world takes its scene updates from `mailbox` (config/world_editor.hpp pushes them)
  /// from the next tick on: one a tick, checked whole for every device, then applied by every
  /// device's loop on that same tick. Before the world runs, or from its thread.
  // clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
  // clang-format off
  template <class M>
  void listen(M& mailbox) noexcept
    requires(kStages.live && std::same_as<M, WorldMailbox<SceneT>>)
  {
    live_.mailbox = &mailbox;
  }
  /// Live world: updates refused (torn, or failing a check of any device's part).
  std::uint64_t updates_refused() const noexcept
    requires(kStages.live)
  {
    return live_.intake.refused();
  }
  // clang-format on

  /// The last tick of a run: zero force on every device (ServoLoop::shutdown).
  void shutdown(std::int64_t k) noexcept {
    for (Loop& loop : loops_) static_cast<void>(loop.shutdown(k));
  }

  /// Asks the world to let go of the hold and every loop to re-arm at the next tick (any
  /// thread: one atomic counter, which the tick reads). A fault still present holds again.
  void request_rearm() noexcept { rearm_requests_.fetch_add(1, std::memory_order_release); }

  bool held() const noexcept { return held_.load(std::memory_order_acquire); }
  /// The device whose fault started the hold (N: not held).
  std::size_t held_by() const noexcept { return held() ? held_by_.load(std::memory_order_relaxed) : N; }
  static constexpr std::size_t size() noexcept { return N; }
  Loop& loop(std::size_t i) noexcept { return loops_[i]; }
  const Loop& loop(std::size_t i) const noexcept { return loops_[i]; }
  /// Device i's HIP in the world frame this tick (valid when hip_known(i)).
  const Vec3<S>& hip_m(std::size_t i) const noexcept { return hip_m_[i]; }
  const Vec3<S>& hip_m_per_s(std::size_t i) const noexcept { return hip_v_[i]; }
  bool hip_known(std::size_t i) const noexcept { return known_[i]; }
  /// The forces between HIPs on device i this tick, world frame, before its safety chain [N].
  const Vec3<S>& world_force_n(std::size_t i) const noexcept { return world_force_n_[i]; }
  /// Of that, what the couplings put on device i, and what the ball did [N].
  const Vec3<S>& coupling_sum_n(std::size_t i) const noexcept { return coupling_sum_n_[i]; }
  const Vec3<S>& ball_force_n(std::size_t i) const noexcept { return ball_n_[i]; }
  /// Of the ball's force, its slippery surface's and its impact's parts [N] (zero when off).
  const Vec3<S>& ball_slippery_n(std::size_t i) const noexcept { return ball_slippery_n_[i]; }
  const Vec3<S>& ball_impact_n(std::size_t i) const noexcept { return ball_impact_n_[i]; }
  /// Device i's state against the ball's impact (fresh while it is out of the world).
  const between::BallHipState& ball_hip_state(std::size_t i) const noexcept { return ball_hip_[i]; }
  /// Coupling j's force on its device a this tick (b got its negation) [N].
  const Vec3<S>& coupling_force_n(std::size_t j) const noexcept { return coupling_n_[j]; }
  const between::BallState& ball() const noexcept { return ball_; }
  const WorldConfig& config() const noexcept { return config_; }

 private:
  template <std::size_t... I>
  World(const std::array<Member, N>& members, const WorldConfig& config, std::index_sequence<I...>) noexcept
      : config_(config),
        period_s_(members[0].config.period_s),
        estimators_{VelocityEstimator<S>(members[I].config.velocity_cutoff_hz)...},
        fresh_estimators_{estimators_},
        loops_{Loop(WorldDevice<Device>(members[I].device),
                    FramedScene<SceneT>(members[I].scene, members[I].frame, &share_[I], world_slots(config, I)),
                    members[I].config, WorldPins{{}, WorldStopPin{&held_}, {}, {}})...} {
    // (The loop owns its WorldDevice; the world fetches through loop.device().)
    ball_.position_m = config_.ball.start_m;
    coupling_gain_.fill(1.0);
    coupling_step_.fill(1.0);
    ball_gain_.fill(1.0);
    const auto step = [this](double soft_start_s) { return soft_start_s > 0.0 ? period_s_ / soft_start_s : 1.0; };
    for (std::size_t i = 0; i < N; ++i) ball_step_[i] = step(members[i].config.safety.soft_start_s);
    for (std::size_t j = 0; j < config_.coupling_count && j < kMaxCouplings; ++j) {
      const CouplingSpec& c = config_.couplings[j];
      coupling_step_[j] = std::min(ball_step_[c.a < N ? c.a : 0], ball_step_[c.b < N ? c.b : 0]);
    }
  }

  /// A live world's one update a tick, if there is one: checked whole (every device's part
  /// against that device's scene), then offered to every loop, which applies it in this tick.
  void offer_update() noexcept {
    if constexpr (kStages.live) {
      if (live_.mailbox == nullptr) return;
      const auto current = [this](std::size_t i) -> const SceneT& { return loops_[i].scene().inner(); };
      if (live_.intake.take(*live_.mailbox, current) != decltype(live_.intake)::Taken::kChecked) return;
      const auto& update = live_.intake.update();
      for (std::size_t i = 0; i < N; ++i) {
        const SceneUpdate<SceneT>& part = update.devices[i];
        auto& offered = live_.offered[i];
        offered.scene = loops_[i].scene().with_inner(part.scene);
        offered.continues = part.continues;
        offered.events = part.events;
        offered.event_count = part.event_count;
        offered.sequence = update.sequence;
        loops_[i].offer(offered);
      }
      live_.applied = update.sequence;
    }
  }

  /// The ball's active parts device i takes part in: its slippery surface, its impact.
  static std::size_t world_slots(const WorldConfig& c, std::size_t i) noexcept {
    if (!c.has_ball || (c.ball_devices & (1U << i)) == 0) return 0;
    return (c.ball.has_slippery ? 1U : 0U) + (c.ball.has_impact ? 1U : 0U);
  }

  /// Device i's reading, its HIP in the world frame and a velocity (the device's, or the
  /// estimator's, the same low-pass the loop uses).
  void sense(std::size_t i, S rate_hz) noexcept {
    WorldDevice<Device>& device = loops_[i].device();
    const DeviceStatus read = device.fetch();
    const DeviceReading& r = device.reading();
    const bool was_known = known_[i];
    known_[i] = read == DeviceStatus::kOk && is_finite(r.position_m) && is_finite(r.velocity_m_per_s);
    if (!known_[i]) return;
    // Back after ticks without a position: the last one is old, and a difference over one tick
    // would be a velocity spike (the coupling's damper would kick); the estimate starts afresh.
    if (!was_known) estimators_[i] = fresh_estimators_[i];
    const DeviceFrame& frame = loops_[i].scene().frame();  // the one its scene carries the HIP with
    hip_m_[i] = frame.position_to_world(vec_cast<S>(r.position_m));
    if (r.has_velocity) {
      hip_v_[i] = frame.velocity_to_world(vec_cast<S>(r.velocity_m_per_s));
    } else {
      hip_v_[i] = estimators_[i].estimate(hip_m_[i], rate_hz);
      estimators_[i].commit(hip_m_[i], hip_v_[i]);
    }
  }

  /// The forces between HIPs: each coupling's once, its negation on the other end; the ball's
  /// on each HIP in it, their sum's negation on the ball, which then moves one step. A HIP
  /// not in the world this tick takes part in nothing.
  void between(double dt_s, std::int64_t k) noexcept {
    const bool ball_effects = config_.has_ball && (config_.ball.has_slippery || config_.ball.has_impact);
    for (std::size_t i = 0; i < N; ++i) {
      world_force_n_[i] = coupling_sum_n_[i] = ball_n_[i] = Vec3<S>{};
      if (ball_effects) {  // a world without them pays nothing for them
        ball_slippery_n_[i] = ball_impact_n_[i] = Vec3<S>{};
        share_[i].active = {};
      }
    }
    for (std::size_t j = 0; j < config_.coupling_count; ++j) {
      const CouplingSpec& c = config_.couplings[j];
      coupling_n_[j] = Vec3<S>{};
      if (!in_world_[c.a] || !in_world_[c.b]) {
        coupling_gain_[j] = 0.0;
        continue;
      }
      // Back together after one end was out: ramped in over the slower end's soft start (a
      // step of the spring's whole force would kick the end that never left).
      coupling_gain_[j] = std::min(1.0, coupling_gain_[j] + coupling_step_[j]);
      Vec3<S> f = between::coupling_force(c.params, hip_m_[c.a], hip_v_[c.a], hip_m_[c.b], hip_v_[c.b]);
      if (coupling_gain_[j] < 1.0) f = f * scalar_cast<S>(coupling_gain_[j]);
      coupling_n_[j] = f;
      coupling_sum_n_[c.a] += f;
      coupling_sum_n_[c.b] -= f;
    }
    if (config_.has_ball) {
      Vec3<double> on_ball{};
      for (std::size_t i = 0; i < N; ++i) {
        if ((config_.ball_devices & (1U << i)) == 0) continue;
        if (!in_world_[i]) {
          ball_gain_[i] = 0.0;
          ball_hip_[i] = between::BallHipState{};  // back in the world: armed, no transient
          continue;
        }
        ball_gain_[i] = std::min(1.0, ball_gain_[i] + ball_step_[i]);
        const between::BallHipForce h = between::ball_force_on_hip(
            config_.ball, ball_, ball_hip_[i], to_double(hip_m_[i]), to_double(hip_v_[i]), Instant{k, 0}, period_s_);
        const Vec3<double> f = h.force_n * ball_gain_[i];
        ball_n_[i] = vec_cast<S>(f);
        on_ball -= f;
        // The active parts as they reach the device (after the same ramp), for its passivity
        // controller: the slippery surface in an episode while the HIP is in the ball, the
        // impact while its transient runs (as on a single device's surface).
        std::size_t slot = 0;
        if (config_.ball.has_slippery) {
          ball_slippery_n_[i] = vec_cast<S>(h.slippery_n * ball_gain_[i]);
          share_[i].active[slot++] = {ball_slippery_n_[i], h.in_contact, false};
        }
        if (config_.ball.has_impact) {
          ball_impact_n_[i] = vec_cast<S>(h.impact_n * ball_gain_[i]);
          share_[i].active[slot++] = {ball_impact_n_[i], h.impact_running, h.impact_triggered};
        }
      }
      static_cast<void>(between::step_ball(config_.ball, ball_, on_ball, dt_s));
    }
    for (std::size_t i = 0; i < N; ++i) share_[i].force_n = world_force_n_[i] = coupling_sum_n_[i] + ball_n_[i];
  }

  WorldConfig config_;
  double period_s_;
  std::atomic<bool> held_{false};
  std::atomic<std::size_t> held_by_{N};
  std::atomic<std::uint64_t> rearm_requests_{0};
  std::uint64_t rearms_seen_ = 0;
  bool started_ = false;
  [[no_unique_address]] detail::WorldLive<SceneT, N, kStages.live> live_{};
  std::int64_t last_k_ = 0;
  std::array<Vec3<S>, N> world_force_n_{};
  std::array<Vec3<S>, N> coupling_sum_n_{};
  std::array<Vec3<S>, N> ball_n_{};
  std::array<Vec3<S>, N> ball_slippery_n_{};
  std::array<Vec3<S>, N> ball_impact_n_{};
  std::array<between::BallHipState, N> ball_hip_{};
  std::array<WorldShare<S>, N> share_{};  ///< what each device's FramedScene reads
  std::array<Vec3<S>, kMaxCouplings> coupling_n_{};
  std::array<Vec3<S>, N> hip_m_{};
  std::array<Vec3<S>, N> hip_v_{};
  std::array<bool, N> known_{};
  std::array<bool, N> in_world_{};
  /// 1 while both ends have been in the world; from 0 back to 1 over the soft start after one left.
  std::array<double, kMaxCouplings> coupling_gain_{};
  std::array<double, kMaxCouplings> coupling_step_{};
  std::array<double, N> ball_gain_{};
  std::array<double, N> ball_step_{};
  between::BallState ball_{};
  std::array<VelocityEstimator<S>, N> estimators_;
  std::array<VelocityEstimator<S>, N> fresh_estimators_;  ///< as at the start
  std::array<Loop, N> loops_;
};

}  // namespace toonforce
