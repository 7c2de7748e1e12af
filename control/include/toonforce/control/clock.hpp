// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The loop's time (spec effects.md §0): integer ticks on a fixed period, so a loop that has run
/// for a day computes dt exactly as in its first second, and a skipped tick gives dt = 2T. A
/// replayed recording instead carries each row's own time stamp (`time_from_stamps`): dt is the
/// difference of consecutive stamps and the effects' times are stamp differences.

#include <cstdint>

#include "toonforce/effects/tick.hpp"

namespace toonforce {

/// One tick's time.
struct TickTime {
  Instant now;                 ///< the tick (and its stamp)
  std::int64_t gap = 1;        ///< periods since the previous tick (1 on the first)
  double period_s = 0.0;       ///< [s] for TickInput: the fixed period, or 0 when times are stamps
  double dt = 0.0;             ///< [s] true time since the previous tick (the period on the first); double-time clocks
  std::int64_t period_ns = 0;  ///< [ns] integer-time clocks: period_s (0 when times are stamps)
  std::int64_t dt_ns = 0;      ///< [ns] integer-time clocks: dt

  constexpr double dt_s() const noexcept { return dt; }
  /// Seconds from `earlier` to this tick, in double (TickInput::seconds_since).
  constexpr double seconds_since(Instant earlier) const noexcept {
    return period_s > 0.0 ? static_cast<double>(now.tick - earlier.tick) * period_s
                          : static_cast<double>(now.stamp_ns - earlier.stamp_ns) / static_cast<double>(kNsPerS);
  }
  /// Integer-time clocks: nanoseconds from `earlier` to this tick (TickInput::ns_since).
  constexpr std::int64_t ns_since(Instant earlier) const noexcept {
    return period_ns > 0 ? (now.tick - earlier.tick) * period_ns : now.stamp_ns - earlier.stamp_ns;
  }
};

/// The loop's clock. `kIntegerTime`: dt and the period in whole nanoseconds instead of double
/// seconds (a fixed-point loop: no floating point on its ticks, so an FPU-less target links
/// none; tools/mcu). The period is rounded to the nanosecond once, here.
template <bool kIntegerTime = false>
class BasicLoopClock {
 public:
  /// `period_s` > 0: the servo period (with stamps: the first tick's dt).
  constexpr BasicLoopClock(double period_s, bool time_from_stamps) noexcept
      : period_s_(period_s), period_ns_(ns_from_seconds(period_s)), stamped_(time_from_stamps) {}

  /// The time of the tick at `now`; a tick that does not come after the last is taken as last + 1.
  constexpr TickTime advance(Instant now) noexcept {
    // The usual tick: the next period of a fixed-period loop.
    if (started_ && !stamped_ && now.tick == last_.tick + 1) {
      last_ = now;
      if constexpr (kIntegerTime) {
        return {now, 1, period_s_, 0.0, period_ns_, period_ns_};
      } else {
        return {now, 1, period_s_, period_s_};
      }
    }
    TickTime t;
    t.period_s = stamped_ ? 0.0 : period_s_;
    if (started_ && now.tick <= last_.tick) now.tick = last_.tick + 1;
    if (started_) t.gap = now.tick - last_.tick;
    t.now = now;
    if constexpr (kIntegerTime) {
      t.period_ns = stamped_ ? 0 : period_ns_;
      t.dt_ns = !started_ ? period_ns_ : stamped_ ? now.stamp_ns - last_.stamp_ns : t.gap * period_ns_;
    } else {
      t.dt = !started_  ? period_s_
             : stamped_ ? static_cast<double>(now.stamp_ns - last_.stamp_ns) / static_cast<double>(kNsPerS)
                        : static_cast<double>(t.gap) * period_s_;
    }
    started_ = true;
    last_ = now;
    return t;
  }

  /// The tick after the last one (for a shutdown tick).
  constexpr Instant next() const noexcept { return Instant{started_ ? last_.tick + 1 : 0, last_.stamp_ns}; }
  constexpr bool started() const noexcept { return started_; }
  /// TickInput::period_s: the fixed period, or 0 when times are stamps.
  constexpr double period_s_for_input() const noexcept { return stamped_ ? 0.0 : period_s_; }
  /// TickInput::period_ns: the fixed period, or 0 when times are stamps.
  constexpr std::int64_t period_ns_for_input() const noexcept { return stamped_ ? 0 : period_ns_; }
  /// [s] the last tick's time: k T on a fixed period, else its stamp.
  constexpr double time_s() const noexcept {
    return stamped_ ? static_cast<double>(last_.stamp_ns) / static_cast<double>(kNsPerS)
                    : static_cast<double>(last_.tick) * period_s_;
  }
  constexpr const Instant& last() const noexcept { return last_; }
  constexpr double period_s() const noexcept { return period_s_; }
  /// [ns] the configured period, rounded once.
  constexpr std::int64_t period_ns() const noexcept { return period_ns_; }

 private:
  double period_s_;
  std::int64_t period_ns_;
  bool stamped_;
  bool started_ = false;
  Instant last_{};
};

using LoopClock = BasicLoopClock<false>;

}  // namespace toonforce
