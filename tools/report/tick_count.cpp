// SPDX-License-Identifier: Apache-2.0
// toonforce_tick_count: runs the latency cases' ticks for callgrind to count (never timed).
// Run under
//   valgrind --tool=callgrind --collect-atstart=no --toggle-collect='*measured_tick*'
//            --callgrind-out-file=DIR/cg.out toonforce_tick_count --root SOURCE_TREE [--filter F]
// so only measured_tick() (one tick, nothing else) is counted. Each case first runs one
// untimed pass (caches, lazy symbol binding) whose counts are discarded, then:
//   - a scenario case (scene, controller) dumps its counts after every tick of one pass
//     (dump "case I tick J"): the mean and the maximum per tick over its scenario;
//   - a branch case (effect, safety stage, harness) dumps once after --ticks ticks
//     (dump "case I ticks N"): its mean per tick.
// Standard output lists the cases: "case<TAB>I<TAB>ID<TAB>MODE<TAB>TICKS". Outside valgrind
// the client requests do nothing and the program just runs the ticks.
#include <valgrind/callgrind.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include <fmt/format.h>

#include "toonforce/report/workloads.hpp"

namespace {

struct DumpContext {
  std::size_t index = 0;
};

void dump_tick(std::uint64_t tick, void* context) {
  const auto* c = static_cast<const DumpContext*>(context);
  const std::string name = fmt::format("case {} tick {}", c->index, tick);
  CALLGRIND_DUMP_STATS_AT(name.c_str());
}

int usage() {
  std::fputs("usage: toonforce_tick_count --root SOURCE_TREE [--filter TEXT[,TEXT...]] [--ticks N]\n", stderr);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string root = TOONFORCE_SOURCE_DIR;
  std::string filter;
  std::uint64_t branch_ticks = 1024;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (i + 1 >= argc) return usage();
    if (arg == "--root") {
      root = argv[++i];
    } else if (arg == "--filter") {
      filter = argv[++i];
    } else if (arg == "--ticks") {
      branch_ticks = std::strtoull(argv[++i], nullptr, 10);
      if (branch_ticks == 0) return usage();
    } else {
      return usage();
    }
  }
  auto cases = toonforce::report::make_cases(root);
  if (!cases) {
    std::fprintf(stderr, "toonforce_tick_count: %s\n", cases.error().c_str());
    return 1;
  }
  using toonforce::report::Level;
  for (std::size_t index = 0; index < cases->size(); ++index) {
    auto& c = *cases.value()[index];
    if (!toonforce::report::selected(c.info().id, filter)) continue;
    const bool scenario =
        c.info().level == Level::kScene || c.info().level == Level::kSpecLoop || c.info().level == Level::kLoop;
    const std::uint64_t pass = c.info().ticks_per_pass;
    const std::uint64_t ticks = scenario ? pass : branch_ticks;
    std::printf("case\t%zu\t%s\t%s\t%llu\n", index, c.info().id.c_str(), scenario ? "per-tick" : "total",
                static_cast<unsigned long long>(ticks));
    std::fflush(stdout);
    // Warm-up pass: its counts go to a dump of their own, ignored. (Not CALLGRIND_ZERO_STATS:
    // with callgrind 3.19 it left stale costs behind that reappeared in the next dump.)
    c.restart();
    c.run_counted(scenario ? pass : std::min<std::uint64_t>(pass, branch_ticks), nullptr, nullptr);
    CALLGRIND_DUMP_STATS_AT("warm-up");
    DumpContext context{index};
    if (scenario) {
      // The second pass: effect states continue from the first, as in a run.
      c.run_counted(ticks, &dump_tick, &context);
    } else {
      c.run_counted(ticks, nullptr, nullptr);
      const std::string name = fmt::format("case {} ticks {}", index, ticks);
      CALLGRIND_DUMP_STATS_AT(name.c_str());
    }
  }
  return 0;
}
