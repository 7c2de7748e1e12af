// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The live viewer's server: serves the page (its own files only, embedded in the
/// binary) and streams telemetry to it over a WebSocket, from a thread of its own that never
/// runs at real-time priority. Boost.Beast over Boost.Asio (docs/VIEWER.md says why).
///
///   producer thread (run's ring consumer, or sim)   server thread (Asio)        page
///   publish(frame) -> SpscRing (lock-free, drops  -> every batch_interval:   -> one binary
///                     and counts when full)          drain, keep history,       message per
///                                                    send to each page          batch
///
/// Read-only: the socket carries telemetry one way. A page that sends anything is closed with
/// a policy-violation code; no message on it changes the run or the scene. Only /control,
/// when the program asks for it (ViewerOptions::control), takes messages: the control protocol
/// of live scenes, after a hello with the token (docs/spec/control-protocol.md). The WebSocket upgrade is
/// refused (403) unless the Origin header is this server's own origin, and every request is
/// refused (421) unless its Host header names this server: the loopback names, the address
/// given (on 0.0.0.0 or ::, the addresses of this host's interfaces), or a name in
/// ViewerOptions::hosts. That defeats DNS rebinding on every address: a page of another name
/// resolved to this host asks with its own name. Only GET and HEAD of the embedded files.
///
/// A page that reads slower than frames come gets at most `max_queued_batches` live batches
/// queued; older ones are dropped and counted (the page sees the gap in the sequence numbers
/// and the count in the status messages). Nothing the page does can make publish() wait.
///
/// Bounded as a server: at most `max_pages` pages and `max_connections` other
/// connections at once (a slot is taken when the upgrade is read, so a burst cannot overshoot);
/// a page holds one history chunk at a time (kHistoryChunkFrames, made when the one before has
/// been written), never a copy of the whole history; when the last page closes the allocator
/// gives freed memory back. A failing accept (out of descriptors) waits before it tries again.

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/trace/telemetry_sink.hpp"
#include "toonforce/viewer/control_protocol.hpp"
#include "toonforce/viewer/view_frame.hpp"

namespace toonforce::viewer {

inline constexpr std::uint16_t kDefaultPort = 8765;
/// Frames per history message. A page holds one at a time: 1024 frames are 221 kB.
inline constexpr std::size_t kHistoryChunkFrames = 1024;
/// After a failed accept (EMFILE, ENFILE, ENOBUFS, ENOMEM) the server waits this long before it
/// accepts again, doubling up to kAcceptRetryMaxS while it keeps failing.
inline constexpr double kAcceptRetryMinS = 0.05;
inline constexpr double kAcceptRetryMaxS = 1.0;

struct ViewerOptions {
  std::string address = "127.0.0.1";  ///< listen address; another one only when asked for
  /// More names the Host header may give (`--view-host`): DNS names or IP addresses, no port;
  /// e.g. the name other hosts know this one by when it listens on another address.
  std::vector<std::string> hosts;
  std::uint16_t port = kDefaultPort;      ///< 0: a free port (see ViewerServer::port())
  std::size_t history_frames = 1U << 17;  ///< kept for pages that connect late (131 s at 1 kHz)
  double batch_interval_s = 0.02;         ///< frames go out in batches this often (50 Hz)
  std::size_t max_queued_batches = 16;    ///< per page, beyond the one being written
  std::size_t max_pages = 16;             ///< WebSocket pages open at once; more upgrades get 503
  /// HTTP connections (not yet pages) open at once. One more: the connection reading its
  /// request longest is closed to make room if it has been reading for evict_reading_after_s;
  /// else the new one is closed at once.
  std::size_t max_connections = 32;
  double evict_reading_after_s = 1.0;
  int send_buffer_bytes = 0;  ///< SO_SNDBUF of page sockets; 0: the system's (tests set it)
  bool has_loop = true;       ///< the frames come from the servo loop (false: sim)
  /// The option that gave `address`, for messages (`toonforce view` calls it --address).
  std::string address_option = "--view-address";
  /// Live scenes: when set, /control takes the control protocol's messages
  /// (control_protocol.hpp) and drives this; it must outlive the server. Null: no /control.
  SceneControl* control = nullptr;
  ControlOptions control_options;
  std::size_t max_controls = 4;  ///< control connections past their hello at once; a hello beyond is refused (1013)
  /// Control connections that have not said hello yet, apart from those: more upgrades get 503.
  std::size_t max_control_pending = 4;
  double control_hello_deadline_s = 5.0;  ///< a control connection without a hello by then is closed (1008)
  double request_deadline_s = 5.0;        ///< an HTTP connection without a whole request by then is closed
  /// Called once the socket listens, before anything is served: no connection accepted yet,
  /// the server's thread not started. `run --view`'s server process gives up its user and
  /// installs its seccomp filter there (tools/cli/server_process.cpp). Returns why the server
  /// must not start (the error of start()); empty: it starts.
  std::function<std::string()> before_serving;
};

/// Counters for the summary and the tests (any thread).
struct ViewerStats {
  std::uint64_t frames_in = 0;               ///< frames published
  std::uint64_t frames_dropped_ring = 0;     ///< published while the hand-over ring was full
  std::uint64_t frames_dropped_pages = 0;    ///< queued for a page, dropped before it took them
  std::uint64_t pages_connected = 0;         ///< WebSocket connections accepted so far
  std::uint64_t pages_refused = 0;           ///< upgrades refused (origin or host)
  std::uint64_t messages_refused = 0;        ///< pages closed for sending a message
  std::uint64_t control_messages = 0;        ///< control protocol messages received
  std::uint64_t control_refused = 0;         ///< of those, answered with an error
  std::uint64_t controls_authenticated = 0;  ///< control connections whose hello passed
  std::size_t controls_pending = 0;          ///< control connections open now, before their hello
  std::size_t controls_open = 0;             ///< control connections open now, past their hello
  std::uint64_t control_hello_late = 0;      ///< control connections closed for no hello in time
  std::size_t control_bytes = 0;             ///< control replies held now (each being written)
  std::size_t max_control_bytes = 0;         ///< the most control_bytes has been
  std::uint64_t requests_late = 0;           ///< HTTP connections closed for no whole request in time
  std::size_t connections_open = 0;          ///< HTTP connections open now (not pages or control connections)
  std::uint64_t requests_evicted = 0;        ///< HTTP connections still reading, closed to make room for a new one
  std::uint64_t http_refused = 0;            ///< HTTP requests answered 4xx
  std::uint64_t connections_refused = 0;     ///< connections closed on accept: max_connections were open
  std::uint64_t accept_failures = 0;  ///< accepts that failed (no descriptors, no memory), each followed by a wait
  std::size_t max_queued = 0;         ///< the longest live queue any page had
  std::size_t pages_open = 0;         ///< WebSocket connections open now
  std::size_t queued_bytes = 0;       ///< bytes held for pages now (a message shared by pages counts for each)
  std::size_t max_queued_bytes = 0;   ///< the most queued_bytes has been
};

class ViewerServer final : public TelemetrySink {
 public:
  /// Binds and starts the server thread. `hello_json` is the first message every page gets
  /// (make_hello in hello.hpp: the scene, the columns, the run). Errors: the address or port.
  static Result<std::unique_ptr<ViewerServer>> start(const ViewerOptions& options, std::string hello_json);
  /// The same for a whole recording (`toonforce view`): every page gets all of it as history,
  /// and the stream is over from the start (publish nothing).
  static Result<std::unique_ptr<ViewerServer>> start_recording(const ViewerOptions& options, std::string hello_json,
                                                               std::optional<std::vector<ViewFrame>> recording);
  ~ViewerServer();

  /// Producer side (one thread): lock-free, allocation-free, never blocks.
  void publish(const TelemetryFrame& frame) noexcept override;
  void publish(const ViewFrame& frame) noexcept;
  void finish() noexcept override;

  /// Waits until a page has connected, or `stop` becomes non-zero, polling every 50 ms.
  /// True if a page connected.
  bool wait_for_page(const std::atomic<int>& stop) const;
  /// Waits until a control client's hello has passed (the token was right), or `stop` becomes
  /// non-zero, polling every 5 ms. True if one has: `run --control-wait` starts the loop then.
  bool wait_for_control(const std::atomic<int>& stop) const;
  /// Waits until every published frame has been handed to the pages' queues.
  void wait_drained(const std::atomic<int>& stop) const;

  std::uint16_t port() const noexcept;
  /// http://HOST:PORT/ to open (HOST 127.0.0.1 unless another address was given).
  std::string url() const;
  /// Every Host header value a request may carry ("name:port", lower case, sorted).
  std::vector<std::string> host_names() const;
  ViewerStats stats() const noexcept;

  struct Impl;

 private:
  explicit ViewerServer(std::unique_ptr<Impl> impl) noexcept;
  std::unique_ptr<Impl> impl_;
};

}  // namespace toonforce::viewer
