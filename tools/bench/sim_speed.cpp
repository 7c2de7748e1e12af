// SPDX-License-Identifier: Apache-2.0
// Benchmark (never a test): how many simulated seconds the host simulation runs per second
// of wall-clock time, for each of the paper's figure scenarios, on one thread. Target:
// at least 1000x real time at 1 kHz. Two numbers per scenario: the closed loop alone
// (device reading, controller, device and hand physics) and with the trace formatted and
// written to /dev/null as `toonforce sim` does. Each figure is measured `--repeats` times and
// the fastest is reported (throughput on a shared machine: the slower runs measure the
// neighbours). Time is the thread's CPU time (CLOCK_THREAD_CPUTIME_ID), so time the scheduler
// gives to other processes on a shared machine is not counted; the wall-clock ratio of the
// same runs is printed too.
//
//   taskset -c 0 build/release/bin/toonforce_sim_bench [--seconds S] [--repeats N]
//                                  [--integrator NAME] [--substeps N] [--rate HZ]
#include <time.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "toonforce/sim/figures.hpp"
#include "toonforce/sim/sim_trace.hpp"

namespace {

using Clock = std::chrono::steady_clock;

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

struct Measurement {
  double simulated_s = 0.0;
  double cpu_s = 0.0;
  double wall_s = 0.0;
  std::int64_t ticks = 0;
};

/// Runs the scenario again and again until `seconds` have been simulated; `trace` writes
/// every record to /dev/null.
toonforce::Result<Measurement> measure(const toonforce::FigureSpec& spec, const toonforce::SimOptions& options,
                                       double seconds, bool trace) {
  using namespace toonforce;
  auto scene = load_scene_file(options.scene_path, options.scalar);
  if (!scene) return Error{scene.error()};
  auto hand = load_hand_script(options.script_path);
  if (!hand) return Error{hand.error()};
  const SimConfig config = sim_config(options);
  Measurement m;
  double wall = 0.0;
  double cpu = 0.0;
  double guard = 0.0;  // keeps the records alive for the optimiser
  while (m.simulated_s < seconds) {
    auto session = SimSession::create(scene.value(), hand.value(), config);  // set-up: not timed
    if (!session) return Error{session.error()};
    const std::vector<std::string> columns = sim_trace_columns(session->value_names());
    auto writer = trace ? TraceWriter::open("/dev/null", columns)
                        : Result<std::unique_ptr<TraceWriter>>(TraceWriter::in_memory(columns));
    if (!writer) return Error{writer.error()};
    const std::size_t values = session->value_names().size();
    const std::int64_t ticks = session->ticks_for(spec.duration_s);
    const auto start = Clock::now();
    const double cpu_start = thread_cpu_s();
    for (std::int64_t k = 0; k < ticks; ++k) {
      const SimRecord record = session->step();
      if (trace) write_sim_record(*writer.value(), record, values);
      guard += record.frame.force_n.z;
    }
    if (trace) static_cast<void>(writer.value()->close());
    cpu += thread_cpu_s() - cpu_start;
    wall += std::chrono::duration<double>(Clock::now() - start).count();
    m.ticks += ticks;
    m.simulated_s += static_cast<double>(ticks) * config.plant.period_s;
  }
  m.wall_s = wall;
  m.cpu_s = cpu;
  if (guard == 12345.678) std::puts("");  // never true; the loop cannot be optimised away
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  double seconds = 60.0;
  int repeats = 3;
  std::string integrator = "rk4";
  int substeps = 4;
  double rate_hz = 1000.0;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--seconds" && has_value) {
      seconds = std::atof(argv[++i]);
    } else if (arg == "--repeats" && has_value) {
      repeats = std::atoi(argv[++i]);
    } else if (arg == "--integrator" && has_value) {
      integrator = argv[++i];
    } else if (arg == "--substeps" && has_value) {
      substeps = std::atoi(argv[++i]);
    } else if (arg == "--rate" && has_value) {
      rate_hz = std::atof(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: %s [--seconds S] [--repeats N] [--integrator semi-implicit-euler|velocity-verlet|rk4|exact] "
                   "[--substeps N] [--rate HZ]\n",
                   argv[0]);
      return 2;
    }
  }
  const auto chosen = toonforce::host_sim::parse_integrator(integrator);
  if (!chosen || !(seconds > 0.0) || repeats < 1 || substeps < 1 || !(rate_hz > 0.0)) {
    std::fprintf(stderr, "toonforce_sim_bench: bad option value\n");
    return 2;
  }
  const std::string root = toonforce::figures_root();
  fmt::print("host simulation speed: {} with {} sub-steps, {:g} Hz, {:g} simulated s per scenario, best of {}, "
             "one thread\n\n",
             integrator, substeps, rate_hz, seconds, repeats);
  fmt::print("| scenario | x real time, loop | ns per tick, loop | x real time, with trace | ns per tick, with trace "
             "| x real time, loop (wall clock) |\n");
  fmt::print("| --- | ---: | ---: | ---: | ---: | ---: |\n");
  for (const auto& spec : toonforce::figure_specs()) {
    toonforce::SimOptions options = toonforce::figure_sim_options(spec, root);
    options.integrator = *chosen;
    options.substeps = substeps;
    options.rate_hz = rate_hz;
    toonforce::Result<Measurement> loop = toonforce::Error{""};
    toonforce::Result<Measurement> traced = toonforce::Error{""};
    for (int r = 0; r < repeats; ++r) {
      auto l = measure(spec, options, seconds, false);
      auto t = measure(spec, options, seconds, true);
      if (!l || !t) {
        std::fprintf(stderr, "%s: %s\n", std::string(spec.name).c_str(), (!l ? l.error() : t.error()).c_str());
        return 1;
      }
      if (!loop || l->cpu_s < loop->cpu_s) loop = std::move(l);
      if (!traced || t->cpu_s < traced->cpu_s) traced = std::move(t);
    }
    const auto ns = [](const Measurement& m) { return m.cpu_s * 1e9 / static_cast<double>(m.ticks); };
    fmt::print("| {} | {:.0f} | {:.0f} | {:.0f} | {:.0f} | {:.0f} |\n", spec.name, loop->simulated_s / loop->cpu_s,
               ns(loop.value()), traced->simulated_s / traced->cpu_s, ns(traced.value()),
               loop->simulated_s / loop->wall_s);
  }
  return 0;
}
