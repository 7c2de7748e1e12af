// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/staged_outputs.hpp"

#include <fcntl.h>
#include <linux/limits.h>
#include <signal.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>

#include <fmt/format.h>

#include "toonforce/control/realtime_runner.hpp"

namespace toonforce::report {

namespace fs = std::filesystem;

namespace {

// The staged files the stop handler removes: a fixed table (no allocation in the handler). A
// slot's path is written before it is marked in use, and unmarked before it is reused. A step
// stages at most a few dozen files (stability: two per map and its document).
constexpr int kSlots = 64;
std::array<std::array<char, PATH_MAX>, kSlots> g_staged_paths{};
std::array<std::atomic<bool>, kSlots> g_staged_in_use{};
std::atomic<pid_t> g_waited_child{0};
const char* g_command = "toonforce-lab report";
const char* g_left = kReportLeaves;

int take_slot(const fs::path& staged) noexcept {
  const std::string& text = staged.native();
  if (text.size() >= PATH_MAX) return -1;
  for (int i = 0; i < kSlots; ++i) {
    auto& used = g_staged_in_use[static_cast<std::size_t>(i)];
    if (used.load()) continue;
    auto& buffer = g_staged_paths[static_cast<std::size_t>(i)];
    std::memcpy(buffer.data(), text.c_str(), text.size() + 1);
    used.store(true);
    return i;
  }
  return -1;
}

void free_slot(int slot) noexcept {
  if (slot >= 0) g_staged_in_use[static_cast<std::size_t>(slot)].store(false);
}

void say(const char* text) noexcept {
  std::size_t left = std::strlen(text);
  while (left > 0) {
    const ssize_t n = ::write(STDERR_FILENO, text, left);
    if (n <= 0) return;  // nothing more can be said
    text += n;
    left -= static_cast<std::size_t>(n);
  }
}

void on_stop(int signo, siginfo_t* info, void*) {
  if (is_file_size_limit_signal(signo, info)) return;  // the write fails with EFBIG and says so
  // The child first, so that it cannot create a staged file after it was removed.
  if (const pid_t child = g_waited_child.load(); child > 0) {
    ::kill(child, SIGKILL);
    while (::waitpid(child, nullptr, 0) < 0 && errno == EINTR) {
    }
  }
  for (int i = 0; i < kSlots; ++i) {
    if (g_staged_in_use[static_cast<std::size_t>(i)].load())
      ::unlink(g_staged_paths[static_cast<std::size_t>(i)].data());
  }
  const char* name = sigabbrev_np(signo);
  say(g_command);
  say(": stopped by SIG");
  say(name != nullptr ? name : "?");
  say("; ");
  say(g_left);
  say("\n");
  ::_exit(1);
}

}  // namespace

StagedOutputs::~StagedOutputs() {
  for (const auto& entry : entries_) {
    std::error_code ec;
    fs::remove(entry.staged, ec);
    free_slot(entry.slot);
  }
}

Result<fs::path> StagedOutputs::stage(const fs::path& target) {
  // Hidden, beside the target (a rename within one file system), unique to this process, with
  // the target's extension (matplotlib picks the format from it).
  const fs::path staged = target.parent_path() / fmt::format(".{}.staged-{}{}", target.stem().string(), ::getpid(),
                                                             target.extension().string());
  const int slot = take_slot(staged);
  if (slot < 0)
    return Error{fmt::format("cannot stage {}: too many files in one step, or the path is too long", target.string())};
  entries_.push_back(Entry{staged, target, slot});
  return staged;
}

Result<fs::path> StagedOutputs::write(const fs::path& target, const std::string& text) {
  auto staged = stage(target);
  if (!staged) return Error{staged.error()};
  const int fd = ::open(staged->c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Error{fmt::format("cannot write {}: {}", target.string(), std::strerror(errno))};
  const char* data = text.data();
  std::size_t left = text.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, data, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = n < 0 ? errno : EIO;
      ::close(fd);
      return Error{fmt::format("cannot write {}: {}", target.string(), std::strerror(error))};
    }
    data += n;
    left -= static_cast<std::size_t>(n);
  }
  // On disk before the rename, so a power cut leaves the old file or the whole new one.
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    return Error{fmt::format("cannot write {}: {}", target.string(), std::strerror(errno))};
  }
  return staged;
}

Result<std::vector<std::string>> StagedOutputs::commit() {
  std::vector<std::string> targets;
  for (auto& entry : entries_) {
    std::error_code ec;
    fs::rename(entry.staged, entry.target, ec);
    if (ec) return Error{fmt::format("cannot put {} in place: {}", entry.target.string(), ec.message())};
    free_slot(entry.slot);
    entry.slot = -1;
    targets.push_back(entry.target.string());
  }
  entries_.clear();
  return targets;
}

void install_report_stop_handlers(const char* command, const char* left) {
  g_command = command;
  g_left = left;
  struct sigaction action {};
  action.sa_sigaction = on_stop;
  action.sa_flags = SA_SIGINFO;
  sigfillset(&action.sa_mask);  // one stop at a time
  for (const int signo : stop_signals()) sigaction(signo, &action, nullptr);
}

void set_waited_child(pid_t pid) noexcept { g_waited_child.store(pid); }

}  // namespace toonforce::report
