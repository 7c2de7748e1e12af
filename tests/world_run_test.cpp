// SPDX-License-Identifier: Apache-2.0
// `toonforce run` of a world scene (tools/run world_run.hpp): the README's two players in real
// time on simulated devices, the trace's meaning (Newton's third law on every row, zero force on
// every device once one stop holds), the errors that name the device and the fix, and the
// guardian's zero-force row at the end of a world's trace.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

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
  // --device scene: an Omni cannot join a world yet, and two Falcons must each be selected.
  o = two_players();
  o.device = "scene";
  o.world_scripts.clear();
  o.duration_s = 0.01;
  o.scene_text = "[[device]]\nname = \"a\"\nbackend = \"omni\"\n[[device]]\nname = \"b\"\n"
                 "[[surface]]\npoint = [0.0, 0.0, -0.03]\nnormal = [0.0, 0.0, 1.0]\nstiffness = 300.0\n";
  EXPECT_NE(error_of(o).find("device 'a': backend 'omni': an Omni is clocked by its own servo thread"),
            std::string::npos)
      << error_of(o);
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
