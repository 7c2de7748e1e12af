// SPDX-License-Identifier: Apache-2.0
// `toonforce sim` and the paper's figures: each figure scenario asserts the fact the paper
// shows, measured from its trace; runs are byte-for-byte reproducible; the loop is the servo
// loop `run` drives, its safety layer included, and its scene force is what replay computes
// for the same positions; the tick allocates nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <unistd.h>

#include "alloc_counter.hpp"
#include "toonforce/replay/replay.hpp"
#include "toonforce/sim/figures.hpp"
#include "toonforce/sim/sim_trace.hpp"
#include "toonforce/control/supervisor.hpp"

namespace toonforce {
namespace {

namespace fs = std::filesystem;

const FigureSpec& figure(std::string_view name) {
  for (const FigureSpec& spec : figure_specs()) {
    if (spec.name == name) return spec;
  }
  ADD_FAILURE() << "no figure " << name;
  return figure_specs().front();
}

FigureRun run(std::string_view name) {
  auto figure_run = run_figure(figure(name), TOONFORCE_SOURCE_DIR);
  if (!figure_run) ADD_FAILURE() << figure_run.error();
  return figure_run ? std::move(figure_run).value() : FigureRun{};
}

std::size_t first_contact(const std::vector<SimRecord>& r) {
  for (std::size_t i = 0; i < r.size(); ++i) {
    if (r[i].frame.in_contact) return i;
  }
  ADD_FAILURE() << "never in contact";
  return 0;
}

double mean_speed_x(const std::vector<SimRecord>& r, std::size_t from, std::size_t to, bool hand) {
  double sum = 0.0;
  for (std::size_t i = from; i < to; ++i) {
    sum += hand ? (r[i + 1].hand_target_m.x - r[i].hand_target_m.x) / (r[i + 1].frame.t_s - r[i].frame.t_s)
                : r[i].true_velocity_m_per_s.x;
  }
  return sum / static_cast<double>(to - from);
}

// ---- figure 1: the stroke ------------------------------------------------------------------

/// Tangential speed of the handle over the first 150 ms of contact, relative to the hand's
/// intended speed over the same ticks (the intent is identical in both scenes).
double stroke_speed_ratio(const std::vector<SimRecord>& r) {
  const std::size_t contact = first_contact(r);
  return mean_speed_x(r, contact, contact + 150, false) / mean_speed_x(r, contact, contact + 150, true);
}

TEST(Figure1, RealisticFrictionSlowsTheStrokeDown) {
  const FigureRun fr = run("fig1_realistic");
  const auto& r = fr.records;
  const std::size_t contact = first_contact(r);
  const double before = mean_speed_x(r, contact - 50, contact, false);
  const double during = mean_speed_x(r, contact, contact + 150, false);
  EXPECT_LT(during, 0.9 * before) << "before contact " << before << " m/s, in contact " << during;
  EXPECT_LT(stroke_speed_ratio(r), 0.9);
  // The friction force opposes the motion throughout the contact phase.
  for (std::size_t i = contact + 5; i < contact + 400; ++i) EXPECT_LE(r[i].frame.force_n.x, 0.0) << "tick " << i;
}

TEST(Figure1, TheSuperSlipperySurfaceSpeedsItUp) {
  const FigureRun fr = run("fig1_slippery");
  const auto& r = fr.records;
  const std::size_t contact = first_contact(r);
  const double before = mean_speed_x(r, contact - 50, contact, false);
  const double during = mean_speed_x(r, contact, contact + 150, false);
  EXPECT_GT(during, 1.1 * before) << "before contact " << before << " m/s, in contact " << during;
  EXPECT_GT(stroke_speed_ratio(r), 1.1);
  // ... and the handle runs ahead of where the hand aims ("slides out from under the hand").
  double lead = -1.0;
  for (std::size_t i = contact; i < contact + 300; ++i)
    lead = std::max(lead, r[i].true_position_m.x - r[i].hand_target_m.x);
  EXPECT_GT(lead, 0.001);
}

// ---- figures 2-3: the walls ----------------------------------------------------------------

double highest_after(const std::vector<SimRecord>& r, std::size_t from) {
  double z = -1.0;
  for (std::size_t i = from; i < r.size(); ++i) z = std::max(z, r[i].true_position_m.z);
  return z;
}

/// The frequency [Hz] at which the handle's acceleration has most energy over `ticks`: a
/// Hann-windowed Fourier sum of the second difference of its height, scanned 5-100 Hz.
double dominant_frequency_hz(const std::vector<SimRecord>& r, const std::vector<std::size_t>& ticks) {
  double best_magnitude = 0.0;
  double best_hz = 0.0;
  const double n = static_cast<double>(ticks.size() - 1);
  for (int tenth = 50; tenth <= 1000; ++tenth) {
    const double f = tenth / 10.0;
    double re = 0.0;
    double im = 0.0;
    for (std::size_t k = 0; k < ticks.size(); ++k) {
      const std::size_t i = ticks[k];
      const double dt = r[i + 1].frame.t_s - r[i].frame.t_s;
      const double a =
          (r[i + 1].true_position_m.z - 2 * r[i].true_position_m.z + r[i - 1].true_position_m.z) / (dt * dt);
      const double w = 0.5 - 0.5 * std::cos(2 * std::numbers::pi * static_cast<double>(k) / n);
      re += w * a * std::cos(2 * std::numbers::pi * f * r[i].frame.t_s);
      im -= w * a * std::sin(2 * std::numbers::pi * f * r[i].frame.t_s);
    }
    if (std::hypot(re, im) > best_magnitude) {
      best_magnitude = std::hypot(re, im);
      best_hz = f;
    }
  }
  return best_hz;
}

TEST(Figure3, ThePenaltyWallBringsTheStylusToAStop) {
  const FigureRun fr = run("fig3_wall");
  const auto& r = fr.records;
  const std::size_t contact = first_contact(r);
  EXPECT_LT(highest_after(r, contact), 0.0005);  // at most half a millimetre of rebound
  for (std::size_t i = 0; i < r.size(); ++i) EXPECT_TRUE(std::isnan(fr.value(i, "surface1.impact_t"))) << i;
  // At rest on the wall at the end, pressed in by about F / k.
  EXPECT_LT(std::abs(r.back().true_velocity_m_per_s.z), 1e-3);
  EXPECT_LT(r.back().true_position_m.z, 0.0);
}

TEST(Figure3, TheCartoonWallThrowsTheStylusBackOutAndShakesItAtItsFrequency) {
  const FigureRun fr = run("fig3_cartoon_wall");
  const auto& r = fr.records;
  const FigureRun wall_run = run("fig3_wall");
  const auto& wall = wall_run.records;
  const std::size_t contact = first_contact(r);
  // Rebound: out past the surface, and far further than the penalty wall lets it.
  const double rebound = highest_after(r, contact);
  EXPECT_GT(rebound, 0.003);
  EXPECT_GT(rebound, 5.0 * std::max(highest_after(wall, first_contact(wall)), 1e-4));

  // The first transient, and the part of it after the stylus left the wall.
  std::vector<std::size_t> transient;
  std::vector<std::size_t> out_of_contact;
  for (std::size_t i = contact; i + 1 < r.size() && !std::isnan(fr.value(i, "surface1.impact_t")); ++i) {
    transient.push_back(i);
    if (fr.value(i, "surface1.contact") == 0.0) out_of_contact.push_back(i);
  }
  ASSERT_GT(transient.size(), 100U);
  ASSERT_GT(out_of_contact.size(), 60U) << "the oscillation must go on after contact ends";
  // The scene's frequency, read from its file, not assumed.
  const double set_hz = fr.scene.of<RuntimeSurface>().front().impact.law.frequency_hz;
  EXPECT_NEAR(dominant_frequency_hz(r, transient), set_hz, 0.05 * set_hz);
  EXPECT_NEAR(dominant_frequency_hz(r, out_of_contact), set_hz, 0.05 * set_hz);
}

// ---- figure 4: the cliff -------------------------------------------------------------------

struct CliffFacts {
  bool ever_fell = false;
  bool fell_over_gap = true;  // every fall happened with the handle over the gap
  double lowest_m = 0.0;
  double lowest_over_gap_m = 0.0;
  double speed_at_fall = -1.0;  // lateral speed the controller saw when it fell
};

CliffFacts cliff_facts(const FigureRun& fr) {
  const auto& cliff = fr.scene.of<CartoonCliff>().front();
  // Depths count once the soft start is over: while the ground ramps in under the hand's
  // press it gives way, as it would on the device.
  const double settled_s = fr.scene.safety.soft_start_s + 0.05;
  CliffFacts facts;
  double previous = 0;
  for (std::size_t i = 0; i < fr.records.size(); ++i) {
    const SimRecord& record = fr.records[i];
    const double state = fr.value(i, "cliff1.state");
    const double across = record.true_position_m.x - cliff.ground.point_m.x;
    const bool over_gap = cliff.gap_min_m <= across && across <= cliff.gap_max_m;
    if (record.frame.t_s >= settled_s) facts.lowest_m = std::min(facts.lowest_m, record.true_position_m.z);
    if (over_gap) facts.lowest_over_gap_m = std::min(facts.lowest_over_gap_m, record.true_position_m.z);
    if (state == 1.0 && previous == 0.0) {
      facts.ever_fell = true;
      const double seen = record.frame.position_m.x - cliff.ground.point_m.x;  // what the loop saw
      facts.fell_over_gap = facts.fell_over_gap && cliff.gap_min_m <= seen && seen <= cliff.gap_max_m;
      facts.speed_at_fall = std::hypot(record.frame.velocity_m_per_s.x, record.frame.velocity_m_per_s.y);
    }
    previous = state;
  }
  return facts;
}

TEST(Figure4, ACrossingAtSpeedStaysUp) {
  const CliffFacts fast = cliff_facts(run("fig4_fast"));
  EXPECT_FALSE(fast.ever_fell);
  // Pressed 2 N into a 1500 N/m ground: 1.3 mm, never more than 2 mm, gap or not.
  EXPECT_GT(fast.lowest_m, -0.002);
}

TEST(Figure4, SlowingDownOverTheGapDropsTheHandle) {
  const CliffFacts slow = cliff_facts(run("fig4_slow"));
  EXPECT_TRUE(slow.ever_fell);
  EXPECT_TRUE(slow.fell_over_gap);
  EXPECT_LT(slow.speed_at_fall, 0.08);  // cliff.toml's speed_threshold
  // It falls until the hand's arm holds it: 2 N / 200 N/m = 1 cm below the ground.
  EXPECT_LT(slow.lowest_over_gap_m, -0.008);
}

// ---- reproducibility and the loop --------------------------------------------------------

class SimFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("toonforce_sim_{}_{}",
                                                   ::testing::UnitTest::GetInstance()->current_test_info()->name(),
                                                   static_cast<long>(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static std::string slurp(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  }
  fs::path dir_;
};

SimOptions options_for(std::string_view figure_name, const std::string& trace) {
  SimOptions o = figure_sim_options(figure(figure_name), TOONFORCE_SOURCE_DIR);
  o.trace_path = trace;
  return o;
}

TEST_F(SimFiles, TwoRunsGiveIdenticalBytesAndTheTraceStartsWithTheSpecColumns) {
  SimOptions o = options_for("fig3_cartoon_wall", path("a.csv"));
  o.sensor_noise_m = 30e-6;  // seeded noise too
  o.seed = 42;
  ASSERT_TRUE(run_sim(o));
  o.trace_path = path("b.csv");
  ASSERT_TRUE(run_sim(o));
  const std::string a = slurp(path("a.csv"));
  EXPECT_EQ(a, slurp(path("b.csv")));
  EXPECT_EQ(a.rfind("t,x,y,z,vx,vy,vz,fx,fy,fz,", 0), 0U);
  EXPECT_GT(a.size(), 100000U);
  // Another seed gives another (noisy) run: the seed is what makes it repeat.
  o.seed = 43;
  o.trace_path = path("c.csv");
  ASSERT_TRUE(run_sim(o));
  EXPECT_NE(a, slurp(path("c.csv")));
}

TEST_F(SimFiles, TheCommandLineTwiceGivesIdenticalBytes) {
  const auto command = [this](const std::string& out) {
    return fmt::format("'{}' sim --scene '{}/scenes/slippery.toml' --script '{}/scenes/hands/stroke.toml' "
                       "--duration 1.0 --trace '{}' --device omni --integrator velocity-verlet --scalar q16.16 -q",
                       TOONFORCE_BINARY, TOONFORCE_SOURCE_DIR, TOONFORCE_SOURCE_DIR, out);
  };
  ASSERT_EQ(std::system(command(path("one.csv")).c_str()), 0);
  ASSERT_EQ(std::system(command(path("two.csv")).c_str()), 0);
  const std::string one = slurp(path("one.csv"));
  EXPECT_EQ(one, slurp(path("two.csv")));
  EXPECT_EQ(std::count(one.begin(), one.end(), '\n'), 1001);  // header + 1 s at 1 kHz
}

TEST_F(SimFiles, ReplayingWhatTheLoopSawGivesTheSameSceneForces) {
  // The sim's loop computes the scene's force exactly as replay does: feed the positions the
  // loop saw back through replay and the scene forces (before the safety chain, which differs:
  // replay has only effects.md §6's) come out the same, velocity estimate included.
  const SimOptions o = options_for("fig1_realistic", path("sim.csv"));
  ASSERT_TRUE(run_sim(o));
  std::ifstream trace(path("sim.csv"));
  std::ofstream motion(path("motion.csv"));
  std::string line;
  std::getline(trace, line);
  motion << "t,x,y,z\n";
  std::vector<std::array<double, 3>> sim_forces;
  while (std::getline(trace, line)) {
    std::stringstream row(line);
    std::string cell;
    std::vector<std::string> cells;
    while (std::getline(row, cell, ',')) cells.push_back(cell);
    motion << cells[0] << ',' << cells[1] << ',' << cells[2] << ',' << cells[3] << '\n';
    sim_forces.push_back({std::stod(cells[10]), std::stod(cells[11]), std::stod(cells[12])});  // scene_f
  }
  motion.close();
  ReplayOptions replay;
  replay.scene_path = o.scene_path;
  replay.input_path = path("motion.csv");
  replay.output_path = path("forces.csv");
  const auto summary = run_replay(replay);
  ASSERT_TRUE(summary) << summary.error();
  std::ifstream forces(path("forces.csv"));
  std::getline(forces, line);
  std::size_t i = 0;
  double worst = 0.0;
  while (std::getline(forces, line) && i < sim_forces.size()) {
    std::stringstream row(line);
    std::string cell;
    std::vector<double> cells;
    while (std::getline(row, cell, ',') && cells.size() < 9) cells.push_back(std::stod(cell));
    for (std::size_t axis = 0; axis < 3; ++axis) {  // replay's scene_fx..scene_fz
      worst = std::max(worst, std::abs(cells[axis + 6] - sim_forces[i][axis]));
    }
    ++i;
  }
  EXPECT_EQ(i, sim_forces.size());
  // Replay's stamped time t = k * 0.001 and the loop's tick count agree to an ulp or so.
  EXPECT_LT(worst, 1e-9);
  double largest_friction = 0.0;  // the comparison covers the stroke's friction, not zeros
  for (const auto& f : sim_forces) largest_friction = std::max(largest_friction, std::abs(f[0]));
  EXPECT_GT(largest_friction, 0.1);
}

TEST(SimSession, ATickAllocatesNothingInAnyScalar) {
  const auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/cartoon_wall.toml");
  const auto hand = load_hand_script(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/hands/strike.toml");
  ASSERT_TRUE(scene && hand);
  for (const ScalarKind scalar : {ScalarKind::kDouble, ScalarKind::kFloat, ScalarKind::kQ16_16}) {
    SimConfig config;
    config.scalar = scalar;
    auto session = SimSession::create(scene.value(), hand.value(), config);
    ASSERT_TRUE(session) << session.error();
    std::size_t impacts = 0;
    const test::AllocationScope scope;
    const std::size_t impact_t = session->value_index("surface1.impact_t");
    for (int k = 0; k < 1000; ++k) impacts += session->step().frame.values[impact_t] == 0.0 ? 1U : 0U;
    EXPECT_EQ(scope.count(), 0U) << scalar_kind_name(scalar);
    EXPECT_GE(impacts, 1U) << scalar_kind_name(scalar);  // and it did something
  }
}

TEST(SimSession, TheControllerClampIsTheSmallerOfSceneAndDevice) {
  const auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/cartoon_wall.toml");  // 8 N
  const auto hand = load_hand_script(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/hands/strike.toml");
  ASSERT_TRUE(scene && hand);
  SimConfig config;
  config.device = host_sim::omni_params();  // 3.3 N
  auto session = SimSession::create(scene.value(), hand.value(), config);
  ASSERT_TRUE(session);
  EXPECT_DOUBLE_EQ(session->servo_config().limits.max_force_n, 3.3);
  double peak = 0.0;
  for (int k = 0; k < 600; ++k) {
    const SimRecord record = session->step();
    peak = std::max(peak, std::sqrt(dot(record.frame.force_n, record.frame.force_n)));
  }
  EXPECT_LE(peak, 3.3 + 1e-12);
  EXPECT_GT(peak, 3.0);  // the cartoon wall does ask for it
}

TEST(SimSession, APassiveSceneWithAPassiveHandGainsNoEnergy) {
  // Realistic friction on a penalty wall (passive laws) and a hand that only holds a point
  // 2 mm inside the floor (a spring and a damper to a fixed point: passive). The handle is
  // thrown at the floor; it bounces, slides and settles. The total energy (moving mass, arm
  // spring, wall spring at the true penetration) may never exceed its start by more than the
  // integrator's stated bound, the loop must absorb energy overall (the hand's damping keeps
  // the sampled, delayed wall inside the Colgate-Brown bound b > K T / 2, with margin), and the
  // plant may not gain more than the device's work plus that bound.
  auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/realistic_friction.toml");
  const auto hand = parse_hand_script("[hand]\nstart = [0.0, 0.0, -0.002]\n[[segment]]\ntype = \"hold\"\n"
                                      "duration = 3.0\n",
                                      "passive.toml");
  ASSERT_TRUE(scene) << scene.error();
  ASSERT_TRUE(hand) << hand.error();
  // No soft start here: a gain that ramps up while the handle is in the wall raises the
  // stiffness under load and so returns more energy than the wall stored, which is the ramp's
  // doing, not the laws' or the integrators' this test is about.
  scene.value().safety.soft_start_s = 0.0;
  const double wall_k = scene->of<RuntimeSurface>().front().wall.stiffness_n_per_m;
  for (const auto integrator : {host_sim::Integrator::kSemiImplicitEuler, host_sim::Integrator::kVelocityVerlet,
                                host_sim::Integrator::kRk4, host_sim::Integrator::kExact}) {
    SimConfig config;
    config.plant.integrator = integrator;
    auto session = SimSession::create(scene.value(), hand.value(), config);
    ASSERT_TRUE(session) << session.error();
    session->device().set_state({-0.01, 0.0, 0.01}, {0.15, 0.05, -0.4});
    const host_sim::Plant& plant = session->device().plant();
    const double omega_h = plant.hand_omega_rad_per_s() * config.plant.period_s / config.plant.substeps;
    const double bound = host_sim::energy_gain_bound(integrator, omega_h);
    const auto total_energy = [&](double t) {
      const double depth = -plant.position_m().z;
      return plant.mechanical_energy_j(t) + (depth > 0.0 ? 0.5 * wall_k * depth * depth : 0.0);
    };
    const double e0 = total_energy(0.0);
    const double mechanical0 = plant.mechanical_energy_j(0.0);
    double peak = 0.0;
    double worst_balance = -1.0;
    bool touched = false;
    for (int k = 0; k < 3000; ++k) {
      touched = session->step().frame.in_contact || touched;
      const double t = (k + 1) * config.plant.period_s;
      peak = std::max(peak, total_energy(t));
      worst_balance = std::max(worst_balance, plant.mechanical_energy_j(t) - mechanical0 - plant.device_work_j());
    }
    const std::string name(host_sim::integrator_name(integrator));
    EXPECT_TRUE(touched) << name;
    EXPECT_LE(peak, e0 * (1.0 + bound) + 1e-12) << name;
    EXPECT_LT(plant.device_work_j(), 0.0) << name;
    EXPECT_LT(total_energy(3.0), 0.02 * e0) << name;
    EXPECT_LE(worst_balance, bound * e0 + 1e-12) << name;
  }
}

TEST(SimRun, ReportsBadOptionsAndInputs) {
  SimOptions o = figure_sim_options(figure("fig4_fast"), TOONFORCE_SOURCE_DIR);
  o.trace_path = "/nonexistent-dir/x.csv";
  const auto unwritable = run_sim(o);
  ASSERT_FALSE(unwritable);
  EXPECT_NE(unwritable.error().find("/nonexistent-dir/x.csv: cannot open"), std::string::npos);
  o.trace_path = "-";
  o.script_path = "nowhere.toml";
  const auto missing = run_sim(o);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("nowhere.toml: no such hand script"), std::string::npos);
}

TEST(SimTrace, HasTheLoopsColumnsThenTheSimulationsAndShortestRoundTripNumbers) {
  const std::vector<std::string> names{"surface1.contact", "surface1.impact_t"};
  const auto writer = TraceWriter::in_memory(sim_trace_columns(names));
  SimRecord r;
  r.frame.t_s = 0.1;
  r.frame.position_m = {0.1, 1.0 / 3.0, -2e-5};
  r.frame.faults = 1;
  r.frame.value_count = 2;
  r.frame.values[0] = 1.0;
  r.frame.values[1] = std::numeric_limits<double>::quiet_NaN();
  r.segment = 3;
  ASSERT_TRUE(write_sim_record(*writer, r, names.size()));
  const std::string& text = writer->text();
  EXPECT_EQ(text.rfind("t,x,y,z,vx,vy,vz,fx,fy,fz,scene_fx,", 0), 0U) << text;
  EXPECT_NE(text.find(",tick,surface1.contact,surface1.impact_t,true_x,"), std::string::npos) << text;
  EXPECT_NE(text.find("\n0.1,0.1,0.3333333333333333,-2e-05,0,0,0,0,0,0,"), std::string::npos) << text;
  EXPECT_NE(text.find(",1,nan,0,0,0,"), std::string::npos) << text;  // the values, then true_x..
  EXPECT_EQ(text.substr(text.size() - 3), ",3\n") << text;           // the segment last
}

TEST(SimTrace, EveryValueIsWrittenInItsShortestRoundTripFormWholeNumbersIncluded) {
  // The writer takes a faster path for whole numbers; the characters must still be those of
  // the shortest round-trip form ("{}"), and parse back to the same double, at the path's
  // edges too (-0 keeps its sign; 1e16 and up take an exponent).
  const std::vector<double> values{0.0,
                                   -0.0,
                                   1.0,
                                   -1.0,
                                   498.0,
                                   0.5,
                                   -3.0,
                                   4095.0,
                                   1e9,
                                   -1e9,
                                   999999999999999.0,
                                   1e15,
                                   -1e15,
                                   9999999999999998.0,
                                   1e16,
                                   1e17,
                                   9007199254740993.0,
                                   2.5e-7,
                                   1e300,
                                   -1e-300,
                                   std::numeric_limits<double>::infinity(),
                                   -std::numeric_limits<double>::infinity(),
                                   std::numeric_limits<double>::quiet_NaN()};
  const std::vector<std::string> names(values.size(), "v");
  const auto writer = TraceWriter::in_memory(names);
  // Three rows: the values, the same again (a repeated value is copied from the row before),
  // then each value's neighbour in sign or size (0 after -0: equal as doubles, not as text).
  std::vector<double> changed = values;
  for (double& x : changed) x = (x == 0.0) ? -x : (std::isnan(x) ? 1.5 : -x * 3.0);
  ASSERT_TRUE(writer->write(TraceCore{}, values));
  ASSERT_TRUE(writer->write(TraceCore{}, values));
  ASSERT_TRUE(writer->write(TraceCore{}, changed));
  const std::string& text = writer->text();
  const auto row_of = [](const std::vector<double>& xs) {
    std::string row = "0,0,0,0,0,0,0,0,0,0";
    for (const double x : xs) row += fmt::format(",{}", x);
    return row + "\n";
  };
  const std::string rows = text.substr(text.find('\n') + 1);
  EXPECT_EQ(rows, row_of(values) + row_of(values) + row_of(changed));
  const std::string row = row_of(values);
  EXPECT_NE(row.find(",-0,"), std::string::npos) << row;
  EXPECT_NE(row.find(",1e+16,"), std::string::npos) << row;
}

TEST(SimSession, TracesCarryTheSafetyLayersStateFromTheLoop) {
  // The cartoon wall on the Omni (3.3 N): the soft start, the clamp and the passivity
  // observer all act, and the trace says so, as `run` would.
  const auto scene = load_scene_file(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/cartoon_wall.toml");
  const auto hand = load_hand_script(std::string(TOONFORCE_SOURCE_DIR) + "/scenes/hands/strike.toml");
  ASSERT_TRUE(scene && hand);
  SimConfig config;
  config.device = host_sim::omni_params();
  auto session = SimSession::create(scene.value(), hand.value(), config);
  ASSERT_TRUE(session) << session.error();
  bool ramped = false;
  bool clamped = false;
  bool active = false;
  double energy_change = 0.0;
  double gain_min = 1.0;
  for (int k = 0; k < 1000; ++k) {
    const TelemetryFrame f = session->step().frame;
    ramped = ramped || has(f.limits, Limit::kSoftStart);
    clamped = clamped || has(f.limits, Limit::kClamped);
    active = active || f.state == static_cast<std::uint8_t>(LoopState::kActive);
    energy_change = std::max(energy_change, std::abs(f.observed_energy_j));
    gain_min = std::min(gain_min, f.gain);
    EXPECT_EQ(f.max_force_n, 3.3);
  }
  EXPECT_TRUE(ramped);
  EXPECT_TRUE(clamped);
  EXPECT_TRUE(active);
  EXPECT_EQ(gain_min, 0.0);        // the ramp starts at zero
  EXPECT_GT(energy_change, 1e-4);  // the observer saw the strike
}

}  // namespace
}  // namespace toonforce
