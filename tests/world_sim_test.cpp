// SPDX-License-Identifier: Apache-2.0
// `toonforce sim` of a world scene (sim/world_sim.hpp), read back from its trace: two simulated
// hands on two simulated devices facing each other, a coupling and a ball. Each tick the
// couplings' forces on the two devices are exact negations; after one device's cable is pulled,
// every device is held at zero force from the tick after its fault latched; mistakes in the
// hand scripts' naming are refused with the device's name.
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

#include "toonforce/sim/check.hpp"
#include "toonforce/sim/world_sim.hpp"

namespace toonforce::test {
namespace {

namespace fs = std::filesystem;

class Dir {
 public:
  Dir() : path_(fs::temp_directory_path() / ("toonforce-world-" + std::to_string(::getpid()))) {
    fs::create_directories(path_);
  }
  ~Dir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string write(const std::string& name, const std::string& text) const {
    const fs::path p = path_ / name;
    std::ofstream(p) << text;
    return p.string();
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

// Two devices facing each other across x, 8 cm apart; each device's +x points to the middle.
// The coupling is slack at the start (its rest length is their distance: the loops engage) and
// soft enough that the hands reach the ball between them.
const char* kWorld = R"(name = "pair"
[[surface]]
point = [0.0, 0.0, -0.03]
normal = [0.0, 0.0, 1.0]
stiffness = 800.0

[[device]]
name = "left"
offset = [-0.04, 0.0, 0.0]
max_force = 6.0

[[device]]
name = "right"
offset = [0.04, 0.0, 0.0]
yaw = 180.0

[[coupling]]
between = ["left", "right"]
stiffness = 40.0
damping = 1.0
rest_length = 0.08

[ball]
radius = 0.015
mass = 0.05
start = [0.0, 0.0, -0.015]
wall_point = [0.0, 0.0, -0.03]
wall_normal = [0.0, 0.0, 1.0]
)";

// Toward the middle at the ball's height, in the device's own frame.
std::string hand(double reach_m) {
  std::ostringstream s;
  s << "name = \"reach\"\n[hand]\nstart = [0.0, 0.0, -0.015]\n"
    << "[[segment]]\ntype = \"hold\"\nduration = 0.2\n"
    << "[[segment]]\ntype = \"move\"\nto = [" << reach_m << ", 0.0, -0.015]\nduration = 0.5\n"
    << "[[segment]]\ntype = \"hold\"\nduration = 0.6\n";
  return s.str();
}

struct Trace {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
  std::size_t col(const std::string& name) const {
    for (std::size_t i = 0; i < header.size(); ++i) {
      if (header[i] == name) return i;
    }
    ADD_FAILURE() << "no column " << name;
    return 0;
  }
};

Trace read_trace(const std::string& path) {
  Trace t;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::stringstream h(line);
  for (std::string c; std::getline(h, c, ',');) t.header.push_back(c);
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::stringstream r(line);
    for (std::string c; std::getline(r, c, ',');) row.push_back(std::stod(c));
    t.rows.push_back(std::move(row));
  }
  return t;
}

WorldSimOptions options_for(const Dir& dir) {
  WorldSimOptions o;
  o.scene_path = dir.write("pair.toml", kWorld);
  o.scripts = {{"left", dir.write("left.toml", hand(0.04))}, {"right", dir.write("right.toml", hand(0.04))}};
  o.trace_path = dir.file("trace.csv");
  return o;
}

TEST(WorldSim, TheCouplingsForcesOnTheTwoDevicesAreExactNegationsAtEveryTick) {
  Dir dir;
  const WorldSimOptions o = options_for(dir);
  const auto summary = run_world_sim(o);
  ASSERT_TRUE(summary) << summary.error();
  EXPECT_EQ(summary->ticks, 1300);
  EXPECT_EQ(summary->coupling_imbalance_n, 0.0);
  EXPECT_FALSE(summary->held_at_s.has_value());
  const Trace t = read_trace(o.trace_path);
  ASSERT_EQ(t.rows.size(), 1300U);
  std::size_t coupled = 0;
  std::size_t ball_touched = 0;
  for (const auto& row : t.rows) {
    for (const char* axis : {"x", "y", "z"}) {
      const double l = row[t.col(std::string("left.coupling_f") + axis)];
      const double r = row[t.col(std::string("right.coupling_f") + axis)];
      ASSERT_EQ(l, -r) << "t = " << row[0];
    }
    if (std::abs(row[t.col("left.coupling_fx")]) > 0.1) ++coupled;
    if (std::abs(row[t.col("left.ball_fx")]) > 0.01 || std::abs(row[t.col("right.ball_fx")]) > 0.01) ++ball_touched;
  }
  EXPECT_GT(coupled, 100U);       // the comparison is of forces, not of zeros
  EXPECT_GT(ball_touched, 100U);  // the hands reach the ball (4 cm in: its surface is 2.5 cm from each)
  // The device facing the other way: world +x is its -x, so its commanded force is the world
  // force turned back. Both devices are pulled toward the middle at the end of the reach.
  EXPECT_EQ(summary->devices.size(), 2U);
}

TEST(WorldSim, AfterOneDevicesCableIsPulledEveryDeviceIsHeldAtZeroForce) {
  Dir dir;
  WorldSimOptions o = options_for(dir);
  o.fail = std::pair{std::string("right"), 0.9};
  const auto summary = run_world_sim(o);
  ASSERT_TRUE(summary) << summary.error();
  ASSERT_TRUE(summary->held_at_s.has_value());
  EXPECT_EQ(summary->held_by, "right");
  // Pulled at 0.9 s; the right device's supervisor latches it silent after 10 failed reads.
  EXPECT_NEAR(*summary->held_at_s, 0.909, 0.0015);
  EXPECT_EQ(summary->forced_while_held, 0);
  const Trace t = read_trace(o.trace_path);
  std::size_t held_rows = 0;
  bool left_pushed_before = false;
  bool seen_hold = false;
  for (const auto& row : t.rows) {
    const bool held = row[t.col("held")] == 1.0;
    if (!seen_hold && !held && std::abs(row[t.col("left.fx")]) > 0.1) left_pushed_before = true;
    if (seen_hold) {
      ASSERT_TRUE(held) << "t = " << row[0];
      for (const char* name : {"left.fx", "left.fy", "left.fz", "right.fx", "right.fy", "right.fz"}) {
        ASSERT_EQ(row[t.col(name)], 0.0) << name << " at t = " << row[0];
      }
      ++held_rows;
    }
    seen_hold = seen_hold || held;
  }
  EXPECT_TRUE(left_pushed_before);
  EXPECT_GT(held_rows, 300U);
  EXPECT_NE(summary->devices[0].latched, 0U);  // left: held (its e-stop input)
}

TEST(WorldSim, AWallThatNamesOneDeviceIsFeltByItAloneTheOtherPassesThrough) {
  // Both hands press 1 cm down through a wall 5 mm below them; the wall names `right` only, so
  // left's handle goes through unopposed (no coupling, no ball: nothing else pushes).
  Dir dir;
  WorldSimOptions o;
  o.scene_path = dir.write("named.toml", R"([[device]]
name = "left"
offset = [-0.04, 0.0, 0.0]
[[device]]
name = "right"
offset = [0.04, 0.0, 0.0]
yaw = 180.0
[[surface]]
point = [0.0, 0.0, -0.005]
normal = [0.0, 0.0, 1.0]
stiffness = 500.0
devices = ["right"]
)");
  const std::string down = "name = \"down\"\n[hand]\nstart = [0.0, 0.0, 0.0]\n[[segment]]\ntype = \"hold\"\n"
                           "duration = 0.3\n[[segment]]\ntype = \"move\"\nto = [0.0, 0.0, -0.01]\nduration = 0.3\n"
                           "[[segment]]\ntype = \"hold\"\nduration = 0.4\n";
  o.scripts = {{"left", dir.write("l.toml", down)}, {"right", dir.write("r.toml", down)}};
  o.trace_path = dir.file("named.csv");
  const auto summary = run_world_sim(o);
  ASSERT_TRUE(summary) << summary.error();
  const Trace t = read_trace(o.trace_path);
  double left_peak = 0.0, right_peak = 0.0, left_lowest = 0.0, right_lowest = 0.0;
  for (const auto& row : t.rows) {
    left_peak = std::max(left_peak, std::abs(row[t.col("left.fz")]));
    right_peak = std::max(right_peak, std::abs(row[t.col("right.fz")]));
    left_lowest = std::min(left_lowest, row[t.col("left.z")]);
    right_lowest = std::min(right_lowest, row[t.col("right.z")]);
  }
  EXPECT_EQ(left_peak, 0.0) << "the wall does not act on left";
  EXPECT_GT(right_peak, 0.5) << "right presses into its wall";
  EXPECT_LT(left_lowest, -0.008) << "left's handle goes through the plane";
  EXPECT_GT(right_lowest, left_lowest + 0.001) << "right's is held up by it";
}

TEST(WorldSim, EveryDeviceNeedsItsOwnNamedHandScript) {
  Dir dir;
  WorldSimOptions o = options_for(dir);
  o.scripts.pop_back();
  auto r = run_world_sim(o);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("device 'right' has no hand script: give --script right=FILE"), std::string::npos)
      << r.error();
  o = options_for(dir);
  o.scripts.push_back({"middle", o.scripts[0].second});
  r = run_world_sim(o);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("the scene has no device 'middle' (its devices: left, right)"), std::string::npos)
      << r.error();
  o = options_for(dir);
  o.scripts[1].first = "left";
  r = run_world_sim(o);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("device 'left' is given a hand script twice"), std::string::npos) << r.error();
  EXPECT_FALSE(parse_named_script("hand.toml"));
  EXPECT_FALSE(parse_named_script("=hand.toml"));
  EXPECT_EQ(parse_named_script("left=a=b.toml")->second, "a=b.toml");
}

TEST(WorldSim, TheSameRunGivesTheSameTraceToTheByte) {
  Dir dir;
  WorldSimOptions o = options_for(dir);
  ASSERT_TRUE(run_world_sim(o));
  std::stringstream first;
  first << std::ifstream(o.trace_path).rdbuf();
  ASSERT_TRUE(run_world_sim(o));
  std::stringstream second;
  second << std::ifstream(o.trace_path).rdbuf();
  EXPECT_EQ(first.str(), second.str());
  EXPECT_GT(first.str().size(), 10000U);
}

// ---- toonforce check of a world ------------------------------------------------------------

bool any_has(const std::vector<std::string>& lines, const std::string& part) {
  for (const std::string& l : lines) {
    if (l.find(part) != std::string::npos) return true;
  }
  return false;
}

TEST(WorldCheck, EachDeviceIsCheckedWithTheSceneInItsOwnFrame) {
  // A floor at world z = -0.03 is inside a Falcon's workspace (+-5 cm) for a device at the
  // world's origin; for one lifted 9 cm, the floor is 12 cm below its centre: 7 cm out of reach.
  Dir dir;
  CheckOptions o;
  o.scene_path =
      dir.write("w.toml", std::string(kWorld) + "\n[[device]]\nname = \"high\"\noffset = [0.0, 0.0, 0.09]\n");
  const CheckReport r = check_scene(o);
  EXPECT_TRUE(r.world);
  EXPECT_TRUE(r.errors.empty()) << r.errors.front();
  EXPECT_TRUE(any_has(r.warnings, "(high):2: surface[1]: its plane lies")) << format_check_report(r, o);
  EXPECT_FALSE(any_has(r.warnings, "(left):2: surface[1]: its plane lies"));
  EXPECT_FALSE(any_has(r.warnings, "(right):2: surface[1]: its plane lies"));
  EXPECT_NE(format_check_report(r, o).find("a world of several devices; loads as sim would load it"),
            std::string::npos);
}

TEST(WorldCheck, ACouplingOverThePassiveBoundEvenWhenHeldIsAWarningAtEachOfItsPorts) {
  Dir dir;
  CheckOptions o;
  std::string text = kWorld;
  text.replace(text.find("stiffness = 40.0"), std::string("stiffness = 40.0").size(), "stiffness = 20000.0");
  o.scene_path = dir.write("w.toml", text);
  CheckReport r = check_scene(o);
  EXPECT_TRUE(any_has(r.warnings, "device 'left': coupling[1] K = 20000 N/m"));
  EXPECT_TRUE(any_has(r.warnings, "device 'right': coupling[1] K = 20000 N/m"));
  o.strict = true;
  r = check_scene(o);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.exit_code, 1);
  // The example's soft coupling is not.
  o.strict = false;
  o.scene_path = dir.write("w.toml", kWorld);
  r = check_scene(o);
  EXPECT_FALSE(any_has(r.warnings, "coupling[1]"));
  EXPECT_TRUE(r.ok);
}

TEST(WorldCheck, AWorldTakesItsHandScriptsThroughSimNotOneHere) {
  Dir dir;
  CheckOptions o;
  o.scene_path = dir.write("w.toml", kWorld);
  o.script_path = dir.write("hand.toml", hand(0.01));
  const CheckReport r = check_scene(o);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(any_has(r.errors, "a world scene takes one hand script per device"));
}

}  // namespace
}  // namespace toonforce::test
