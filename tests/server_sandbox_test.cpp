// SPDX-License-Identifier: Apache-2.0
// The server process's seccomp filter (tools/cli/server_sandbox.hpp), shown to act: each case
// forks a child of this test, installs the very filter the server installs, and makes one call.
// What serving needs goes through; what an attacker who took the parser over would try next
// (open a file, ptrace or signal the loop's process, exec a program, open a socket) kills the
// child with SIGSYS.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <linux/futex.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/ptrace.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/uio.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <string>
#include <thread>

#include "server_sandbox.hpp"

namespace toonforce::cli {
namespace {

constexpr int kFilterFailed = 100;

/// Forks; the child installs the filter and exits with `body()`'s value. The child's wait status.
template <class Body>
int status_of_filtered_child(Body body) {
  const pid_t pid = fork();
  if (pid == 0) {
    if (!install_server_filter().empty()) _exit(kFilterFailed);
    _exit(body());
  }
  int status = 0;
  if (pid < 0 || waitpid(pid, &status, 0) != pid) return -1;
  return status;
}

::testing::AssertionResult killed_by_sigsys(int status) {
  if (WIFSIGNALED(status) && WTERMSIG(status) == SIGSYS) return ::testing::AssertionSuccess();
  if (WIFEXITED(status)) {
    return ::testing::AssertionFailure() << "the child exited with status " << WEXITSTATUS(status)
                                         << " (the call went through, or the filter was not installed: "
                                         << kFilterFailed << ")";
  }
  return ::testing::AssertionFailure() << "wait status " << status;
}

::testing::AssertionResult exited_0(int status) {
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return ::testing::AssertionSuccess();
  if (WIFSIGNALED(status)) return ::testing::AssertionFailure() << "killed by signal " << WTERMSIG(status);
  return ::testing::AssertionFailure() << "exited with status " << WEXITSTATUS(status);
}

std::string slurp(const std::string& path) {
  std::string out;
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return out;
  char buffer[4096];
  for (ssize_t n; (n = read(fd, buffer, sizeof buffer)) > 0;) out.append(buffer, static_cast<std::size_t>(n));
  close(fd);
  return out;
}

// In force on the process, as the server's /proc/PID/status shows it: read while the child,
// filtered, waits on a pipe (so read and write go through).
TEST(ServerSandbox, IsInForceWithNoNewPrivileges) {
  int to_parent[2];
  int to_child[2];
  ASSERT_EQ(pipe2(to_parent, O_CLOEXEC), 0);
  ASSERT_EQ(pipe2(to_child, O_CLOEXEC), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    if (!install_server_filter().empty()) _exit(kFilterFailed);
    char c = 'i';
    if (write(to_parent[1], &c, 1) != 1) _exit(1);
    if (read(to_child[0], &c, 1) != 1) _exit(2);
    _exit(0);
  }
  char c = 0;
  const bool installed = read(to_parent[0], &c, 1) == 1;
  const std::string status = slurp("/proc/" + std::to_string(pid) + "/status");
  EXPECT_EQ(write(to_child[1], "g", 1), 1);
  int wait_status = 0;
  ASSERT_EQ(waitpid(pid, &wait_status, 0), pid);
  for (const int fd : {to_parent[0], to_parent[1], to_child[0], to_child[1]}) close(fd);
  ASSERT_TRUE(installed) << "the child ended before it said it was filtered: " << wait_status;
  EXPECT_TRUE(exited_0(wait_status));
  EXPECT_NE(status.find("Seccomp:\t2"), std::string::npos) << status;
  EXPECT_NE(status.find("NoNewPrivs:\t1"), std::string::npos) << status;
}

// What the server does once it serves: read and write its descriptors, memory, futexes, a new
// thread, time, sleeping, random bytes, a signal to itself.
TEST(ServerSandbox, LetsThroughWhatServingNeeds) {
  EXPECT_TRUE(exited_0(status_of_filtered_child([] {
    int fds[2];
    if (pipe2(fds, O_CLOEXEC | O_NONBLOCK) != 0) return 1;
    char c = 'x';
    if (write(fds[1], &c, 1) != 1 || read(fds[0], &c, 1) != 1) return 2;
    void* p = mmap(nullptr, 1 << 20, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED || munmap(p, 1 << 20) != 0) return 3;
    std::atomic<int> word{0};
    if (syscall(SYS_futex, &word, FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr, 0) < 0) return 4;
    int seen = 0;
    std::thread thread([&] { seen = 1; });
    thread.join();
    if (seen != 1) return 5;
    timespec now{};
    const timespec pause{0, 1000};
    if (clock_gettime(CLOCK_MONOTONIC, &now) != 0 || nanosleep(&pause, nullptr) != 0) return 6;
    unsigned char bytes[8];
    if (getrandom(bytes, sizeof bytes, 0) != static_cast<ssize_t>(sizeof bytes)) return 7;
    if (kill(getpid(), 0) != 0 || getppid() <= 0) return 8;
    close(fds[0]);
    close(fds[1]);
    return 0;
  })));
}

/// One call the filter must refuse, by name.
struct Refused {
  const char* name;
  int (*call)();
};

const Refused kRefused[] = {
    {"openat", [] { return static_cast<int>(syscall(SYS_openat, AT_FDCWD, "/etc/hostname", O_RDONLY | O_CLOEXEC)); }},
    {"ptrace_of_the_parent", [] { return static_cast<int>(syscall(SYS_ptrace, PTRACE_ATTACH, getppid(), 0, 0)); }},
    {"kill_of_the_parent", [] { return static_cast<int>(syscall(SYS_kill, getppid(), 0)); }},
    {"tgkill_of_the_parent", [] { return static_cast<int>(syscall(SYS_tgkill, getppid(), getppid(), 0)); }},
    {"execve",
     [] {
       char* const argv[] = {const_cast<char*>("/bin/true"), nullptr};
       return static_cast<int>(syscall(SYS_execve, "/bin/true", argv, environ));
     }},
    {"socket", [] { return static_cast<int>(syscall(SYS_socket, AF_INET, SOCK_STREAM, 0)); }},
    {"process_vm_readv_of_the_parent",
     [] {
       char mine[8];
       char theirs[8];
       iovec local{mine, sizeof mine};
       iovec remote{theirs, sizeof theirs};
       return static_cast<int>(syscall(SYS_process_vm_readv, getppid(), &local, 1, &remote, 1, 0));
     }},
    {"fork", [] { return static_cast<int>(fork()); }},
    {"executable_memory",
     [] {
       void* p = mmap(nullptr, 4096, PROT_READ | PROT_EXEC, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
       return p == MAP_FAILED ? -1 : 0;
     }},
};

class ServerSandboxRefuses : public ::testing::TestWithParam<Refused> {};

TEST_P(ServerSandboxRefuses, KillsTheProcess) {
  const Refused refused = GetParam();
  EXPECT_TRUE(killed_by_sigsys(status_of_filtered_child([&] {
    refused.call();
    return 0;  // the call went through (or failed) without the filter killing it
  })));
}

INSTANTIATE_TEST_SUITE_P(ServerSandbox, ServerSandboxRefuses, ::testing::ValuesIn(kRefused),
                         [](const ::testing::TestParamInfo<Refused>& p) { return std::string(p.param.name); });

}  // namespace
}  // namespace toonforce::cli
