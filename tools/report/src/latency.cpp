#include "toonforce/report/latency.hpp"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <map>
#include <vector>

#include <fmt/format.h>

#include "toonforce/report/callgrind.hpp"

namespace toonforce::report {

bool pin_to_cpu(int cpu) {
  if (cpu < 0 || cpu >= CPU_SETSIZE) return false;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(static_cast<std::size_t>(cpu), &set);
  return pthread_setaffinity_np(pthread_self(), sizeof set, &set) == 0;
}

Result<LatencyReport> run_latency(const LatencyOptions& options, const Progress& progress) {
  const auto say = [&progress](const std::string& line) {
    if (progress) progress(line);
  };
  auto cases = make_cases(options.root);
  if (!cases) return Error{cases.error()};
  if (options.cpu >= 0 && !pin_to_cpu(options.cpu)) return Error{fmt::format("cannot pin to CPU {}", options.cpu)};

  LatencyReport report;
  report.machine = machine_info();
  report.ticks = options.ticks;
  report.cold_ticks = options.cold_ticks;
  report.load_before = load_average();
  say("calibrating the time-stamp counter");
  report.clock = calibrate();
  if (!report.clock.invariant) say("warning: this CPU does not report an invariant TSC; times may be wrong");
  const double cycles_per_ns = report.clock.cycles_per_ns;
  const auto to_ns = [&](std::uint64_t cycles) {
    const std::uint64_t net = cycles > report.clock.overhead_cycles ? cycles - report.clock.overhead_cycles : 0;
    return static_cast<double>(net) / cycles_per_ns;
  };

  // Cache-cold ticks (issue 15: the figures were warm only, and a cold tick cost about five
  // warm ones): 64 MiB, more than this VM's last-level cache, written a line at a time between
  // ticks, so the tick's data (scene, loop state, inputs) comes from memory. The instruction
  // cache and the branch predictors are not flushed: what they keep, this does not measure.
  std::vector<unsigned char> evict(options.cold_ticks > 0 ? std::size_t{64} << 20 : 0);
  unsigned char evict_value = 0;
  const auto evict_caches = [&evict, &evict_value] {
    ++evict_value;
    for (std::size_t i = 0; i < evict.size(); i += 64) evict[i] = evict_value;
    asm volatile("" ::: "memory");  // the stores happen before the tick's first counter read
  };

  CycleHistogram histogram;
  for (auto& c : cases.value()) {
    if (!selected(c->info().id, options.filter)) continue;
    say(fmt::format("timing {} ({} ticks)", c->info().id, options.ticks));
    c->restart();
    c->run(std::max<std::uint64_t>(c->info().ticks_per_pass, 10000));  // warm caches and predictors
    histogram = CycleHistogram();
    c->time(options.ticks, histogram);
    LatencyRow row;
    row.info = c->info();
    row.ticks = histogram.count();
    row.mean_ns = std::max(0.0, histogram.mean_in_bins() - report.clock.overhead_mean_cycles) /
                  cycles_per_ns;
    row.median_ns = to_ns(histogram.percentile(0.5));
    row.p999_ns = to_ns(histogram.percentile(0.999));
    row.max_ns = to_ns(histogram.max());
    const Level level = c->info().level;
    if (options.cold_ticks > 0 && (level == Level::kScene || level == Level::kLoop || level == Level::kSpecLoop)) {
      CycleHistogram cold;
      for (std::uint64_t k = 0; k < options.cold_ticks; ++k) {
        evict_caches();
        c->time(1, cold);  // the next input of the pass, alone
      }
      row.cold_median_ns = to_ns(cold.percentile(0.5));
      row.cold_p99_ns = to_ns(cold.percentile(0.99));
    }
    report.rows.push_back(std::move(row));
  }
  report.load_after = load_average();

  if (options.callgrind) {
    say("counting instructions under callgrind");
    CallgrindOptions counting;
    counting.valgrind = options.valgrind;
    counting.tick_count = options.tick_count.empty() ? default_tick_count_path() : options.tick_count;
    counting.root = options.root;
    // The harness always, for its overhead; then what was timed.
    counting.filter = options.filter.empty() ? std::string() : "harness/," + options.filter;
    auto counted = count_instructions(counting);
    if (!counted) return Error{counted.error()};
    report.callgrind_command = counted->command;
    std::map<std::string, const CountedCase*> by_id;
    for (const auto& c : counted->cases) by_id[c.id] = &c;
    if (const auto h = by_id.find("harness/empty"); h != by_id.end()) report.harness_instructions = h->second->mean();
    for (auto& row : report.rows) {
      const auto found = by_id.find(row.info.id);
      if (found == by_id.end()) continue;
      row.instructions_mean = found->second->mean() - report.harness_instructions;
      if (found->second->per_tick) {
        row.instructions_max = static_cast<double>(found->second->max()) - report.harness_instructions;
      }
    }
  }
  return report;
}

namespace {

std::string cell(const std::optional<double>& v, int decimals) {
  if (!v) return "-";
  return decimals == 0 ? fmt::format("{:.0f}", *v) : fmt::format("{:.{}f}", *v, decimals);
}

std::string times(const LatencyRow& r) {
  return fmt::format("{:.1f} | {:.0f} | {:.0f} | {:.0f}", r.mean_ns, r.median_ns, r.p999_ns, r.max_ns);
}

}  // namespace

std::string latency_markdown(const LatencyReport& r) {
  std::string md;
  md += fmt::format("Measured {} UTC on {}; load average (1, 5, 15 min) {} before and {} after the timing runs.\n\n",
                    r.machine.date_utc, describe(r.machine), r.load_before, r.load_after);
  md += fmt::format("Clock: {}. {} ticks timed per row (each tick alone; median, p99.9 and maximum of all of them), "
                    "warm: after a pass that fills the caches. **Cold**: {} more ticks of scene and loop rows, each "
                    "after writing a 64 MiB buffer (more than the last-level cache), so the tick's data comes from "
                    "memory; the instruction cache and branch predictors are not flushed.\n\n",
                    describe(r.clock), r.ticks, r.cold_ticks);
  if (!r.callgrind_command.empty()) {
    md += fmt::format(
        "Instructions: callgrind, counting only the ticks (`{}`); the empty tick's {:.0f} instructions (the call "
        "into the counted function and its return) are subtracted. Scenario rows give the mean over one pass of the "
        "scenario and its most expensive tick (the largest of that pass: a sample, not a bound on every input); "
        "branch rows the mean over 1024 ticks of the branch.\n\n",
        r.callgrind_command, r.harness_instructions);
  }

  md += "### Paper scenes: effects plus the safety stage\n\n";
  md += fmt::format(
      "One tick = `scene.force()` then `ForceSafety::limit()` (rate limit, clamp), inputs from the scene's scripted "
      "scenario at 1 kHz (tools/report/src/scenario.cpp: every branch, the expensive ones included). Target (issue "
      "8), double: at most {:.0f} instructions and at most {:.0f} ns median per tick.\n\n",
      kTargetInstructionsPerTick, kTargetMedianNsPerTick);
  md += "| scene | scalar | form | mean ns | median ns | p99.9 ns | max ns | cold median ns | cold p99 ns | "
        "instructions, mean | instructions, max over the pass | target |\n";
  md += "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n";
  for (const auto& row : r.rows) {
    if (row.info.level != Level::kScene) continue;
    std::string target = "";
    if (row.info.scalar == ScalarKind::kDouble) {
      const bool instructions_ok = !row.instructions_max || *row.instructions_max <= kTargetInstructionsPerTick;
      const bool time_ok = row.median_ns <= kTargetMedianNsPerTick;
      target = instructions_ok && time_ok ? "met" : (!instructions_ok ? "MISSED (instructions)" : "MISSED (time)");
    }
    md += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", row.info.subject,
                      scalar_kind_name(row.info.scalar), row.info.form, times(row), cell(row.cold_median_ns, 0),
                      cell(row.cold_p99_ns, 0), cell(row.instructions_mean, 1), cell(row.instructions_max, 0), target);
  }

  md += "\n### Effects and the safety stage, branch by branch\n\n";
  md += "Each row drives one branch: the law's state is restored before every tick (outside the timed region), the "
        "inputs vary within the branch. Parameters are the bundled scenes' (the damped wall: 2 N s/m).\n\n";
  md += "| effect | branch | scalar | mean ns | median ns | p99.9 ns | max ns | instructions |\n";
  md += "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |\n";
  for (const auto& row : r.rows) {
    if (row.info.level != Level::kEffect && row.info.level != Level::kSafety) continue;
    md += fmt::format("| {} | {} | {} | {} | {} |\n", row.info.subject, row.info.branch,
                      scalar_kind_name(row.info.scalar), times(row), cell(row.instructions_mean, 1));
  }

  md += "\n### The whole servo loop tick\n\n";
  md += fmt::format(
      "`ServoLoop::tick()`, read to write, on a scripted device that plays the scene's scenario (positions only, "
      "as from a Falcon: the loop estimates velocity): the supervisor, the effects on a copy of their state with "
      "the non-finite guard, and the safety chain. **every stage**: engage and soft start, passivity observer and "
      "controller, thermal model, velocity limit and workspace, rate limit, clamp, all configured on (the "
      "`run` loop); **spec stages**: only effects.md §6's (rate limit, clamp), as `toonforce replay` runs it. "
      "Target (issue 14), double, every stage: at most {:.0f} instructions mean per tick.\n\n",
      kTargetLoopInstructionsPerTick);
  md += "| scene | stages | scalar | form | mean ns | median ns | p99.9 ns | max ns | cold median ns | cold p99 ns | "
        "instructions, mean | instructions, max over the pass | target |\n";
  md += "| --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n";
  for (const Level level : {Level::kLoop, Level::kSpecLoop}) {
    for (const auto& row : r.rows) {
      if (row.info.level != level) continue;
      std::string target;
      if (level == Level::kLoop && row.info.scalar == ScalarKind::kDouble && row.instructions_mean) {
        target = *row.instructions_mean <= kTargetLoopInstructionsPerTick ? "met" : "MISSED";
      }
      md += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", row.info.subject,
                        level == Level::kLoop ? "every stage" : "spec stages", scalar_kind_name(row.info.scalar),
                        row.info.form, times(row), cell(row.cold_median_ns, 0), cell(row.cold_p99_ns, 0),
                        cell(row.instructions_mean, 1), cell(row.instructions_max, 0), target);
    }
  }
  for (const auto& row : r.rows) {
    if (row.info.level != Level::kHarness) continue;
    md += fmt::format("\nThe empty tick (harness check, after subtracting the clock's overhead): median {:.1f} ns, "
                      "p99.9 {:.1f} ns, max {:.0f} ns.\n",
                      row.median_ns, row.p999_ns, row.max_ns);
  }
  return md;
}

}  // namespace toonforce::report
