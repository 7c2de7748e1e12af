// SPDX-License-Identifier: Apache-2.0
// toonforce replay against the closed forms of effects.md (an independent implementation of
// the spec in tests/support/spec_oracle.hpp), on random motions through random scenes: double
// must match to a relative error of 1e-9. Also the command itself, end to end, and its errors.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/format.h>

#include "spec_oracle.hpp"
#include "toonforce/replay/motion_csv.hpp"
#include "toonforce/replay/replay.hpp"

namespace toonforce {
namespace {

namespace fs = std::filesystem;
using oracle::V;

fs::path temp_dir() {
  const fs::path dir = fs::temp_directory_path() / fmt::format("toonforce_replay_test_{}", ::getpid());
  fs::create_directories(dir);
  return dir;
}

void write_file(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

std::string vec(const V& v) { return fmt::format("[{}, {}, {}]", v[0], v[1], v[2]); }

/// A random scene: the oracle's description and the same as TOML.
struct RandomScene {
  oracle::Scene scene;
  std::string toml;
};

RandomScene random_scene(std::mt19937_64& rng, bool limits) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto pick = [&](double lo, double hi) { return lo + (hi - lo) * u(rng); };
  auto unit_near_z = [&] { return oracle::unit({pick(-0.3, 0.3), pick(-0.3, 0.3), 1.0}); };
  RandomScene r;
  if (limits) {
    r.scene.max_force = pick(3.0, 10.0);
    r.scene.max_rate = pick(500.0, 5000.0);
    r.toml += fmt::format("[device]\nmax_force = {}\nmax_force_rate = {}\n", *r.scene.max_force, *r.scene.max_rate);
  }
  r.scene.f_c = pick(20.0, 100.0);
  r.toml += fmt::format("{}velocity_cutoff = {}\n", limits ? "" : "[device]\n", r.scene.f_c);
  const int surfaces = 1 + static_cast<int>(u(rng) * 3);
  for (int i = 0; i < surfaces; ++i) {
    oracle::Surface s;
    s.p0 = {pick(-0.01, 0.01), pick(-0.01, 0.01), pick(-0.004, 0.004)};
    s.n = unit_near_z();
    if (i == 1) s.n = oracle::unit({1.0, pick(-0.3, 0.3), pick(-0.3, 0.3)});  // a side wall
    s.k = pick(300.0, 3000.0);
    s.b = u(rng) < 0.5 ? 0.0 : pick(0.5, 10.0);
    r.toml += fmt::format("[[surface]]\npoint = {}\nnormal = {}\nstiffness = {}\ndamping = {}\n", vec(s.p0), vec(s.n),
                          s.k, s.b);
    const double which = u(rng);
    if (which < 0.35) {
      s.friction = true;
      s.mu_v = -pick(0.0, 3.0);
      s.mu_c = pick(0.0, 0.8);
      s.v_reg = pick(0.005, 0.05);
      r.toml += fmt::format("[surface.friction]\nviscous = {}\ncoulomb = {}\nregularization_speed = {}\n", s.mu_v,
                            s.mu_c, s.v_reg);
    } else if (which < 0.7) {
      s.slippery = true;
      s.mu = pick(0.5, 10.0);
      s.max_t = pick(0.5, 3.0);
      r.toml += fmt::format("[surface.slippery]\nmu = {}\nmax_tangential_force = {}\n", s.mu, s.max_t);
    }
    if (u(rng) < 0.6) {
      s.impact = true;
      s.k_r = pick(0.0, 400.0);
      s.k_osc = pick(0.0, 800.0);
      s.d = pick(0.05, 0.3);
      s.f = pick(5.0, 60.0);
      s.v_min = pick(0.0, 0.1);
      s.rearm = pick(0.0, 0.003);
      r.toml += fmt::format(
          "[surface.impact]\nrecoil_gain = {}\noscillation_gain = {}\nduration = {}\nfrequency = {}\n"
          "min_impact_speed = {}\nrearm_distance = {}\n"
          "sine = \"library\"\n",  // the oracle's std::sin: the laws compared to 1e-9, not the sine's method
          s.k_r, s.k_osc, s.d, s.f, s.v_min, s.rearm);
    }
    r.scene.surfaces.push_back(s);
  }
  if (u(rng) < 0.6) {
    oracle::Cliff c;
    c.p0 = {pick(-0.01, 0.01), 0.0, pick(-0.01, -0.005)};
    c.n = {0, 0, 1};
    c.a = oracle::unit({1.0, pick(-0.5, 0.5), 0.0});
    c.gap_min = pick(-0.01, 0.0);
    c.gap_max = c.gap_min + pick(0.005, 0.02);
    c.k = pick(300.0, 3000.0);
    c.b = u(rng) < 0.5 ? 0.0 : pick(0.5, 5.0);
    c.threshold = pick(0.02, 0.15);
    c.tau = u(rng) < 0.2 ? 0.0 : pick(0.005, 0.05);
    c.rearm_h = pick(0.0, 0.003);
    c.fall = pick(0.0, 1.0);
    r.toml += fmt::format(
        "[[cliff]]\npoint = {}\nnormal = {}\naxis = {}\ngap_min = {}\ngap_max = {}\nstiffness = {}\ndamping = {}\n"
        "speed_threshold = {}\ntau = {}\nrearm_height = {}\nfall_force = {}\n",
        vec(c.p0), vec(c.n), vec(c.a), c.gap_min, c.gap_max, c.k, c.b, c.threshold, c.tau, c.rearm_h, c.fall);
    r.scene.cliffs.push_back(c);
  }
  return r;
}

/// A random smooth motion through the workspace: sums of sines, with their exact derivative,
/// an uneven clock (jitter, to the nanosecond), and optionally a few non-finite rows.
std::vector<oracle::Row> random_motion(std::mt19937_64& rng, int rows, bool with_nan) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double amp[3][3], freq[3][3], phase[3][3];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      amp[i][j] = (i == 2 ? 0.012 : 0.02) * u(rng) / (j + 1);
      freq[i][j] = 0.5 + 6.0 * u(rng) * (j + 1);
      phase[i][j] = 6.283 * u(rng);
    }
  }
  std::vector<oracle::Row> out;
  double t = u(rng);
  for (int k = 0; k < rows; ++k) {
    t += 1e-3 * (0.8 + 0.4 * u(rng));
    // On the nanosecond grid: the loop's stamps are whole nanoseconds (effects/tick.hpp,
    // Instant), which a recording at any real clock's resolution already is.
    t = std::round(t * 1e9) / 1e9;
    oracle::Row r{t, {}, {}};
    for (std::size_t i = 0; i < 3; ++i) {
      for (std::size_t j = 0; j < 3; ++j) {
        const double w = 6.283185307179586 * freq[i][j];
        r.x[i] += amp[i][j] * std::sin(w * t + phase[i][j]);
        r.v[i] += amp[i][j] * w * std::cos(w * t + phase[i][j]);
      }
    }
    r.x[2] -= 0.002;
    if (with_nan && u(rng) < 0.004) r.x[static_cast<std::size_t>(k % 3)] = std::nan("");
    out.push_back(r);
  }
  return out;
}

std::string motion_csv(const std::vector<oracle::Row>& rows, bool velocity) {
  std::string csv = velocity ? "t,x,y,z,vx,vy,vz\n" : "t,x,y,z\n";
  for (const auto& r : rows) {
    csv += fmt::format("{},{},{},{}", r.t, r.x[0], r.x[1], r.x[2]);
    if (velocity) csv += fmt::format(",{},{},{}", r.v[0], r.v[1], r.v[2]);
    csv += '\n';
  }
  return csv;
}

/// The t,fx,fy,fz columns of a forces.csv.
std::vector<std::pair<double, V>> read_forces(const fs::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line.rfind("t,fx,fy,fz,", 0), 0U) << line;
  std::vector<std::pair<double, V>> out;
  while (std::getline(in, line)) {
    double t = 0;
    V f{};
    EXPECT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &t, &f[0], &f[1], &f[2]), 4) << line;
    out.push_back({t, f});
  }
  return out;
}

void expect_matches_oracle(const std::vector<std::pair<double, V>>& got, const std::vector<V>& want,
                           const std::vector<oracle::Row>& rows, const std::string& context) {
  ASSERT_EQ(got.size(), want.size()) << context;
  int nonzero = 0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    ASSERT_EQ(got[i].first, rows[i].t) << context;  // t written so it reads back the same
    const double scale = std::max(oracle::len(want[i]), 1e-3);
    ASSERT_LE(oracle::len(oracle::sub(got[i].second, want[i])), 1e-9 * scale)
        << context << " row " << i << " t " << rows[i].t << ": got (" << got[i].second[0] << ", " << got[i].second[1]
        << ", " << got[i].second[2] << ") want (" << want[i][0] << ", " << want[i][1] << ", " << want[i][2] << ")";
    nonzero += oracle::len(want[i]) > 0.01;
  }
  EXPECT_GT(nonzero, static_cast<int>(want.size() / 10)) << context << ": the motion barely touched the scene";
}

class ReplayOracle : public ::testing::TestWithParam<int> {};

TEST_P(ReplayOracle, MatchesTheClosedFormsOnRandomScenesAndMotions) {
  const int seed = GetParam();
  std::mt19937_64 rng(static_cast<std::uint64_t>(seed) * 7919U + 11U);
  const bool given_velocity = seed % 2 == 0;
  const RandomScene rs = random_scene(rng, seed % 3 != 0);
  const auto rows = random_motion(rng, 3000, seed % 4 == 1);
  const fs::path dir = temp_dir();
  const fs::path scene = dir / fmt::format("scene{}.toml", seed);
  const fs::path motion = dir / fmt::format("motion{}.csv", seed);
  const fs::path forces = dir / fmt::format("forces{}.csv", seed);
  write_file(scene, rs.toml);
  write_file(motion, motion_csv(rows, given_velocity));

  ReplayOptions options;
  options.scene_path = scene.string();
  options.input_path = motion.string();
  options.output_path = forces.string();
  const auto summary = run_replay(options);
  ASSERT_TRUE(summary) << summary.error() << "\n" << rs.toml;
  expect_matches_oracle(read_forces(forces), oracle::replay(rs.scene, rows, given_velocity), rows,
                        fmt::format("seed {}\n{}", seed, rs.toml));
}

INSTANTIATE_TEST_SUITE_P(Seeds, ReplayOracle, ::testing::Range(1, 25));

TEST(ReplayOracle, BundledScenesOnBundledMotionsThroughTheBinary) {
  // The real command line, as a user runs it, against the oracle.
  struct Case {
    const char* scene;
    const char* motion;
  };
  const fs::path dir = temp_dir();
  for (const Case c : {Case{"wall", "strike"}, Case{"cartoon_wall", "strike"}, Case{"realistic_friction", "stroke"},
                       Case{"slippery", "stroke"}, Case{"cliff", "crossing_fast"}, Case{"cliff", "crossing_slow"}}) {
    const std::string root = TOONFORCE_SOURCE_DIR;
    const fs::path out = dir / fmt::format("{}_{}.csv", c.scene, c.motion);
    // --sine library: the oracle's std::sin (the default polynomial is within 6e-7 of it,
    // math_test.cpp; here the laws are compared to 1e-9).
    const std::string command =
        fmt::format("'{}' replay --scene '{}/scenes/{}.toml' --input '{}/scenes/motions/{}.csv' "
                    "--output '{}' --quiet --sine library",
                    TOONFORCE_BINARY, root, c.scene, root, c.motion, out.string());
    ASSERT_EQ(std::system(command.c_str()), 0) << command;

    const auto motion = read_motion_csv(root + "/scenes/motions/" + c.motion + ".csv");
    ASSERT_TRUE(motion) << motion.error();
    std::vector<oracle::Row> rows;
    for (const auto& r : motion->rows) rows.push_back({r.t_s, {r.position_m.x, r.position_m.y, r.position_m.z}, {}});
    // The bundled scenes, as the oracle reads them (their values are in scenes/*.toml).
    oracle::Scene s;
    s.max_force = 8.0;
    s.max_rate = 2000.0;
    const std::string name = c.scene;
    if (name == "cliff") {
      s.cliffs.push_back({{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, 0.0, 0.02, 1500.0, 0.0, 0.08, 0.02, 0.001, 0.0});
    } else {
      oracle::Surface f;
      f.k = 1500.0;
      if (name == "realistic_friction") {
        f.friction = true;
        f.mu_v = -1.0;
        f.mu_c = 0.3;
        f.v_reg = 0.02;
      } else if (name == "slippery") {
        f.slippery = true;
        f.mu = 4.0;
        f.max_t = 2.0;
      } else if (name == "cartoon_wall") {
        f.impact = true;
        f.k_r = 200.0;
        f.k_osc = 400.0;
        f.d = 0.15;
        f.f = 30.0;
      }
      s.surfaces.push_back(f);
    }
    expect_matches_oracle(read_forces(out), oracle::replay(s, rows, false), rows,
                          fmt::format("{} {}", c.scene, c.motion));
  }
}

/// Runs the binary; returns its exit status and what it wrote to stderr.
std::pair<int, std::string> run_binary(const std::string& args) {
  const fs::path err = temp_dir() / "stderr.txt";
  const std::string command = fmt::format("'{}' {} 2> '{}' > /dev/null", TOONFORCE_BINARY, args, err.string());
  const int status = std::system(command.c_str());
  std::ifstream in(err);
  std::stringstream text;
  text << in.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, text.str()};
}

TEST(ReplayCommand, RejectsTimeThatDoesNotIncreaseNamingFileAndLine) {
  const fs::path dir = temp_dir();
  write_file(dir / "back.csv", "t,x,y,z\n0.000,0,0,0\n0.001,0,0,0\n0.001,0,0,0\n");
  const auto [status, err] =
      run_binary(fmt::format("replay --scene '{}/scenes/wall.toml' --input '{}' --output '{}'", TOONFORCE_SOURCE_DIR,
                             (dir / "back.csv").string(), (dir / "o.csv").string()));
  EXPECT_NE(status, 0);
  EXPECT_NE(err.find("back.csv:4: t must increase strictly"), std::string::npos) << err;
}

TEST(ReplayCommand, RejectsStampsCloserThanTheLoopsNanosecondNamingFileAndLine) {
  // The loop's stamps are whole nanoseconds: two rows 0.1 ns apart would be one instant.
  const fs::path dir = temp_dir();
  write_file(dir / "close.csv", "t,x,y,z\n0.000,0,0,0\n0.001,0,0,0\n0.0010000001,0,0,0\n");
  const auto [status, err] =
      run_binary(fmt::format("replay --scene '{}/scenes/wall.toml' --input '{}' --output '{}'", TOONFORCE_SOURCE_DIR,
                             (dir / "close.csv").string(), (dir / "o.csv").string()));
  EXPECT_NE(status, 0);
  EXPECT_NE(err.find("close.csv:4: t must increase by 1 ns at least"), std::string::npos) << err;
}

TEST(ReplayCommand, RejectsABadSceneNamingFileLineAndKey) {
  const fs::path dir = temp_dir();
  write_file(dir / "typo.toml", "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffnes = 10\n");
  const auto [status, err] =
      run_binary(fmt::format("replay --scene '{}' --input '{}/scenes/motions/strike.csv' --output '{}'",
                             (dir / "typo.toml").string(), TOONFORCE_SOURCE_DIR, (dir / "o.csv").string()));
  EXPECT_NE(status, 0);
  EXPECT_NE(err.find("typo.toml:4: surface[1]: unknown key 'stiffnes' (did you mean 'stiffness'?)"), std::string::npos)
      << err;
  EXPECT_NE(err.find("typo.toml:1: surface[1]: missing required key 'stiffness'"), std::string::npos) << err;
}

TEST(ReplayCommand, Q16RefusesRowsWhoseOneOverDtDoesNotFitNamingTheLine) {
  // Replay's rate is each row's 1/dt (spec §0); Q16.16 holds it below 32768 Hz (whole: 32767).
  const fs::path dir = temp_dir();
  const auto motion = [&](const std::string& name, double rate_hz) {
    std::string text = "t,x,y,z\n";
    for (int k = 0; k < 4; ++k) text += fmt::format("{},0,0,0.01\n", k / rate_hz);
    write_file(dir / name, text);
    return (dir / name).string();
  };
  const auto replay = [&](const std::string& input, const std::string& scalar) {
    return run_binary(fmt::format("replay --scene '{}/scenes/wall.toml' --input '{}' --output '{}' --scalar {}",
                                  TOONFORCE_SOURCE_DIR, input, (dir / "o.csv").string(), scalar));
  };
  const std::string fast = motion("fast.csv", 40000.0);
  auto [status, err] = replay(fast, "q16.16");
  EXPECT_NE(status, 0);
  EXPECT_NE(err.find("fast.csv:3: t: "), std::string::npos) << err;
  EXPECT_NE(err.find("up to 32767 Hz"), std::string::npos) << err;
  std::tie(status, err) = replay(fast, "double");
  EXPECT_EQ(status, 0) << err;
  std::tie(status, err) = replay(motion("below.csv", 32000.0), "q16.16");
  EXPECT_EQ(status, 0) << err;
}

TEST(ReplayCommand, Q16TakesAMotionRecordedAtTheHighestRateItAllowsDespiteWholeNanosecondStamps) {
  // `sim` runs Q16.16 at 32767 Hz (the rule's limit, scene_file.hpp), a tick of
  // 30518.51 ns. Replay rounds t to whole ns, which makes some gaps 30518 ns (32767.55 Hz): the
  // rule is about the recording's rate, not that rounding, so the motion must be taken. One
  // Hz faster (32768 Hz, gaps of 30517 ns) it is over the limit whatever the rounding did.
  const fs::path dir = temp_dir();
  const auto motion = [&](const std::string& name, double rate_hz) {
    std::string text = "t,x,y,z\n";
    for (int k = 0; k < 40; ++k) text += fmt::format("{},0,0,0.01\n", k / rate_hz);
    write_file(dir / name, text);
    return (dir / name).string();
  };
  const auto replay = [&](const std::string& input) {
    return run_binary(fmt::format("replay --scene '{}/scenes/wall.toml' --input '{}' --output '{}' --scalar q16.16",
                                  TOONFORCE_SOURCE_DIR, input, (dir / "o.csv").string()));
  };
  auto [status, err] = replay(motion("limit.csv", 32767.0));
  EXPECT_EQ(status, 0) << err;
  std::tie(status, err) = replay(motion("over.csv", 32768.0));
  EXPECT_NE(status, 0);
  EXPECT_NE(err.find("up to 32767 Hz"), std::string::npos) << err;
}

TEST(ReplayCommand, RejectsAnUnknownScalarType) {
  const auto [status, err] = run_binary("replay --scene a.toml --input b.csv --output c.csv --scalar half");
  EXPECT_NE(status, 0);
  EXPECT_NE(err.find("half"), std::string::npos) << err;
}

TEST(MotionCsv, AcceptsColumnsInAnyOrderAndReportsExtraOnes) {
  const auto m =
      parse_motion_csv("# a comment\nz, t, y, x, fx\n0.3, 0.0, 0.2, 0.1, 9\n0.3, 0.5, 0.2, 0.1, 9\n", "m.csv");
  ASSERT_TRUE(m) << m.error();
  EXPECT_EQ(m->rows[0].position_m, (Vec3<double>{0.1, 0.2, 0.3}));
  EXPECT_EQ(m->rows[1].t_s, 0.5);
  EXPECT_FALSE(m->has_velocity);
  ASSERT_EQ(m->ignored_columns.size(), 1U);
  EXPECT_EQ(m->ignored_columns[0], "fx");
}

// An Excel "CSV UTF-8" file starts with a byte order mark; it made "no column 't'".
TEST(MotionCsv, AUtf8ByteOrderMarkBeforeTheHeaderIsReadPast) {
  const auto motion = parse_motion_csv("\xEF\xBB\xBFt,x,y,z\n0,0,0,0\n0.001,0,0,0\n", "excel.csv");
  ASSERT_TRUE(motion) << motion.error();
  EXPECT_EQ(motion->rows.size(), 2U);
}

// A directory was "empty", an unreadable file had no reason.
TEST(MotionCsv, ADirectoryOrAMissingFileIsNamedWithTheReason) {
  const auto dir = read_motion_csv(std::filesystem::temp_directory_path().string());
  ASSERT_FALSE(dir);
  EXPECT_NE(dir.error().find("is a directory"), std::string::npos) << dir.error();
  const auto missing = read_motion_csv("/nonexistent/motion.csv");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("No such file or directory"), std::string::npos) << missing.error();
}

TEST(MotionCsv, NonFinitePositionsAreValidRows) {
  const auto m = parse_motion_csv("t,x,y,z\n0,nan,0,0\n0.001,0,inf,0\n", "m.csv");
  ASSERT_TRUE(m) << m.error();
  EXPECT_TRUE(std::isnan(m->rows[0].position_m.x));
  EXPECT_TRUE(std::isinf(m->rows[1].position_m.y));
}

struct BadMotion {
  const char* text;
  const char* expected;
};
class BadMotionCsv : public ::testing::TestWithParam<BadMotion> {};
TEST_P(BadMotionCsv, IsRejectedWithFileAndLine) {
  const auto m = parse_motion_csv(GetParam().text, "m.csv");
  ASSERT_FALSE(m);
  EXPECT_NE(m.error().find(GetParam().expected), std::string::npos) << m.error();
}
const BadMotion kBadMotions[] = {
    {"t,x,y\n0,0,0\n", "m.csv:1: the header has no column 'z'"},
    {"t,x,y,z,vx\n0,0,0,0,0\n0.1,0,0,0,0\n", "m.csv:1: give all three of vx,vy,vz or none"},
    {"t,x,y,z,x\n", "m.csv:1: column 'x' appears twice"},
    {"t,x,y,z\n0,0,0\n", "m.csv:2: 3 fields, but the header has 4"},
    {"t,x,y,z\n0,0,abc,0\n", "m.csv:2: column 'y': 'abc' is not a number"},
    {"t,x,y,z\nnan,0,0,0\n", "m.csv:2: t must be finite"},
    {"t,x,y,z\n0,0,0,0\n", "replay needs at least two"},
    {"", "empty motion file"},
};
INSTANTIATE_TEST_SUITE_P(MotionCsv, BadMotionCsv, ::testing::ValuesIn(kBadMotions));

// A full disk or a killed writer leaves a last row without its newline, possibly cut
// mid-number ("0.00" of "0.0042"): it is left out with a warning naming the file and line,
// never read as data.
TEST(MotionCsv, ALastRowWithoutItsEndOfLineIsLeftOutAndNamed) {
  const auto m = parse_motion_csv("t,x,y,z\n0,0,0,0.0042\n0.001,0,0,0.0042\n0.002,0,0,0.00", "cut.csv");
  ASSERT_TRUE(m) << m.error();
  EXPECT_EQ(m->rows.size(), 2U);
  EXPECT_NE(m->note.find("cut.csv:4: the last row has no end of line"), std::string::npos) << m->note;
  const auto whole = parse_motion_csv("t,x,y,z\n0,0,0,0\n0.001,0,0,0\n", "whole.csv");
  ASSERT_TRUE(whole) << whole.error();
  EXPECT_TRUE(whole->note.empty()) << whole->note;
}

// A field quoted in a message is escaped and cut (printable, as scene messages): an
// escape sequence retitled or cleared the terminal, a 20 MB field made a 20 MB line.
TEST(MotionCsv, AFieldQuotedInAMessageIsEscapedAndCut) {
  const auto m = parse_motion_csv("t,x,y,z\n0,0,\x1b]0;owned\x07,0\n", "m.csv");
  ASSERT_FALSE(m);
  EXPECT_EQ(m.error().find('\x1b'), std::string::npos) << m.error();
  EXPECT_NE(m.error().find("\\x1B]0;owned\\x07"), std::string::npos) << m.error();
  const auto big = parse_motion_csv("t,x,y,z\n0,0," + std::string(1 << 20, 'k') + ",0\n", "m.csv");
  ASSERT_FALSE(big);
  EXPECT_LT(big.error().size(), 300U);
}

}  // namespace
}  // namespace toonforce
