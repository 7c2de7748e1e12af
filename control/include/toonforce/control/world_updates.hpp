// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Live scenes of a world (docs/spec/live-scenes.md, "Worlds"): one update carries a new scene
/// for every device of the world (each device's effects: those that act on it), so that a
/// change of an effect several devices feel reaches all of them on the same world tick, never
/// one device a tick before the other.
///
/// The update travels as a single device's does (scene_updates.hpp): an UpdateMailbox in memory
/// that a server process may share and write at any time. The world's side (WorldIntake) keeps
/// its own index, copies the update out under the slot's sequence, and checks it whole against
/// every device's current scene before any device sees any of it: the device count must be the
/// world's, and each device's part must pass check_update against that device's scene. A
/// refused update is counted and changes nothing on any device. The couplings and the ball are
/// not in an update: they stay as the world started (their parameters are the world file's).
///
/// Nothing here allocates; the copies are sized at start-up.

#include <array>
#include <cstddef>
#include <cstdint>

#include "toonforce/control/scene_updates.hpp"

namespace toonforce {

/// The most devices a world update carries (a world's devices: world_file.hpp allows 4).
inline constexpr std::size_t kMaxWorldUpdateDevices = 4;

template <LiveSceneType SceneT>
struct WorldUpdate {
  static constexpr std::size_t kMaxDevices = kMaxWorldUpdateDevices;
  /// Device i's scene, continues and events (its own `sequence` is not read).
  std::array<SceneUpdate<SceneT>, kMaxDevices> devices{};
  /// Must be the world's number of devices.
  std::uint8_t device_count = 0;
  /// The application's number for this update (increasing); the world says which it applied.
  std::uint64_t sequence = 0;
};

template <LiveSceneType SceneT, std::size_t kCapacity = 4>
using WorldMailbox = UpdateMailbox<WorldUpdate<SceneT>, kCapacity>;

/// The world's side of a WorldMailbox, in the loop's own memory: its index of the next update,
/// the copy it takes and the update it checked.
template <LiveSceneType SceneT, std::size_t N, std::size_t kCapacity = 4>
class WorldIntake {
  static_assert(N >= 1 && N <= kMaxWorldUpdateDevices, "a world update carries at most 4 devices");

 public:
  using Mailbox = WorldMailbox<SceneT, kCapacity>;
  using Update = WorldUpdate<SceneT>;
  enum class Taken : std::uint8_t { kNone, kChecked, kRefused };

  /// At most once a world tick: if the producer announces an update, copies the next one out
  /// (its slot is free again at once) and checks it against `current(i)`, device i's scene, for
  /// every device. Never waits: a torn copy is refused, not retried.
  template <class Current>
  Taken take(Mailbox& mailbox, const Current& current) noexcept {
    if (mailbox.announced() == next_) return Taken::kNone;
    const bool whole = mailbox.template copy_out<SceneUpdateCopy<Update>>(next_, copy_);
    ++next_;
    mailbox.release(next_);
    if (!whole || !check(current)) {
      ++refused_;
      mailbox.report_refused(refused_);
      return Taken::kRefused;
    }
    return Taken::kChecked;
  }
  /// After kChecked: the update to apply (its first N devices).
  const Update& update() const noexcept { return checked_; }
  std::uint64_t refused() const noexcept { return refused_; }

 private:
  template <class Current>
  bool check(const Current& current) noexcept {
    if (copy_.device_count != N) return false;
    for (std::size_t i = 0; i < N; ++i) {
      if (!check_update(copy_.devices[i], current(i), checked_.devices[i])) return false;
    }
    checked_.device_count = static_cast<std::uint8_t>(N);
    checked_.sequence = copy_.sequence;
    return true;
  }

  std::uint64_t next_ = 0;
  std::uint64_t refused_ = 0;
  Update copy_{};
  Update checked_{};
};

}  // namespace toonforce
