// toonforce run's guardian process (guardian.hpp; docs/DEPLOY.md "Processes").
#include "toonforce/run/guardian.hpp"

#include <fcntl.h>
#include <linux/usbdevice_fs.h>
#include <poll.h>
#include <signal.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>

#include <fmt/format.h>

#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/trace/json.hpp"
#include "toonforce/trace/telemetry_trace.hpp"
#include "toonforce/trace/trace_writer.hpp"

namespace toonforce::guardian {
namespace {

std::int64_t now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Stop signals that reached the guardian, for its loop to pass on (a small ring: the handler
// only stores).
struct Pending {
  int signo;
  bool from_terminal;  ///< the kernel sent it (Ctrl-C): the loop process got it too
  pid_t sender;        ///< si_pid of a signal sent with kill() (0: none)
};
constexpr unsigned kPendingSlots = 16;
Pending g_pending[kPendingSlots];
volatile sig_atomic_t g_pending_count = 0;

extern "C" void on_guardian_signal(int signo, siginfo_t* info, void*) {
  const sig_atomic_t n = g_pending_count;
  if (n >= static_cast<sig_atomic_t>(kPendingSlots)) return;  // a flood: the first ones matter
  const bool from_terminal = info != nullptr && info->si_code == SI_KERNEL;
  const pid_t sender = info != nullptr && info->si_code == SI_USER ? info->si_pid : 0;
  g_pending[n] = Pending{signo, from_terminal, sender};
  g_pending_count = n + 1;
}

int open_pidfd(pid_t pid) noexcept { return static_cast<int>(::syscall(SYS_pidfd_open, pid, 0)); }

/// Claims the interface the dead process held, then one bulk transfer of the zero frame.
bool usb_zero(const ExternalZero& zero, int fd, std::string& detail) {
  unsigned int interface = zero.interface;
  if (::ioctl(fd, USBDEVFS_CLAIMINTERFACE, &interface) != 0 && errno == EBUSY) {
    // A kernel driver (ftdi_sio) took the interface back: detach it and claim in one call.
    usbdevfs_disconnect_claim dc{};
    dc.interface = interface;
    static_cast<void>(::ioctl(fd, USBDEVFS_DISCONNECT_CLAIM, &dc));
  }
  // (usbfs claims an unclaimed interface itself on its first transfer: a failed claim above is
  // not yet a failure.)
  std::uint8_t buffer[sizeof zero.frame];
  std::memcpy(buffer, zero.frame, sizeof buffer);
  usbdevfs_bulktransfer bulk{};
  bulk.ep = zero.endpoint;
  bulk.len = zero.frame_bytes;
  bulk.timeout = 20;  // ms
  bulk.data = buffer;
  const int sent = ::ioctl(fd, USBDEVFS_BULK, &bulk);
  if (sent == static_cast<int>(zero.frame_bytes)) {
    detail = fmt::format("the zero-force frame was sent to the device at {}", zero.usbfs_node);
    return true;
  }
  detail = fmt::format("the zero-force frame could NOT be sent to the device at {}: {}", zero.usbfs_node,
                       sent < 0 ? std::strerror(errno) : fmt::format("{} of {} bytes", sent, zero.frame_bytes));
  return false;
}

}  // namespace

std::string describe_wait_status(int status) {
  if (WIFSIGNALED(status)) {
    return fmt::format("killed by {}{}", signal_name(WTERMSIG(status)), WCOREDUMP(status) ? " (core dumped)" : "");
  }
  if (WIFEXITED(status)) return fmt::format("exited with status {}", WEXITSTATUS(status));
  return fmt::format("ended (wait status {:#x})", status);
}


SharedPage* map_shared_page() noexcept {
  // Backed by a named memfd, not MAP_ANONYMOUS: /proc/PID/maps then names the page in every
  // process that holds it ("/memfd:toonforce-guardian"), so a test can see that the viewer's
  // server process dropped it. The mapping keeps the memory; the descriptor is not needed.
  const int fd = ::memfd_create("toonforce-guardian", MFD_CLOEXEC);
  if (fd < 0) return nullptr;
  void* p = MAP_FAILED;
  if (::ftruncate(fd, static_cast<off_t>(sizeof(SharedPage))) == 0) {
    p = ::mmap(nullptr, sizeof(SharedPage), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  }
  const int saved = errno;
  ::close(fd);
  errno = saved;
  if (p == MAP_FAILED) return nullptr;
  return new (p) SharedPage{};
}

void publish_frame(SharedPage& page, const TelemetryFrame& frame) noexcept {
  const std::uint32_t seq = page.frame_seq.load(std::memory_order_relaxed);
  page.frame_seq.store(seq + 1, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  page.frame = frame;
  page.frame_seq.store(seq + 2, std::memory_order_release);
  page.frames.fetch_add(1, std::memory_order_relaxed);
}

bool read_frame(const SharedPage& page, TelemetryFrame& out) noexcept {
  for (int attempt = 0; attempt < 1000; ++attempt) {
    const std::uint32_t before = page.frame_seq.load(std::memory_order_acquire);
    if (before == 0) return false;  // none yet
    if ((before & 1U) != 0) continue;
    out = page.frame;
    std::atomic_thread_fence(std::memory_order_acquire);
    if (page.frame_seq.load(std::memory_order_relaxed) == before) return true;
  }
  // A writer killed in the middle of its copy leaves the sequence odd for good: the copy is
  // torn, say nothing rather than something wrong.
  return false;
}

GuardOutcome guard(pid_t loop, SharedPage& page, const GuardOptions& options) {
  GuardOutcome out;
  // Stop signals are passed on, not acted on: the guardian stays until the loop process ends.
  struct sigaction action {};
  action.sa_sigaction = on_guardian_signal;
  action.sa_flags = SA_SIGINFO;  // no SA_RESTART: poll() returns at once
  sigemptyset(&action.sa_mask);
  for (const int signo : stop_signals()) sigaction(signo, &action, nullptr);
  signal(SIGPIPE, SIG_IGN);

  const int pidfd = open_pidfd(loop);
  if (pidfd < 0) {
    out.warnings += fmt::format("guardian: pidfd_open failed ({}): the loop process's end is seen by polling\n",
                                std::strerror(errno));
  }
  int usb_fd = -1;
  bool usb_tried = false;
  bool enabled = false;
  bool enable_failed = false;
  std::int64_t enable_dropped_ns = 0;  ///< when a stall dropped the line
  int passed_on = 0;
  // The last signal passed on: the same one from the same sender within kRepeatWindowNs is the
  // same request, passed on once. A parent that dies with PR_SET_PDEATHSIG set (a Python script
  // killed outright, toonforce.live) sends it once for each of its threads as they exit, a few
  // ms apart; the loop's process would take the second copy for a second stop, which exits at
  // once, without the trace's shut-down row and the statistics (the force zeroed either way).
  constexpr std::int64_t kRepeatWindowNs = 1'000'000'000;
  Pending last_passed{0, false, 0};
  std::int64_t last_passed_ns = 0;
  std::int64_t last_beat = 0;
  std::int64_t last_beat_ns = now_ns();
  int status = 0;
  for (;;) {
    const auto phase = static_cast<Phase>(page.phase.load(std::memory_order_acquire));
    const std::int64_t beat = page.heartbeat.load(std::memory_order_acquire);
    const bool ticking = beat > 0 && phase != Phase::kLoopEnded;
    const std::int64_t now = now_ns();
    if (beat != last_beat) {
      last_beat = beat;
      last_beat_ns = now;
    } else if (ticking && !out.stalled && now - last_beat_ns > options.stall_limit_ns) {
      out.stalled = true;
      out.cause = fmt::format("stalled: no tick for {:.0f} ms (limit {:.0f} ms), so the guardian killed it",
                              static_cast<double>(now - last_beat_ns) * 1e-6,
                              static_cast<double>(options.stall_limit_ns) * 1e-6);
      ::kill(loop, SIGKILL);
      if (enabled && options.enable != nullptr && options.enable->set(false)) {  // now, not at its end
        enabled = false;
        enable_dropped_ns = now_ns();
      }
    }
    // The device's node, opened while the loop process still holds the device: at its end,
    // only the claim and the transfer remain to be done.
    if (!usb_tried && phase != Phase::kStarting && page.zero.kind == ExternalZero::Kind::kUsbBulk) {
      usb_tried = true;
      usb_fd = ::open(page.zero.usbfs_node, O_RDWR | O_CLOEXEC);
      if (usb_fd < 0) {
        out.warnings += fmt::format(
            "guardian: WARNING: cannot open {} ({}): if the loop process dies, the guardian cannot zero the force\n",
            page.zero.usbfs_node, std::strerror(errno));
        std::fputs(out.warnings.c_str(), stderr);
      }
    }
    if (options.enable != nullptr && ticking != enabled && !out.stalled) {
      if (options.enable->set(ticking)) {
        enabled = ticking;
      } else if (!enable_failed) {
        enable_failed = true;
        out.warnings += fmt::format("guardian: cannot set {}\n", options.enable->describe());
        std::fputs(out.warnings.c_str(), stderr);
      }
    }
    while (g_pending_count > 0) {
      // Taken with the signals blocked, so none is lost between reading and clearing.
      sigset_t all, old;
      sigfillset(&all);
      sigprocmask(SIG_BLOCK, &all, &old);
      const int n = g_pending_count;
      Pending taken[kPendingSlots];
      for (int i = 0; i < n; ++i) taken[i] = g_pending[i];
      g_pending_count = 0;
      sigprocmask(SIG_SETMASK, &old, nullptr);
      for (int i = 0; i < n; ++i) {
        if (taken[i].from_terminal) continue;  // the terminal sent it to the loop process too
        const std::int64_t at = now_ns();
        if (taken[i].sender != 0 && taken[i].sender == last_passed.sender && taken[i].signo == last_passed.signo &&
            at - last_passed_ns < kRepeatWindowNs) {
          continue;  // a repeat (above)
        }
        sigval value{};
        value.sival_int = passed_on == 0 ? kGuardianFirstCopy : 0;
        ::sigqueue(loop, taken[i].signo, value);
        ++passed_on;
        last_passed = taken[i];
        last_passed_ns = at;
      }
    }
    pollfd fd{pidfd, POLLIN, 0};
    // 1 ms while the loop ticks (the stall check, the enable line), 10 ms otherwise; the
    // loop process's end wakes this at once either way.
    const int timeout_ms = ticking ? 1 : 10;
    const int ready = pidfd >= 0 ? ::poll(&fd, 1, timeout_ms) : 0;
    if (pidfd < 0) {
      timespec ts{0, timeout_ms * 1'000'000L};
      nanosleep(&ts, nullptr);
    }
    if ((ready > 0 || pidfd < 0) && ::waitpid(loop, &status, WNOHANG) == loop) break;
  }
  out.death_ns = now_ns();
  out.wait_status = status;
  out.phase = static_cast<Phase>(page.phase.load(std::memory_order_acquire));
  out.ticks = page.heartbeat.load(std::memory_order_acquire);
  const bool device_was_open = out.phase == Phase::kDeviceOpen;
  out.loop_died = device_was_open;
  if (options.enable != nullptr && (enabled || enable_dropped_ns != 0 || device_was_open)) {
    if (options.enable->set(false)) {  // again after a stall's drop: it costs one ioctl
      enabled = false;
      if (device_was_open) {
        out.zero_sent = true;
        out.zero_ns = enable_dropped_ns != 0 ? enable_dropped_ns : now_ns();
        out.zero_detail = fmt::format("{} was dropped", options.enable->describe());
      }
    } else {
      out.zero_detail = fmt::format("{} could NOT be dropped", options.enable->describe());
    }
  }
  if (device_was_open) {
    std::string detail;
    if (page.zero.kind == ExternalZero::Kind::kUsbBulk && usb_fd >= 0) {
      const bool sent = usb_zero(page.zero, usb_fd, detail);
      if (sent && !out.zero_sent) out.zero_ns = now_ns();
      out.zero_sent = out.zero_sent || sent;
    } else if (page.zero.kind == ExternalZero::Kind::kUsbBulk) {
      detail = fmt::format("the device at {} could not be reached (its node did not open)", page.zero.usbfs_node);
    } else if (!out.zero_sent) {
      detail = "nothing outside the loop process can reach this device: its force ended with the process "
               "(the simulated device lives in it; an Omni's driver stops with the process that opened it)";
      out.zero_ns = now_ns();
    }
    if (!detail.empty()) out.zero_detail += (out.zero_detail.empty() ? "" : "; ") + detail;
  }
  if (out.cause.empty()) out.cause = describe_wait_status(status);
  out.have_frame = read_frame(page, out.last_frame);
  if (out.ticks > 0 && page.period_ns > 0) {
    const std::int64_t at = out.zero_ns != 0 ? out.zero_ns : out.death_ns;
    out.t_end_s = static_cast<double>(out.ticks - 1) * static_cast<double>(page.period_ns) * 1e-9 +
                  static_cast<double>(at - last_beat_ns) * 1e-9;
  } else if (out.have_frame) {
    out.t_end_s = out.last_frame.t_s;
  }
  if (usb_fd >= 0) ::close(usb_fd);
  if (pidfd >= 0) ::close(pidfd);
  // The loop's process has ended: a stop signal from now on (the rest of a burst of copies, as a
  // dying parent sends one per thread) finds nothing to stop, and by its default action it would
  // end this process before it says how the run ended and writes the trace's last row.
  for (const int signo : stop_signals()) signal(signo, SIG_IGN);
  return out;
}

std::string end_trace(const std::string& path, const GuardOutcome& outcome, std::size_t effect_values) {
  auto writer = TraceWriter::append_to(path, std::vector<std::string>(telemetry_extra_count(effect_values, true)));
  if (!writer) return writer.error();
  TelemetryFrame f = outcome.have_frame ? outcome.last_frame : TelemetryFrame{};
  const double period_s = f.tick > 0 ? f.t_s / static_cast<double>(f.tick) : 0.0;
  f.t_s = std::max(outcome.t_end_s, f.t_s);
  if (period_s > 0.0) f.tick = static_cast<std::int64_t>(std::llround(f.t_s / period_s));
  f.force_n = {};
  f.damping_n = {};
  f.gain = 0.0;
  f.timing = TickTiming{};
  f.value_count = static_cast<std::uint16_t>(std::min<std::size_t>(effect_values, f.values.size()));
  if (!write_frame(*writer.value(), f, effect_values, true) || !writer.value()->close()) {
    return fmt::format("{}: the zero-force row could not be written: {}", path, std::strerror(errno != 0 ? errno : EIO));
  }
  return {};
}

std::string describe_outcome(const GuardOutcome& o, pid_t loop) {
  std::string text = fmt::format("guardian: the loop's process (pid {}) ended during the loop, at t = {:.4f} s (tick {}): {}\n",
                                 loop, o.t_end_s, std::max<std::int64_t>(0, o.ticks - 1), o.cause);
  if (o.zero_sent) {
    const double after_ms = static_cast<double>(o.zero_ns - o.death_ns) * 1e-6;
    text += after_ms >= 0.0 ? fmt::format("guardian: zero force commanded {:.3f} ms after its end: {}\n", after_ms, o.zero_detail)
                            : fmt::format("guardian: zero force commanded at the stall, {:.3f} ms before its end: {}\n",
                                          -after_ms, o.zero_detail);
  } else {
    text += fmt::format("guardian: {}\n", o.zero_detail);
  }
  if (o.have_frame) {
    const auto& f = o.last_frame.force_n;
    text += fmt::format("guardian: its last frame taken: t = {:.4f} s, force ({:.3f}, {:.3f}, {:.3f}) N, "
                        "position ({:.4f}, {:.4f}, {:.4f}) m\n",
                        o.last_frame.t_s, f.x, f.y, f.z, o.last_frame.position_m.x, o.last_frame.position_m.y,
                        o.last_frame.position_m.z);
  }
  return text;
}

std::string outcome_json(const GuardOutcome& o, pid_t loop) {
  std::string out = "{\n";
  out += fmt::format("  \"loop_process_died\": true,\n  \"loop_pid\": {},\n  \"cause\": {},\n", loop, json_string(o.cause));
  out += fmt::format("  \"stalled\": {},\n  \"ticks\": {},\n  \"t_end_s\": {},\n", o.stalled,
                     std::max<std::int64_t>(0, o.ticks), o.t_end_s);
  out += fmt::format("  \"zero_sent\": {},\n  \"zero_after_ms\": {},\n  \"zero\": {},\n", o.zero_sent,
                     o.zero_sent ? static_cast<double>(o.zero_ns - o.death_ns) * 1e-6 : 0.0, json_string(o.zero_detail));
  out += fmt::format("  \"death_monotonic_ns\": {},\n  \"zero_monotonic_ns\": {},\n", o.death_ns, o.zero_ns);
  const auto& f = o.last_frame.force_n;
  out += fmt::format("  \"last_frame\": {{\"t_s\": {}, \"force_n\": [{}, {}, {}]}}\n", o.have_frame ? o.last_frame.t_s : 0.0,
                     f.x, f.y, f.z);
  out += "}\n";
  return out;
}

}  // namespace toonforce::guardian
