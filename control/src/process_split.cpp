// SPDX-License-Identifier: Apache-2.0
// `toonforce run`'s process split (process_split.hpp).
#include "toonforce/control/process_split.hpp"

#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include <fmt/format.h>

#include "toonforce/control/realtime_runner.hpp"

namespace toonforce {
namespace {

sigset_t stop_set() noexcept {
  sigset_t set;
  sigemptyset(&set);
  for (const int signo : stop_signals()) sigaddset(&set, signo);
  return set;
}

std::string self_directory() {
  char path[PATH_MAX] = {};
  const ssize_t n = ::readlink("/proc/self/exe", path, sizeof path - 1);
  if (n <= 0) return {};
  std::string exe(path, static_cast<std::size_t>(n));
  const std::size_t slash = exe.rfind('/');
  return slash == std::string::npos ? std::string() : exe.substr(0, slash);
}

/// The loop's process's second parent-death signal (guardian.hpp): a thread that asks for
/// SIGCONT when the guardian dies, so that a loop stopped as a whole (SIGSTOP, a group stop)
/// whose guardian died is continued, takes the SIGTERM its main thread asked for, and stops with
/// zero force instead of staying behind holding the device. It only waits.
extern "C" void* continue_on_guardian_death(void* guardian) {
  sigset_t all;
  sigfillset(&all);
  pthread_sigmask(SIG_BLOCK, &all, nullptr);  // the process's signals are the other threads'
  prctl(PR_SET_PDEATHSIG, SIGCONT);
  if (getppid() != static_cast<pid_t>(reinterpret_cast<std::intptr_t>(guardian))) kill(getpid(), SIGCONT);
  for (;;) pause();
  return nullptr;
}

}  // namespace

Result<std::string> guardian_program_path() {
  const std::string here = self_directory();
  for (const std::string& candidate :
       {here + "/toonforce-guardian", here + "/../libexec/toonforce/toonforce-guardian"}) {
    if (!here.empty() && ::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return Error{fmt::format("the guardian program toonforce-guardian is not beside {} (nor in ../libexec/toonforce/): "
                           "reinstall toonforce, or run with --no-guardian to debug the loop in one process",
                           here.empty() ? std::string("this program") : here)};
}

Result<guardian::SharedPage*> split_off_guardian(const GuardianStart& start) {
  int fd = -1;
  guardian::SharedPage* page = guardian::create_shared_page(fd);
  if (page == nullptr) {
    return Error{
        fmt::format("cannot make the page shared with the guardian process: {} (--no-guardian runs without it)",
                    std::strerror(errno))};
  }
  // The guardian's arguments, made before the fork (the parent only execs after it).
  const pid_t guardian_pid = getpid();
  page->guardian_pid = guardian_pid;
  std::vector<std::string> args{start.program,
                                "--page-fd",
                                std::to_string(fd),
                                "--stall-limit-ms",
                                fmt::format("{:.0f}", start.stall_limit_ms),
                                "--priority",
                                std::to_string(start.priority)};
  if (!start.enable_chip.empty()) {
    args.insert(args.end(),
                {"--enable-chip", start.enable_chip, "--enable-offset", std::to_string(start.enable_offset)});
    if (start.enable_active_low) args.emplace_back("--enable-active-low");
  }
  args.emplace_back("--loop-pid");
  args.emplace_back();  // filled in by the parent after the fork
  args.emplace_back("--");
  args.insert(args.end(), start.epilogue.begin(), start.epilogue.end());
  std::vector<char*> argv;
  argv.reserve(args.size() + 1);
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const std::size_t loop_pid_at = args.size() - start.epilogue.size() - 2;
  char loop_pid_text[16] = {};
  argv[loop_pid_at] = loop_pid_text;

  const sigset_t stops = stop_set();
  sigset_t before;
  sigprocmask(SIG_BLOCK, &stops, &before);
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t loop = fork();
  if (loop < 0) {
    const int error = errno;
    sigprocmask(SIG_SETMASK, &before, nullptr);
    ::close(fd);
    guardian::unmap_shared_page(page);
    return Error{
        fmt::format("cannot start the loop's process: {} (--no-guardian runs without it)", std::strerror(error))};
  }
  if (loop == 0) {
    // The loop's process: SIGTERM when the guardian dies (it stops with zero force, as on any
    // stop signal); the guardian may be gone already. The page's descriptor is the guardian's.
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != guardian_pid) raise(SIGTERM);  // blocked: taken once the handlers are in
    ::close(fd);
    return page;
  }
  // The guardian: the descriptor goes across the exec, nothing else of this process does.
  std::snprintf(loop_pid_text, sizeof loop_pid_text, "%d", static_cast<int>(loop));
  const int flags = fcntl(fd, F_GETFD);
  if (flags >= 0) fcntl(fd, F_SETFD, flags & ~FD_CLOEXEC);
  ::execv(argv[0], argv.data());
  const int error = errno;
  std::fprintf(stderr, "cannot start the guardian program %s: %s; the loop does not start\n", argv[0],
               std::strerror(error));
  page->guardian_ready.store(2, std::memory_order_release);
  int status = 0;
  ::waitpid(loop, &status, 0);
  std::_Exit(2);
}

void unblock_stop_signals() noexcept {
  const sigset_t stops = stop_set();
  sigprocmask(SIG_UNBLOCK, &stops, nullptr);
}

bool wait_for_guardian(const guardian::SharedPage& page, double timeout_s) noexcept {
  const auto polls = static_cast<long>(timeout_s * 1000.0);
  for (long i = 0; i <= polls; ++i) {
    const std::uint32_t ready = page.guardian_ready.load(std::memory_order_acquire);
    if (ready == 1) {
      // Armed only now, before the device opens: the process had to be single-threaded until
      // it forked its server process.
      pthread_t thread{};
      pthread_attr_t attr;
      pthread_attr_init(&attr);
      pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
      pthread_attr_setstacksize(&attr, std::size_t{64} * 1024);
      // The thread's one argument carries the pid as a pointer-sized integer; nothing
      // dereferences it, so the check's concern (pointer provenance) does not arise.
      // NOLINTBEGIN(performance-no-int-to-ptr)
      const int made = pthread_create(&thread, &attr, continue_on_guardian_death,
                                      reinterpret_cast<void*>(static_cast<std::intptr_t>(page.guardian_pid)));
      // NOLINTEND(performance-no-int-to-ptr)
      pthread_attr_destroy(&attr);
      // Without it (no memory for a thread), a stopped orphan waits for a SIGCONT from someone
      // else, as any stopped process does (DEPLOY.md): the run goes on.
      static_cast<void>(made);
      return true;
    }
    if (ready == 2) return false;
    timespec ts{0, 1'000'000};
    nanosleep(&ts, nullptr);
  }
  return false;
}

}  // namespace toonforce
