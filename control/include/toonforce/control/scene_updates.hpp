// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Live scenes (docs/spec/live-scenes.md): how an application's thread changes the
/// scene a running servo loop renders.
///
/// An update is a whole scene, already checked by the application's side (config/
/// scene_editor.hpp checks it with the scene files' rules), with what the loop needs to carry
/// the effects' states over and the one-shot events to fire. The application pushes it into a
/// `SceneMailbox`, a single-producer single-consumer queue of fixed capacity, wait-free on
/// both sides: the application never blocks the loop and the loop never waits. The loop takes
/// at most one update at the start of a tick (bounded work: a copy of the scene and its checks)
/// and applies it whole before the scene's force, so a tick sees either the old scene or the new one, never
/// half of each. A full mailbox refuses the push: the caller learns it and may try again (the
/// loop takes one update a tick, so that is also the rate limit).
///
/// The mailbox may live in memory shared with another process (`run --view --control`: the
/// server process parses the network's changes and pushes them), which the loop must assume
/// an attacker controls: it may write any bytes there at any time, while the loop copies too.
/// So the loop trusts nothing it reads there (SceneIntake below): it keeps its own index of
/// the next update, reads the producer's index as a hint, copies the update out of its slot
/// (a sequence number per slot says whether a writer changed it during the copy) and checks the
/// copy whole before it applies anything (check_update); an update that fails is refused: taken
/// off, counted, and the loop ticks on with the scene it had.
///
/// Nothing here allocates; the mailbox and the loop's copies are sized at start-up.

#include <array>
#include <atomic>
#include <cstring>
#include <cstddef>
#include <cstdint>
#include <concepts>

#include "toonforce/control/seqlock_fence.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {

/// A scene a live loop can take updates of: a run-time scene (RuntimeSceneOf), whose effects
/// carry their states over and take events, and which can rebuild itself from an untrusted copy.
// clang-format 14 mangles requires-clauses and requires-expressions (see .clang-format).
// clang-format off
template <class T>
concept LiveSceneType = SceneType<T> && requires(const T& scene, T& rebuilt, const typename T::State& from,
                                                 typename T::State& s, const std::int16_t* continues) {
  { T::kMaxEffects } -> std::convertible_to<std::size_t>;
  scene.carry(from, s, continues);
  { scene.fire(s, std::size_t{}, std::size_t{}, 0.0, Instant{}) } -> std::same_as<bool>;
  { rebuilt.assign_checked(scene) } noexcept -> std::same_as<bool>;
  { scene.continues_ok(scene, continues) } noexcept -> std::same_as<bool>;
  { scene.takes_event(std::size_t{}, std::size_t{}, 0.0) } noexcept -> std::same_as<bool>;
};
// clang-format on

/// One event for one effect of the update's scene.
struct SceneEvent {
  std::uint16_t effect = 0;  ///< the effect's place in the scene's order (from 0)
  std::uint8_t event = 0;    ///< its number in the effect's kEvents
  double value = 0.0;        ///< e.g. the impact speed [m/s]
};

template <LiveSceneType SceneT>
struct SceneUpdate {
  static constexpr std::size_t kMaxEffects = SceneT::kMaxEffects;
  static constexpr std::size_t kMaxEvents = 8;

  SceneT scene{};
  /// For each effect of `scene` (in its order): the index, among the previous scene's effects of
  /// its kind, of the effect it continues (its state carries over), or -1 (a new effect).
  std::array<std::int16_t, kMaxEffects> continues{};
  /// Fired after the scene is in place, in order.
  std::array<SceneEvent, kMaxEvents> events{};
  std::uint8_t event_count = 0;
  /// The application's number for this update (increasing); the loop says which it applied.
  std::uint64_t sequence = 0;
};

/// Defined only by tests and fuzz targets, to write the bytes a process sharing the mailbox
/// could (scene.hpp declares it).
struct ForgeAccess;

/// The wait-free queue from one application thread to the servo loop. Its bytes are all the
/// two sides share: the producer's side is push(); the loop's is SceneIntake (or a world's
/// WorldIntake), which keeps its own index and reads and writes here only through the members
/// marked "loop". `UpdateT` is a fixed-size, pointer-free record (SceneUpdate, WorldUpdate).
template <class UpdateT, std::size_t kCapacity = 4>
class UpdateMailbox {
 public:
  using Update = UpdateT;
  static_assert(kCapacity >= 1);

  /// Application thread: copies `u` in (a scene's parameters: fixed arrays, no allocation); false (nothing pushed) when the loop has not yet taken
  /// the updates before it. The slot's sequence is odd while it is written, then 2 (n + 1) for
  /// the n-th update (from 0).
  bool push(const Update& u) noexcept {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) >= kCapacity) return false;
    Slot& slot = slots_[head % kCapacity];
    slot.sequence.store(2 * head + 1, std::memory_order_relaxed);
    seqlock_write_fence();  // odd before any byte of the update
    slot.update = u;
    slot.sequence.store(2 * head + 2, std::memory_order_release);
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  /// Any thread: the sequence of the last update the loop applied (0: none yet).
  std::uint64_t applied() const noexcept { return applied_.load(std::memory_order_acquire); }
  /// Any thread: how many updates the loop refused (they failed its checks; live-scenes.md).
  std::uint64_t refused() const noexcept { return refused_.load(std::memory_order_acquire); }
  /// Any thread: updates pushed and not yet taken.
  std::size_t pending() const noexcept {
    return static_cast<std::size_t>(head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire));
  }
  static constexpr std::size_t capacity() noexcept { return kCapacity; }

  /// Loop: the producer's index (how many updates it says it pushed): any value.
  std::uint64_t announced() const noexcept { return head_.load(std::memory_order_acquire); }
  /// Loop: copies the update numbered `n` out of its slot (n % kCapacity) into `out` with
  /// `Copy::copy` (a memcpy; SceneUpdateCopy below) and says whether it is whole: the slot's
  /// sequence was 2 (n + 1) before the copy and still is after it (seqlock). `out` may hold
  /// any bytes either way: check it before reading it as an update.
  template <class Copy>
  bool copy_out(std::uint64_t n, Update& out) const noexcept {
    const Slot& slot = slots_[n % kCapacity];
    const std::uint64_t expected = 2 * n + 2;
    if (slot.sequence.load(std::memory_order_acquire) != expected) return false;
    // The slot's bytes as bytes: a writer in another process may change them meanwhile (then
    // the sequence below says so), and the copy is not trusted until check_update passed it.
    Copy::copy(static_cast<void*>(&out), static_cast<const void*>(&slot.update), sizeof(Update));
    seqlock_read_fence();  // the copy before the second read
    return slot.sequence.load(std::memory_order_relaxed) == expected;
  }
  /// Loop: the updates before number `n` are taken (their slots may be written again).
  void release(std::uint64_t n) noexcept { tail_.store(n, std::memory_order_release); }
  /// Loop: the last update applied was the application's number `sequence`.
  void report_applied(std::uint64_t sequence) noexcept { applied_.store(sequence, std::memory_order_release); }
  /// Loop: it has refused `count` updates so far.
  void report_refused(std::uint64_t count) noexcept { refused_.store(count, std::memory_order_release); }

 private:
  friend struct ForgeAccess;
  struct Slot {
    std::atomic<std::uint64_t> sequence{0};  ///< odd: being written; 2 (n + 1): holds update n
    Update update{};
  };
  std::array<Slot, kCapacity> slots_{};
  alignas(64) std::atomic<std::uint64_t> head_{0};  ///< written by the application
  alignas(64) std::atomic<std::uint64_t> tail_{0};  ///< written by the loop (never read back by it)
  alignas(64) std::atomic<std::uint64_t> applied_{0};
  std::atomic<std::uint64_t> refused_{0};
};

/// The mailbox of one loop's scene updates.
template <LiveSceneType SceneT, std::size_t kCapacity = 4>
using SceneMailbox = UpdateMailbox<SceneUpdate<SceneT>, kCapacity>;

/// How the loop copies an update's bytes out of the mailbox: a memcpy. A specialisation for a
/// scene type of its own lets a test play a writer that changes the slot during the copy.
template <class SceneT>
struct SceneUpdateCopy {
  static void copy(void* to, const void* from, std::size_t n) noexcept { std::memcpy(to, from, n); }
};

/// Checks `raw`, an update copied out of the mailbox (any bytes), against `current`, the scene
/// the loop renders, and leaves in `out` the update the loop may apply: true only if all of it
/// passed. Its scene is rebuilt from `raw`'s effects (RuntimeSceneOf::assign_checked: kinds,
/// indices, counts and offsets within capacity, every parameter finite and in its scene-file
/// range); `continues[i]` is -1 or an effect of its kind in `current`; at most kMaxEvents
/// events, each for an effect of the new scene that has that event, with a finite value S
/// holds. The sequence is taken as a number, nothing more. Bounded work, no allocation.
template <LiveSceneType SceneT>
bool check_update(const SceneUpdate<SceneT>& raw, const SceneT& current, SceneUpdate<SceneT>& out) noexcept {
  using Update = SceneUpdate<SceneT>;
  if (!out.scene.assign_checked(raw.scene)) return false;
  if (!out.scene.continues_ok(current, raw.continues.data())) return false;
  out.continues = raw.continues;
  for (std::size_t i = out.scene.effect_count(); i < Update::kMaxEffects; ++i) out.continues[i] = -1;
  if (raw.event_count > Update::kMaxEvents) return false;
  // Bounded by the capacity as well: the events are never read past their end.
  const std::size_t events = raw.event_count < Update::kMaxEvents ? raw.event_count : Update::kMaxEvents;
  for (std::size_t i = 0; i < events; ++i) {
    const SceneEvent& e = raw.events[i];
    if (!out.scene.takes_event(e.effect, e.event, e.value)) return false;
    out.events[i] = e;
  }
  out.event_count = static_cast<std::uint8_t>(events);
  out.sequence = raw.sequence;
  return true;
}

/// The loop's side of a mailbox, kept in the loop's own memory: its index of the next update
/// (never read back from the mailbox), the copy it takes and the update it checked.
template <LiveSceneType SceneT, std::size_t kCapacity = 4>
class SceneIntake {
 public:
  using Mailbox = SceneMailbox<SceneT, kCapacity>;
  using Update = SceneUpdate<SceneT>;
  enum class Taken : std::uint8_t {
    kNone,     ///< nothing announced
    kChecked,  ///< update() is an update to apply
    kRefused,  ///< torn, or it failed check_update: taken off, not to be applied
  };

  /// Loop, at most once a tick: if the producer announces an update (its index differs from
  /// this intake's), copies the next one out (its slot is free again at once), checks it
  /// against `current` and says what came of it. Without an announced update it reads one
  /// index and returns. Never waits: a torn copy is refused, not retried.
  Taken take(Mailbox& mailbox, const SceneT& current) noexcept {
    if (mailbox.announced() == next_) return Taken::kNone;
    const bool whole = mailbox.template copy_out<SceneUpdateCopy<SceneT>>(next_, copy_);
    ++next_;
    mailbox.release(next_);
    if (!whole || !check_update(copy_, current, checked_)) {
      ++refused_;
      mailbox.report_refused(refused_);
      return Taken::kRefused;
    }
    return Taken::kChecked;
  }
  /// A new mailbox: its first update is the next (the refused count goes on).
  void restart() noexcept { next_ = 0; }
  /// After kChecked: the update to apply.
  const Update& update() const noexcept { return checked_; }
  /// Updates refused so far.
  std::uint64_t refused() const noexcept { return refused_; }

 private:
  std::uint64_t next_ = 0;  ///< the number of the next update to take
  std::uint64_t refused_ = 0;
  Update copy_{};
  Update checked_{};
};

}  // namespace toonforce
