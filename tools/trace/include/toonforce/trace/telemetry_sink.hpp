// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Somewhere telemetry frames go besides the trace (the live viewer, tools/viewer). A sink is
/// fed by the thread that already consumes the servo loop's telemetry ring (`toonforce run`'s
/// writer thread) or by the simulation's own thread (`toonforce sim`), never by the servo
/// thread: the loop does no work for it. publish() must not block and must not fail loudly: a
/// sink that falls behind drops frames and counts them.

#include "toonforce/control/telemetry.hpp"

namespace toonforce {

class TelemetrySink {
 public:
  TelemetrySink() = default;
  TelemetrySink(const TelemetrySink&) = delete;
  TelemetrySink& operator=(const TelemetrySink&) = delete;

  /// One frame, in order; called from a single thread for the whole run.
  virtual void publish(const TelemetryFrame& frame) noexcept = 0;
  /// The run is over: no frame follows.
  virtual void finish() noexcept = 0;

 protected:
  ~TelemetrySink() = default;
};

}  // namespace toonforce
