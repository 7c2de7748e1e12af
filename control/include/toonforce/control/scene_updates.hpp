#pragma once
/// Live scenes (issue 19; docs/spec/live-scenes.md): how an application's thread changes the
/// scene a running servo loop renders.
///
/// An update is a whole scene, already checked by the application's side (config/
/// scene_editor.hpp checks it with the scene files' rules), with what the loop needs to carry
/// the effects' states over and the one-shot events to fire. The application pushes it into a
/// `SceneMailbox`, a single-producer single-consumer queue of fixed capacity, wait-free on
/// both sides: the application never blocks the loop and the loop never waits. The loop takes
/// at most one update at the start of a tick (bounded work: a copy of the scene) and applies it
/// whole before the scene's force, so a tick sees either the old scene or the new one, never
/// half of each. A full mailbox refuses the push: the caller learns it and may try again (the
/// loop takes one update a tick, so that is also the rate limit).
///
/// Nothing here allocates; the mailbox is sized at start-up.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <concepts>

#include "toonforce/effects/scene.hpp"

namespace toonforce {

/// A scene a live loop can take updates of: a run-time scene (RuntimeSceneOf), whose effects
/// carry their states over and take events.
template <class T>
concept LiveSceneType = SceneType<T> && requires(const T& scene, const typename T::State& from, typename T::State& s,
                                                 const std::int16_t* continues) {
  { T::kMaxEffects } -> std::convertible_to<std::size_t>;
  scene.carry(from, s, continues);
  { scene.fire(s, std::size_t{}, std::size_t{}, 0.0, Instant{}) } -> std::same_as<bool>;
};

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

/// The wait-free queue from one application thread to the servo loop.
template <LiveSceneType SceneT, std::size_t kCapacity = 4>
class SceneMailbox {
 public:
  using Update = SceneUpdate<SceneT>;
  static_assert(kCapacity >= 1);

  /// Application thread: copies `u` in (a scene's parameters: fixed arrays, no allocation); false (nothing pushed) when the loop has not yet taken
  /// the updates before it.
  bool push(const Update& u) noexcept {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) == kCapacity) return false;
    slots_[head % kCapacity] = u;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  /// Loop thread: the oldest update not taken yet, or null. Valid until `pop()`.
  const Update* front() const noexcept {
    const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return nullptr;
    return &slots_[tail % kCapacity];
  }
  /// Loop thread: done with front(); `applied` is what the loop made of it (its sequence).
  void pop(std::uint64_t applied) noexcept {
    applied_.store(applied, std::memory_order_release);
    tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }
  /// Any thread: the sequence of the last update the loop applied (0: none yet).
  std::uint64_t applied() const noexcept { return applied_.load(std::memory_order_acquire); }
  /// Any thread: updates pushed and not yet taken.
  std::size_t pending() const noexcept {
    return static_cast<std::size_t>(head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire));
  }
  static constexpr std::size_t capacity() noexcept { return kCapacity; }

 private:
  std::array<Update, kCapacity> slots_{};
  alignas(64) std::atomic<std::uint64_t> head_{0};  ///< written by the application
  alignas(64) std::atomic<std::uint64_t> tail_{0};  ///< written by the loop
  alignas(64) std::atomic<std::uint64_t> applied_{0};
};

}  // namespace toonforce
