// SPDX-License-Identifier: Apache-2.0
// The guardian's watch (guardian.hpp; docs/DEPLOY.md "Processes").
#include "toonforce/control/guardian.hpp"

#include <fcntl.h>
#include <linux/gpio.h>
#include <linux/usbdevice_fs.h>
#include <poll.h>
#include <signal.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <new>

#include <fmt/format.h>

#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/control/running_clock.hpp"
#include "toonforce/control/seqlock_fence.hpp"

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
  bool from_terminal;  ///< the kernel sent it (Ctrl-C): the loop's process got it too
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
bool usb_zero(const ExternalZero& zero, int fd, const std::string& node, std::string& detail) {
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
  bulk.len = std::min<unsigned>(zero.frame_bytes, sizeof buffer);
  bulk.timeout = 20;  // ms
  bulk.data = buffer;
  const int sent = ::ioctl(fd, USBDEVFS_BULK, &bulk);
  if (sent == static_cast<int>(bulk.len)) {
    detail = fmt::format("the zero-force frame was sent to the device at {}", node);
    return true;
  }
  detail = fmt::format("the zero-force frame could NOT be sent to the device at {}: {}", node,
                       sent < 0 ? std::strerror(errno) : fmt::format("{} of {} bytes", sent, bulk.len));
  return false;
}

/// One line of a sysfs attribute, without its newline ("" if it cannot be read).
std::string sysfs_word(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return {};
  char text[32] = {};
  const ssize_t n = ::read(fd, text, sizeof text - 1);
  ::close(fd);
  if (n <= 0) return {};
  std::string word(text, static_cast<std::size_t>(n));
  while (!word.empty() && (word.back() == '\n' || word.back() == ' ')) word.pop_back();
  while (!word.empty() && word.front() == ' ') word.erase(word.begin());
  return word;
}

/// Three decimal digits, exactly.
bool three_digits(const char* p, unsigned& out) {
  out = 0;
  for (int i = 0; i < 3; ++i) {
    if (p[i] < '0' || p[i] > '9') return false;
    out = out * 10 + static_cast<unsigned>(p[i] - '0');
  }
  return true;
}

// The Falcon's USB identity (its FTDI chip with Novint's product id; hal/falcon).
constexpr const char* kFalconVendor = "0403";
constexpr const char* kFalconProduct = "cb48";
// Linux numbers USB device nodes on character major 189, minor (bus - 1) * 128 + (address - 1)
// (drivers/usb/core/usb.h, USB_DEVICE_MAJOR; devio.c usbdev_open).
constexpr unsigned kUsbDeviceMajor = 189;

}  // namespace

std::string describe_wait_status(int status) {
  if (WIFSIGNALED(status)) {
    return fmt::format("killed by {}{}", signal_name(WTERMSIG(status)), WCOREDUMP(status) ? " (core dumped)" : "");
  }
  if (WIFEXITED(status)) return fmt::format("exited with status {}", WEXITSTATUS(status));
  return fmt::format("ended (wait status {:#x})", status);
}

SharedPage* create_shared_page(int& fd) noexcept {
  fd = static_cast<int>(::syscall(SYS_memfd_create, "toonforce-guardian", MFD_CLOEXEC));
  if (fd < 0) return nullptr;
  if (::ftruncate(fd, static_cast<off_t>(sizeof(SharedPage))) != 0) {
    const int error = errno;
    ::close(fd);
    fd = -1;
    errno = error;
    return nullptr;
  }
  void* p = ::mmap(nullptr, sizeof(SharedPage), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (p == MAP_FAILED) {
    const int error = errno;
    ::close(fd);
    fd = -1;
    errno = error;
    return nullptr;
  }
  return new (p) SharedPage{};
}

SharedPage* map_shared_page() noexcept {
  int fd = -1;
  SharedPage* page = create_shared_page(fd);
  if (fd >= 0) ::close(fd);
  return page;
}

SharedPage* attach_shared_page(int fd) noexcept {
  struct stat st {};
  if (fd < 0 || ::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || st.st_size != static_cast<off_t>(sizeof(SharedPage))) {
    return nullptr;
  }
  void* p = ::mmap(nullptr, sizeof(SharedPage), PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  return p == MAP_FAILED ? nullptr : static_cast<SharedPage*>(p);
}

void unmap_shared_page(SharedPage* page) noexcept {
  if (page != nullptr) ::munmap(page, sizeof(SharedPage));
}

void publish_frame(SharedPage& page, const TelemetryFrame& frame) noexcept {
  const std::uint32_t seq = page.frame_seq.load(std::memory_order_relaxed);
  page.frame_seq.store(seq + 1, std::memory_order_relaxed);
  seqlock_write_fence();
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
    seqlock_read_fence();
    if (page.frame_seq.load(std::memory_order_relaxed) == before) {
      // The writer's frame, but its counts are the reader's to keep in range.
      out.value_count = static_cast<std::uint16_t>(std::min<std::size_t>(out.value_count, out.values.size()));
      return true;
    }
  }
  // A writer killed in the middle of its copy leaves the sequence odd for good: the copy is
  // torn, say nothing rather than something wrong.
  return false;
}

int open_verified_usbfs(const ExternalZero& zero, std::string& why) {
  const std::size_t length = ::strnlen(zero.usbfs_node, sizeof zero.usbfs_node);
  const std::string claimed(zero.usbfs_node, length);
  // "/dev/bus/usb/BBB/DDD", nothing more: the path the guardian opens is rebuilt from the two
  // numbers, never taken as given.
  constexpr std::string_view kPrefix = "/dev/bus/usb/";
  unsigned bus = 0;
  unsigned address = 0;
  if (length != kPrefix.size() + 7 || claimed.compare(0, kPrefix.size(), kPrefix) != 0 ||
      !three_digits(zero.usbfs_node + kPrefix.size(), bus) || zero.usbfs_node[kPrefix.size() + 3] != '/' ||
      !three_digits(zero.usbfs_node + kPrefix.size() + 4, address) || bus < 1 || address < 1 || address > 127) {
    why = fmt::format("'{}' is not a USB device node (/dev/bus/usb/BBB/DDD): refused", claimed.substr(0, 64));
    return -1;
  }
  const std::string node = fmt::format("/dev/bus/usb/{:03}/{:03}", bus, address);
  const unsigned minor_number = (bus - 1) * 128 + (address - 1);
  const std::string sys = fmt::format("/sys/dev/char/{}:{}", kUsbDeviceMajor, minor_number);
  const std::string vendor = sysfs_word(sys + "/idVendor");
  const std::string product = sysfs_word(sys + "/idProduct");
  if (vendor != kFalconVendor || product != kFalconProduct) {
    why = fmt::format("{} is not a Falcon ({} says {}:{}, not {}:{}): refused", node, sys,
                      vendor.empty() ? "?" : vendor, product.empty() ? "?" : product, kFalconVendor, kFalconProduct);
    return -1;
  }
  if (sysfs_word(sys + "/busnum") != std::to_string(bus) || sysfs_word(sys + "/devnum") != std::to_string(address)) {
    why = fmt::format("{}: {} names another bus or address: refused", node, sys);
    return -1;
  }
  // The node must be that device's: the USB device character device of that bus and address
  // (the path is under /dev, which only root can change, so what stat() sees is what opens).
  struct stat st {};
  if (::stat(node.c_str(), &st) != 0 || !S_ISCHR(st.st_mode) || major(st.st_rdev) != kUsbDeviceMajor ||
      minor(st.st_rdev) != minor_number) {
    why = fmt::format("{} is not the character device {}:{}: refused", node, kUsbDeviceMajor, minor_number);
    return -1;
  }
  const int fd = ::open(node.c_str(), O_RDWR | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    why = fmt::format("cannot open {} ({})", node, std::strerror(errno));
    return -1;
  }
  return fd;
}

std::string GpioEnableLine::open(const std::string& chip, std::uint32_t offset, bool active_low) {
  constexpr std::string_view kPrefix = "/dev/gpiochip";
  if (chip.size() <= kPrefix.size() || chip.compare(0, kPrefix.size(), kPrefix) != 0 ||
      chip.find_first_not_of("0123456789", kPrefix.size()) != std::string::npos) {
    return fmt::format("{} is not a GPIO chip's node (/dev/gpiochipN)", chip);
  }
  // (`run` names the chip: a path of this form, which the chip's own answer below confirms.)
  const int fd = ::open(chip.c_str(), O_RDWR | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) return fmt::format("cannot open {}: {}", chip, std::strerror(errno));
  gpiochip_info info{};
  if (::ioctl(fd, GPIO_GET_CHIPINFO_IOCTL, &info) != 0) {
    const int error = errno;
    ::close(fd);
    return fmt::format("{} does not answer as a GPIO chip: {}", chip, std::strerror(error));
  }
  if (offset >= info.lines) {
    ::close(fd);
    return fmt::format("{} has {} lines: no line {}", chip, info.lines, offset);
  }
  gpiohandle_request request{};
  request.lineoffsets[0] = offset;
  request.lines = 1;
  request.flags = GPIOHANDLE_REQUEST_OUTPUT | (active_low ? GPIOHANDLE_REQUEST_ACTIVE_LOW : 0U);
  request.default_values[0] = 0;  // inactive until the loop ticks
  std::snprintf(request.consumer_label, sizeof request.consumer_label, "%s", "toonforce-guardian");
  const int requested = ::ioctl(fd, GPIO_GET_LINEHANDLE_IOCTL, &request);
  const int error = errno;
  ::close(fd);
  if (requested != 0 || request.fd < 0) {
    return fmt::format("{} line {} cannot be requested: {}", chip, offset, std::strerror(error));
  }
  handle_ = request.fd;
  chip_ = chip;
  offset_ = offset;
  return {};
}

GpioEnableLine::~GpioEnableLine() {
  if (handle_ >= 0) ::close(handle_);
}

bool GpioEnableLine::set(bool active) noexcept {
  if (handle_ < 0) return false;
  gpiohandle_data data{};
  data.values[0] = active ? 1 : 0;
  return ::ioctl(handle_, GPIOHANDLE_SET_LINE_VALUES_IOCTL, &data) == 0;
}

std::string GpioEnableLine::describe() const {
  return fmt::format("the amplifier-enable line {} line {}", chip_, offset_);
}

GuardOutcome guard(pid_t loop, SharedPage& page, const GuardOptions& options) {
  GuardOutcome out;
  const auto warn = [&](const std::string& text) {
    out.warnings += text;
    if (!options.quiet_warnings) std::fputs(text.c_str(), stderr);
  };
  // Stop signals are passed on, not acted on: the guardian stays until the loop's process ends.
  struct sigaction action {};
  action.sa_sigaction = on_guardian_signal;
  action.sa_flags = SA_SIGINFO;  // no SA_RESTART: poll() returns at once
  sigemptyset(&action.sa_mask);
  for (const int signo : stop_signals()) sigaction(signo, &action, nullptr);
  signal(SIGPIPE, SIG_IGN);
  if (options.unblock_stop_signals) {
    sigset_t stops;
    sigemptyset(&stops);
    for (const int signo : stop_signals()) sigaddset(&stops, signo);
    sigprocmask(SIG_UNBLOCK, &stops, nullptr);
  }

  const int pidfd = open_pidfd(loop);
  if (pidfd < 0) {
    warn(fmt::format("guardian: pidfd_open failed ({}): the loop's process's end is seen by polling\n",
                     std::strerror(errno)));
  }
  // One verified node per device that can be reached from outside (a world has several).
  struct UsbTarget {
    int fd = -1;
    std::string node;
    std::string refused;
  };
  std::array<UsbTarget, kMaxGuardedDevices> usb{};
  std::array<ExternalZero, kMaxGuardedDevices> zeros{};
  std::size_t zero_count = 0;
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
  // The stall is counted in time this process ran: the poll below returns every 1 ms (10 ms
  // while nothing ticks); a step longer than 50 ms is time in which the guardian itself was
  // stopped or starved, and the loop's process most likely with it (a group stop, Ctrl-Z).
  RunningClock silence(50'000'000);
  silence.look(last_beat_ns);
  int status = 0;
  for (;;) {
    const auto phase = static_cast<Phase>(page.phase.load(std::memory_order_acquire));
    const bool ended = page.loop_ended.load(std::memory_order_acquire) != 0;
    const std::int64_t beat = page.heartbeat.load(std::memory_order_acquire);
    if (phase == Phase::kDeviceOpen) out.device_seen_open = true;
    const bool ticking = beat > 0 && out.device_seen_open && !ended;
    const std::int64_t now = now_ns();
    const std::int64_t silent_ns = silence.look(now);
    if (beat != last_beat) {
      last_beat = beat;
      last_beat_ns = now;
      silence.restart();
    } else if (ticking && !out.stalled && silent_ns > options.stall_limit_ns) {
      out.stalled = true;
      out.cause =
          fmt::format("stalled: no tick for {:.0f} ms (limit {:.0f} ms), so the guardian killed it",
                      static_cast<double>(silent_ns) * 1e-6, static_cast<double>(options.stall_limit_ns) * 1e-6);
      ::kill(loop, SIGKILL);
      if (enabled && options.enable != nullptr && options.enable->set(false)) {  // now, not at its end
        enabled = false;
        enable_dropped_ns = now_ns();
      }
    }
    // The device's node, opened while the loop's process still holds the device: at its end,
    // only the claim and the transfer remain to be done.
    if (!usb_tried && out.device_seen_open) {
      usb_tried = true;
      const std::size_t count = std::min<std::size_t>(page.zero_count, kMaxGuardedDevices);
      for (std::size_t i = 0; i < count; ++i) {
        const ExternalZero zero = page.zeros[i];  // a copy: what is checked is what is used
        zeros[i] = zero;
        if (zero.kind != ExternalZero::Kind::kUsbBulk) continue;
        usb[i].node.assign(zero.usbfs_node, ::strnlen(zero.usbfs_node, sizeof zero.usbfs_node));
        usb[i].fd = open_verified_usbfs(zero, usb[i].refused);
        if (usb[i].fd < 0) {
          warn(fmt::format("guardian: WARNING: {}: if the loop's process dies, the guardian cannot zero that "
                           "device's force\n",
                           usb[i].refused));
        }
      }
      zero_count = count;
    }
    if (options.enable != nullptr && ticking != enabled && !out.stalled) {
      if (options.enable->set(ticking)) {
        enabled = ticking;
      } else if (!enable_failed) {
        enable_failed = true;
        warn(fmt::format("guardian: cannot set {}\n", options.enable->describe()));
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
        if (taken[i].from_terminal) continue;  // the terminal sent it to the loop's process too
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
    // loop's process's end wakes this at once either way.
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
  if (static_cast<Phase>(page.phase.load(std::memory_order_acquire)) == Phase::kDeviceOpen) out.device_seen_open = true;
  out.loop_ended = page.loop_ended.load(std::memory_order_acquire) != 0;
  out.ticks = page.heartbeat.load(std::memory_order_acquire);
  // The wait status is the truth of how it ended: a death by a signal is zeroed whatever the
  // page says (a loop that had ended already commanded zero; once more costs one transfer).
  // An exit with a status `run` does not give (0, 1, 2) is a death too: a second stop signal
  // leaves with 128 + its number, possibly after the shut-down tick but before the writer wrote
  // that tick's row.
  const bool own_exit = WIFEXITED(status) && WEXITSTATUS(status) <= 2;
  out.loop_died = out.device_seen_open && (out.stalled || WIFSIGNALED(status) || !out.loop_ended || !own_exit);
  if (options.enable != nullptr && (enabled || enable_dropped_ns != 0 || out.loop_died)) {
    if (options.enable->set(false)) {  // again after a stall's drop: it costs one ioctl
      enabled = false;
      if (out.loop_died) {
        out.zero_sent = true;
        out.zero_ns = enable_dropped_ns != 0 ? enable_dropped_ns : now_ns();
        out.zero_detail = fmt::format("{} was dropped", options.enable->describe());
      }
    } else {
      out.zero_detail = fmt::format("{} could NOT be dropped", options.enable->describe());
    }
  }
  if (out.loop_died) {
    // Every device the guardian can reach, one transfer each; the others' force ended with the
    // process that drove them.
    bool unreachable = zero_count == 0;
    for (std::size_t i = 0; i < zero_count; ++i) {
      std::string detail;
      if (zeros[i].kind == ExternalZero::Kind::kUsbBulk && usb[i].fd >= 0) {
        const bool sent = usb_zero(zeros[i], usb[i].fd, usb[i].node, detail);
        if (sent && !out.zero_sent) out.zero_ns = now_ns();
        out.zero_sent = out.zero_sent || sent;
      } else if (zeros[i].kind == ExternalZero::Kind::kUsbBulk) {
        detail = fmt::format("the device could not be reached: {}", usb[i].refused);
      } else {
        unreachable = true;
        continue;
      }
      if (zero_count > 1) detail = fmt::format("device {}: {}", i + 1, detail);
      out.zero_detail += (out.zero_detail.empty() ? "" : "; ") + detail;
    }
    if (unreachable && !out.zero_sent) {
      const std::string detail =
          "nothing outside the loop's process can reach this device: its force ended with the process "
          "(the simulated device lives in it; an Omni's driver stops with the process that opened it)";
      out.zero_ns = now_ns();
      out.zero_detail += (out.zero_detail.empty() ? "" : "; ") + detail;
    }
  }
  if (out.cause.empty()) out.cause = describe_wait_status(status);
  out.have_frame = read_frame(page, out.last_frame);
  if (out.ticks > 0 && page.period_ns > 0 && page.period_ns < 1'000'000'000) {
    const std::int64_t at = out.zero_ns != 0 ? out.zero_ns : out.death_ns;
    out.t_end_s = static_cast<double>(out.ticks - 1) * static_cast<double>(page.period_ns) * 1e-9 +
                  static_cast<double>(std::max<std::int64_t>(0, at - last_beat_ns)) * 1e-9;
  } else if (out.have_frame) {
    out.t_end_s = out.last_frame.t_s;
  }
  for (const UsbTarget& t : usb) {
    if (t.fd >= 0) ::close(t.fd);
  }
  if (pidfd >= 0) ::close(pidfd);
  // The loop's process has ended: a stop signal from now on (the rest of a burst of copies, as a
  // dying parent sends one per thread) finds nothing to stop, and by its default action it would
  // end this process before it says how the run ended and the trace gets its last row.
  for (const int signo : stop_signals()) signal(signo, SIG_IGN);
  return out;
}

Verdict make_verdict(const GuardOutcome& o, pid_t loop, int exit_status) noexcept {
  Verdict v;
  v.loop_pid = loop;
  v.wait_status = o.wait_status;
  v.exit_status = exit_status;
  v.stalled = o.stalled ? 1 : 0;
  v.zero_sent = o.zero_sent ? 1 : 0;
  v.loop_ended = o.loop_ended ? 1 : 0;
  v.ticks = o.ticks;
  v.death_ns = o.death_ns;
  v.zero_ns = o.zero_ns;
  v.t_end_s = o.t_end_s;
  std::snprintf(v.cause, sizeof v.cause, "%s", o.cause.c_str());
  std::snprintf(v.zero_detail, sizeof v.zero_detail, "%s", o.zero_detail.c_str());
  return v;
}

}  // namespace toonforce::guardian
