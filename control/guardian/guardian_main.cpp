// SPDX-License-Identifier: Apache-2.0
// toonforce-guardian: the guardian process of `toonforce run` (guardian.hpp). `run` forks, and
// its parent execs this program, so the loop's process is this process's child:
//
//   toonforce-guardian --loop-pid PID --page-fd FD [--stall-limit-ms MS] [--priority P]
//                      [--enable-chip /dev/gpiochipN --enable-offset N [--enable-active-low]]
//                      -- EPILOGUE...
//
// It watches the loop's process until it ends. If it ended as `run` ends, this process exits as
// it did (its status, or its signal). If it died while its device was open, the guardian zeroes
// the force, writes its verdict into the page and execs EPILOGUE with "--page-fd FD" appended
// (`toonforce run-epilogue ...`: the trace's zero-force row, the statistics, the words); if that
// cannot start, it says so in one line and exits with status 3. Nothing here parses more than
// its own arguments, each a number or a fixed word.
#include <sched.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/control/guardian.hpp"
#include "toonforce/control/realtime_runner.hpp"

namespace {

using namespace toonforce;

/// A whole decimal number in [lo, hi], or false.
bool number(const char* text, long long lo, long long hi, long long& out) {
  if (text == nullptr || *text == '\0') return false;
  errno = 0;
  char* end = nullptr;
  const long long v = std::strtoll(text, &end, 10);
  if (errno != 0 || end == text || *end != '\0' || v < lo || v > hi) return false;
  out = v;
  return true;
}

int usage(const char* what) {
  std::fprintf(stderr,
               "toonforce-guardian: %s\n"
               "  (toonforce run starts this program; it is not meant to be run by hand)\n",
               what);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  long long loop = -1;
  long long page_fd = -1;
  long long stall_ms = 500;
  long long priority = 0;
  const char* enable_chip = nullptr;
  long long enable_offset = -1;
  bool enable_active_low = false;
  int epilogue_at = -1;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    const char* value = i + 1 < argc ? argv[i + 1] : nullptr;
    if (a == "--") {
      epilogue_at = i + 1;
      break;
    }
    bool ok = true;
    if (a == "--loop-pid") {
      ok = number(value, 1, 0x7fffffff, loop);
      ++i;
    } else if (a == "--page-fd") {
      ok = number(value, 0, 1 << 20, page_fd);
      ++i;
    } else if (a == "--stall-limit-ms") {
      ok = number(value, 50, 10'000, stall_ms);
      ++i;
    } else if (a == "--priority") {
      ok = number(value, 0, 99, priority);
      ++i;
    } else if (a == "--enable-chip") {
      enable_chip = value;
      ok = value != nullptr;
      ++i;
    } else if (a == "--enable-offset") {
      ok = number(value, 0, 0xffff, enable_offset);
      ++i;
    } else if (a == "--enable-active-low") {
      enable_active_low = true;
    } else {
      ok = false;
    }
    if (!ok) return usage(("bad argument: " + std::string(a)).c_str());
  }
  if (loop <= 0 || page_fd < 0) return usage("--loop-pid and --page-fd are required");
  const auto loop_pid = static_cast<pid_t>(loop);
  guardian::SharedPage* page = guardian::attach_shared_page(static_cast<int>(page_fd));
  if (page == nullptr) {
    std::fprintf(stderr,
                 "toonforce-guardian: descriptor %lld is not the guardian's page; stopping the loop's process\n",
                 page_fd);
    ::kill(loop_pid, SIGTERM);
    return 2;
  }
  // Above the loop's priority when it may (a wedged loop thread must not starve it); without the
  // permission it runs at normal priority (its end is seen by the kernel's wake-up on the pidfd
  // either way).
  if (priority > 0) {
    sched_param sp{};
    sp.sched_priority = static_cast<int>(priority);
    static_cast<void>(sched_setscheduler(0, SCHED_FIFO, &sp));
  }
  guardian::GpioEnableLine enable;
  guardian::GuardOptions options;
  options.stall_limit_ns = stall_ms * 1'000'000;
  if (enable_chip != nullptr) {
    const std::string bad =
        enable_offset < 0 ? std::string("--enable-chip needs --enable-offset")
                          : enable.open(enable_chip, static_cast<std::uint32_t>(enable_offset), enable_active_low);
    if (!bad.empty()) {
      // The loop's process waits for the guardian before it opens its device (ready below): it
      // is told, and ends without having commanded any force.
      std::fprintf(stderr, "--amp-enable-pin: the guardian cannot hold the line: %s; the loop does not start\n",
                   bad.c_str());
      page->guardian_ready.store(2, std::memory_order_release);
      int status = 0;
      ::waitpid(loop_pid, &status, 0);
      return 2;
    }
    options.enable = &enable;
  }
  // `run` blocked the stop signals before it forked: guard() lets them through once its
  // handlers are in place, so none is lost and none takes its default action.
  options.unblock_stop_signals = true;
  page->guardian_ready.store(1, std::memory_order_release);
  const guardian::GuardOutcome outcome = guardian::guard(loop_pid, *page, options);
  const int status = outcome.wait_status;
  if (!outcome.loop_died) {
    // It ended as `run` ends, or before its device opened (no force of its own then): its
    // status is the command's; a signal's default action is passed on as such.
    if (WIFSIGNALED(status)) {
      signal(WTERMSIG(status), SIG_DFL);
      sigset_t one;
      sigemptyset(&one);
      sigaddset(&one, WTERMSIG(status));
      sigprocmask(SIG_UNBLOCK, &one, nullptr);
      raise(WTERMSIG(status));
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : 1;
  }
  // A death: exit status 3, or the loop's own when it exited by itself with its loop running
  // (a second stop signal: 128 + its number).
  const int exit_status =
      WIFEXITED(status) && !outcome.stalled && WEXITSTATUS(status) != 0 ? WEXITSTATUS(status) : guardian::kExitLoopDied;
  page->verdict = guardian::make_verdict(outcome, loop_pid, exit_status);
  if (epilogue_at > 0 && epilogue_at < argc) {
    std::vector<char*> args(argv + epilogue_at, argv + argc);
    std::string fd_text = std::to_string(page_fd);
    std::string flag = "--page-fd";
    args.push_back(flag.data());
    args.push_back(fd_text.data());
    args.push_back(nullptr);
    std::fflush(stderr);
    ::execv(args[0], args.data());
    std::fprintf(stderr, "toonforce-guardian: cannot start %s (%s)\n", args[0], std::strerror(errno));
  }
  std::fprintf(stderr, "guardian: the loop's process (pid %d) ended during the loop: %s; %s\n",
               static_cast<int>(loop_pid), outcome.cause.c_str(), outcome.zero_detail.c_str());
  return exit_status;
}
