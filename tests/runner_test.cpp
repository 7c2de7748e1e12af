// SPDX-License-Identifier: Apache-2.0
// The real-time runner and `toonforce run`, asserting counts and file contents, never times
// (this VM has multi-millisecond hypervisor stalls: docs/performance/latency.md, measured with cyclictest).
// In process: every deadline is either ticked or counted as missed; a stalled tick trips the
// heartbeat watchdog; a sim run writes one trace row per tick plus the final zero-force row.
// The binary as a child process under signals and faults: fault_injection_test.cpp.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "toonforce/control/realtime_runner.hpp"
#include "toonforce/run/guardian_report.hpp"
#include "toonforce/run/run.hpp"
#include "toonforce/trace/json.hpp"
#include "toonforce/trace/telemetry_trace.hpp"

extern char** environ;

namespace toonforce {
namespace {

std::filesystem::path temp_path(const std::string& name) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string file = std::string("toonforce_") + info->test_suite_name() + "_" + info->name() + "_" +
                     std::to_string(getpid()) + "_" + name;
  std::replace(file.begin(), file.end(), '/', '_');  // parameterised names contain '/'
  return std::filesystem::temp_directory_path() / file;
}

std::vector<std::string> lines_of(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<double> fields(const std::string& line) {
  std::vector<double> out;
  std::stringstream ss(line);
  for (std::string cell; std::getline(ss, cell, ',');) {
    char* end = nullptr;
    const double v = std::strtod(cell.c_str(), &end);
    out.push_back(end != cell.c_str() && *end == '\0' ? v : std::nan("bad"));
  }
  return out;
}

// ---- the runner with a counting task ---------------------------------------------------------

struct CountingTask final : PeriodicTask {
  std::vector<std::int64_t> ticks;
  std::atomic<std::int64_t> publishes{0};  ///< read by a stopper thread while the loop runs
  std::int64_t shutdowns = 0;
  std::int64_t shutdown_at = -1;
  std::int64_t stall_at = -1;  ///< the first tick from this one on sleeps 100 ms
  std::int64_t stalled = -1;   ///< the tick that slept (a late deadline may skip stall_at itself)
  void tick(std::int64_t k) noexcept override {
    ticks.push_back(k);  // reserved beforehand: no allocation here
    if (stall_at >= 0 && stalled < 0 && k >= stall_at) {
      stalled = k;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  void publish(std::int64_t, const TickTiming&) noexcept override { publishes.fetch_add(1); }
  void shutdown(std::int64_t k) noexcept override {
    ++shutdowns;
    shutdown_at = k;
  }
};

RealtimeOptions quick(std::int64_t deadlines) {
  RealtimeOptions o;
  o.rate_hz = 2000.0;
  o.deadlines = deadlines;
  o.allow_non_realtime = true;  // the test must run where SCHED_FIFO is refused, too
  o.lock_memory = false;
  return o;
}

TEST(RealtimeRunner, EveryDeadlineIsEitherTickedOrCountedAsMissedAndTimeOnlyMovesForward) {
  CountingTask task;
  task.ticks.reserve(1000);
  std::atomic<int> stop{0};
  const auto report = run_realtime(task, quick(600), EmergencyZero{}, stop);
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report->ticks + report->missed, 600);
  EXPECT_EQ(static_cast<std::int64_t>(task.ticks.size()), report->ticks);
  EXPECT_EQ(task.publishes.load(), report->ticks);
  EXPECT_EQ(task.shutdowns, 1);
  EXPECT_EQ(task.shutdown_at, 600);
  for (std::size_t i = 1; i < task.ticks.size(); ++i) ASSERT_GT(task.ticks[i], task.ticks[i - 1]);
  EXPECT_EQ(report->wake.count(), report->ticks);
  EXPECT_EQ(report->stop_signal, 0);
}

std::atomic<int> g_emergency_calls{0};
void count_emergency(void*) noexcept { g_emergency_calls.fetch_add(1); }

TEST(RealtimeRunner, AStalledTickIsSkippedNotBurstedAndTripsTheHeartbeatWatchdog) {
  CountingTask task;
  task.ticks.reserve(1000);
  task.stall_at = 100;
  g_emergency_calls = 0;
  std::atomic<int> stop{0};
  RealtimeOptions o = quick(600);
  o.watchdog_periods = 30;  // 15 ms at 2 kHz, well under the 100 ms stall
  const auto report = run_realtime(task, o, EmergencyZero{count_emergency, nullptr}, stop);
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report->ticks + report->missed, 600);
  EXPECT_GE(report->missed, 199) << "100 ms at 2 kHz is 200 periods";
  ASSERT_GE(task.stalled, 100);
  const auto after = std::find(task.ticks.begin(), task.ticks.end(), task.stalled);
  ASSERT_NE(after, task.ticks.end());
  ASSERT_NE(after + 1, task.ticks.end());
  EXPECT_GE(*(after + 1) - task.stalled, 200) << "the next tick runs at the latest passed deadline";
  EXPECT_GE(report->watchdog_trips, 1);
  EXPECT_GE(g_emergency_calls.load(), 1);
}

// ---- a stack overflow in the servo thread still commands zero force -----------------
// Without an alternate signal stack the fatal-signal handler had no stack to run on: the
// process died of SIGSEGV with the device's last force still commanded. A child process runs
// the real runner with its handlers; its device writes every command into a pipe, the
// parent reads what the device was told.

int g_device_pipe = -1;

/// A device as the loop sees it, reduced to its commands: each one goes out on the pipe as
/// "F <newtons>\n", the emergency zero as "Z 0\n" (write(2) is async-signal-safe).
void send_command(char kind, int newtons) noexcept {
  char text[16];
  const int n = std::snprintf(text, sizeof text, "%c %d\n", kind, newtons);
  if (n > 0) static_cast<void>(::write(g_device_pipe, text, static_cast<std::size_t>(n)));
}
void pipe_emergency_zero(void*) noexcept { send_command('Z', 0); }

volatile bool g_recurse = true;  // always true: only so the compiler sees an end to the recursion

[[gnu::noinline]] int overflow_the_stack(volatile char* caller, int depth) noexcept {
  volatile char frame[1024];  // volatile: the recursion cannot be folded away
  frame[0] = caller != nullptr ? caller[0] : 1;
  if (!g_recurse) return frame[0];
  return overflow_the_stack(frame, depth + 1) + frame[depth % 1024];
}

/// Commands 2 N every tick, like a stylus pressed into a wall, until tick `overflow_at` (or the
/// first after it, should that deadline be missed).
struct OverflowingTask final : PeriodicTask {
  std::int64_t overflow_at = 20;
  void tick(std::int64_t k) noexcept override {
    send_command('F', 2);
    if (k >= overflow_at) static_cast<void>(overflow_the_stack(nullptr, 0));
  }
  void publish(std::int64_t, const TickTiming&) noexcept override {}
  void shutdown(std::int64_t) noexcept override { send_command('F', 0); }
};

TEST(RealtimeRunner, AStackOverflowInTheServoThreadStillCommandsZeroForceBeforeTheProcessDies) {
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer takes SIGSEGV and stack overflows for its own reports";
#endif
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::close(fds[0]);
    g_device_pipe = fds[1];
    static std::atomic<int> stop{0};
    const EmergencyZero zero{pipe_emergency_zero, nullptr};
    install_signal_handlers(stop, zero);
    OverflowingTask task;
    // The heartbeat watchdog would zero too if the overflow outlasted its 15 ms (page faults
    // in a VM can): what is tested here is the fatal-signal handler's zero, alone.
    RealtimeOptions options = quick(2000);
    options.watchdog_periods = 2000;
    static_cast<void>(run_realtime(task, options, zero, stop));
    ::_exit(0);  // not reached: the tick overflows its stack
  }
  ::close(fds[1]);
  std::string commands;
  char buffer[4096];
  for (ssize_t n; (n = ::read(fds[0], buffer, sizeof buffer)) != 0;) {
    if (n < 0 && errno == EINTR) continue;
    ASSERT_GT(n, 0) << std::strerror(errno);
    commands.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(status)) << "status " << status << "; the device was told:\n" << commands;
  EXPECT_EQ(WTERMSIG(status), SIGSEGV) << "the overflow ends the process as it would have";
  // 2 N on every tick up to the one that overflowed, then the emergency zero and nothing else
  // (the loop's own shutdown never ran): the last thing the device was told is zero force.
  ASSERT_GE(commands.size(), 8U) << commands;
  EXPECT_EQ(commands.substr(commands.size() - 8), "F 2\nZ 0\n") << "the device was told:\n" << commands;
  EXPECT_EQ(commands.find("F 0"), std::string::npos) << commands;
}

TEST(RealtimeRunner, StopsOnTheStopFlagAfterShuttingDown) {
  CountingTask task;
  task.ticks.reserve(100000);
  std::atomic<int> stop{0};
  // The stop comes once the loop has ticked (a fixed 50 ms could pass before a loaded host
  // started the loop's thread).
  std::thread stopper([&stop, &task] {
    for (int i = 0; i < 60000 && task.publishes.load() == 0; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    stop.store(SIGTERM);
  });
  const auto report = run_realtime(task, quick(0), EmergencyZero{}, stop);
  stopper.join();
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report->stop_signal, SIGTERM);
  EXPECT_EQ(task.shutdowns, 1);
  EXPECT_GT(report->ticks, 0);
}

/// A child that takes stop signals as the loop's process does, and exits 0 some time after the
/// first (a stop) unless a second one makes it leave at once (128 + the signal). `directs`:
/// direct SIGTERMs the parent sends after the guardian-style copy. Returns its exit status.
int stop_signals_in_a_child(int directs) {
  int fds[2];
  if (::pipe(fds) != 0) return -1;
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    ::close(fds[0]);
    static std::atomic<int> stop{0};
    install_signal_handlers(stop, EmergencyZero{});
    const char ready = 'r';
    static_cast<void>(::write(fds[1], &ready, 1));  // the handlers are in place
    // Bounded: a stop that never arrives fails the test (exit 2) instead of hanging it.
    for (int ms = 0; stop.load() == 0; ++ms) {
      if (ms > 10'000) ::_exit(2);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const char one = '1';
    static_cast<void>(::write(fds[1], &one, 1));
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    ::_exit(0);
  }
  ::close(fds[1]);
  char got = 0;
  static_cast<void>(::read(fds[0], &got, 1));  // its handlers are in place
  // As `toonforce run`'s guardian passes a stop on: from the parent, queued, the first copy.
  sigval value{};
  value.sival_int = kGuardianFirstCopy;
  ::sigqueue(pid, SIGTERM, value);
  static_cast<void>(::read(fds[0], &got, 1));  // the child took it
  ::close(fds[0]);
  for (int i = 0; i < directs; ++i) {
    ::kill(pid, SIGTERM);  // the same group kill's copy sent to it directly, then another stop
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

TEST(RealtimeRunner, TheDirectCopyOfAGroupKillAfterTheGuardiansIsOneStopAndAThirdIsASecond) {
  // `kill -TERM -PGID`: the guardian (woken at once on the other CPU) may pass its copy on before
  // the kernel has queued the direct one; the direct one is then the same request, not a second
  // stop. One more after it is a second stop, which leaves at once.
  EXPECT_EQ(stop_signals_in_a_child(1), 0);
  EXPECT_EQ(stop_signals_in_a_child(2), 128 + SIGTERM);
}

// The advice for a refused SCHED_FIFO names the file the install puts in place
// (cmake/ToonforceInstallHost.cmake.in: limits.d/toonforce.conf from tools/deploy), the
// priority asked for, and the way out without real-time scheduling.
TEST(RealtimeRunner, PermissionAdviceNamesTheInstalledLimitsFileAndThePriority) {
  const std::string advice = toonforce::realtime_permission_advice(97);
  EXPECT_NE(advice.find("/etc/security/limits.d/toonforce.conf"), std::string::npos) << advice;
  EXPECT_NE(advice.find("tools/deploy/toonforce-limits.conf"), std::string::npos) << advice;
  EXPECT_NE(advice.find("rtprio   97"), std::string::npos) << advice;
  EXPECT_NE(advice.find("--allow-non-rt"), std::string::npos) << advice;
}

TEST(RealtimeRunner, RejectsRatesOutsideItsRange) {
  CountingTask task;
  std::atomic<int> stop{0};
  RealtimeOptions o = quick(10);
  o.rate_hz = 20000.0;
  EXPECT_FALSE(run_realtime(task, o, EmergencyZero{}, stop));
}

// ---- toonforce run in process ------------------------------------------------------------------

// The stats JSON and the viewer's hello share one escaper: RFC 8259 §7 requires quote,
// backslash and every control character below 0x20 escaped; '<' is escaped as well so that no
// "</script>" can appear in anything a page inlines.
TEST(JsonString, EscapesWhatRfc8259RequiresAndTheClosingScriptTag) {
  EXPECT_EQ(toonforce::json_string(""), "\"\"");
  EXPECT_EQ(toonforce::json_string("scenes/wall.toml"), "\"scenes/wall.toml\"");
  EXPECT_EQ(toonforce::json_string("a\"b\\c"), "\"a\\\"b\\\\c\"");
  EXPECT_EQ(toonforce::json_string("l1\nl2\tx"), "\"l1\\nl2\\tx\"");
  EXPECT_EQ(toonforce::json_string(std::string_view("\x01\x1f", 2)), "\"\\u0001\\u001f\"");
  EXPECT_EQ(toonforce::json_string("</script>"), "\"\\u003c/script>\"");
  EXPECT_EQ(toonforce::json_string("\xc3\xa9"), "\"\xc3\xa9\"");  // UTF-8 passes through
}

TEST(RunCommand, ASimRunWritesOneTraceRowPerTickPlusTheFinalZeroForceRow) {
  RunOptions o;
  o.device = "sim";
  o.scene_path = TOONFORCE_SOURCE_DIR "/scenes/cartoon_wall.toml";
  o.duration_s = 0.5;
  o.trace_path = temp_path("trace.csv").string();
  o.allow_non_realtime = true;
  o.lock_memory = false;
  o.handle_signals = false;
  o.interactive = false;
  const auto summary = run_servo(o);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_EQ(summary->report.ticks + summary->report.missed, 500);
  EXPECT_EQ(summary->frames_dropped, 0U) << "16384 frames cannot fill in 500 ticks";
  EXPECT_EQ(summary->frames_written, static_cast<std::uint64_t>(summary->report.ticks + 1));
  const auto lines = lines_of(o.trace_path);
  ASSERT_EQ(lines.size(), summary->frames_written + 1);
  EXPECT_EQ(lines[0].rfind("t,x,y,z,vx,vy,vz,fx,fy,fz,", 0), 0U) << lines[0];
  const auto last = fields(lines.back());
  EXPECT_EQ(last[7], 0.0);
  EXPECT_EQ(last[8], 0.0);
  EXPECT_EQ(last[9], 0.0);
  const auto json = stats_json(summary.value(), o);
  EXPECT_NE(json.find("\"frames_dropped\": 0"), std::string::npos);
  EXPECT_NE(json.find("\"device_limited_ticks\": 0"), std::string::npos) << "the simulated device has no envelope";
  EXPECT_EQ(format_run_summary(summary.value(), o).find("could not give the force"), std::string::npos);
  std::filesystem::remove(o.trace_path);
}

TEST(RunCommand, TicksADeviceCouldNotGiveInFullAreCountedAndSaid) {
  RunOptions o;
  o.device = "falcon";
  RunSummary s;
  s.device_limited_ticks = 7;
  EXPECT_NE(stats_json(s, o).find("\"device_limited_ticks\": 7"), std::string::npos);
  EXPECT_NE(format_run_summary(s, o).find("could not give the force asked in 7 tick(s)"), std::string::npos)
      << format_run_summary(s, o);
}

TEST(RunCommand, AFalconThatIsNotThereIsAClearErrorBeforeTheLoopStarts) {
  // No USB on this host (or in CI): the real libusb backend finds none and says what to check.
  RunOptions o;
  o.device = "falcon";
  const auto device = open_device(o);
  ASSERT_FALSE(device);
  EXPECT_NE(device.error().find("no Novint Falcon found on USB (vendor 0403, product cb48)"), std::string::npos)
      << device.error();
}

TEST(RunCommand, OmniRunsInsideTheDevicesOwnSchedulerAgainstTheFakeLibHD) {
  // Our fake libHD (tests/omni/fake_hd, a simulated Omni behind the documented HD C API): this
  // proves the device-clocked path of toonforce run, not the vendor's driver.
  RunOptions o;
  o.device = "omni";
  o.scene_path = TOONFORCE_SOURCE_DIR "/scenes/wall.toml";
  o.omni.library_path = TOONFORCE_FAKE_HD;
  o.duration_s = 0.3;
  o.handle_signals = false;
  o.interactive = false;
  o.trace_path = temp_path("omni.csv").string();
  const auto summary = run_servo(o);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_EQ(summary->report.ticks, 300);
  EXPECT_EQ(summary->report.setup.priority, -1);  // the vendor's thread, not ours
  EXPECT_NE(summary->device_name.find("OpenHaptics"), std::string::npos) << summary->device_name;
  EXPECT_EQ(summary->frames_dropped, 0U);
  const auto lines = lines_of(o.trace_path);
  ASSERT_EQ(lines.size(), summary->frames_written + 1);
  const auto last = fields(lines.back());
  EXPECT_EQ(last[7], 0.0);  // the run ends with zero force, commanded inside the frame
  EXPECT_EQ(last[8], 0.0);
  EXPECT_EQ(last[9], 0.0);
  std::filesystem::remove(o.trace_path);

  o.omni.library_path = "/nonexistent/libHD.so";
  const auto missing = run_servo(o);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("/nonexistent/libHD.so"), std::string::npos) << missing.error();
}

TEST(RunCommand, TheSimulatedDeviceFollowsAHandScriptOrReportsItsErrors) {
  RunOptions o;
  o.device = "sim";
  o.hand_script_path = TOONFORCE_SOURCE_DIR "/scenes/hands/strike.toml";
  const auto device = open_device(o);
  ASSERT_TRUE(device) << device.error();
  EXPECT_NE(device.value()->info().name.find("simulated Novint Falcon"), std::string::npos);
  o.sim_device = "omni";
  const auto omni = open_device(o);
  ASSERT_TRUE(omni) << omni.error();
  EXPECT_NE(omni.value()->info().name.find("Omni"), std::string::npos) << omni.value()->info().name;
  o.hand_script_path = "/nonexistent/hand.toml";
  const auto missing = open_device(o);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("/nonexistent/hand.toml"), std::string::npos) << missing.error();
  o.sim_device = "phantom";
  o.hand_script_path.clear();
  EXPECT_FALSE(open_device(o));
}

// ---- the trace writer (shared with toonforce sim) -------------------------------------------------

std::vector<std::string> fields_of_line(std::string line) {
  if (!line.empty() && line.back() == '\n') line.pop_back();
  std::vector<std::string> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    out.push_back(line.substr(start, comma - start));
    if (comma == std::string::npos) return out;
    start = comma + 1;
  }
}

TEST(TraceWriter, StartsWithTheSpecColumnsAndWritesNumbersThatReadBackExactly) {
  const auto path = temp_path("trace.csv");
  {
    auto w = TraceWriter::open(path.string(), {"extra_a", "extra_b"});
    ASSERT_TRUE(w) << w.error();
    const TraceCore core{0.1, {1.0 / 3.0, -2e-7, 0.0}, {1e-300, 5.5, -0.0}, {8.0, 0.1 + 0.2, 1e10}};
    EXPECT_TRUE(w.value()->write(core, std::vector<double>{std::nan(""), 42.0}));
    EXPECT_FALSE(w.value()->write(core, std::vector<double>{1.0})) << "a row must match the header";
    EXPECT_FALSE(w.value()->close()) << "the failed row makes close() report failure";
  }
  const auto lines = lines_of(path);
  ASSERT_EQ(lines.size(), 2U);
  EXPECT_EQ(lines[0], "t,x,y,z,vx,vy,vz,fx,fy,fz,extra_a,extra_b");
  const auto row = fields(lines[1]);
  ASSERT_EQ(row.size(), 12U);
  EXPECT_EQ(row[1], 1.0 / 3.0);
  EXPECT_EQ(row[4], 1e-300);
  EXPECT_EQ(row[8], 0.1 + 0.2);
  EXPECT_NE(lines[1].find(",nan,42"), std::string::npos) << lines[1];
  std::filesystem::remove(path);
}

TEST(GuardianEpilogue, TheZeroForceRowIsAsWideAsTheHeaderWithOrWithoutAFrame) {
  // A loop's process that dies before its writer took a frame leaves the guardian no frame to
  // copy: the row is still as wide as the header (its effect values NaN), and so it is when the
  // frame carries fewer values than the trace has columns for.
  const std::vector<std::string> values{"surface1.contact", "surface1.impact_t", "cliff1.state"};
  for (const bool with_frame : {false, true}) {
    const auto path = temp_path(with_frame ? "epilogue_frame.csv" : "epilogue_none.csv");
    {
      auto w = TraceWriter::open(path.string(), telemetry_columns(values, true));
      ASSERT_TRUE(w) << w.error();
      ASSERT_TRUE(w.value()->close());
    }
    guardian::Verdict verdict;
    verdict.t_end_s = 0.25;
    TelemetryFrame frame{};
    frame.t_s = 0.2;
    frame.tick = 200;
    frame.force_n = {0.0, 0.0, 3.0};
    frame.value_count = 1;  // fewer than the header's three
    frame.values[0] = 1.0;
    EXPECT_EQ(guardian::end_trace(path.string(), verdict, with_frame ? &frame : nullptr), "");
    const auto lines = lines_of(path);
    ASSERT_EQ(lines.size(), 2U);
    const auto header = fields_of_line(lines[0]);
    const auto row = fields_of_line(lines[1]);
    EXPECT_EQ(row.size(), header.size()) << (with_frame ? "with" : "without") << " a frame: " << lines[1];
    EXPECT_EQ(std::stod(row[0]), 0.25);
    EXPECT_EQ(std::stod(row[9]), 0.0) << "zero force";
    std::filesystem::remove(path);
  }
}

TEST(TraceWriter, TelemetryColumnsMatchWhatWriteFrameWrites) {
  const std::vector<std::string> values{"surface1.contact", "surface1.impact_t", "cliff1.state"};
  for (const bool timing : {false, true}) {
    const auto columns = telemetry_columns(values, timing);
    EXPECT_EQ(columns.size(), telemetry_extra_count(values.size(), timing));
    const auto writer = TraceWriter::in_memory(columns);
    TelemetryFrame f;
    f.value_count = 3;
    f.values = {};
    f.values[2] = 7.0;  // cliff1.state: a value a reader can find in its column
    f.timing.compute_ns = 2500;
    ASSERT_TRUE(write_frame(*writer, f, values.size(), timing));
    const std::string text = writer->text();
    const auto header = fields_of_line(text.substr(0, text.find('\n')));
    const auto row = fields_of_line(text.substr(text.find('\n') + 1));
    ASSERT_EQ(header.size(), row.size()) << "timing " << timing;
    const auto at = [&](std::string_view name) {
      for (std::size_t i = 0; i < header.size(); ++i) {
        if (header[i] == name) return row[i];
      }
      return std::string("missing");
    };
    EXPECT_EQ(at("cliff1.state"), "7");
    EXPECT_EQ(at("compute_us"), timing ? "2.5" : "missing");
  }
}

}  // namespace
}  // namespace toonforce
