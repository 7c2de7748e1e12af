// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A real-time run of a servo loop on a device (`toonforce run`, the examples): the loop ticks
/// on the device's clock (the host's timer or the device's own thread, realtime_runner.hpp);
/// after each tick one telemetry frame goes into a lock-free ring, and a writer thread hands the
/// frames, in order, to a `FrameConsumer` (a trace, the live viewer, messages): the servo
/// thread never waits on them, and a full ring drops frames and counts them. SIGINT and SIGTERM
/// stop the run with zero force first; on a terminal, 'r' re-arms and 'q' stops.
///
///   auto report = run_loop(loop, driver, consumer, options);

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <memory>

#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/control/telemetry.hpp"
#include "toonforce/hal/device.hpp"

namespace toonforce {

/// Where the frames of a run go; called from the writer thread only, in tick order.
class FrameConsumer {
 public:
  FrameConsumer() = default;
  FrameConsumer(const FrameConsumer&) = delete;
  FrameConsumer& operator=(const FrameConsumer&) = delete;
  virtual void consume(const TelemetryFrame& frame) = 0;
  /// No frame follows.
  virtual void finish() {}

 protected:
  ~FrameConsumer() = default;
};

struct SessionOptions {
  RealtimeOptions realtime;
  bool handle_signals = true;    ///< SIGINT/SIGTERM stop the run; fatal signals zero the force
  bool interactive = true;       ///< read 'r' (re-arm) and 'q' (stop) from stdin if it is a terminal
  std::FILE* messages = stderr;  ///< where "type q and Enter" goes
  /// A stop that came before the session's handlers were in place (the command's own stop
  /// flag, tools/run/command_stop.hpp): if set, the run stops at its first tick, with zero force.
  const std::atomic<int>* pending_stop = nullptr;
};

struct SessionReport {
  RunReport report;
  std::uint64_t frames_dropped = 0;  ///< the ring was full: frames the consumer never saw
  bool interactive = false;          ///< stdin was a terminal and 'r'/'q' were read
};

/// The stop value of a 'q' typed on the terminal (signals use their own numbers).
inline constexpr int kStopByUser = 1000;

/// Stops the running session as its stop signals do (`signal` is reported as the one that
/// stopped it; the first stop wins): from another thread of a program that handles its signals
/// itself, e.g. the Python module on Ctrl-C or an exception (handle_signals false). Together
/// with `pending_stop`, which covers a stop asked before the session starts.
void request_session_stop(int signal) noexcept;

/// 16384 frames: 1.6 s of telemetry at 10 kHz, 16 s at 1 kHz, before the writer must catch up.
using TelemetryRing = SpscRing<TelemetryFrame, 16384>;

/// A servo loop as the runner's task: tick, one frame into the ring, zero force at the end.
/// Everything here runs on the servo thread: no allocation, no lock, no blocking.
template <class Loop>
class LoopTask final : public PeriodicTask {
 public:
  LoopTask(Loop& loop, TelemetryRing& ring) noexcept : loop_(loop), ring_(ring) {}
  void tick(std::int64_t k) noexcept override { static_cast<void>(loop_.tick(k)); }
  void publish(std::int64_t, const TickTiming& timing) noexcept override {
    loop_.fill_frame(frame_);
    frame_.timing = timing;
    missed_ = timing.missed_total;
    static_cast<void>(ring_.push(frame_));  // a full ring drops and counts, never waits
  }
  void shutdown(std::int64_t k) noexcept override {
    static_cast<void>(loop_.shutdown(k));  // zero force before anything else
    loop_.fill_frame(frame_);
    frame_.timing = TickTiming{};
    frame_.timing.missed_total = missed_;
    last_frame_ready_ = true;
  }
  /// The shutdown frame, for the session to deliver once the servo thread is done.
  bool last_frame(TelemetryFrame& out) const noexcept {
    if (!last_frame_ready_) return false;
    out = frame_;
    return true;
  }

 private:
  Loop& loop_;
  TelemetryRing& ring_;
  TelemetryFrame frame_{};
  std::int64_t missed_ = 0;
  bool last_frame_ready_ = false;
};

/// How the session asks the loop to re-arm ('r' on the terminal).
struct RearmRequest {
  void (*request)(void* loop) noexcept = nullptr;
  void* loop = nullptr;
};

/// The writer thread's side of a session: what the servo thread queued, taken in tick order
/// and handed on (a trace, the viewer, messages). Called from the writer thread only.
class FrameDrain {
 public:
  FrameDrain() = default;
  FrameDrain(const FrameDrain&) = delete;
  FrameDrain& operator=(const FrameDrain&) = delete;
  /// Takes one queued frame and hands it on; false when the queue was empty.
  virtual bool drain_one() = 0;
  /// After the servo thread is done: its shut-down frame, if it made one; then no frame follows.
  virtual void finish() = 0;
  /// Frames the queue had no room for.
  virtual std::uint64_t dropped() const noexcept = 0;

 protected:
  ~FrameDrain() = default;
};

/// The non-template part: signals, the writer and command threads, the runner. `device` gives
/// the clock (run_on_device) and the emergency zero of the watchdog and the signal handlers
/// (several devices: one DeviceDriver that zeroes every one).
Result<SessionReport> run_session(PeriodicTask& task, FrameDrain& drain, DeviceDriver& device,
                                  const SessionOptions& options, RearmRequest rearm);

/// A ring of frames of type Frame into a consumer with `consume(const Frame&)` and `finish()`;
/// `last` gives the shut-down frame (or nullptr).
template <class Frame, std::size_t Capacity, class Consumer, class Last>
class RingDrain final : public FrameDrain {
 public:
  RingDrain(SpscRing<Frame, Capacity>& ring, Consumer& consumer, Last last)
      : ring_(ring), consumer_(consumer), last_(last) {}
  bool drain_one() override {
    if (!ring_.pop(frame_)) return false;
    consume(frame_);
    return true;
  }
  void finish() override {
    if (const Frame* f = last_()) consume(*f);
    consumer_.finish();
  }
  std::uint64_t dropped() const noexcept override { return ring_.dropped(); }

 private:
  /// A message the consumer cannot write (standard error a closed pipe: fmt throws) must not end
  /// the process from the writer thread (std::terminate): the frame's message is lost, the run
  /// and the trace go on.
  void consume(const Frame& f) noexcept {
    try {
      consumer_.consume(f);
    } catch (...) {  // NOLINT(bugprone-empty-catch): nothing left to say it on
    }
  }
  SpscRing<Frame, Capacity>& ring_;
  Consumer& consumer_;
  Last last_;
  Frame frame_{};
};

/// Runs `loop` (a ServoLoop on `device`, built and configured by the caller) until
/// options.realtime.deadlines periods have passed or a signal or 'q' stops it.
template <class Loop>
Result<SessionReport> run_loop(Loop& loop, DeviceDriver& device, FrameConsumer& consumer,
                               const SessionOptions& options) {
  auto ring = std::make_unique<TelemetryRing>();  // allocated before the servo thread starts
  auto task = std::make_unique<LoopTask<Loop>>(loop, *ring);
  auto frame = std::make_unique<TelemetryFrame>();
  const auto last = [t = task.get(), f = frame.get()]() -> const TelemetryFrame* {
    return t->last_frame(*f) ? f : nullptr;
  };
  RingDrain<TelemetryFrame, TelemetryRing::kCapacity, FrameConsumer, decltype(last)> drain(*ring, consumer, last);
  const RearmRequest rearm{[](void* l) noexcept { static_cast<Loop*>(l)->request_rearm(); }, &loop};
  return run_session(*task, drain, device, options, rearm);
}

}  // namespace toonforce
