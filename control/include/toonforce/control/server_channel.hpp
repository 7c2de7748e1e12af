// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The memory `run --view` shares with its server process (tools/cli/server_process.hpp): one
/// MAP_SHARED region, mapped by the loop's process before it forks the server. Address-free:
/// atomics, the frame ring and the live-scene (or live world's) mailbox's bytes (a scene's parameters are fixed
/// arrays: no pointer). The server process may write any bytes into all of it at any time: the
/// loop's side keeps its own indices (SpscRing::Producer, the mailbox's consumer index) and
/// copies and checks each update before it applies it (scene_updates.hpp), so the channel can
/// cost the viewer its frames and the control protocol its updates, nothing more.

#include <algorithm>
#include <atomic>
#include <cstddef>

#include "toonforce/control/scene_updates.hpp"
#include "toonforce/control/telemetry.hpp"
#include "toonforce/control/world_updates.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {

struct ServerChannel {
  /// As large as the run's own telemetry ring (servo_session.hpp): 16 s at 1 kHz before a
  /// starved server process loses frames (2048 lost the frames of a fall on a loaded CI host).
  SpscRing<TelemetryFrame, 16384> frames;
  std::atomic<int> state{0};             ///< 0 starting, 1 listening, 2 failed
  std::atomic<int> control_ready{0};     ///< a control client's hello passed
  std::atomic<int> run_over{0};          ///< 1: keep serving the recording, 2: close now
  alignas(64) unsigned char mailbox[1];  ///< the live-scene mailbox (mapped with room for it)

  /// Room for the largest mailbox of the three scalars and of a world (only the run's is
  /// placed there).
  static constexpr std::size_t kMailboxBytes =
      std::max({sizeof(SceneMailbox<RuntimeScene<double>>), sizeof(SceneMailbox<RuntimeScene<float>>),
                sizeof(SceneMailbox<RuntimeScene<Q16_16>>), sizeof(WorldMailbox<RuntimeScene<double>>)});
};
/// The bytes to map: the channel and its mailbox.
inline constexpr std::size_t kServerChannelBytes = sizeof(ServerChannel) + ServerChannel::kMailboxBytes;
static_assert(std::atomic<int>::is_always_lock_free, "shared between processes: lock-free atomics only");

}  // namespace toonforce
