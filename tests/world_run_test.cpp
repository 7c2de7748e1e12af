// SPDX-License-Identifier: Apache-2.0
// `toonforce run` of a world scene (tools/run world_run.hpp): the README's two players in real
// time on simulated devices, the trace's meaning (Newton's third law on every row, zero force on
// every device once one stop holds), the errors that name the device and the fix, and the
// guardian's zero-force row at the end of a world's trace.
#include <gtest/gtest.h>

#include <dlfcn.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "toonforce/control/clock_bridge.hpp"
#include "toonforce/control/guardian.hpp"
#include "toonforce/control/world_session.hpp"
#include "toonforce/run/guardian_report.hpp"
#include "toonforce/run/world_run.hpp"

namespace toonforce {
namespace {

std::filesystem::path temp_path(const std::string& name) {
  return std::filesystem::temp_directory_path() / ("toonforce_world_run_" + std::to_string(getpid()) + "_" + name);
}

/// A CSV as its header's names to columns of numbers ("nan" reads as NaN).
struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
  std::size_t at(const std::string& name) const {
    for (std::size_t i = 0; i < header.size(); ++i) {
      if (header[i] == name) return i;
    }
    ADD_FAILURE() << "no column " << name;
    return 0;
  }
};

Csv read_csv(const std::string& path) {
  Csv csv;
  std::ifstream in(path);
  std::string line;
  if (!std::getline(in, line)) return csv;
  std::stringstream h(line);
  for (std::string name; std::getline(h, name, ',');) csv.header.push_back(name);
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::stringstream r(line);
    for (std::string v; std::getline(r, v, ',');) row.push_back(std::strtod(v.c_str(), nullptr));
    csv.rows.push_back(std::move(row));
  }
  return csv;
}

RunOptions two_players() {
  RunOptions o;
  o.device = "sim";
  o.scene_path = TOONFORCE_SOURCE_DIR "/scenes/two_players.toml";
  o.world_scripts = {{"left", TOONFORCE_SOURCE_DIR "/scenes/hands/left_push.toml"},
                     {"right", TOONFORCE_SOURCE_DIR "/scenes/hands/right_push.toml"}};
  o.allow_non_realtime = true;
  o.lock_memory = false;
  o.handle_signals = false;
  o.interactive = false;
  static std::FILE* const messages = std::tmpfile();  // the run's messages, out of the test's output
  o.messages = messages;
  return o;
}

TEST(WorldRun, TwoPlayersFeelEqualAndOppositeCouplingForcesAndOneFaultZeroesBoth) {
  RunOptions o = two_players();
  o.duration_s = 1.5;
  o.world_fail = std::pair{std::string("right"), 1.2};
  o.trace_path = temp_path("two_players.csv").string();
  const auto summary = run_world_servo(o);
  ASSERT_TRUE(summary) << summary.error();
  // Every deadline is a tick or a skipped one; one row a tick and the shut-down row.
  EXPECT_EQ(summary->report.ticks + summary->report.missed, 1500);
  EXPECT_EQ(summary->frames_dropped, 0U);
  const Csv csv = read_csv(o.trace_path);
  ASSERT_EQ(csv.rows.size(), summary->frames_written);
  EXPECT_EQ(csv.rows.size(), static_cast<std::size_t>(summary->report.ticks + 1));
  double largest_coupling_n = 0.0;
  std::size_t held_rows = 0;
  bool held_before = false;
  for (const auto& row : csv.rows) {
    for (const char* axis : {"x", "y", "z"}) {
      const double left = row[csv.at(std::string("left.coupling_f") + axis)];
      const double right = row[csv.at(std::string("right.coupling_f") + axis)];
      ASSERT_EQ(left, -right) << "t = " << row[0];  // exactly: one force computed, the other its negation
      largest_coupling_n = std::max(largest_coupling_n, std::abs(left));
    }
    // From the row after the hold began, no device is commanded any force.
    if (held_before) {
      ++held_rows;
      for (const char* f : {"left.fx", "left.fy", "left.fz", "right.fx", "right.fy", "right.fz"}) {
        ASSERT_EQ(row[csv.at(f)], 0.0) << f << " at t = " << row[0];
      }
    }
    held_before = held_before || row[csv.at("held")] == 1.0;
  }
  EXPECT_GT(largest_coupling_n, 0.3) << "the players felt the spring before the fault";
  EXPECT_GT(held_rows, 100U) << "the hold came about 0.3 s before the end";
  ASSERT_TRUE(summary->held_at_s);
  EXPECT_GE(*summary->held_at_s, 1.2);
  EXPECT_LT(*summary->held_at_s, 1.3);
  EXPECT_EQ(summary->held_by, "right");
  EXPECT_EQ(summary->forced_while_held, 0);
  EXPECT_EQ(summary->coupling_imbalance_n, 0.0);
  ASSERT_EQ(summary->devices.size(), 2U);
  EXPECT_GT(summary->devices[0].peak_force_n, 0.5) << "the left player pushed the ball";
  EXPECT_NE(summary->devices[1].fault_bits, 0U);
  const std::string text = format_world_run_summary(summary.value(), o);
  EXPECT_NE(text.find("device 'right' latched a fault: every device held at zero force (0 frame(s) after that"),
            std::string::npos)
      << text;
  const std::string json = world_stats_json(summary.value(), o);
  EXPECT_NE(json.find("\"held_by\": \"right\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"name\": \"left\""), std::string::npos) << json;
  std::filesystem::remove(o.trace_path);
}

TEST(WorldRun, EachStationOnItsOwnRunsOnAfterAnotherDevicesFault) {
  // `stop = "each"`: the pulled cable stops its own device only; the other runs on, unlatched.
  std::ifstream in(TOONFORCE_SOURCE_DIR "/scenes/two_players.toml");
  std::stringstream text;
  text << in.rdbuf();
  RunOptions o = two_players();
  std::string world = text.str();
  const std::size_t at = world.find("stop = \"all\"");
  ASSERT_NE(at, std::string::npos);
  o.scene_text = world.replace(at, std::string_view("stop = \"all\"").size(), "stop = \"each\"");
  o.duration_s = 1.5;
  o.world_fail = std::pair{std::string("right"), 1.0};
  o.trace_path = temp_path("each.csv").string();
  const auto summary = run_world_servo(o);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_FALSE(summary->held_at_s);
  const Csv csv = read_csv(o.trace_path);
  ASSERT_GT(csv.rows.size(), 1300U);
  double running = -1.0;  // the left device's state at 0.9 s, before the fault
  for (const auto& row : csv.rows) {
    if (row[0] <= 0.9) running = row[csv.at("left.state")];
  }
  std::size_t after = 0;
  for (const auto& row : csv.rows) {
    if (row[0] < 1.1 || row == csv.rows.back()) continue;  // the shut-down row stops every device
    ++after;
    ASSERT_NE(row[csv.at("right.latched")], 0.0) << "t = " << row[0];
    ASSERT_EQ(row[csv.at("left.latched")], 0.0) << "the left station goes on, t = " << row[0];
    ASSERT_EQ(row[csv.at("left.state")], running) << "t = " << row[0];
    ASSERT_EQ(row[csv.at("held")], 0.0);
  }
  EXPECT_GT(after, 300U);
  std::filesystem::remove(o.trace_path);
}

TEST(WorldRun, ErrorsNameTheDeviceTheOptionAndTheFix) {
  const auto error_of = [](RunOptions o) {
    const auto r = run_world_servo(o);
    return r ? std::string("(no error)") : r.error();
  };
  RunOptions o = two_players();
  o.duration_s = 0.01;
  o.world_scripts.push_back({"middle", "x.toml"});
  EXPECT_NE(error_of(o).find("--script middle=x.toml: the scene has no device 'middle' (its devices: left, right)"),
            std::string::npos)
      << error_of(o);
  o = two_players();
  o.duration_s = 0.01;
  o.world_scripts.push_back({"left", "x.toml"});
  EXPECT_NE(error_of(o).find("device 'left' is given a hand script twice"), std::string::npos);
  o = two_players();
  o.duration_s = 0.01;
  o.world_fail = std::pair{std::string("center"), 0.1};
  EXPECT_NE(error_of(o).find("--fail center: the scene has no such device"), std::string::npos);
  o = two_players();
  o.device = "falcon";
  EXPECT_NE(error_of(o).find("--device scene opens each as its table says"), std::string::npos) << error_of(o);
  o = two_players();
  o.scalar = ScalarKind::kFloat;
  EXPECT_NE(error_of(o).find("a world runs in double"), std::string::npos);
  // --device scene: two Falcons must each be selected.
  o = two_players();
  o.device = "scene";
  o.world_scripts.clear();
  o.duration_s = 0.01;
  o.scene_text = "[[device]]\nname = \"a\"\nbackend = \"falcon\"\n[[device]]\nname = \"b\"\nbackend = \"falcon\"\n"
                 "[[surface]]\npoint = [0.0, 0.0, -0.03]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 300.0\n";
  EXPECT_NE(error_of(o).find("device 'a': the world has 2 Falcons: give each its `select`"), std::string::npos)
      << error_of(o);
  // A hand script for a device that is not simulated is refused, not ignored.
  o.scene_text = "[[device]]\nname = \"a\"\nbackend = \"falcon\"\nselect = \"NOSUCH\"\n[[device]]\nname = \"b\"\n"
                 "[[surface]]\npoint = [0.0, 0.0, -0.03]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 300.0\n";
  o.world_scripts = {{"a", TOONFORCE_SOURCE_DIR "/scenes/hands/left_push.toml"}};
  EXPECT_NE(error_of(o).find("--script a=" TOONFORCE_SOURCE_DIR
                             "/scenes/hands/left_push.toml: device 'a' is a falcon (backend), not simulated"),
            std::string::npos)
      << error_of(o);
  // No output replaces an input.
  o = two_players();
  o.trace_path = TOONFORCE_SOURCE_DIR "/scenes/hands/left_push.toml";
  EXPECT_NE(error_of(o).find("it would be overwritten"), std::string::npos) << error_of(o);
}

/// A device that counts its emergency zeros.
class CountingDevice final : public DeviceDriver {
 public:
  explicit CountingDevice(Clocking clocking) {
    info_.name = "counting";
    info_.clocking = clocking;
  }
  DeviceStatus read(DeviceReading&) noexcept override { return DeviceStatus::kOk; }
  DeviceStatus write(const Vec3<double>&) noexcept override { return DeviceStatus::kOk; }
  void emergency_zero() noexcept override { ++zeros; }
  const DeviceInfo& info() const noexcept override { return info_; }
  int zeros = 0;

 private:
  DeviceInfo info_;
};

TEST(WorldRun, TheDeviceGroupsEmergencyZeroReachesEveryDeviceAndOwnClocksAreRefused) {
  CountingDevice a(Clocking::kHostTimer), b(Clocking::kHostTimer), own(Clocking::kDeviceThread);
  auto group = DeviceGroup::create({&a, &b}, {"a", "b"});
  ASSERT_TRUE(group) << group.error();
  EXPECT_EQ(group.value()->info().clocking, Clocking::kHostTimer);
  group.value()->emergency_zero();  // the heartbeat watchdog's and the fatal signals' path
  EXPECT_EQ(a.zeros, 1);
  EXPECT_EQ(b.zeros, 1);
  const auto refused = DeviceGroup::create({&a, &own}, {"a", "omni"});
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().find("device 'omni' (counting) is clocked by its own servo thread"), std::string::npos)
      << refused.error();
}

// ---- a device on a clock of its own, bridged to the world's ----

struct Numbered {
  std::array<std::uint64_t, 5> words{};
};

TEST(Handoff, AReaderRacingTheWriterSeesOnlyWholeValuesNewestFirstAndNeverWaits) {
  Handoff<Numbered> handoff;
  constexpr std::uint64_t kWrites = 200'000;
  std::atomic<bool> go{false};
  std::thread writer([&] {
    while (!go.load(std::memory_order_acquire)) std::this_thread::yield();
    for (std::uint64_t n = 1; n <= kWrites; ++n) {
      Numbered v;
      v.words.fill(n);
      handoff.write(v);
    }
  });
  std::uint64_t last = 0, torn = 0, backwards = 0, fresh = 0;
  go.store(true, std::memory_order_release);
  while (last < kWrites) {
    Numbered v;
    const bool is_new = handoff.read(v);
    fresh += is_new ? 1U : 0U;
    for (const std::uint64_t w : v.words) torn += w != v.words[0] ? 1U : 0U;
    backwards += v.words[0] < last ? 1U : 0U;
    if (!is_new && v.words[0] != last) ++torn;  // "not new" must mean the same value again
    last = v.words[0];
  }
  writer.join();
  EXPECT_EQ(torn, 0U);
  EXPECT_EQ(backwards, 0U);
  EXPECT_GT(fresh, 0U);
  Numbered v;
  EXPECT_FALSE(handoff.read(v)) << "nothing new after the last value was read";
  EXPECT_EQ(v.words[0], kWrites);
}

/// A device with a servo thread of its own, as OpenHaptics' scheduler is: run_clocked calls the
/// tick every `period` on its thread until the tick says stop (or `ticks_before_end` ran).
class SelfClockedDevice final : public DeviceDriver {
 public:
  explicit SelfClockedDevice(std::int64_t ticks_before_end = -1) : ticks_before_end_(ticks_before_end) {
    info_.name = "self-clocked";
    info_.clocking = Clocking::kDeviceThread;
  }
  DeviceStatus read(DeviceReading& r) noexcept override {
    r.position_m = {static_cast<double>(ticks_.load()) * 1e-6, 0.0, 0.0};
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>& f) noexcept override {
    last_x_bits_.store(std::bit_cast<std::uint64_t>(f.x), std::memory_order_relaxed);
    return DeviceStatus::kOk;
  }
  void emergency_zero() noexcept override { emergencies.fetch_add(1); }
  const DeviceInfo& info() const noexcept override { return info_; }
  Result<ClockedEnd> run_clocked(ClockedTickFn tick, void* context) override {
    for (std::int64_t k = 0;; ++k) {
      if (ticks_before_end_ >= 0 && k >= ticks_before_end_) return ClockedEnd{"the device's thread gave up"};
      ticks_.store(k + 1);
      if (tick(context, ClockedTick{k, 1e-3, 1e-3}) == TickVerdict::kStop) return ClockedEnd{};
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
  }
  double last_x() const noexcept { return std::bit_cast<double>(last_x_bits_.load(std::memory_order_relaxed)); }
  std::int64_t ticks() const noexcept { return ticks_.load(); }
  std::atomic<int> emergencies{0};

 private:
  DeviceInfo info_;
  std::int64_t ticks_before_end_;
  std::atomic<std::int64_t> ticks_{0};
  std::atomic<std::uint64_t> last_x_bits_{0};
};

template <class Predicate>
bool eventually(Predicate p) {  // a condition that must come, however slow the host (10 s at most)
  for (int i = 0; i < 10'000; ++i) {
    if (p()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return p();
}

TEST(ClockBridge, TheDeviceAppliesTheWorldsNewestForceAndZeroOnceItIsTooOld) {
  SelfClockedDevice device;
  auto bridge = ClockBridge::start(device, 0.005);  // 5 ms
  ASSERT_TRUE(bridge) << bridge.error();
  ClockBridge& b = *bridge.value();
  EXPECT_EQ(b.info().clocking, Clocking::kHostTimer) << "to the world it is one more host-clocked device";
  DeviceReading r;
  ASSERT_TRUE(eventually([&] { return b.read(r) == DeviceStatus::kOk; }));
  // The world writes a force every millisecond: the device applies it.
  ASSERT_TRUE(eventually([&] {
    static_cast<void>(b.write({1.5, 0.0, 0.0}));
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return device.last_x() == 1.5;
  }));
  // The world stops writing (it stalled): once the force is over 5 ms old the device writes zero.
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_TRUE(eventually([&] { return device.last_x() == 0.0; }));
  EXPECT_GT(b.stale_force_ticks(), 0);
  // Writing again brings the force back; an emergency zero holds it at zero and reaches the device.
  ASSERT_TRUE(eventually([&] {
    static_cast<void>(b.write({2.0, 0.0, 0.0}));
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return device.last_x() == 2.0;
  }));
  b.emergency_zero();
  EXPECT_EQ(device.emergencies.load(), 1);
  ASSERT_TRUE(eventually([&] {
    static_cast<void>(b.write({2.0, 0.0, 0.0}));
    return device.last_x() == 0.0;
  }));
  b.stop();
  EXPECT_EQ(device.last_x(), 0.0) << "its last tick wrote zero";
  EXPECT_GT(b.reading_age().summary().count, 0);
  EXPECT_GT(b.force_age().summary().count, 0);
}

TEST(ClockBridge, ADeviceThreadThatEndsIsATimeoutNamingWhy) {
  SelfClockedDevice device(50);  // its thread ends by itself after 50 ticks
  auto bridge = ClockBridge::start(device, 0.005);
  ASSERT_TRUE(bridge) << bridge.error();
  ClockBridge& b = *bridge.value();
  DeviceReading r;
  ASSERT_TRUE(eventually([&] { return device.ticks() >= 50; }));
  ASSERT_TRUE(eventually([&] { return b.read(r) == DeviceStatus::kTimeout; }));
  EXPECT_NE(b.last_error().find("its servo thread ended: the device's thread gave up"), std::string::npos)
      << b.last_error();
}

TEST(WorldRun, AnOmniOnItsOwnClockJoinsASimulatedDeviceAndBothFeelTheCoupling) {
  // The fake libHD (tests/omni/fake_hd) runs a scheduler thread of its own, as OpenHaptics does.
  RunOptions o = two_players();
  o.device = "scene";
  o.world_scripts = {{"hand", TOONFORCE_SOURCE_DIR "/scenes/hands/left_push.toml"}};
  o.omni.library_path = TOONFORCE_FAKE_HD;
  o.allow_empty = true;
  o.duration_s = 1.2;
  o.trace_path = temp_path("mixed.csv").string();
  o.scene_text = "name = \"hand and omni\"\n"
                 "[[device]]\nname = \"hand\"\nbackend = \"sim\"\noffset = [-0.04, 0.0, 0.0]\n"
                 "[[device]]\nname = \"omni\"\nbackend = \"omni\"\noffset = [0.04, 0.0, 0.0]\nyaw = 180.0\n"
                 "[[coupling]]\nbetween = [\"hand\", \"omni\"]\nstiffness = 100.0\ndamping = 0.5\n"
                 "rest_length = 0.08\n";
  const auto summary = run_world_servo(o);
  ASSERT_TRUE(summary) << summary.error();
  ASSERT_EQ(summary->devices.size(), 2U);
  const WorldRunDevice& omni = summary->devices[1];
  EXPECT_EQ(omni.backend, "omni");
  EXPECT_TRUE(omni.bridged);
  EXPECT_GT(omni.reading_age.count, 100);
  EXPECT_GT(omni.force_age.count, 100);
  EXPECT_GT(omni.peak_force_n, 0.2) << "the Omni felt the hand's pull through the coupling";
  const Csv csv = read_csv(o.trace_path);
  ASSERT_EQ(csv.rows.size(), summary->frames_written);
  for (const auto& row : csv.rows) {
    ASSERT_EQ(row[csv.at("hand.coupling_fx")], -row[csv.at("omni.coupling_fx")]) << "t = " << row[0];
  }
  for (const char* f : {"hand.fx", "hand.fy", "hand.fz", "omni.fx", "omni.fy", "omni.fz"}) {
    EXPECT_EQ(csv.rows.back()[csv.at(f)], 0.0) << f;
  }
  const std::string text = format_world_run_summary(summary.value(), o);
  EXPECT_NE(text.find("clocks   omni: on its own servo thread; reading age median"), std::string::npos) << text;
  EXPECT_NE(world_stats_json(summary.value(), o).find("\"reading_age_us\""), std::string::npos);
  std::filesystem::remove(o.trace_path);
  // Two Omnis, neither named: which is which is the user's to say.
  o.scene_text = "[[device]]\nname = \"a\"\nbackend = \"omni\"\n[[device]]\nname = \"b\"\nbackend = \"omni\"\n";
  o.world_scripts.clear();
  const auto two = run_world_servo(o);
  ASSERT_FALSE(two);
  EXPECT_NE(two.error().find("device 'a': the world has 2 Omnis: give each its `select = \"<device name>\"`"),
            std::string::npos)
      << two.error();
}

/// The fake libHD's own controls (tests/omni/fake_hd/fake_hd_control.h), from the same file the
/// backend loads, so both see one fake.
struct FakeHdDevices {
  FakeHdDevices() {
    handle = dlopen(TOONFORCE_FAKE_HD, RTLD_LAZY | RTLD_GLOBAL | RTLD_NODELETE);
    if (handle == nullptr) return;
    reset = reinterpret_cast<void (*)()>(dlsym(handle, "tf_fake_hd_reset"));
    add_device = reinterpret_cast<int (*)(const char*, const char*)>(dlsym(handle, "tf_fake_hd_add_device"));
  }
  ~FakeHdDevices() {
    if (reset != nullptr) reset();  // back to its one default device for the other tests
  }
  void* handle = nullptr;
  void (*reset)() = nullptr;
  int (*add_device)(const char*, const char*) = nullptr;
};

TEST(WorldRun, TwoOmnisOnOpenHapticsOneSchedulerFeelEqualAndOppositeCoupling) {
  // Two devices configured by name in the fake libHD, one scheduler thread for both, as
  // OpenHaptics runs several devices; each Omni behind its own clock bridge.
  FakeHdDevices fake;
  ASSERT_NE(fake.handle, nullptr) << dlerror();
  ASSERT_NE(fake.add_device, nullptr);
  fake.reset();
  ASSERT_EQ(fake.add_device("Left", "FAKE-L"), 0);
  ASSERT_EQ(fake.add_device("Right", "FAKE-R"), 1);
  RunOptions o = two_players();
  o.device = "scene";
  o.world_scripts.clear();
  o.omni.library_path = TOONFORCE_FAKE_HD;
  o.allow_empty = true;
  o.duration_s = 1.2;
  o.trace_path = temp_path("two_omnis.csv").string();
  // Both hands hold their handle at the device's origin, 5 mm off the workspace centre: in the
  // world (-40, -5, 5) mm and (40, 5, 5) mm, 80.6 mm apart. The coupling's rest length is 79 mm,
  // so it pulls them together with 0.16 N, under the 0.2 N below which a loop engages.
  o.scene_text = "name = \"two omnis\"\n"
                 "[[device]]\nname = \"l\"\nbackend = \"omni\"\nselect = \"Left\"\noffset = [-0.04, 0.0, 0.0]\n"
                 "soft_start = 0.1\n"
                 "[[device]]\nname = \"r\"\nbackend = \"omni\"\nselect = \"Right\"\noffset = [0.04, 0.0, 0.0]\n"
                 "yaw = 180.0\nsoft_start = 0.1\n"
                 "[[coupling]]\nbetween = [\"l\", \"r\"]\nstiffness = 100.0\ndamping = 0.5\nrest_length = 0.079\n";
  const auto summary = run_world_servo(o);
  ASSERT_TRUE(summary) << summary.error();
  ASSERT_EQ(summary->devices.size(), 2U);
  for (const WorldRunDevice& d : summary->devices) {
    EXPECT_EQ(d.backend, "omni") << d.name;
    EXPECT_TRUE(d.bridged) << d.name;
    EXPECT_GT(d.reading_age.count, 100) << d.name;
    EXPECT_GT(d.force_age.count, 100) << d.name;
    EXPECT_GT(d.peak_force_n, 0.1) << d.name << " felt the other through the coupling";
  }
  EXPECT_NE(summary->devices[0].device_name.find("serial FAKE-L"), std::string::npos)
      << summary->devices[0].device_name;
  EXPECT_NE(summary->devices[1].device_name.find("serial FAKE-R"), std::string::npos)
      << summary->devices[1].device_name;
  const Csv csv = read_csv(o.trace_path);
  ASSERT_EQ(csv.rows.size(), summary->frames_written);
  ASSERT_GT(csv.rows.size(), 100U);
  for (const auto& row : csv.rows) {
    for (const char* axis : {"x", "y", "z"}) {
      ASSERT_EQ(row[csv.at(std::string("l.coupling_f") + axis)], -row[csv.at(std::string("r.coupling_f") + axis)])
          << "t = " << row[0] << ", " << axis;
    }
  }
  for (const char* f : {"l.fx", "l.fy", "l.fz", "r.fx", "r.fy", "r.fz"}) {
    EXPECT_EQ(csv.rows.back()[csv.at(f)], 0.0) << f;
  }
  std::filesystem::remove(o.trace_path);
}

TEST(WorldRun, TheGuardianEndsAWorldsTraceWithZeroForceOnEveryDevice) {
  // The loop's process died in the middle of a row: the guardian's epilogue cuts the part and
  // writes the row of its zero command, every device's force zero, the rest not known.
  const std::string path = temp_path("died.csv").string();
  {
    std::ofstream out(path);
    out << "t,a.x,a.y,a.z,a.fx,a.fy,a.fz,a.coupling_fx,a.coupling_fy,a.coupling_fz,a.ball_fx,a.ball_fy,a.ball_fz,"
           "a.faults,a.latched,a.state,b.x,b.y,b.z,b.fx,b.fy,b.fz,b.coupling_fx,b.coupling_fy,b.coupling_fz,"
           "b.ball_fx,b.ball_fy,b.ball_fz,b.faults,b.latched,b.state,coupling1.fx,coupling1.fy,coupling1.fz,held\n";
    out << "0.001";
    for (int i = 0; i < 34; ++i) out << ",1";
    out << "\n0.002,1,1,1,2,2";  // cut short
  }
  guardian::Verdict v;
  v.t_end_s = 0.0025;
  ASSERT_EQ(guardian::end_trace(path, v, nullptr), "");
  const Csv csv = read_csv(path);
  ASSERT_EQ(csv.rows.size(), 2U) << "the part row is cut";
  const auto& last = csv.rows.back();
  ASSERT_EQ(last.size(), csv.header.size());
  EXPECT_EQ(last[0], 0.0025);
  for (std::size_t i = 1; i < csv.header.size(); ++i) {
    const std::string& c = csv.header[i];
    const bool device_force = c == "a.fx" || c == "a.fy" || c == "a.fz" || c == "b.fx" || c == "b.fy" || c == "b.fz";
    if (device_force) {
      EXPECT_EQ(last[i], 0.0) << c;
    } else {
      EXPECT_TRUE(std::isnan(last[i])) << c << " = " << last[i];
    }
  }
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace toonforce
