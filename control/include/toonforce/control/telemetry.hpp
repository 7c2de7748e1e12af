// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Telemetry from the servo thread: one `TelemetryFrame` per tick, in double and SI units, and
/// `SpscRing`, the fixed-capacity lock-free single-producer/single-consumer ring that carries
/// the frames to a writer thread. A full ring drops the frame and counts it: the loop never
/// blocks, never allocates, never takes a lock, and no frame is lost silently.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <new>
#include <type_traits>

#include "toonforce/math/vec3.hpp"

namespace toonforce {

/// Timing of one tick as the real-time runner measured it [ns].
struct TickTiming {
  std::int64_t wake_latency_ns = 0;  ///< wake-up time minus the deadline
  std::int64_t compute_ns = 0;       ///< the tick itself, device I/O included
  std::int64_t slack_ns = 0;         ///< the next deadline minus the end of this tick (< 0: overran)
  std::int64_t missed_total = 0;     ///< deadlines skipped since the start
};

/// The most effect values a frame carries (what the scene's effects show, in order:
/// SceneType::effect_info names them). A scene file's reader refuses a scene that shows more.
inline constexpr std::size_t kMaxEffectValues = 64;

/// One tick of the servo loop, scene frame, SI units.
struct TelemetryFrame {
  double t_s = 0.0;  ///< tick * period
  std::int64_t tick = 0;
  Vec3<double> position_m;  ///< HIP as the controller saw it
  Vec3<double> velocity_m_per_s;
  Vec3<double> force_n;            ///< commanded, after the whole safety layer
  Vec3<double> scene_force_n;      ///< the scene's force before it
  Vec3<double> damping_n;          ///< the passivity controller's damping (before ramp and limits)
  std::uint32_t faults = 0;        ///< Fault bits of this tick (latched ones included)
  std::uint32_t latched = 0;       ///< latched Fault bits
  std::uint8_t limits = 0;         ///< Limit bits
  std::uint8_t state = 0;          ///< LoopState
  bool in_contact = false;         ///< the HIP touches some effect's geometry
  double max_force_n = 0.0;        ///< the clamp in force (thermal derating included)
  double temperature = 0.0;        ///< thermal model, 0 cold, 1 rated
  double observed_energy_j = 0.0;  ///< Hannaford-Ryu E_obs (>= 0 passive)
  double episode_energy_j = 0.0;   ///< largest active-effect episode energy
  double gain = 0.0;               ///< soft-start gain 0..1
  TickTiming timing;
  std::uint16_t value_count = 0;  ///< of `values` in use
  /// The effects' values (effects/effect.hpp kValues: "surface1.impact_t", "cliff1.state", ...).
  std::array<double, kMaxEffectValues> values{};
};
static_assert(std::is_trivially_copyable_v<TelemetryFrame>);

/// Fixed-capacity lock-free ring for one producer thread and one consumer thread.
/// `Capacity` is a power of two; the storage is inside the object (allocate the ring once, at
/// start-up, e.g. with std::make_unique). push() and pop() are wait-free.
template <class T, std::size_t Capacity>
class SpscRing {
  static_assert(Capacity >= 2 && (Capacity & (Capacity - 1)) == 0, "capacity must be a power of two");
  static_assert(std::is_trivially_copyable_v<T>);

 public:
  static constexpr std::size_t kCapacity = Capacity;

  /// Producer: copies `item` in, or counts a drop and returns false when full. Its indices are
  /// in the ring: with a consumer that cannot be trusted with them, use push(item, producer).
  /// Even then the slot written is within the ring (an index modulo the capacity).
  bool push(const T& item) noexcept {
    if (try_push(item)) return true;
    dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    return false;
  }
  /// Producer: like push() but a full ring is not counted as a drop (the caller retries).
  bool try_push(const T& item) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_cache_ == Capacity) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head - tail_cache_ == Capacity) return false;
    }
    slots_[head & (Capacity - 1)] = item;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  /// The producer's own indices, for a ring whose consumer is another process that may write
  /// any bytes into the ring (the viewer's server process: its frame ring is in memory the two
  /// share). Kept in the producer's memory, never in the ring; push(item, producer) reads only
  /// tail_ from the ring, as a hint.
  struct Producer {
    std::size_t head = 0;        ///< the next item's number
    std::size_t tail_cache = 0;  ///< the consumer's index as last read
    std::uint64_t dropped = 0;   ///< items dropped because the ring was (or said it was) full
  };
  /// Producer: push() with the producer's indices in `p`. The slot written is `p.head` modulo
  /// the capacity whatever the ring's bytes say; a consumer index the producer has not reached
  /// or that lags by more than the capacity reads as a full ring (the item is dropped and
  /// counted in `p`). The consumer may lose its own frames, nothing more.
  bool push(const T& item, Producer& p) noexcept {
    if (p.head - p.tail_cache >= Capacity) {
      p.tail_cache = tail_.load(std::memory_order_acquire);
      if (p.head - p.tail_cache >= Capacity) {
        ++p.dropped;
        return false;
      }
    }
    slots_[p.head & (Capacity - 1)] = item;
    ++p.head;
    head_.store(p.head, std::memory_order_release);
    return true;
  }

  /// Consumer: moves the oldest item into `out`, or returns false when empty.
  bool pop(T& out) noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_cache_) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (tail == head_cache_) return false;
    }
    out = slots_[tail & (Capacity - 1)];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  /// Frames dropped because the ring was full (any thread may read it).
  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }
  /// Frames pushed so far (any thread; approximate while the producer runs).
  std::size_t pushed() const noexcept { return head_.load(std::memory_order_relaxed); }

 private:
  // Producer and consumer indices on their own cache lines, so they do not false-share.
  static constexpr std::size_t kLine = 64;
  alignas(kLine) std::atomic<std::size_t> head_{0};  ///< next slot to write (producer)
  std::size_t tail_cache_ = 0;                       ///< producer's last view of tail_
  std::atomic<std::uint64_t> dropped_{0};
  alignas(kLine) std::atomic<std::size_t> tail_{0};  ///< next slot to read (consumer)
  std::size_t head_cache_ = 0;                       ///< consumer's last view of head_
  alignas(kLine) std::array<T, Capacity> slots_{};
};

}  // namespace toonforce
