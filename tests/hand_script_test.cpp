// SPDX-License-Identifier: Apache-2.0
// Hand script files: every committed script loads, and malformed files get errors that name
// the file, the line and the key (the same standard as scene files).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <unistd.h>

#include "toonforce/config/hand_script_file.hpp"

namespace toonforce {
namespace {

namespace fs = std::filesystem;

/// Writes `text` to a file named `name` in a fresh directory and loads it as a hand script.
class HandScriptFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("toonforce_hand_{}_{}",
                                                   ::testing::UnitTest::GetInstance()->current_test_info()->name(),
                                                   static_cast<long>(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& text) {
    const fs::path path = dir_ / name;
    std::ofstream(path) << text;
    return path.string();
  }
  /// The error text of loading `text`, which must fail.
  std::string error_of(const std::string& text) {
    const std::string path = write("bad.toml", text);
    const auto loaded = load_hand_script(path);
    EXPECT_FALSE(loaded) << "expected an error for:\n" << text;
    return loaded ? std::string() : loaded.error();
  }
  /// "<dir>/bad.toml:LINE: WHERE: "
  std::string at(int line, const std::string& where) const {
    return fmt::format("{}:{}: {}: ", (dir_ / "bad.toml").string(), line, where);
  }

  fs::path dir_;
};

constexpr const char* kHead = "[hand]\nstart = [0.0, 0.0, 0.01]\n";  // lines 1-2

TEST_F(HandScriptFileTest, EveryCommittedScriptLoads) {
  int count = 0;
  for (const auto& entry : fs::directory_iterator(fs::path(TOONFORCE_SOURCE_DIR) / "scenes" / "hands")) {
    if (entry.path().extension() != ".toml") continue;
    const auto loaded = load_hand_script(entry.path().string());
    EXPECT_TRUE(loaded) << loaded.error();
    if (loaded) {
      EXPECT_GT(loaded->intent.duration_s(), 0.5) << entry.path();
    }
    ++count;
  }
  EXPECT_GE(count, 4);
}

TEST_F(HandScriptFileTest, ReadsValuesAndDefaults) {
  const std::string path = write("ok.toml", std::string(kHead) + R"(stiffness = 150.0
[[segment]]
type = "stroke"
to = [0.03, 0.0, 0.0]
speed = 0.1
force = 1.5
normal = [0.0, 0.0, 2.0]
label = "along"
[[segment]]
type = "hold"
duration = 0.2
)");
  const auto loaded = load_hand_script(path);
  ASSERT_TRUE(loaded) << loaded.error();
  const auto& s = loaded->script;
  EXPECT_EQ(s.name, "ok");
  EXPECT_EQ(s.start_m, (Vec3<double>{0.0, 0.0, 0.01}));
  EXPECT_DOUBLE_EQ(s.impedance.stiffness_n_per_m, 150.0);
  EXPECT_DOUBLE_EQ(s.impedance.damping_n_s_per_m, host_sim::HandImpedance{}.damping_n_s_per_m);
  ASSERT_EQ(s.segments.size(), 2U);
  EXPECT_EQ(s.segments[0].kind, host_sim::SegmentKind::kStroke);
  EXPECT_EQ(s.segments[0].normal, (Vec3<double>{0.0, 0.0, 1.0}));  // normalised
  EXPECT_TRUE(s.segments[0].stop);                                 // a stroke stops by default
  EXPECT_DOUBLE_EQ(*s.segments[0].force_n, 1.5);
  EXPECT_EQ(s.segments[0].label, "along");
  EXPECT_EQ(s.segments[0].line, 4U);
  EXPECT_FALSE(s.segments[1].force_n.has_value());  // a hold keeps the previous press force
}

TEST_F(HandScriptFileTest, UnknownKeyWithDidYouMean) {
  const std::string e = error_of(std::string(kHead) + R"([[segment]]
type = "stroke"
to = [0.03, 0.0, 0.0]
sped = 0.1
force = 1.0
)");
  EXPECT_NE(e.find(at(6, "segment[1]") + "unknown key 'sped' (did you mean 'speed'?)"), std::string::npos) << e;
  EXPECT_NE(e.find(at(3, "segment[1]") + "missing required key 'speed' [m/s]"), std::string::npos) << e;
}

TEST_F(HandScriptFileTest, WrongTypeAndOutOfRange) {
  const std::string e = error_of(std::string(kHead) + R"([[segment]]
type = "strike"
to = [0.0, 0.0, -0.01]
speed = "fast"
[[segment]]
type = "hold"
duration = -0.5
[[segment]]
type = "cross"
to = [0.05, 0.0, 0.0]
speed = 0.1
force = 1.0
stop = "yes"
)");
  EXPECT_NE(e.find(at(6, "segment[1].speed") + "must be a number, not a string"), std::string::npos) << e;
  EXPECT_NE(e.find(at(9, "segment[2].duration") + "must be > 0 (got -0.5)"), std::string::npos) << e;
  EXPECT_NE(e.find(at(15, "segment[3].stop") + "must be true or false, not a string"), std::string::npos) << e;
}

TEST_F(HandScriptFileTest, UnknownSegmentTypeSuggestsTheNearestOne) {
  const std::string e = error_of(std::string(kHead) + "[[segment]]\ntype = \"strok\"\nto = [0.01, 0.0, 0.0]\n");
  EXPECT_NE(e.find(at(4, "segment[1].type") + "unknown segment type 'strok', did you mean 'stroke'?"),
            std::string::npos)
      << e;
}

TEST_F(HandScriptFileTest, AKeyOfAnotherKindIsNamedAsSuch) {
  const std::string e = error_of(std::string(kHead) + R"([[segment]]
type = "move"
to = [0.01, 0.0, 0.0]
duration = 0.3
force = 1.0
)");
  EXPECT_NE(e.find(at(7, "segment[1].force") + "does not apply to a move segment (its keys: to, speed, duration, "
                                               "force_ramp, label)"),
            std::string::npos)
      << e;
  EXPECT_EQ(e.find("unknown key"), std::string::npos) << e;  // reported once, precisely
}

TEST_F(HandScriptFileTest, AMoveTakesDurationOrSpeedNotBoth) {
  const std::string e = error_of(std::string(kHead) + R"([[segment]]
type = "move"
to = [0.01, 0.0, 0.0]
duration = 0.3
speed = 0.1
)");
  EXPECT_NE(e.find(at(7, "segment[1].speed") + "a move takes either duration or speed"), std::string::npos) << e;
}

TEST_F(HandScriptFileTest, ReleaseMustBeLast) {
  const std::string e = error_of(std::string(kHead) + R"([[segment]]
type = "release"
[[segment]]
type = "hold"
duration = 0.1
)");
  EXPECT_NE(e.find(at(4, "segment[1].type") + "release must be the last segment"), std::string::npos) << e;
}

TEST_F(HandScriptFileTest, APathTooShortForItsRampsIsReportedAtItsLine) {
  const std::string e = error_of(std::string(kHead) + R"([[segment]]
type = "hold"
duration = 0.1

[[segment]]
type = "stroke"
to = [0.004, 0.0, 0.01]
speed = 0.2
force = 1.0
label = "nudge"
)");
  EXPECT_NE(e.find(at(9, "segment[2].to") + "the path is 0.004 m long"), std::string::npos) << e;
  EXPECT_NE(e.find("(segment 'nudge')"), std::string::npos) << e;
}

TEST_F(HandScriptFileTest, MissingHandTableAndBadStart) {
  const std::string no_hand = error_of("name = \"x\"\n[[segment]]\ntype = \"hold\"\nduration = 1.0\n");
  EXPECT_NE(no_hand.find("missing required table [hand]"), std::string::npos) << no_hand;
  const std::string bad_start = error_of("[hand]\nstart = [0.0, 0.0]\n[[segment]]\ntype = \"hold\"\nduration = 1.0\n");
  EXPECT_NE(bad_start.find(at(2, "hand.start") + "must be an array of three numbers [m]"), std::string::npos)
      << bad_start;
  const std::string bad_mass = error_of("[hand]\nstart = [0.0, 0.0, 0.0]\nmass = 0\n[[segment]]\ntype = \"hold\"\n"
                                        "duration = 1.0\n");
  EXPECT_NE(bad_mass.find(at(3, "hand.mass") + "must be > 0 (got 0)"), std::string::npos) << bad_mass;
}

TEST_F(HandScriptFileTest, UnknownTopLevelKeyAndNoSegments) {
  const std::string e = error_of(std::string(kHead) + "[segments]\ntype = \"hold\"\n");
  EXPECT_NE(e.find("unknown key 'segments' (did you mean 'segment'?)"), std::string::npos) << e;
  EXPECT_NE(e.find("no [[segment]]"), std::string::npos) << e;
}

TEST_F(HandScriptFileTest, ZeroNormalAndMissingType) {
  const std::string e = error_of(std::string(kHead) + R"([[segment]]
type = "hold"
duration = 0.1
force = 1.0
normal = [0.0, 0.0, 0.0]
[[segment]]
duration = 0.1
)");
  EXPECT_NE(e.find(at(7, "segment[1].normal") + "must not be a zero vector"), std::string::npos) << e;
  EXPECT_NE(e.find(at(8, "segment[2]") + "missing required key 'type'"), std::string::npos) << e;
}

TEST_F(HandScriptFileTest, TomlSyntaxErrorsNameTheLine) {
  const std::string e = error_of(std::string(kHead) + "[[segment]]\ntype = \"hold\nduration = 0.1\n");
  EXPECT_NE(e.find((dir_ / "bad.toml").string() + ":4: TOML syntax:"), std::string::npos) << e;
}

TEST_F(HandScriptFileTest, AMissingFileSaysSo) {
  const auto loaded = load_hand_script((dir_ / "nowhere.toml").string());
  ASSERT_FALSE(loaded);
  EXPECT_NE(loaded.error().find("no such hand script"), std::string::npos) << loaded.error();
}

TEST(HandScriptText, ParsesFromTextWithTheGivenSourceName) {
  const auto bad = parse_hand_script("[hand]\nstart = [0, 0, 0]\n[[segment]]\ntype = \"hold\"\n", "inline.toml");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("inline.toml:3: segment[1]: missing required key 'duration' [s]"), std::string::npos)
      << bad.error();
}

// `force = 1e308` drove `sim` to NaN and exited 0.
TEST(HandScriptText, AForceNoHandCanPressWithIsRefusedWithItsRange) {
  const auto bad = parse_hand_script(
      "[hand]\nstart = [0, 0, 0]\n[[segment]]\ntype = \"hold\"\nduration = 1\nforce = 1e308\n", "hand.toml");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("hand.toml:6: segment[1].force"), std::string::npos) << bad.error();
  EXPECT_NE(bad.error().find("up to 1e+12"), std::string::npos) << bad.error();
  const auto strong = parse_hand_script(
      "[hand]\nstart = [0, 0, 0]\n[[segment]]\ntype = \"hold\"\nduration = 1\nforce = 5000\n", "hand.toml");
  ASSERT_FALSE(strong);
  EXPECT_NE(strong.error().find("5000 N is more than a hand can press with: allowed 0 .. 1000 N"), std::string::npos)
      << strong.error();
}

}  // namespace
}  // namespace toonforce
