// SPDX-License-Identifier: Apache-2.0
// `run --view`'s server process (server_process.hpp).
#include "server_process.hpp"

#include <fcntl.h>
#include <grp.h>
#include <linux/capability.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <thread>

#include <fmt/format.h>

#include "commands.hpp"
#include "server_sandbox.hpp"
#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/control/servo_session.hpp"
#include "toonforce/control/guardian.hpp"
#include "toonforce/control/server_channel.hpp"
#include "viewer_support.hpp"

namespace toonforce::cli {

namespace {

static_assert(viewer::kViewStride <= kMaxEffectValues, "a world's page row travels in a frame's values");

void sleep_ms(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

/// Right after the fork: let go of what the loop's process holds and a server must not. A
/// parser bug handed to an attacker then finds none of it: the guardian's page (whose heartbeat
/// and zero-force recipe it could forge), the loop's descriptors (the device, the trace, the
/// pidfd), the loop's protection from the OOM killer. Empty, or why not (the server does not
/// start).
std::string let_go_of_the_loops(const ServerSetup& setup) {
  for (const DroppedMapping& m : setup.dropped_mappings) {
    if (m.address != nullptr && munmap(m.address, m.length) != 0) {
      return fmt::format("viewer: its server process cannot unmap the loop's shared memory: {}", std::strerror(errno));
    }
  }
  // Every descriptor but the standard streams, before it opens its socket.
  if (close_range(3, ~0U, 0) != 0) {
    if (errno != ENOSYS)
      return fmt::format("viewer: its server process cannot close its descriptors: {}", std::strerror(errno));
    rlimit files{};
    getrlimit(RLIMIT_NOFILE, &files);
    for (rlim_t fd = 3; fd < files.rlim_cur; ++fd) close(static_cast<int>(fd));  // a kernel before 5.9
  }
  // Under memory pressure the OOM killer takes this process first, never the loop's for it (a
  // service lowers the whole group's score: OOMScoreAdjust). Raising one's own needs no right.
  const int fd = open("/proc/self/oom_score_adj", O_WRONLY | O_CLOEXEC);
  const bool written = fd >= 0 && write(fd, "1000", 4) == 4;
  const int saved = errno;
  if (fd >= 0) close(fd);
  if (!written)
    return fmt::format("viewer: its server process cannot raise its oom_score_adj: {}", std::strerror(saved));
  return {};
}

/// Sets the effective and permitted capabilities to `keep` (bits of CAP_*) of those it has.
void keep_capabilities(std::uint64_t keep) {
  __user_cap_header_struct header{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct data[2] = {};
  syscall(SYS_capget, &header, data);
  for (int i = 0; i < 2; ++i) {
    const auto bits = static_cast<std::uint32_t>(keep >> (32 * i));
    data[i].effective &= bits;
    data[i].permitted &= bits;
    data[i].inheritable = 0;
  }
  syscall(SYS_capset, &header, data);
}

/// No more privilege than a web server needs: no real-time priority, no locked memory, no
/// capability (a binary given cap_sys_nice/cap_ipc_lock for the loop passes them to a fork),
/// no_new_privs. Until its socket is bound it keeps, if it has them, binding a port below 1024
/// and changing its user (started as root); become_server() drops them.
void drop_privileges() {
  const rlimit none{0, 0};
  setrlimit(RLIMIT_RTPRIO, &none);
  setrlimit(RLIMIT_MEMLOCK, &none);
  keep_capabilities((1ULL << CAP_NET_BIND_SERVICE) | (1ULL << CAP_SETUID) | (1ULL << CAP_SETGID));
  prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0);
}

/// Once it listens, before it serves (ViewerOptions::before_serving): another user when it was
/// started as root, no capability left, and the seccomp filter. Empty, or why not (it then
/// does not serve).
std::string become_server(const ServerSetup& setup, pid_t loop) {
  if (setup.user) {
    const ServerUser& u = *setup.user;
    // Groups first: setuid() takes the right to change them.
    if (setgroups(0, nullptr) != 0 || setgid(u.gid) != 0 || setuid(u.uid) != 0 || getuid() != u.uid ||
        geteuid() != u.uid || getgid() != u.gid || getegid() != u.gid) {
      return fmt::format("viewer: its server process cannot become user {} (--server-user): {}", u.name,
                         std::strerror(errno));
    }
    // A change of credentials clears the parent-death signal: set it again.
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != loop) _exit(0);
  }
  keep_capabilities(0);
  if (std::string bad = install_server_filter(); !bad.empty()) {
    return fmt::format("viewer: its server process cannot install its seccomp filter: {}", bad);
  }
  return {};
}

/// The server process's life; returns its exit status.
int serve(ServerChannel& ch, const ServerSetup& setup, pid_t loop) {
  // During the run, stop signals are the loop's business (a terminal's Ctrl-C reaches this
  // process too): ignored here until the run is over.
  for (const int signo : stop_signals()) signal(signo, SIG_IGN);
  signal(SIGPIPE, SIG_IGN);
  viewer::ViewerOptions vo = setup.viewer;
  vo.before_serving = [&setup, loop] { return become_server(setup, loop); };
  LiveMailboxes live;
  std::unique_ptr<viewer::SceneControl> control;
  if (setup.control) {
    auto opened = setup.world ? open_world_control(setup.scene_text, setup.scene_name, live, ch.mailbox)
                              : open_live_control(setup.scene_text, setup.scene_name, setup.scalar, live, ch.mailbox);
    if (!opened) {
      fmt::print(stderr, "--control: {}\n", opened.error());
      ch.state.store(2);
      return 2;
    }
    control = std::move(opened.value());
    vo.control = control.get();
  }
  auto started = start_viewer(vo, setup.hello);
  if (!started) {
    fmt::print(stderr, "{}\n", started.error());
    ch.state.store(2);
    return 2;
  }
  std::unique_ptr<viewer::ViewerServer> server = std::move(started.value());
  if (setup.control) {
    std::string url = server->url();
    url.replace(0, 4, "ws");  // http://HOST:PORT/ -> ws://HOST:PORT/
    fmt::print(stderr, "control: {}control, token {}{}\n", url, vo.control_options.token, setup.token_note);
    std::fflush(stderr);
  }
  std::atomic<int> done{0};
  std::thread waiter;
  if (setup.control) {
    waiter = std::thread([&] {
      if (server->wait_for_control(done)) ch.control_ready.store(1);
    });
  }
  ch.state.store(1);
  TelemetryFrame f;
  int over = 0;
  // A world's frames come as the page's rows already (world_view.hpp), in the frame's values.
  const bool world = !setup.hello.world_columns.empty();
  viewer::ViewFrame row{};
  for (;;) {
    while (ch.frames.pop(f)) {
      if (!world) {
        server->publish(f);
        continue;
      }
      std::copy_n(f.values.begin(), row.size(), row.begin());
      server->publish(row);
    }
    if (over != 0) break;
    over = ch.run_over.load(std::memory_order_acquire);  // then one more drain
    if (over == 0) {
      if (getppid() != loop) break;  // the loop process is gone (PDEATHSIG races its end)
      sleep_ms(2);
    }
  }
  done.store(1);
  if (waiter.joinable()) waiter.join();
  server->finish();
  if (over == 1) {
    for (const int signo : stop_signals()) signal(signo, SIG_DFL);
    serve_until_stopped(*server, "the run is over");
  }
  server.reset();
  return 0;
}

}  // namespace

class ServerProcess::Sink final : public TelemetrySink {
 public:
  explicit Sink(ServerProcess& p) : process_(p) {}
  void publish(const TelemetryFrame& frame) noexcept override {
    if (gone_) return;
    // The ring is in memory the server process can write: the producer's indices are kept
    // here (a forged head or tail can cost the page frames, nothing more); full: dropped.
    static_cast<void>(process_.channel_->frames.push(frame, producer_));
    if ((++count_ & 255U) == 0) check();
  }
  void finish() noexcept override {}  // ServerProcess::finish() says how the serving ends
  /// Whether the server process ended (reaped here, on the writer thread, where the loop never
  /// waits); says so once.
  void check() noexcept {
    int status = 0;
    if (gone_ || waitpid(process_.pid_, &status, WNOHANG) != process_.pid_) return;
    gone_ = true;
    status_ = status;
    std::fprintf(stderr, "viewer: the server process (pid %d) %s during the run; the loop goes on without the viewer\n",
                 static_cast<int>(process_.pid_), guardian::describe_wait_status(status).c_str());
    std::fflush(stderr);
  }
  std::atomic<bool> gone_{false};
  int status_ = 0;

 private:
  ServerProcess& process_;
  std::uint64_t count_ = 0;
  decltype(ServerChannel::frames)::Producer producer_{};
};

Result<std::unique_ptr<ServerProcess>> ServerProcess::start(const ServerSetup& setup) {
  std::unique_ptr<ServerProcess> p(new ServerProcess());
  p->channel_bytes_ = kServerChannelBytes;
  void* memory = mmap(nullptr, p->channel_bytes_, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (memory == MAP_FAILED)
    return Error{fmt::format("viewer: cannot map the memory shared with its server: {}", std::strerror(errno))};
  p->channel_ = new (memory) ServerChannel{};
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t loop = getpid();
  const pid_t child = fork();
  if (child < 0) return Error{fmt::format("viewer: cannot start its server process: {}", std::strerror(errno))};
  if (child == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);  // it holds nothing that needs an orderly end
    if (getppid() != loop) _exit(0);
    if (std::string bad = let_go_of_the_loops(setup); !bad.empty()) {
      fmt::print(stderr, "{}\n", bad);
      p->channel_->state.store(2);
      _exit(2);
    }
    drop_privileges();
    const int status = serve(*p->channel_, setup, loop);
    std::fflush(stdout);
    std::fflush(stderr);
    _exit(status);  // never back into the loop process's code
  }
  p->pid_ = child;
  p->sink_ = std::make_unique<Sink>(*p);
  while (p->channel_->state.load() == 0) {
    int status = 0;
    if (waitpid(child, &status, WNOHANG) == child) {
      p->pid_ = -1;
      return Error{
          fmt::format("viewer: its server process {} before it listened", guardian::describe_wait_status(status))};
    }
    sleep_ms(2);
  }
  if (p->channel_->state.load() == 2) {
    int status = 0;
    waitpid(child, &status, 0);
    p->pid_ = -1;
    return Error{std::string()};  // it said why
  }
  if (setup.control && setup.world) {
    p->live_.of_world = static_cast<WorldMailbox<RuntimeScene<double>>*>(static_cast<void*>(p->channel_->mailbox));
  } else if (setup.control) {
    void* mailbox = p->channel_->mailbox;
    with_scalar(
        setup.scalar,
        [&]<Scalar S>() {
          auto* m = static_cast<SceneMailbox<RuntimeScene<S>>*>(mailbox);
          if constexpr (std::same_as<S, double>) {
            p->live_.of_double = m;
          } else if constexpr (std::same_as<S, float>) {
            p->live_.of_float = m;
          } else {
            p->live_.of_q16 = m;
          }
          return 0;
        },
        [](ScalarKind) { return 0; });
  }
  return p;
}

TelemetrySink& ServerProcess::sink() noexcept { return *sink_; }

bool ServerProcess::wait_for_control(const std::atomic<int>& stop) const {
  while (stop.load() == 0) {
    if (channel_->control_ready.load() != 0) return true;
    sink_->check();
    if (sink_->gone_) return false;
    sleep_ms(5);
  }
  return false;
}

void ServerProcess::finish(bool keep_serving) {
  if (pid_ < 0) return;
  channel_->run_over.store(keep_serving ? 1 : 2, std::memory_order_release);
  if (!sink_->gone_) {
    // Serving the recording: this process's stop signals end it (passed on); a terminal's
    // Ctrl-C reaches the server itself. A server that does not end 2 s after it was told to
    // (hung, stopped) is killed: nothing of the run waits on it.
    install_command_stop_signals();
    int status = 0;
    bool told = !keep_serving;  // to end: run_over 2, or SIGTERM below
    bool killed = false;
    int waited_ms = 0;  // since it was told
    while (waitpid(pid_, &status, WNOHANG) != pid_) {
      if (!told && command_stop().load() != 0) {
        kill(pid_, SIGTERM);
        told = true;
      }
      if (told && !killed && waited_ms >= 2000) {
        fmt::print(stderr, "viewer: its server process (pid {}) did not end within 2 s; killed\n", pid_);
        kill(pid_, SIGKILL);
        killed = true;
      }
      sleep_ms(20);
      if (told) waited_ms += 20;
    }
    restore_command_stop_signals();
  }
  pid_ = -1;
}

std::string ServerProcess::ended_early() const {
  return sink_ && sink_->gone_ ? guardian::describe_wait_status(sink_->status_) : std::string();
}

ServerProcess::~ServerProcess() {
  finish(false);
  if (channel_ != nullptr) munmap(channel_, channel_bytes_);
}

}  // namespace toonforce::cli
