// SPDX-License-Identifier: Apache-2.0
// The real-time runner (Linux). See realtime_runner.hpp for the contract; the method follows
// cyclictest (rt-tests): absolute CLOCK_MONOTONIC deadlines with clock_nanosleep(TIMER_ABSTIME),
// SCHED_FIFO, mlockall, and latency = wake-up time - deadline.
#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/control/running_clock.hpp"

#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <future>
#include <iterator>
#include <system_error>
#include <thread>

#include <fmt/format.h>

namespace toonforce {
namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;

std::int64_t now_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * kNsPerS + ts.tv_nsec;
}

timespec to_timespec(std::int64_t ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / kNsPerS);
  ts.tv_nsec = static_cast<long>(ns % kNsPerS);
  return ts;
}

/// Sleeps until the absolute CLOCK_MONOTONIC time `ns` (retrying after signals).
void sleep_until(std::int64_t ns) noexcept {
  const timespec ts = to_timespec(ns);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

constexpr bool kSanitized =
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    true;
#else
    false;
#endif

/// Touches a stack region so its pages are mapped (and locked) before the first tick.
void prefault_stack() noexcept {
  constexpr std::size_t kBytes = std::size_t{256} * 1024;
  unsigned char buffer[kBytes];
  for (std::size_t i = 0; i < kBytes; i += 4096) static_cast<volatile unsigned char*>(buffer)[i] = 0;
  asm volatile("" : : "r"(buffer) : "memory");  // keep the writes
}

/// Makes the calling thread SCHED_FIFO at `priority`; errno value on failure, 0 on success.
int make_fifo(int priority) noexcept {
  sched_param param{};
  param.sched_priority = priority;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
}

int pin_to(int cpu) noexcept {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(static_cast<std::size_t>(cpu), &set);
  return pthread_setaffinity_np(pthread_self(), sizeof set, &set);
}

/// The watchdog outside the servo thread: zero force when the heartbeat stops.
struct Watchdog {
  const std::atomic<std::int64_t>& heartbeat;
  const std::atomic<bool>& done;
  EmergencyZero emergency;
  std::int64_t timeout_ns;
  std::atomic<std::int64_t> trips{0};

  void run() noexcept {
    const std::int64_t poll_ns = std::max<std::int64_t>(timeout_ns / 4, 100'000);
    std::int64_t last_beat = heartbeat.load(std::memory_order_acquire);
    // Only time in which this thread ran counts (running_clock.hpp): a process stopped and
    // continued as a whole (Ctrl-Z, fg) did not stall its loop.
    RunningClock clock(2 * poll_ns + 5'000'000);
    clock.look(now_ns());
    bool tripped = false;
    while (!done.load(std::memory_order_acquire)) {
      timespec ts = to_timespec(poll_ns);
      nanosleep(&ts, nullptr);
      const std::int64_t beat = heartbeat.load(std::memory_order_acquire);
      const std::int64_t silent_ns = clock.look(now_ns());
      if (beat != last_beat) {
        last_beat = beat;
        clock.restart();
        tripped = false;
      } else if (beat > 0 && !tripped && silent_ns > timeout_ns) {
        emergency();  // the loop stalled: zero force from outside it
        trips.fetch_add(1, std::memory_order_relaxed);
        tripped = true;
      }
    }
  }
};

}  // namespace

std::string realtime_permission_advice(int priority) {
  return fmt::format(
      "SCHED_FIFO priority {} was refused: this user may not use real-time scheduling.\n"
      "  To grant it, either\n"
      "    - allow real-time priorities for the group realtime in /etc/security/limits.d/toonforce.conf\n"
      "      (the toonforce package installs it; from a source tree: tools/deploy/toonforce-limits.conf):\n"
      "        @realtime  -  rtprio   {}\n"
      "        @realtime  -  memlock  unlimited\n"
      "      (sudo groupadd -f realtime && sudo usermod -aG realtime $USER, then log in again), or\n"
      "    - give the binary the capabilities: sudo setcap cap_sys_nice,cap_ipc_lock+ep $(command -v toonforce)\n"
      "  or run again with --allow-non-rt to run WITHOUT real-time scheduling (timing will be poor).",
      priority, std::max(priority, 95));
}

Result<RunReport> run_realtime(PeriodicTask& task, const RealtimeOptions& options, EmergencyZero emergency,
                               const std::atomic<int>& stop) {
  if (!(options.rate_hz >= 500.0 && options.rate_hz <= 10000.0)) {
    return Error{fmt::format("rate {} Hz is outside 500..10000 Hz", options.rate_hz)};
  }
  if (options.priority < 1 || options.priority > 98) {
    return Error{fmt::format("priority {} is outside 1..98 (99 is left for the watchdog)", options.priority)};
  }
  const auto period_ns = static_cast<std::int64_t>(std::llround(1e9 / options.rate_hz));
  const long cpus = sysconf(_SC_NPROCESSORS_ONLN);
  if (options.cpu >= 0 && options.cpu >= cpus) {
    return Error{fmt::format("--cpu {}: this machine has CPUs 0..{}", options.cpu, cpus - 1)};
  }

  auto report = std::make_unique<RunReport>();  // histograms allocated here, before the loop
  RealtimeSetup& setup = report->setup;
  if (options.lock_memory) {
    if (kSanitized) {
      setup.notes += "memory not locked: sanitizer builds map terabytes of shadow memory\n";
    } else if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
      setup.memory_locked = true;
    } else {
      setup.notes += fmt::format("mlockall failed ({}): page faults may stall the loop; raise 'memlock' in "
                                 "/etc/security/limits.d or grant CAP_IPC_LOCK\n",
                                 std::strerror(errno));
    }
  }

  std::atomic<std::int64_t> own_heartbeat{0};
  std::atomic<std::int64_t>& heartbeat = options.heartbeat != nullptr ? *options.heartbeat : own_heartbeat;
  std::atomic<bool> done{false};
  std::promise<std::string> ready;  // the servo thread's set-up result ("" = go)
  std::future<std::string> ready_result = ready.get_future();

  const auto servo = [&]() noexcept {
    pthread_setname_np(pthread_self(), "toonforce-servo");
    const int fifo_error = make_fifo(options.priority);
    if (fifo_error == 0) {
      setup.fifo = true;
      setup.priority = options.priority;
    } else if (!options.allow_non_realtime) {
      ready.set_value(realtime_permission_advice(options.priority));
      return;
    } else {
      setup.notes += fmt::format("running WITHOUT real-time scheduling: SCHED_FIFO {} refused ({})\n", options.priority,
                                 std::strerror(fifo_error));
    }
    if (options.cpu >= 0) {
      const int pin_error = pin_to(options.cpu);
      if (pin_error == 0) {
        setup.cpu = options.cpu;
      } else {
        setup.notes += fmt::format("not pinned to CPU {} ({})\n", options.cpu, std::strerror(pin_error));
      }
    }
    static_cast<void>(use_alternate_signal_stack());  // before the loop: the tick makes no system call
    prefault_stack();
    ready.set_value("");

    // Start two periods from now, so the first deadline is in the future.
    const std::int64_t start = now_ns() + 2 * period_ns;
    std::int64_t k = 0;
    std::int64_t missed = 0;
    std::int64_t ticks = 0;
    while (stop.load(std::memory_order_acquire) == 0 && (options.deadlines == 0 || k < options.deadlines)) {
      const std::int64_t deadline = start + k * period_ns;
      sleep_until(deadline);
      const std::int64_t woke = now_ns();
      if (stop.load(std::memory_order_acquire) != 0) break;
      // Woke a whole period or more late: those deadlines are gone. Run at the latest one that
      // has passed, so the tick's integer time (and dt) tells the truth; never burst.
      const std::int64_t behind = (woke - deadline) / period_ns;
      if (behind > 0) {
        k += behind;
        missed += behind;
        if (options.deadlines != 0 && k >= options.deadlines) {
          missed -= k - (options.deadlines - 1);  // deadlines past the end were never due
          k = options.deadlines - 1;
        }
      }
      task.tick(k);
      heartbeat.store(k + 1, std::memory_order_release);
      const std::int64_t done_at = now_ns();
      ++ticks;
      TickTiming timing;
      timing.wake_latency_ns = woke - deadline;
      timing.compute_ns = done_at - woke;
      timing.slack_ns = start + (k + 1) * period_ns - done_at;
      timing.missed_total = missed;
      report->wake.record(timing.wake_latency_ns);
      report->compute.record(timing.compute_ns);
      report->slack.record(timing.slack_ns);
      task.publish(k, timing);
      ++k;
    }
    task.shutdown(k);  // zero force first; everything else afterwards
    heartbeat.store(k + 1, std::memory_order_release);
    if (options.ended != nullptr) options.ended->store(1, std::memory_order_release);
    report->ticks = ticks;
    report->missed = missed;
    report->elapsed_s = static_cast<double>(now_ns() - start) / 1e9;
  };

  Watchdog watchdog{heartbeat, done, emergency, options.watchdog_periods * period_ns};
  // Both threads exist before the loop runs: a thread refused for want of memory (`ulimit -v`)
  // is an error before the first tick, never a running servo thread left joinable while the
  // exception passes (std::terminate).
  std::atomic<int> go{0};  // 1: the servo thread is set up, watch it; -1: give up
  std::thread watchdog_thread;
  try {
    watchdog_thread = std::thread([&watchdog, &setup, &options, &go] {
      while (go.load(std::memory_order_acquire) == 0) {
        timespec ts = to_timespec(1'000'000);
        nanosleep(&ts, nullptr);
      }
      if (go.load(std::memory_order_acquire) < 0) return;
      pthread_setname_np(pthread_self(), "toonforce-wdog");
      static_cast<void>(use_alternate_signal_stack());
      // Above the servo thread, so a runaway loop cannot starve its own watchdog.
      if (setup.fifo) static_cast<void>(make_fifo(options.priority + 1));
      watchdog.run();
    });
  } catch (const std::system_error& e) {
    return Error{fmt::format("cannot start the watchdog thread: {} (too little memory: `ulimit -v`?)", e.what())};
  }
  std::thread servo_thread;
  try {
    servo_thread = std::thread(servo);
  } catch (const std::system_error& e) {
    go.store(-1, std::memory_order_release);
    watchdog_thread.join();
    return Error{fmt::format("cannot start the servo thread: {} (too little memory: `ulimit -v`?)", e.what())};
  }
  const std::string refused = ready_result.get();
  if (!refused.empty()) {
    servo_thread.join();
    go.store(-1, std::memory_order_release);
    watchdog_thread.join();
    return Error{refused};
  }
  go.store(1, std::memory_order_release);
  servo_thread.join();
  done.store(true, std::memory_order_release);
  watchdog_thread.join();
  report->watchdog_trips = watchdog.trips.load();
  report->stop_signal = stop.load();
  return std::move(*report);
}

// ---- a device's own servo thread ----------------------------------------------------------------

namespace {

/// What the device's servo thread needs: the task, where to count, when to stop.
struct ClockedRun {
  PeriodicTask& task;
  RunReport& report;
  std::int64_t deadlines;
  const std::atomic<int>& stop;
  std::atomic<std::int64_t>& heartbeat;
  std::atomic<std::uint32_t>* ended;
  std::int64_t last_tick = -1;
  std::int64_t missed = 0;
};

TickVerdict clocked_tick(void* context, const ClockedTick& clock) noexcept {
  auto& run = *static_cast<ClockedRun*>(context);
  // The vendor's thread, which toonforce does not start: its alternate signal stack is set up
  // in its first frame, once (system calls in that frame only).
  if (run.last_tick < 0) static_cast<void>(use_alternate_signal_stack());
  if (run.last_tick >= 0 && clock.tick > run.last_tick + 1) run.missed += clock.tick - run.last_tick - 1;
  run.last_tick = clock.tick;
  if (run.stop.load(std::memory_order_relaxed) != 0 || (run.deadlines > 0 && run.report.ticks >= run.deadlines)) {
    run.task.shutdown(clock.tick);  // zero force inside the frame, then the device stops
    run.heartbeat.store(clock.tick + 1, std::memory_order_release);
    if (run.ended != nullptr) run.ended->store(1, std::memory_order_release);
    return TickVerdict::kStop;
  }
  const std::int64_t start = now_ns();  // vDSO: no system call
  run.task.tick(clock.tick);
  run.heartbeat.store(clock.tick + 1, std::memory_order_release);
  const std::int64_t compute = now_ns() - start;
  const auto period_ns = static_cast<std::int64_t>(std::llround(clock.period_s * 1e9));
  TickTiming timing;
  timing.wake_latency_ns =
      run.report.ticks == 0 ? 0 : static_cast<std::int64_t>(std::llround(clock.dt_s * 1e9)) - period_ns;
  timing.compute_ns = compute;
  timing.slack_ns = period_ns - compute;
  timing.missed_total = run.missed;
  run.report.wake.record(timing.wake_latency_ns);
  run.report.compute.record(timing.compute_ns);
  run.report.slack.record(timing.slack_ns);
  ++run.report.ticks;
  run.task.publish(clock.tick, timing);
  return TickVerdict::kContinue;
}

void zero_device(void* device) noexcept { static_cast<DeviceDriver*>(device)->emergency_zero(); }

}  // namespace

Result<RunReport> run_device_clocked(PeriodicTask& task, DeviceDriver& device, const RealtimeOptions& options,
                                     const std::atomic<int>& stop) {
  auto report = std::make_unique<RunReport>();  // histograms allocated here, before the loop
  report->setup.priority = -1;                  // the device's thread: its priority is not ours to set
  report->setup.notes = "wake-up latency here is the jitter of the device scheduler's period\n";
  if (options.lock_memory && !kSanitized) {
    report->setup.memory_locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
    if (!report->setup.memory_locked) report->setup.notes += "mlockall refused: memory not locked\n";
  }
  std::atomic<std::int64_t> own_heartbeat{0};
  std::atomic<std::int64_t>& heartbeat = options.heartbeat != nullptr ? *options.heartbeat : own_heartbeat;
  std::atomic<bool> done{false};
  const double rate_hz = device.info().nominal_rate_hz > 0.0 ? device.info().nominal_rate_hz : options.rate_hz;
  Watchdog watchdog{heartbeat, done, EmergencyZero{zero_device, &device},
                    options.watchdog_periods * static_cast<std::int64_t>(std::llround(1e9 / rate_hz))};
  std::thread watchdog_thread;
  try {
    watchdog_thread = std::thread([&watchdog] {
      pthread_setname_np(pthread_self(), "toonforce-wdog");
      static_cast<void>(use_alternate_signal_stack());
      watchdog.run();
    });
  } catch (const std::system_error& e) {
    return Error{fmt::format("cannot start the watchdog thread: {} (too little memory: `ulimit -v`?)", e.what())};
  }
  ClockedRun run{task, *report, options.deadlines, stop, heartbeat, options.ended};
  const std::int64_t begin = now_ns();
  auto ended = device.run_clocked(&clocked_tick, &run);
  done.store(true, std::memory_order_release);
  watchdog_thread.join();
  if (!ended) return Error{ended.error()};
  report->elapsed_s = static_cast<double>(now_ns() - begin) * 1e-9;
  report->missed = run.missed;
  report->watchdog_trips = watchdog.trips.load();
  report->stop_signal = stop.load();
  if (!ended->device_stopped.empty()) {
    report->setup.notes += fmt::format("the device stopped the run: {}\n", ended->device_stopped);
  }
  return std::move(*report);
}

Result<RunReport> run_on_device(PeriodicTask& task, DeviceDriver& device, const RealtimeOptions& options,
                                const std::atomic<int>& stop) {
  if (device.info().clocking == Clocking::kDeviceThread) return run_device_clocked(task, device, options, stop);
  return run_realtime(task, options, EmergencyZero{zero_device, &device}, stop);
}

// ---- signals -----------------------------------------------------------------------------------

namespace {

/// One thread's alternate signal stack, mapped when the thread first asks for it and unmapped
/// when it ends (a thread_local's destructor).
class AlternateStack {
 public:
  AlternateStack() noexcept {
    void* memory = mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (memory == MAP_FAILED) return;
    stack_t stack{};
    stack.ss_sp = memory;
    stack.ss_size = kBytes;
    if (sigaltstack(&stack, nullptr) != 0) {
      munmap(memory, kBytes);
      return;
    }
    memory_ = memory;
  }
  ~AlternateStack() {
    if (memory_ == nullptr) return;
    stack_t off{};
    off.ss_flags = SS_DISABLE;
    sigaltstack(&off, nullptr);
    munmap(memory_, kBytes);
  }
  AlternateStack(const AlternateStack&) = delete;
  AlternateStack& operator=(const AlternateStack&) = delete;
  bool installed() const noexcept { return memory_ != nullptr; }

 private:
  // The handler calls the device's emergency zero (a USB or vendor-library write): room for
  // that, far above MINSIGSTKSZ.
  static constexpr std::size_t kBytes = std::size_t{64} << 10;
  void* memory_ = nullptr;
};

}  // namespace

bool use_alternate_signal_stack() noexcept {
  thread_local AlternateStack stack;
  return stack.installed();
}

namespace {

std::atomic<int>* g_stop = nullptr;
/// The stop signal whose direct copy may still come after the guardian's (0: none). Atomic:
/// handlers may run on any of the process's threads (a lock-free atomic is signal-safe).
std::atomic<int> g_direct_copy_expected{0};
static_assert(std::atomic<int>::is_always_lock_free);
EmergencyZero g_emergency;
struct sigaction g_old_pipe {};

extern "C" void on_stop_signal(int signo, siginfo_t* info, void* /*context*/) {
  // A file-size limit (`ulimit -f`) makes the kernel send SIGXFSZ to the writer: ignored, the
  // write fails with EFBIG and the writer reports it as on a full disk (the run goes on). A
  // SIGXFSZ sent by someone (`kill -XFSZ`) is a stop like any other.
  if (is_file_size_limit_signal(signo, info)) return;
  if (g_stop == nullptr) return;
  int expected = 0;
  // `toonforce run`'s guardian passes on each stop signal it gets; the first it marks as a
  // possible duplicate (a service manager or a process-group kill may have sent us the same
  // one): that one is not a second stop (guardian.hpp).
  const bool from_guardian = info != nullptr && info->si_code == SI_QUEUE && info->si_pid == getppid();
  const bool guardian_copy = from_guardian && info->si_value.sival_int == kGuardianFirstCopy;
  if (g_stop->compare_exchange_strong(expected, signo)) {
    // The guardian's copy may overtake the one sent to this process directly by the same group
    // kill (the guardian runs at once on the other CPU): that direct one, when it comes, is the
    // same request.
    g_direct_copy_expected.store(guardian_copy ? signo : 0, std::memory_order_relaxed);
    return;
  }
  if (guardian_copy && expected == signo) return;  // the guardian's copy of the one we got
  int direct = signo;
  if (!from_guardian && g_direct_copy_expected.compare_exchange_strong(direct, 0, std::memory_order_relaxed)) return;
  // Asked twice: the loop did not stop. Zero force and leave now.
  g_emergency();
  _exit(128 + signo);
}

extern "C" void on_fatal_signal(int signo) {
  g_emergency();  // best effort: the process state is unknown
  signal(signo, SIG_DFL);
  raise(signo);
}

// Every signal whose default action ends the process and that can be caught, the fatal ones
// (the process state is unknown after them) aside: each stops the loop like Ctrl-C, so that a
// dropped SSH session (SIGHUP), a CPU limit (SIGXCPU), a `kill -XFSZ`, a timer or a
// stray `kill -USR1` ends with zero force, the summary and a whole trace.
constexpr int kStopSignals[] = {SIGHUP,    SIGINT,  SIGQUIT, SIGTERM, SIGUSR1, SIGUSR2, SIGALRM,
                                SIGVTALRM, SIGPROF, SIGXCPU, SIGXFSZ, SIGIO,   SIGPWR};
constexpr int kFatalSignals[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGSYS, SIGTRAP};

/// What each stop signal did before install_signal_handlers: restore_signals puts it back, so
/// a caller's own stop path (the viewer's, around the run) stays in place after the loop.
struct sigaction g_old_stop[std::size(kStopSignals)]{};

}  // namespace

std::span<const int> stop_signals() noexcept { return kStopSignals; }

bool is_file_size_limit_signal(int signo, const siginfo_t* info) noexcept {
  return signo == SIGXFSZ && info != nullptr &&
         ((info->si_code != SI_USER && info->si_code != SI_QUEUE) || info->si_pid == getpid());
}

std::string signal_name(int signo) {
  const char* abbrev = signo > 0 ? sigabbrev_np(signo) : nullptr;
  return abbrev != nullptr ? std::string("SIG") + abbrev : "signal " + std::to_string(signo);
}

void install_signal_handlers(std::atomic<int>& stop, EmergencyZero emergency) {
  g_stop = &stop;
  g_direct_copy_expected.store(0, std::memory_order_relaxed);
  g_emergency = emergency;
  static_cast<void>(use_alternate_signal_stack());  // this thread's; the others install their own
  struct sigaction action {};
  sigemptyset(&action.sa_mask);
  action.sa_sigaction = on_stop_signal;
  // Restarted: a write of the trace under way when the signal comes completes (the loop polls
  // the flag; nothing waits for EINTR), so the trace stays whole to its last row.
  action.sa_flags = SA_RESTART | SA_SIGINFO | SA_ONSTACK;
  for (std::size_t i = 0; i < std::size(kStopSignals); ++i) sigaction(kStopSignals[i], &action, &g_old_stop[i]);
  action.sa_handler = on_fatal_signal;
  // On the alternate stack: a stack overflow is a SIGSEGV that the overflowed stack cannot run
  // a handler on.
  action.sa_flags = static_cast<int>(SA_RESETHAND | SA_ONSTACK);
  for (const int s : kFatalSignals) sigaction(s, &action, nullptr);
  // A closed pipe (`--trace - | head`) is a write error that the writer reports, never a death.
  struct sigaction ignore {};
  sigemptyset(&ignore.sa_mask);
  ignore.sa_handler = SIG_IGN;
  sigaction(SIGPIPE, &ignore, &g_old_pipe);
}

void restore_signals() {
  for (std::size_t i = 0; i < std::size(kStopSignals); ++i) sigaction(kStopSignals[i], &g_old_stop[i], nullptr);
  for (const int s : kFatalSignals) signal(s, SIG_DFL);
  sigaction(SIGPIPE, &g_old_pipe, nullptr);  // as it was (the toonforce program ignores it throughout)
  g_stop = nullptr;
  g_emergency = EmergencyZero{};
}

}  // namespace toonforce
