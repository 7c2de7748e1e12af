// SPDX-License-Identifier: Apache-2.0
// A command's stop path outside its servo loop (command_stop.hpp).
#include "toonforce/run/command_stop.hpp"

#include <signal.h>
#include <unistd.h>

#include <array>

#include "toonforce/control/realtime_runner.hpp"

namespace toonforce {
namespace {

std::atomic<int> g_stop{0};
constexpr std::size_t kMaxSignals = 32;
std::array<struct sigaction, kMaxSignals> g_old_actions{};
bool g_installed = false;

extern "C" void on_command_stop(int signal, siginfo_t* info, void* /*context*/) {
  // The kernel's SIGXFSZ (a file-size limit) is a write error the writer reports, not a stop;
  // one sent with kill() is a stop like the loop's (realtime_runner.cpp).
  if (is_file_size_limit_signal(signal, info)) return;
  int expected = 0;
  g_stop.compare_exchange_strong(expected, signal);  // the first one is the reason
}

}  // namespace

std::atomic<int>& command_stop() { return g_stop; }

bool command_stop_signals_installed() { return g_installed; }

void install_command_stop_signals() {
  if (g_installed) return;
  g_stop.store(0);
  struct sigaction action {};
  action.sa_sigaction = on_command_stop;
  // Restarted: a message or a statistics file being written when the signal comes completes.
  action.sa_flags = SA_SIGINFO | SA_RESTART;
  sigemptyset(&action.sa_mask);
  const auto signals = stop_signals();
  for (std::size_t i = 0; i < signals.size() && i < kMaxSignals; ++i) sigaction(signals[i], &action, &g_old_actions[i]);
  g_installed = true;
}

void restore_command_stop_signals() {
  if (!g_installed) return;
  const auto signals = stop_signals();
  for (std::size_t i = 0; i < signals.size() && i < kMaxSignals; ++i) sigaction(signals[i], &g_old_actions[i], nullptr);
  g_installed = false;
}

}  // namespace toonforce
