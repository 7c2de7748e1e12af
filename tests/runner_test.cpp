// The real-time runner and `toonforce run`, asserting counts and file contents, never times
// (this VM has multi-millisecond hypervisor stalls: shared/reference/test-environment.md §4).
// In process: every deadline is either ticked or counted as missed; a stalled tick trips the
// heartbeat watchdog; a sim run writes one trace row per tick plus the final zero-force row.
// As a child process: SIGINT and SIGTERM stop the real binary with the force zeroed first and
// a trace valid to its last row; falcon and omni fail with a clear message.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>
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

#include <fmt/format.h>

#include "toonforce/control/realtime_runner.hpp"
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
  std::int64_t publishes = 0;
  std::int64_t shutdowns = 0;
  std::int64_t shutdown_at = -1;
  std::int64_t stall_at = -1;  ///< this tick sleeps 100 ms
  void tick(std::int64_t k) noexcept override {
    ticks.push_back(k);  // reserved beforehand: no allocation here
    if (k == stall_at) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  void publish(std::int64_t, const TickTiming&) noexcept override { ++publishes; }
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
  EXPECT_EQ(task.publishes, report->ticks);
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
  const auto after = std::find(task.ticks.begin(), task.ticks.end(), 100);
  ASSERT_NE(after + 1, task.ticks.end());
  EXPECT_GE(*(after + 1) - 100, 200) << "the next tick runs at the latest passed deadline";
  EXPECT_GE(report->watchdog_trips, 1);
  EXPECT_GE(g_emergency_calls.load(), 1);
}

TEST(RealtimeRunner, StopsOnTheStopFlagAfterShuttingDown) {
  CountingTask task;
  task.ticks.reserve(100000);
  std::atomic<int> stop{0};
  std::thread stopper([&stop] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    stop.store(SIGTERM);
  });
  const auto report = run_realtime(task, quick(0), EmergencyZero{}, stop);
  stopper.join();
  ASSERT_TRUE(report) << report.error();
  EXPECT_EQ(report->stop_signal, SIGTERM);
  EXPECT_EQ(task.shutdowns, 1);
  EXPECT_GT(report->ticks, 0);
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

// ---- the real binary as a child process ---------------------------------------------------------

struct Child {
  pid_t pid = -1;
  int status = 0;
};

Child spawn(const std::vector<std::string>& args, const std::filesystem::path& output) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, output.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  Child child;
  const int rc = posix_spawn(&child.pid, args[0].c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  EXPECT_EQ(rc, 0) << std::strerror(rc);
  if (rc != 0) child.pid = -1;
  return child;
}

/// Never signals or waits for anything but a child this test started: kill(-1) or kill(0)
/// would hit every process of the user or the whole group.
bool started(const Child& c) { return c.pid > 0; }

int wait_exit(Child& c) {
  if (!started(c)) return -1;
  EXPECT_EQ(waitpid(c.pid, &c.status, 0), c.pid);
  return WIFEXITED(c.status) ? WEXITSTATUS(c.status) : 128 + WTERMSIG(c.status);
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// The binary with its standard output on a pipe the test reads (returned in `read_fd`), its
/// standard error to `errors`.
Child spawn_piped(const std::vector<std::string>& args, const std::filesystem::path& errors, int& read_fd) {
  int pipe_fds[2];
  Child child;
  read_fd = -1;
  EXPECT_EQ(pipe(pipe_fds), 0);
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_addclose(&actions, pipe_fds[0]);
  posix_spawn_file_actions_addclose(&actions, pipe_fds[1]);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, errors.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  const int rc = posix_spawn(&child.pid, args[0].c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(pipe_fds[1]);
  EXPECT_EQ(rc, 0) << std::strerror(rc);
  if (rc != 0) {
    child.pid = -1;
    close(pipe_fds[0]);
  } else {
    read_fd = pipe_fds[0];
  }
  return child;
}

class StopSignal : public ::testing::TestWithParam<int> {};

TEST_P(StopSignal, LeavesTheForceZeroAndATraceValidToItsLastRow) {
  const auto trace = temp_path("trace.csv");
  const auto stats = temp_path("stats.json");
  const auto output = temp_path("output.txt");
  Child child = spawn({TOONFORCE_BINARY, "run", "--device", "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                       "--trace", trace.string(), "--stats-json", stats.string(), "--allow-non-rt", "--no-mlock"},
                      output);
  ASSERT_TRUE(started(child));
  // Wait (without a time assertion) until the run is well under way: 300 trace rows.
  for (int i = 0; i < 6000; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    std::error_code ec;
    const auto size = std::filesystem::file_size(trace, ec);  // (uintmax_t)-1 while it does not exist
    if (!ec && size > 300 * 150) break;
    int status = 0;
    ASSERT_EQ(waitpid(child.pid, &status, WNOHANG), 0) << "exited early:\n" << slurp(output);
  }
  ASSERT_TRUE(started(child));
  ASSERT_EQ(kill(child.pid, GetParam()), 0);
  EXPECT_EQ(wait_exit(child), 0) << slurp(output);

  const auto lines = lines_of(trace);
  ASSERT_GT(lines.size(), 300U);
  const auto header = fields(lines[0]);
  EXPECT_EQ(lines[0].rfind("t,x,y,z,vx,vy,vz,fx,fy,fz,", 0), 0U);
  double previous_t = -1.0;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const auto row = fields(lines[i]);
    ASSERT_EQ(row.size(), header.size()) << "row " << i << ": " << lines[i];
    for (std::size_t c = 0; c < 10; ++c) ASSERT_TRUE(std::isfinite(row[c])) << "row " << i << " column " << c;
    ASSERT_GT(row[0], previous_t) << "row " << i;
    previous_t = row[0];
  }
  const auto last = fields(lines.back());
  EXPECT_EQ(last[7], 0.0);
  EXPECT_EQ(last[8], 0.0);
  EXPECT_EQ(last[9], 0.0);
  EXPECT_EQ(last[19], 0.0) << "the last row is the shut-down loop: idle";
  const std::string json = slurp(stats);
  EXPECT_NE(json.find("\"stop_signal\": " + std::to_string(GetParam())), std::string::npos) << json;
  EXPECT_NE(json.find("\"frames_written\": " + std::to_string(lines.size() - 1)), std::string::npos) << json;
  EXPECT_NE(slurp(output).find("stopped by " + signal_name(GetParam())), std::string::npos) << slurp(output);
  for (const auto& p : {trace, stats, output}) std::filesystem::remove(p);
}

/// Every catchable signal whose default action ends a process (issue 16: SIGHUP is what a
/// dropped SSH session sends; SIGXFSZ what a file-size limit sends).
const auto kTerminatingSignals =
    ::testing::Values(SIGHUP, SIGINT, SIGQUIT, SIGTERM, SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM, SIGPROF, SIGXCPU, SIGXFSZ);
const auto kSignalTestName = [](const auto& p) { return signal_name(p.param); };
INSTANTIATE_TEST_SUITE_P(RunCommand, StopSignal, kTerminatingSignals, kSignalTestName);

TEST(RunCommand, SigpipeNeverKillsTheRun) {
  const auto trace = temp_path("trace.csv");
  const auto output = temp_path("output.txt");
  Child child = spawn({TOONFORCE_BINARY, "run", "--device", "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                       "--trace", trace.string(), "--allow-non-rt", "--no-mlock"},
                      output);
  ASSERT_TRUE(started(child));
  for (int i = 0; i < 6000; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    std::error_code ec;
    const auto size = std::filesystem::file_size(trace, ec);
    if (!ec && size > 100 * 150) break;
    int status = 0;
    ASSERT_EQ(waitpid(child.pid, &status, WNOHANG), 0) << "exited early:\n" << slurp(output);
  }
  ASSERT_EQ(kill(child.pid, SIGPIPE), 0);
  // Still running after the SIGPIPE: the trace keeps growing.
  std::error_code ec;
  const auto before = std::filesystem::file_size(trace, ec);
  bool grew = false;
  for (int i = 0; i < 6000 && !grew; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    int status = 0;
    ASSERT_EQ(waitpid(child.pid, &status, WNOHANG), 0) << "SIGPIPE ended the run:\n" << slurp(output);
    grew = std::filesystem::file_size(trace, ec) > before + 50 * 150;
  }
  EXPECT_TRUE(grew);
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  EXPECT_EQ(wait_exit(child), 0) << slurp(output);
  EXPECT_NE(slurp(output).find("stopped by SIGTERM"), std::string::npos) << slurp(output);
  EXPECT_EQ(fields(lines_of(trace).back())[9], 0.0);
  for (const auto& p : {trace, output}) std::filesystem::remove(p);
}

// `sim` with its trace on a pipe this test reads: the simulation cannot run ahead of the reader
// (it waits on the pipe), so the signal comes mid-run on any machine.
class SimStopSignal : public ::testing::TestWithParam<int> {};

TEST_P(SimStopSignal, EndsWithTheSummaryAndTheShutDownTickAsAWholeLastRow) {
  const auto output = temp_path("sim-output.txt");
  int read_fd = -1;
  Child child = spawn_piped({TOONFORCE_BINARY, "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml", "--script",
                             TOONFORCE_SOURCE_DIR "/scenes/hands/strike.toml", "--duration", "1000", "--trace", "-"},
                            output, read_fd);
  ASSERT_TRUE(started(child));
  std::FILE* in = fdopen(read_fd, "r");
  ASSERT_NE(in, nullptr);
  std::vector<std::string> lines;
  char* line = nullptr;
  std::size_t capacity = 0;
  bool signalled = false;
  for (ssize_t n; (n = getline(&line, &capacity, in)) > 0;) {
    lines.emplace_back(line, static_cast<std::size_t>(n));
    if (!signalled && lines.size() == 300) {
      ASSERT_EQ(kill(child.pid, GetParam()), 0);
      signalled = true;
    }
  }
  std::free(line);
  std::fclose(in);
  EXPECT_EQ(wait_exit(child), 0) << slurp(output);
  ASSERT_TRUE(signalled);
  ASSERT_GT(lines.size(), 300U);
  ASSERT_LT(lines.size(), 1000000U) << "the run went on to its end";
  const auto header = fields(lines[0]);
  for (std::size_t i = 1; i < lines.size(); ++i) {
    ASSERT_EQ(lines[i].back(), '\n') << "row " << i << " is cut";
    ASSERT_EQ(fields(lines[i]).size(), header.size()) << "row " << i << ": " << lines[i];
  }
  const auto last = fields(lines.back());
  EXPECT_EQ(last[7], 0.0);
  EXPECT_EQ(last[8], 0.0);
  EXPECT_EQ(last[9], 0.0);
  EXPECT_EQ(last[19], 0.0) << "the last row is the shut-down loop: idle";
  const std::string text = slurp(output);
  EXPECT_NE(text.find("stopped by " + signal_name(GetParam())), std::string::npos) << text;
  EXPECT_NE(text.find("ran     "), std::string::npos) << "the summary: " << text;
  std::filesystem::remove(output);
}
INSTANTIATE_TEST_SUITE_P(SimCommand, SimStopSignal, kTerminatingSignals, kSignalTestName);

// ---- outputs that cannot be written, outputs that are inputs (issue 16) -------------------------

/// Runs the binary to its end; its exit status and everything it printed.
std::pair<int, std::string> run_binary(const std::vector<std::string>& args) {
  const auto output = temp_path("binary-output.txt");
  Child child = spawn(args, output);
  const int status = wait_exit(child);
  std::string text = slurp(output);
  std::filesystem::remove(output);
  return {status, std::move(text)};
}

TEST(ReplayCommand, AnOutputThatCannotBeWrittenIsReportedWithTheSummaryNotAnAbort) {
  const auto [status, text] = run_binary({TOONFORCE_BINARY, "replay", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                                          "--input", TOONFORCE_SOURCE_DIR "/scenes/motions/strike.csv", "--output",
                                          "/dev/full"});
  EXPECT_EQ(status, 1) << text;  // was 134: an uncaught std::system_error
  EXPECT_NE(text.find("/dev/full: writing failed: No space left on device"), std::string::npos) << text;
  EXPECT_NE(text.find("peak"), std::string::npos) << "the summary: " << text;
}

TEST(ReplayCommand, AnOutputThatIsAnInputIsRefusedBeforeItIsTouched) {
  const auto motion = temp_path("motion.csv");
  std::filesystem::copy_file(TOONFORCE_SOURCE_DIR "/scenes/motions/strike.csv", motion);
  const std::string before = slurp(motion);
  const auto [status, text] = run_binary({TOONFORCE_BINARY, "replay", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                                          "--input", motion.string(), "--output", motion.string()});
  EXPECT_EQ(status, 1) << text;
  EXPECT_NE(text.find("is the motion"), std::string::npos) << text;
  EXPECT_EQ(slurp(motion), before);
  std::filesystem::remove(motion);
}

TEST(SimCommand, ATraceThatIsTheSceneIsRefusedAndTheSceneKept) {
  const auto scene = temp_path("w.toml");
  std::filesystem::copy_file(TOONFORCE_SOURCE_DIR "/scenes/wall.toml", scene);
  const std::string before = slurp(scene);
  const auto [status, text] = run_binary({TOONFORCE_BINARY, "sim", "--scene", scene.string(), "--script",
                                          TOONFORCE_SOURCE_DIR "/scenes/hands/strike.toml", "--trace", scene.string()});
  EXPECT_EQ(status, 1) << text;
  EXPECT_NE(text.find("--trace " + scene.string() + " is the scene"), std::string::npos) << text;
  EXPECT_EQ(slurp(scene), before);
  std::filesystem::remove(scene);
}

TEST(SimCommand, APlotInAFormatThePlotterDoesNotWriteIsRefusedBeforeTheRun) {
  const auto trace = temp_path("trace.csv");
  const auto [status, text] = run_binary({TOONFORCE_BINARY, "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                                          "--script", TOONFORCE_SOURCE_DIR "/scenes/hands/strike.toml", "--trace",
                                          trace.string(), "--plot", temp_path("x.jpg").string()});
  EXPECT_EQ(status, 1) << text;
  EXPECT_NE(text.find(".png or .svg"), std::string::npos) << text;
  EXPECT_FALSE(std::filesystem::exists(trace)) << "the run went ahead";
  std::filesystem::remove(trace);
}

/// `COMMAND --trace - | head -1`: the reader goes away after the header; the run goes on to its
/// end (SIGPIPE does not kill it), says at once that the trace cannot be written, and ends with
/// its summary and exit status 1.
std::pair<int, std::string> run_with_a_reader_that_leaves(const std::vector<std::string>& args) {
  const auto errors = temp_path("errors.txt");
  int read_fd = -1;
  Child child = spawn_piped(args, errors, read_fd);
  if (!started(child)) return {-1, ""};
  char c = 0;
  while (read(read_fd, &c, 1) == 1 && c != '\n') {
  }
  close(read_fd);
  const int status = wait_exit(child);
  std::string text = slurp(errors);
  std::filesystem::remove(errors);
  return {status, std::move(text)};
}

TEST(SimCommand, AReaderThatLeavesIsAWriteErrorSaidAtOnceAndTheSummaryStillComes) {
  const auto [status, text] = run_with_a_reader_that_leaves({TOONFORCE_BINARY, "sim", "--scene",
                                                             TOONFORCE_SOURCE_DIR "/scenes/wall.toml", "--script",
                                                             TOONFORCE_SOURCE_DIR "/scenes/hands/strike.toml", "--trace", "-"});
  EXPECT_EQ(status, 1) << text;  // not 141 (SIGPIPE)
  EXPECT_NE(text.find("Broken pipe; nothing more is written, the simulation goes on"), std::string::npos) << text;
  EXPECT_NE(text.find("ran     "), std::string::npos) << "the summary: " << text;
  EXPECT_NE(text.find("INCOMPLETE"), std::string::npos) << text;
}

TEST(SimCommand, DurationsUnderOneTickOrOverTheMaximumAreRefused) {
  for (const char* duration : {"0.0004", "1e16"}) {
    const auto trace = temp_path("trace.csv");
    const auto [status, text] = run_binary({TOONFORCE_BINARY, "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                                            "--script", TOONFORCE_SOURCE_DIR "/scenes/hands/strike.toml", "--trace",
                                            trace.string(), "--duration", duration});
    EXPECT_EQ(status, 1) << duration << ": " << text;
    EXPECT_NE(text.find("--duration"), std::string::npos) << text;
    std::filesystem::remove(trace);
  }
}

TEST(SimCommand, AHandScriptLongerThanTheMaximumIsRefusedNotWrittenToDisk) {
  const auto script = temp_path("long.toml");
  {
    std::ofstream out(script);
    out << "name = \"long\"\n[hand]\nstart = [0.0, 0.0, 0.03]\n[[segment]]\ntype = \"hold\"\nduration = 1e6\n";
  }
  const auto trace = temp_path("trace.csv");
  const auto [status, text] = run_binary({TOONFORCE_BINARY, "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                                          "--script", script.string(), "--trace", trace.string()});
  EXPECT_EQ(status, 1) << text;  // filled the disk at about 50 MB/s
  EXPECT_NE(text.find("lasts 1e+06 s, over the maximum of 86400 s"), std::string::npos) << text;
  EXPECT_FALSE(std::filesystem::exists(trace));
  for (const auto& p : {script, trace}) std::filesystem::remove(p);
}

TEST(RunCommand, DurationsUnderOneTickOrOverTheMaximumCannotStart) {
  for (const char* duration : {"0.0004", "1e16"}) {
    const auto [status, text] =
        run_binary({TOONFORCE_BINARY, "run", "--device", "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                    "--allow-non-rt", "--no-mlock", "--duration", duration});
    EXPECT_EQ(status, 2) << duration << ": " << text;  // 0.0004 ran forever, 1e16 "0 ticks" and exit 0
    EXPECT_NE(text.find(std::string("--duration ") + (duration[1] == 'e' ? "1e+16" : "0.0004")), std::string::npos)
        << text;
  }
}

TEST(RunCommand, AStatisticsFileThatCannotBeCreatedStopsTheStartNotTheEnd) {
  const auto trace = temp_path("trace.csv");
  const auto [status, text] =
      run_binary({TOONFORCE_BINARY, "run", "--device", "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                  "--allow-non-rt", "--no-mlock", "--duration", "0.2", "--trace", trace.string(), "--stats-json",
                  "/nonexistent/s.json"});
  EXPECT_EQ(status, 2) << text;
  EXPECT_NE(text.find("--stats-json /nonexistent/s.json: cannot be created"), std::string::npos) << text;
  EXPECT_FALSE(std::filesystem::exists(trace)) << "the run went ahead";
  std::filesystem::remove(trace);
}

TEST(RunCommand, AReaderThatLeavesIsAWriteErrorSaidAtOnceAndTheRunEndsWithItsSummary) {
  const auto stats = temp_path("stats.json");
  const auto [status, text] = run_with_a_reader_that_leaves(
      {TOONFORCE_BINARY, "run", "--device", "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml", "--allow-non-rt",
       "--no-mlock", "--duration", "0.5", "--trace", "-", "--stats-json", stats.string()});
  EXPECT_EQ(status, 1) << text;  // not 141 (SIGPIPE)
  // Said when the writer first fails (mid-run, or at its last flush for a short run like this).
  EXPECT_NE(text.find("INCOMPLETE"), std::string::npos) << text;
  EXPECT_NE(text.find("Broken pipe"), std::string::npos) << text;
  EXPECT_NE(slurp(stats).find("\"stop_signal\": 0"), std::string::npos) << "the run went on to its end: " << slurp(stats);
  std::filesystem::remove(stats);
}

TEST(RunCommand, ATraceThatCannotBeWrittenAtAllCannotStart) {
  const auto [status, text] =
      run_binary({TOONFORCE_BINARY, "run", "--device", "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                  "--allow-non-rt", "--no-mlock", "--duration", "0.2", "--trace", "/dev/full"});
  EXPECT_EQ(status, 2) << text;
  EXPECT_NE(text.find("/dev/full: cannot write the trace header"), std::string::npos) << text;
}

TEST(RunCommand, ATraceThatIsTheSceneIsRefused) {
  const auto scene = temp_path("w.toml");
  std::filesystem::copy_file(TOONFORCE_SOURCE_DIR "/scenes/wall.toml", scene);
  const std::string before = slurp(scene);
  const auto [status, text] = run_binary({TOONFORCE_BINARY, "run", "--device", "sim", "--scene", scene.string(),
                                          "--allow-non-rt", "--no-mlock", "--duration", "0.2", "--trace",
                                          scene.string()});
  EXPECT_EQ(status, 2) << text;
  EXPECT_NE(text.find("is the scene"), std::string::npos) << text;
  EXPECT_EQ(slurp(scene), before);
  std::filesystem::remove(scene);
}

TEST(Cli, ABadCommandLineIsCannotStartExitStatus2) {
  const std::string scene = TOONFORCE_SOURCE_DIR "/scenes/wall.toml";
  for (const auto& args : std::vector<std::vector<std::string>>{
           {TOONFORCE_BINARY, "run", "--device", "sim", "--scene", scene, "--rate", "0"},  // was 105
           {TOONFORCE_BINARY, "run", "--device", "sim", "--scene", scene, "--no-such-flag"},  // was 109
           {TOONFORCE_BINARY, "run", "--device", "sim", "--scene"},  // was 114
           {TOONFORCE_BINARY, "run", "--device", "sim"},  // was 106
           {TOONFORCE_BINARY, "sim", "--scene", scene, "--trace"}}) {
    const auto [status, text] = run_binary(args);
    EXPECT_EQ(status, 2) << args.back() << ": " << text;
    EXPECT_FALSE(text.empty());
  }
  EXPECT_EQ(run_binary({TOONFORCE_BINARY, "run", "--help"}).first, 0);
}

TEST(ReplayCommand, HelpHasNoRawBytesAndTheSineMethodIsAWord) {
  const auto [status, help] = run_binary({TOONFORCE_BINARY, "replay", "--help"});
  EXPECT_EQ(status, 0);
  EXPECT_EQ(help.find('\0'), std::string::npos) << "a NUL byte in --help";
  EXPECT_NE(help.find("polynomial"), std::string::npos) << help;
  // `--sine 1` was taken silently as "polynomial" (the enumeration's value).
  EXPECT_EQ(run_binary({TOONFORCE_BINARY, "replay", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml", "--input",
                        TOONFORCE_SOURCE_DIR "/scenes/motions/strike.csv", "--output", "-", "--sine", "1"})
                .first,
            2);
}

TEST(Cli, OutputThatCannotBeWrittenIsAFailedExitStatus) {
  Child child = spawn({TOONFORCE_BINARY, "falcon", "udev-rule"}, "/dev/full");
  ASSERT_TRUE(started(child));
  EXPECT_EQ(wait_exit(child), 1);  // was 0
}

TEST(CheckCommand, ACleanSceneAndHandScriptAreOkWithThePlausibilityReport) {
  const auto [status, text] = run_binary({TOONFORCE_BINARY, "check", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                                          TOONFORCE_SOURCE_DIR "/scenes/hands/strike.toml"});
  EXPECT_EQ(status, 0) << text;
  EXPECT_NE(text.find("ok      "), std::string::npos) << text;
  EXPECT_NE(text.find("peak force"), std::string::npos) << text;
}

TEST(CheckCommand, ErrorsAndAnEmptySceneAreReportedWithoutRunningAndExit1) {
  const auto scene = temp_path("huge.toml");
  const auto empty = temp_path("empty.toml");
  {
    std::ofstream(scene) << "name = \"w\"\n[[surface]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n"
                            "stiffness = 1e308\n";
    std::ofstream(empty) << "# nothing but a comment\n";
  }
  auto [status, text] = run_binary({TOONFORCE_BINARY, "check", scene.string()});
  EXPECT_EQ(status, 1) << text;
  EXPECT_NE(text.find(scene.string() + ":5"), std::string::npos) << text;
  std::tie(status, text) = run_binary({TOONFORCE_BINARY, "check", empty.string()});
  EXPECT_EQ(status, 1) << text;
  EXPECT_NE(text.find("no [[surface]] or [[cliff]]"), std::string::npos) << text;
  std::tie(status, text) = run_binary({TOONFORCE_BINARY, "check", empty.string(), "--allow-empty"});
  EXPECT_EQ(status, 0) << text;
  for (const auto& p : {scene, empty}) std::filesystem::remove(p);
}

// ---- Q16.16 guards (issue 15 item 6; scene_file.hpp fixed_point) ------------------------------
// 1/dt must fit Q16.16, whose largest value is (2^31 - 1) / 2^16 = 32767.99998: whole rates up
// to 32767 Hz. A rate refused is a bad command-line value (exit 2), before anything runs.

/// The `faults` column of a trace: no tick may have the fixed-point saturation bit.
bool any_fixed_saturation(const std::filesystem::path& trace) {
  const auto lines = lines_of(trace);
  EXPECT_GT(lines.size(), 1U) << trace << ": no trace to look at";
  if (lines.empty()) return false;
  std::vector<std::string> names;
  std::stringstream header(lines[0]);
  for (std::string name; std::getline(header, name, ',');) names.push_back(name);
  const auto column = static_cast<std::size_t>(std::find(names.begin(), names.end(), "faults") - names.begin());
  EXPECT_LT(column, names.size()) << lines[0];
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const auto row = fields(lines[i]);
    if (column < row.size() && (static_cast<std::uint32_t>(row[column]) & static_cast<std::uint32_t>(Fault::kFixedSaturation)) != 0) {
      return true;
    }
  }
  return false;
}

TEST(SimCommand, Q16RefusesARateWhoseOneOverDtDoesNotFitAndRunsJustBelowItWithoutSaturating) {
  const auto trace = temp_path("q16-rate.csv");
  const auto sim = [&](const std::string& rate, const std::string& scalar) {
    return run_binary({TOONFORCE_BINARY, "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/cartoon_wall.toml", "--script",
                       TOONFORCE_SOURCE_DIR "/scenes/hands/strike.toml", "--trace", trace.string(), "--duration",
                       "0.3", "--quiet", "--rate", rate, "--scalar", scalar});
  };
  auto [status, text] = sim("32768", "q16.16");
  EXPECT_EQ(status, 2) << text;
  EXPECT_NE(text.find("up to 32767 Hz"), std::string::npos) << text;
  EXPECT_FALSE(std::filesystem::exists(trace)) << "the run went ahead";
  std::tie(status, text) = sim("32767", "q16.16");
  EXPECT_EQ(status, 0) << text;
  EXPECT_FALSE(any_fixed_saturation(trace)) << "1/dt, the estimator's and the passivity controller's rate terms fit";
  std::filesystem::remove(trace);
  std::tie(status, text) = sim("40000", "double");
  EXPECT_EQ(status, 0) << "only q16.16 has the rule: " << text;
  std::filesystem::remove(trace);
}

TEST(CheckCommand, Q16RefusesASaturatingSceneWithFileLineKeyAndATooFastRateWithExit2) {
  // A 30000 N/m floor: 0.06 m deep in the largest device workspace, N = 1800 N, and Coulomb
  // 0.5 below v_reg = 0.02 m/s is a 45000 N s/m damper (effects.md §2): over Q16.16.
  const auto scene = temp_path("q16-friction.toml");
  std::ofstream(scene) << "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 30000\n"
                          "[surface.friction]\ncoulomb = 0.5\n";
  auto [status, text] = run_binary({TOONFORCE_BINARY, "check", scene.string(), "--scalar", "q16.16"});
  EXPECT_EQ(status, 1) << text;
  EXPECT_NE(text.find(scene.string() + ":6: surface[1].friction.coulomb: "), std::string::npos) << text;
  EXPECT_NE(text.find(fmt::format("coulomb up to {:.6g}", 32767.0 * 0.02 / 1800.0)), std::string::npos) << text;
  std::tie(status, text) = run_binary({TOONFORCE_BINARY, "check", scene.string()});
  EXPECT_EQ(status, 0) << "double holds it: " << text;
  std::filesystem::remove(scene);
  const std::string wall = TOONFORCE_SOURCE_DIR "/scenes/wall.toml";
  std::tie(status, text) = run_binary({TOONFORCE_BINARY, "check", wall, "--scalar", "q16.16", "--rate", "32768"});
  EXPECT_EQ(status, 2) << text;
  EXPECT_NE(text.find("up to 32767 Hz"), std::string::npos) << text;
  std::tie(status, text) = run_binary({TOONFORCE_BINARY, "check", wall, "--scalar", "q16.16", "--rate", "32767"});
  EXPECT_EQ(status, 0) << text;
}

TEST(RunCommand, Q16RefusesARateTheCliffsFilterCannotHoldBeforeTheDeviceOpens) {
  // cliff.hpp: s_f += (s - s_f) / (1 + tau rate); with tau = 5 s, 1 + tau rate <= 32767 allows
  // up to 32766 / 5 = 6553.2 Hz, inside run's own 500..10000.
  const auto scene = temp_path("q16-cliff.toml");
  std::ofstream(scene) << "[[cliff]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\naxis = [1, 0, 0]\ngap_min = -0.01\n"
                          "gap_max = 0.01\nstiffness = 1500\nspeed_threshold = 0.08\ntau = 5\n";
  auto [status, text] = run_binary({TOONFORCE_BINARY, "run", "--device", "sim", "--scene", scene.string(), "--rate",
                                    "6554", "--scalar", "q16.16", "--duration", "0.05", "--allow-non-rt", "--no-mlock"});
  EXPECT_EQ(status, 2) << text;
  EXPECT_NE(text.find("cliff[1]"), std::string::npos) << text;
  EXPECT_NE(text.find("up to 6553.2 Hz"), std::string::npos) << text;
  RunOptions o;
  o.device = "sim";
  o.scene_path = scene.string();
  o.rate_hz = 6553.0;
  o.scalar = ScalarKind::kQ16_16;
  o.duration_s = 0.05;
  o.trace_path = temp_path("q16-cliff.csv").string();
  o.allow_non_realtime = true;
  o.lock_memory = false;
  o.handle_signals = false;
  o.interactive = false;
  const auto summary = run_servo(o);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_FALSE(any_fixed_saturation(o.trace_path));
  std::filesystem::remove(o.trace_path);
  std::filesystem::remove(scene);
}

TEST(RunCommand, TheBinaryReportsAMissingDeviceAndExitsWithoutRunning) {
  const auto output = temp_path("output.txt");
  Child child = spawn({TOONFORCE_BINARY, "run", "--device", "falcon", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml"},
                      output);
  ASSERT_TRUE(started(child));
  EXPECT_EQ(wait_exit(child), 2);
  EXPECT_NE(slurp(output).find("no Novint Falcon found on USB"), std::string::npos) << slurp(output);
  std::filesystem::remove(output);
}

TEST(RunCommand, TheBinaryRejectsARateOutsideItsRange) {
  const auto output = temp_path("output.txt");
  Child child = spawn({TOONFORCE_BINARY, "run", "--device", "sim", "--scene", TOONFORCE_SOURCE_DIR "/scenes/wall.toml",
                       "--rate", "20000"},
                      output);
  ASSERT_TRUE(started(child));
  EXPECT_NE(wait_exit(child), 0);
  EXPECT_NE(slurp(output).find("--rate"), std::string::npos) << slurp(output);
  std::filesystem::remove(output);
}

}  // namespace
}  // namespace toonforce
