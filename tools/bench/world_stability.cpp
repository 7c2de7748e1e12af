// SPDX-License-Identifier: Apache-2.0
// The virtual coupling's stability map (docs/performance/world.md, "The coupling's stability
// map"): two simulated Falcon-class devices in one world, coupled, on a grid of the coupling's
// stiffness and damping and of the devices' I/O delays, every safety stage on, the passivity
// controller off and then on. One point is world_stability.hpp's run_point; this program walks
// the grid, prints one row a point and a compact map per delay, and each point's analytic bound.
// A benchmark program (a simulation, no timing), never a test.
//
//   toonforce_world_stability                 the whole map (hand a lets go of its handle)
//   toonforce_world_stability --hold          hand a holds its handle instead
//   toonforce_world_stability --csv FILE      also every point as CSV
//   toonforce_world_stability --trace K,B,DA,DB  one point, a CSV line a tick (handles, forces, energies)
#include <array>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "toonforce/control/passivity_bound.hpp"
#include "world_stability.hpp"

namespace toonforce {
namespace {

constexpr std::array<double, 8> kStiffness{50.0, 100.0, 200.0, 400.0, 800.0, 1600.0, 3000.0, 6000.0};
constexpr std::array<double, 7> kDamping{0.0, 0.1, 0.5, 1.0, 2.0, 5.0, 10.0};
constexpr std::array<std::pair<int, int>, 4> kDelays{{{1, 1}, {2, 2}, {4, 4}, {1, 4}}};

/// The analytic bound compared (docs/performance/world.md): the relative motion x_a - x_b of two
/// devices joined by the coupling is a virtual wall of the same K and B on a device whose
/// damping is the two devices' physical dampings in series, b_a b_b / (b_a + b_b) (the dampers
/// carry the same relative velocity split between them, as springs in series share a force);
/// with the larger of the two delays, Diolaiti et al.'s delay-aware form of Colgate's b > K T / 2
/// + B (control/passivity_bound.hpp). A hand that holds a handle adds its damping to that device.
double series_damping(double b_a, double b_b) { return b_a * b_b / (b_a + b_b); }

}  // namespace
}  // namespace toonforce

int main(int argc, char** argv) {
  using namespace toonforce;
  CLI::App app{"The virtual coupling's stability map: two simulated Falcon-class devices in one world"};
  bool hold = false;
  std::string csv_path;
  double duration_s = 4.0;
  app.add_flag("--hold", hold, "hand a holds its handle throughout (default: it lets go at 1.2 s)");
  app.add_option("--csv", csv_path, "also write every point as CSV to this file");
  app.add_option("--duration", duration_s, "simulated seconds per point (the last second is the steady state)")
      ->check(CLI::Range(2.0, 60.0));
  std::vector<double> point;
  app.add_option("--trace", point, "run one point K,B,DELAY_A,DELAY_B and print its trace as CSV (a tick a line)")
      ->delimiter(',')
      ->expected(4);
  CLI11_PARSE(app, argc, argv);
  if (!point.empty()) {
    bench::PointSpec spec;
    spec.stiffness_n_per_m = point[0];
    spec.damping_n_s_per_m = point[1];
    spec.delay_a_ticks = static_cast<int>(point[2]);
    spec.delay_b_ticks = static_cast<int>(point[3]);
    spec.a_releases = !hold;
    spec.duration_s = duration_s;
    spec.trace = stdout;
    fmt::print("t,xa,ya,za,xb,yb,zb,fax,fay,faz,fbx,fby,fbz,energy_a,energy_b\n");
    std::fflush(stdout);
    const bench::PointResult r = bench::run_point(spec);
    if (!r.ok) fmt::print(stderr, "{}\n", r.error);
    return r.ok ? 0 : 1;
  }

  std::FILE* csv = nullptr;
  if (!csv_path.empty()) {
    csv = std::fopen(csv_path.c_str(), "w");
    if (csv == nullptr) {
      fmt::print(stderr, "--csv {}: cannot write it\n", csv_path);
      return 1;
    }
    fmt::print(
        csv,
        "controller,delay_a,delay_b,stiffness_n_per_m,damping_n_s_per_m,bound_passive,stable,held,held_at_s,"
        "least_energy_j,least_sum_energy_j,least_true_sum_energy_j,steady_largest_gap_m,steady_largest_speed_m_per_s,peak_force_n\n");
  }
  const host_sim::DeviceParams falcon = host_sim::falcon_params();
  const double hand_b = host_sim::HandImpedance{}.damping_n_s_per_m;
  // Hand b always holds; hand a holds only with --hold.
  const double b_a = falcon.damping_n_s_per_m + (hold ? hand_b : 0.0);
  const double b_b = falcon.damping_n_s_per_m + hand_b;
  const double b_series = series_damping(b_a, b_b);
  fmt::print("# Two Falcon-class devices (mass {} kg, damping {} N s/m, Coulomb {} N, encoder {} um, max {} N), "
             "1 kHz, coupling rest length 0\n",
             falcon.mass_kg, falcon.damping_n_s_per_m, falcon.coulomb_n, falcon.encoder_step_m * 1e6,
             falcon.max_force_n);
  fmt::print("# hand a {} its handle at {} s; hand b moves its handle {} mm in 50 ms at {} s; {} s a point, the last "
             "second steady\n",
             hold ? "holds" : "lets go of", bench::kReleaseAtS, bench::kStepM * 1e3, bench::kMoveAtS, duration_s);
  fmt::print("# stable: no safety stop, and in the steady state |x_a - x_b| <= {} mm and |v_a - v_b| <= {} mm/s\n",
             bench::kStepM * 1e3, bench::kSteadySpeedMPerS * 1e3);
  fmt::print("# bound: b_series = {:.4f} N s/m (a {:.2f}, b {:.2f}) > K T (1/2 + d_max) + B\n", b_series, b_a, b_b);

  int failures = 0;
  for (const bool controller : {false, true}) {
    for (const auto& [da, db] : kDelays) {
      const int d_max = std::max(da, db);
      fmt::print("\n## passivity controller {}, delays a {} b {} ticks\n", controller ? "ON" : "OFF", da, db);
      fmt::print("{:>6} {:>5} {:>5} {:>6} {:>5} {:>10} {:>10} {:>10} {:>9} {:>9} {:>7}\n", "K", "B", "bound", "stable",
                 "held", "E_port[J]", "E_sum[J]", "E_true[J]", "gap[mm]", "v[mm/s]", "F[N]");
      std::vector<std::string> map_rows;
      for (const double k : kStiffness) {
        std::string map_row = fmt::format("{:>6} ", k);
        for (const double b : kDamping) {
          bench::PointSpec spec;
          spec.stiffness_n_per_m = k;
          spec.damping_n_s_per_m = b;
          spec.delay_a_ticks = da;
          spec.delay_b_ticks = db;
          spec.controller = controller;
          spec.a_releases = !hold;
          spec.duration_s = duration_s;
          const bench::PointResult r = bench::run_point(spec);
          if (!r.ok) {
            fmt::print(stderr, "K {} B {}: {}\n", k, b, r.error);
            ++failures;
            map_row += " ?";
            continue;
          }
          const bool passive = b_series > damping_needed_n_s_per_m(k, spec.period_s, d_max, b);
          fmt::print("{:>6} {:>5} {:>5} {:>6} {:>5} {:>10.3g} {:>10.3g} {:>10.3g} {:>9.3f} {:>9.3f} {:>7.2f}\n", k, b,
                     passive ? "in" : "out", r.stable ? "yes" : "no", r.held ? fmt::format("{:.2f}", r.held_at_s) : "-",
                     r.least_energy_j, r.least_sum_energy_j, r.least_true_sum_energy_j, r.steady_largest_gap_m * 1e3,
                     r.steady_largest_speed_m_per_s * 1e3, r.peak_force_n);
          // The map: S stable, H held by the safety, U unstable; lower case outside the bound.
          const char c = r.stable ? 'S' : r.held ? 'H' : 'U';
          map_row += ' ';
          map_row += passive ? c : static_cast<char>(c - 'A' + 'a');
          if (csv != nullptr) {
            fmt::print(csv, "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", controller ? 1 : 0, da, db, k, b,
                       passive ? 1 : 0, r.stable ? 1 : 0, r.held ? 1 : 0, r.held_at_s, r.least_energy_j,
                       r.least_sum_energy_j, r.least_true_sum_energy_j, r.steady_largest_gap_m,
                       r.steady_largest_speed_m_per_s, r.peak_force_n);
          }
        }
        map_rows.push_back(map_row);
      }
      std::string header = fmt::format("{:>6} ", "K\\B");
      for (const double b : kDamping) header += fmt::format(" {}", b);
      fmt::print("map (S stable, U unstable, H safety stop; lower case: outside the bound)\n{}\n", header);
      for (const std::string& row : map_rows) fmt::print("{}\n", row);
      fmt::print("stiffest passive by the bound at B = 0: {:.1f} N/m\n",
                 stiffest_passive_wall_n_per_m(b_series, 1e-3, d_max));
    }
  }
  if (csv != nullptr && std::fclose(csv) != 0) ++failures;
  return failures == 0 ? 0 : 1;
}
