// SPDX-License-Identifier: Apache-2.0
// Google Benchmark over the latency report's cases (tools/report/include/toonforce/report/
// workloads.hpp): every effect by branch, the safety stage, the five paper scenes as Scene<...>
// and as RuntimeScene, and the servo loop, for double, float and Q16.16. Google Benchmark
// reports the mean time per tick of a batch; `toonforce-lab report latency` times every tick alone
// (median, p99.9, max) and counts instructions. A timed program, never a test.
//
//   build/release/bin/toonforce_effects_bench --benchmark_filter='scene/.*/double'
#include <benchmark/benchmark.h>

#include <cstdio>
#include <memory>
#include <vector>

#include "toonforce/report/paths.hpp"
#include "toonforce/report/workloads.hpp"

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  auto cases = toonforce::report::make_cases(toonforce::report::source_root({}));
  if (!cases) {
    std::fprintf(stderr, "toonforce_effects_bench: %s\n", cases.error().c_str());
    return 1;
  }
  std::vector<std::unique_ptr<toonforce::report::TickCase>> owned = std::move(cases).value();
  for (auto& c : owned) {
    toonforce::report::TickCase* tick_case = c.get();
    benchmark::RegisterBenchmark(tick_case->info().id.c_str(), [tick_case](benchmark::State& state) {
      constexpr benchmark::IterationCount kBatch = 1024;
      tick_case->restart();
      while (state.KeepRunningBatch(kBatch)) tick_case->run(static_cast<std::uint64_t>(kBatch));
    });
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
