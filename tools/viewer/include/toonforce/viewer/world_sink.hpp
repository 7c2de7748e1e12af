// SPDX-License-Identifier: Apache-2.0
#pragma once
/// `toonforce sim --view` of a world: the world simulation's rows (WorldRowSink,
/// sim/world_sim.hpp) as the page's frames (WorldViewMap), published to the viewer server and
/// paced to the wall clock as the one-device simulation is (--view-pace: each tick waits until
/// its simulated time has come; the trace is unchanged). Header-only: the viewer library does
/// not depend on the simulation; the programs that have both use it.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "toonforce/sim/world_sim.hpp"
#include "toonforce/viewer/viewer_server.hpp"
#include "toonforce/viewer/world_view.hpp"

namespace toonforce::viewer {

class WorldViewSink final : public WorldRowSink {
 public:
  /// `map` from the same world's columns (world_columns()); `pace` simulated seconds per wall
  /// second (0: as fast as it runs); `stop` non-zero ends a wait at once.
  WorldViewSink(ViewerServer& server, WorldViewMap map, double pace, const std::atomic<int>* stop)
      : server_(server), map_(std::move(map)), pace_(pace), stop_(stop) {}

  void begin(const std::vector<std::string>& /*columns*/, std::int64_t /*ticks*/) override {
    wall_start_ = std::chrono::steady_clock::now();
  }

  void row(const std::vector<double>& values) override {
    const ViewFrame frame = map_.frame(values, static_cast<double>(tick_++));
    server_.publish(frame);
    if (!(pace_ > 0.0) || values.empty()) return;
    const auto due = wall_start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                       std::chrono::duration<double>(values.front() / pace_));
    // In slices, so that a stop is heard within one even at a slow pace.
    while (stop_ == nullptr || stop_->load() == 0) {
      const auto now = std::chrono::steady_clock::now();
      if (now >= due) break;
      std::this_thread::sleep_for(
          std::min<std::chrono::steady_clock::duration>(due - now, std::chrono::milliseconds(20)));
    }
  }

  std::int64_t rows() const noexcept { return tick_; }

 private:
  ViewerServer& server_;
  WorldViewMap map_;
  double pace_;
  const std::atomic<int>* stop_;
  std::chrono::steady_clock::time_point wall_start_ = std::chrono::steady_clock::now();
  std::int64_t tick_ = 0;
};

}  // namespace toonforce::viewer
