// SPDX-License-Identifier: Apache-2.0
#pragma once
// `run --view`'s server process (docs/DEPLOY.md section 6): the viewer's page
// and the control protocol's server, which parse whatever a local connection sends, run in a
// process of their own, forked by the loop process before it has any thread, device or locked
// memory. That process has no real-time priority and may get none (RLIMIT_RTPRIO 0), locks no
// memory (RLIMIT_MEMLOCK 0), drops every capability and sets no_new_privs; it dies with the loop
// process (PR_SET_PDEATHSIG). A parser bug must not hand an attacker the loop, so it holds only
// its channels and its socket: right after the fork it unmaps the guardian's page
// (ServerSetup::dropped_mappings), closes every descriptor but 0, 1 and 2, and sets its
// oom_score_adj to 1000 (the OOM killer takes it first); started as root, it becomes another
// user (ServerSetup::user, --server-user) once its socket is bound; before it serves, a seccomp
// filter (server_sandbox.hpp) leaves it no open, socket, exec, ptrace or signal to another
// process. It reads no file: the scene's text comes from the loop process, which read it once.
// The two exchange only through memory shared before the fork, which the loop process never
// waits on:
//   - telemetry out: the writer thread pushes each frame into a lock-free ring of 16384 (full: dropped and
//     counted, as the viewer's own ring did); the server process drains it into the page;
//   - scene updates in: the control protocol's editor, in the server process, reads and checks
//     each message and pushes the checked scene into the live-scene mailbox (scene_updates.hpp),
//     placed in the shared memory, which the servo thread reads as before.
// If the server process dies or hangs, the loop goes on (its ring fills and drops, its mailbox
// stays empty) and `run` says so once; the server is not restarted (the page would need the run
// to start again).
#include <sys/types.h>

#include <atomic>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/run/run.hpp"
#include "toonforce/viewer/hello.hpp"
#include "toonforce/viewer/viewer_server.hpp"

namespace toonforce {
struct ServerChannel;
}  // namespace toonforce

namespace toonforce::cli {

/// A mapping of the loop's process (address, length) the server process must not keep.
struct DroppedMapping {
  void* address = nullptr;
  std::size_t length = 0;
};

/// The user the server process runs as when it was started as root (--server-user).
struct ServerUser {
  std::string name;
  uid_t uid = 0;
  gid_t gid = 0;
};

struct ServerSetup {
  viewer::ViewerOptions viewer;  ///< address, port, hosts, control_options (the token); `control` is set in the child
  viewer::HelloInfo hello;
  bool control = false;  ///< --control: /control drives the live scene
  /// The scene the control protocol edits: the text the loop's process read (once: the loop
  /// renders the same text), and the file's name for the editor's messages (file:line: key).
  std::string scene_text;
  std::string scene_name;
  ScalarKind scalar = ScalarKind::kDouble;
  bool world = false;      ///< the scene is a world: its control edits every device's scene at once
  std::string token_note;  ///< appended to the "control: ..." line (e.g. "(random; ...)")
  /// Shared mappings the loop's process holds that the server must not (the guardian's page):
  /// unmapped in the child right after the fork.
  std::vector<DroppedMapping> dropped_mappings;
  /// Set: the user to become once the socket is bound (the loop's process runs as root).
  std::optional<ServerUser> user;
};

class ServerProcess {
 public:
  /// Forks the server process and returns once it listens (it prints its URL) or failed (it
  /// printed why: the error's text is then empty; the command exits 2). Call before this process
  /// starts any thread.
  static Result<std::unique_ptr<ServerProcess>> start(const ServerSetup& setup);
  ~ServerProcess();
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  /// Where the run's writer thread sends frames (never waits).
  TelemetrySink& sink() noexcept;
  /// The live-scene mailbox in the shared memory (--control), for the loop.
  const LiveMailboxes& live() const noexcept { return live_; }
  /// --control-wait: until a control client's hello passed (true), or `stop` is set or the
  /// server process ended (false).
  bool wait_for_control(const std::atomic<int>& stop) const;
  /// The run is over. `keep_serving`: the page keeps the recording until a stop signal (this
  /// process passes its own on); else the server closes now. Waits for the server process.
  void finish(bool keep_serving);
  pid_t pid() const noexcept { return pid_; }
  /// Whether the server process ended before finish(), and how ("killed by SIGKILL").
  std::string ended_early() const;

 private:
  class Sink;
  ServerProcess() = default;
  ServerChannel* channel_ = nullptr;
  std::size_t channel_bytes_ = 0;
  pid_t pid_ = -1;
  LiveMailboxes live_;
  std::unique_ptr<Sink> sink_;
};

}  // namespace toonforce::cli
