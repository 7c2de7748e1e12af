// SPDX-License-Identifier: Apache-2.0
#pragma once
// The guardian (control/guardian.hpp) watching a stand-in for the loop's process: a forked
// child that only ticks the shared heartbeat every millisecond, as the runner does, until this
// test kills it with SIGKILL. The device side is real (the emulated Falcon's usbfs node, the
// emulated GPIO line): what is tested is that the guardian, from outside the process, zeroes it.
// The child touches nothing but the shared page and the clock (fork() in a threaded test
// process allows no more).
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <chrono>
#include <thread>
#include <type_traits>
#include <vector>

#include "toonforce/control/guardian.hpp"

namespace toonforce::test {

struct GuardedStandIn {
  guardian::GuardOutcome outcome;
  std::int64_t killed_ns = 0;         ///< CLOCK_MONOTONIC just before the kill
  bool active_while_ticking = false;  ///< the enable line, sampled while the stand-in ticked
};

inline std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// `sample_enable`: called while the stand-in ticks (before the kill), returns whether the
/// enable line is active; may be null.
/// `zeros`: each device's (a world's devices), at most guardian::kMaxGuardedDevices.
template <class Sample = bool (*)()>
GuardedStandIn guard_a_stand_in(const std::vector<ExternalZero>& zeros, guardian::EnableLine* enable,
                                Sample sample_enable = nullptr) {
  GuardedStandIn result;
  guardian::SharedPage* page = guardian::map_shared_page();
  if (page == nullptr) return result;
  for (std::size_t i = 0; i < zeros.size() && i < guardian::kMaxGuardedDevices; ++i) page->zeros[i] = zeros[i];
  page->zero_count = static_cast<std::uint32_t>(zeros.size());
  page->period_ns = 1'000'000;
  page->guardian_pid = getpid();
  page->phase.store(static_cast<std::uint32_t>(guardian::Phase::kDeviceOpen));
  const pid_t child = fork();
  if (child == 0) {
    for (std::int64_t k = 1;; ++k) {
      page->heartbeat.store(k, std::memory_order_release);
      timespec ts{0, 1'000'000};
      nanosleep(&ts, nullptr);
    }
  }
  // The killer: once the stand-in has ticked 200 times (and the guardian has raised the enable
  // line), SIGKILL, stamped.
  std::thread killer([&] {
    while (page->heartbeat.load() < 200) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if constexpr (!std::is_same_v<Sample, bool (*)()>) result.active_while_ticking = sample_enable();
    result.killed_ns = monotonic_ns();
    kill(child, SIGKILL);
  });
  guardian::GuardOptions options;
  options.enable = enable;
  result.outcome = guardian::guard(child, *page, options);
  killer.join();
  munmap(page, sizeof *page);
  return result;
}

template <class Sample = bool (*)()>
GuardedStandIn guard_a_stand_in(const ExternalZero& zero, guardian::EnableLine* enable,
                                Sample sample_enable = nullptr) {
  return guard_a_stand_in(std::vector<ExternalZero>{zero}, enable, sample_enable);
}

}  // namespace toonforce::test
