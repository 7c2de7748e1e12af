// SPDX-License-Identifier: Apache-2.0
// The server process's seccomp filter (server_sandbox.hpp).
#include "server_sandbox.hpp"

#include <fcntl.h>
#include <sched.h>
#include <seccomp.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <initializer_list>

#include <fmt/format.h>

namespace toonforce::cli {

namespace {

class Filter {
 public:
  Filter() : ctx_(seccomp_init(SCMP_ACT_KILL_PROCESS)) {}
  ~Filter() {
    if (ctx_ != nullptr) seccomp_release(ctx_);
  }
  Filter(const Filter&) = delete;
  Filter& operator=(const Filter&) = delete;

  void allow(const char* name, std::initializer_list<scmp_arg_cmp> args = {}) { add(SCMP_ACT_ALLOW, name, args); }
  void refuse(const char* name, int error) { add(SCMP_ACT_ERRNO(static_cast<std::uint32_t>(error)), name, {}); }

  std::string load() {
    if (ctx_ == nullptr) return "seccomp_init failed";
    if (!error_.empty()) return error_;
    // Every thread of the process, not only the calling one (the viewer's io thread, the
    // waiter): a thread left unfiltered would be the way out.
    if (const int rc = seccomp_attr_set(ctx_, SCMP_FLTATR_CTL_TSYNC, 1); rc != 0) {
      return fmt::format("cannot ask for all threads (TSYNC): {}", std::strerror(-rc));
    }
    if (const int rc = seccomp_attr_set(ctx_, SCMP_FLTATR_CTL_NNP, 1); rc != 0) {
      return fmt::format("cannot set no_new_privs: {}", std::strerror(-rc));
    }
    if (const int rc = seccomp_load(ctx_); rc != 0) return fmt::format("cannot load it: {}", std::strerror(-rc));
    return {};
  }

 private:
  void add(std::uint32_t action, const char* name, std::initializer_list<scmp_arg_cmp> args) {
    if (ctx_ == nullptr || !error_.empty()) return;
    const int nr = seccomp_syscall_resolve_name(name);
    if (nr == __NR_SCMP_ERROR) {
      error_ = fmt::format("no system call named {}", name);
      return;
    }
    if (nr < 0) return;  // not a call of this architecture (e.g. select on arm64): nothing to allow
    const int rc = seccomp_rule_add_array(ctx_, action, nr, static_cast<unsigned>(args.size()), args.begin());
    if (rc != 0) error_ = fmt::format("rule for {}: {}", name, std::strerror(-rc));
  }

  scmp_filter_ctx ctx_;
  std::string error_;
};

}  // namespace

std::string install_server_filter() {
  Filter f;
  const auto self = static_cast<scmp_datum_t>(getpid());

  // The sockets it already holds (the listener, the connections it accepts) and the standard
  // streams it prints to. No socket, socketpair, bind, listen or connect: it opens no new one.
  for (const char* name :
       {"accept", "accept4", "read", "readv", "write", "writev", "recvfrom", "recvmsg", "recvmmsg", "sendto", "sendmsg",
        "sendmmsg", "close", "shutdown", "getsockopt", "setsockopt", "getsockname", "getpeername"}) {
    f.allow(name);
  }
  // Asio's reactor: epoll, its eventfd interrupter and timerfd; poll/select for blocking calls.
  for (const char* name :
       {"epoll_create1", "epoll_ctl", "epoll_wait", "epoll_pwait", "epoll_pwait2", "poll", "ppoll", "select",
        "pselect6", "eventfd2", "timerfd_create", "timerfd_settime", "timerfd_gettime", "pipe2"}) {
    f.allow(name);
  }
  // Descriptor flags only (non-blocking, close-on-exec): no F_DUPFD, no locks, no leases.
  for (const int cmd : {F_GETFL, F_SETFL, F_GETFD, F_SETFD}) {
    f.allow("fcntl", {SCMP_A1(SCMP_CMP_EQ, static_cast<scmp_datum_t>(cmd))});
  }
  // ioctl: non-blocking mode and the bytes readable; nothing that reaches a terminal or device.
  for (const unsigned long request : {static_cast<unsigned long>(FIONBIO), static_cast<unsigned long>(FIONREAD)}) {
    f.allow("ioctl", {SCMP_A1(SCMP_CMP_EQ, static_cast<scmp_datum_t>(request))});
  }

  // Memory (malloc, thread stacks); never executable: the process has no code to load.
  f.allow("mmap", {SCMP_A2(SCMP_CMP_MASKED_EQ, PROT_EXEC, 0)});
  f.allow("mprotect", {SCMP_A2(SCMP_CMP_MASKED_EQ, PROT_EXEC, 0)});
  for (const char* name : {"munmap", "brk", "madvise", "mremap"}) f.allow(name);

  // Threads: std::thread and Asio start them. glibc tries clone3 first, whose flags sit in
  // memory the filter cannot read; refused with ENOSYS, glibc falls back to clone, allowed only
  // for a thread of this process (CLONE_THREAD), never a new process.
  f.refuse("clone3", ENOSYS);
  f.allow("clone", {SCMP_A0(SCMP_CMP_MASKED_EQ, CLONE_THREAD, CLONE_THREAD)});
  for (const char* name :
       {"futex", "set_robust_list", "rseq", "sched_yield", "exit", "exit_group", "restart_syscall"}) {
    f.allow(name);
  }

  // Time and sleeping.
  for (const char* name : {"clock_gettime", "clock_getres", "gettimeofday", "time", "nanosleep", "clock_nanosleep"}) {
    f.allow(name);
  }
  // Who it is and who its parent is (it ends when the loop's process is gone).
  for (const char* name : {"getpid", "gettid", "getppid"}) f.allow(name);
  // What glibc's pthread_getattr_np asks (sanitizer runtimes call it in every new thread):
  // its own affinity, and its limits read, never set.
  f.allow("sched_getaffinity");
  f.allow("prlimit64", {SCMP_A2(SCMP_CMP_EQ, 0)});
  // Signals: its own handlers (stop signals after the run), and raise()/abort() on itself only;
  // kill(), tgkill() and tkill() to any other process are refused.
  for (const char* name : {"rt_sigprocmask", "rt_sigaction", "rt_sigreturn", "sigaltstack"}) f.allow(name);
  f.allow("kill", {SCMP_A0(SCMP_CMP_EQ, self)});
  f.allow("tgkill", {SCMP_A0(SCMP_CMP_EQ, self)});
  f.allow("tkill", {SCMP_A0(SCMP_CMP_EQ, self)});
  f.allow("getrandom");

  return f.load();
}

}  // namespace toonforce::cli
