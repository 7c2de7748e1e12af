// SPDX-License-Identifier: Apache-2.0
// A real-time run of a servo loop (servo_session.hpp): signals, the telemetry writer thread,
// the terminal's commands, and the runner on the device's clock.
#include "toonforce/control/servo_session.hpp"

#include <poll.h>
#include <time.h>
#include <unistd.h>

#include <cstdio>
#include <exception>
#include <thread>

#include <fmt/format.h>

namespace toonforce {
namespace {

void sleep_ms(int ms) noexcept {
  timespec ts{0, static_cast<long>(ms) * 1'000'000L};
  nanosleep(&ts, nullptr);
}

std::atomic<int> g_stop{0};

}  // namespace

void request_session_stop(int signal) noexcept {
  int expected = 0;
  g_stop.compare_exchange_strong(expected, signal);
}

namespace {

/// Drains the queue until the run is over and the queue is empty.
void write_frames(FrameDrain& drain, const std::atomic<bool>& finished) {
  for (;;) {
    if (drain.drain_one()) continue;
    if (finished.load(std::memory_order_acquire)) {
      while (drain.drain_one()) {  // the servo thread is done: what is left is all there is
      }
      return;
    }
    sleep_ms(2);
  }
}

/// Reads 'r' (re-arm) and 'q' (stop) from a terminal while the run lasts.
void read_commands(RearmRequest rearm, std::atomic<int>& stop, const std::atomic<bool>& finished) {
  char buffer[64];
  while (!finished.load(std::memory_order_acquire) && stop.load() == 0) {
    pollfd in{STDIN_FILENO, POLLIN, 0};
    if (poll(&in, 1, 100) <= 0 || (in.revents & POLLIN) == 0) continue;
    const ssize_t n = ::read(STDIN_FILENO, buffer, sizeof buffer);
    if (n <= 0) return;  // end of input
    for (ssize_t i = 0; i < n; ++i) {
      if (buffer[i] == 'r' && rearm.request != nullptr) rearm.request(rearm.loop);
      if (buffer[i] == 'q') {
        int expected = 0;
        stop.compare_exchange_strong(expected, kStopByUser);
      }
    }
  }
}

void zero_device(void* device) noexcept { static_cast<DeviceDriver*>(device)->emergency_zero(); }

}  // namespace

Result<SessionReport> run_session(PeriodicTask& task, FrameDrain& drain, DeviceDriver& device,
                                  const SessionOptions& options, RearmRequest rearm) {
  g_stop.store(0);
  if (options.handle_signals) install_signal_handlers(g_stop, EmergencyZero{zero_device, &device});
  if (options.pending_stop != nullptr && options.pending_stop->load() != 0) {
    int expected = 0;
    g_stop.compare_exchange_strong(expected, options.pending_stop->load());
  }
  SessionReport session;
  session.interactive = options.interactive && isatty(STDIN_FILENO) != 0;
  std::atomic<bool> finished{false};
  std::thread writer([&] {
    static_cast<void>(use_alternate_signal_stack());
    write_frames(drain, finished);
  });
  std::thread commands;
  if (session.interactive) {
    // fputs, not fmt::print: a failed write must not throw past the joinable writer thread.
    std::fputs("running; type q and Enter (or Ctrl-C) to stop, r and Enter to re-arm after a fault\n",
               options.messages);
    commands = std::thread([&] {
      static_cast<void>(use_alternate_signal_stack());
      read_commands(rearm, g_stop, finished);
    });
  }

  // A thread refused for want of memory must not pass the joinable writer (std::terminate).
  Result<RunReport> report = Error{std::string()};
  try {
    report = run_on_device(task, device, options.realtime, g_stop);
  } catch (const std::exception& e) {
    report = Error{fmt::format("the run could not start: {} (too little memory: `ulimit -v`?)", e.what())};
  }

  finished.store(true, std::memory_order_release);
  writer.join();
  if (commands.joinable()) commands.join();
  drain.finish();
  if (options.handle_signals) restore_signals();
  if (!report) return Error{report.error()};
  session.report = std::move(report.value());
  session.frames_dropped = drain.dropped();
  return session;
}

}  // namespace toonforce
