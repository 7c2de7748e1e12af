// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/latency.hpp"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "toonforce/control/faults.hpp"
#include "toonforce/report/callgrind.hpp"
#include "toonforce/report/template.hpp"
#include "toonforce/report/templates.hpp"

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

  // Cache-cold ticks (the figures were warm only, and a cold tick cost about five
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
    row.mean_ns = std::max(0.0, histogram.mean_in_bins() - report.clock.overhead_mean_cycles) / cycles_per_ns;
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
        const auto& counts = found->second->per_tick_counts;
        if (row.info.form == "search" && !counts.empty()) {
          row.instructions_argmax =
              static_cast<std::size_t>(std::max_element(counts.begin(), counts.end()) - counts.begin());
          if (row.info.level == Level::kLoop) {
            auto ticks = search_loop_ticks(options.root, row.info.subject, row.info.scalar);
            if (!ticks) return Error{ticks.error()};
            if (ticks->size() != counts.size()) {
              return Error{fmt::format("{}: {} ticks run, {} counted", row.info.id, ticks->size(), counts.size())};
            }
            row.search_ticks = std::move(ticks).value();
            for (const auto c : counts)
              row.search_instructions.push_back(static_cast<double>(c) - report.harness_instructions);
          }
        }
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

/// The Limit bits of a tick, in words.
std::string limits_words(std::uint8_t limits, std::uint32_t faults) {
  std::vector<std::string> words;
  const std::pair<Limit, const char*> names[] = {{Limit::kSoftStart, "soft start"}, {Limit::kPassivity, "passivity"},
                                                 {Limit::kThermal, "thermal"},      {Limit::kRateLimited, "rate limit"},
                                                 {Limit::kClamped, "clamp"},        {Limit::kEngaging, "engaging"}};
  for (const auto& [bit, name] : names) {
    if ((limits & static_cast<std::uint8_t>(bit)) != 0) words.emplace_back(name);
  }
  if (faults != 0) words.push_back(fmt::format("faults 0x{:x}", faults));
  return words.empty() ? std::string("none") : fmt::format("{}", fmt::join(words, ", "));
}

/// The searched inputs, per scene and scalar: the most expensive tick found,
/// what the loop did on it, and each stage's expensive branch: how often it was reached and the
/// most expensive tick on which it was.
std::string search_markdown(const LatencyReport& r) {
  std::string md;
  bool any = false;
  for (const auto& row : r.rows) any = any || (row.info.form == "search" && row.instructions_max);
  if (!any) return md;
  md += render_prose(templates::latency_search_md, {{"strikes", fmt::format("{}", kSearchStrikes)},
                                                    {"strike_ticks", fmt::format("{}", kSearchStrikeTicks)}});
  md +=
      "| scene | scalar | effects + safety: max found (scenario's max) | whole loop: mean, max found (scenario's max) "
      "| what acted on the max tick | soft start | passivity | thermal | rate limit | clamp | all five |\n";
  md += "| --- | --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |\n";
  const auto find = [&r](Level level, const std::string& subject, ScalarKind scalar, std::string_view form) {
    for (const auto& row : r.rows) {
      if (row.info.level == level && row.info.subject == subject && row.info.scalar == scalar &&
          row.info.form == form) {
        return &row;
      }
    }
    return static_cast<const LatencyRow*>(nullptr);
  };
  const auto max_of = [](const LatencyRow* row) {
    return row && row->instructions_max ? cell(row->instructions_max, 0) : "-";
  };
  for (const auto& loop : r.rows) {
    if (loop.info.level != Level::kLoop || loop.info.form != "search" || loop.search_ticks.empty()) continue;
    const LatencyRow* scene = find(Level::kScene, loop.info.subject, loop.info.scalar, "search");
    const LatencyRow* scene_pass = find(Level::kScene, loop.info.subject, loop.info.scalar, "runtime");
    const LatencyRow* loop_pass = find(Level::kLoop, loop.info.subject, loop.info.scalar, "runtime");
    const auto stage = [&loop](std::uint8_t mask, bool all) {
      std::size_t n = 0;
      double worst = 0.0;
      for (std::size_t k = 0; k < loop.search_ticks.size(); ++k) {
        const std::uint8_t l = loop.search_ticks[k].limits;
        const bool hit = all ? ((l & mask) == mask && (l & (static_cast<std::uint8_t>(Limit::kRateLimited) |
                                                            static_cast<std::uint8_t>(Limit::kClamped))) != 0)
                             : (l & mask) != 0;
        if (!hit) continue;
        ++n;
        worst = std::max(worst, loop.search_instructions[k]);
      }
      return n == 0 ? std::string("0") : fmt::format("{} ({:.0f})", n, worst);
    };
    const std::size_t at = loop.instructions_argmax.value_or(0);
    const SearchTick& t = loop.search_ticks[std::min(at, loop.search_ticks.size() - 1)];
    md += fmt::format("| {} | {} | {} ({}) | {}, {} ({}) | {} | {} | {} | {} | {} | {} | {} |\n", loop.info.subject,
                      scalar_kind_name(loop.info.scalar), max_of(scene), max_of(scene_pass),
                      cell(loop.instructions_mean, 0), max_of(&loop), max_of(loop_pass),
                      limits_words(t.limits, t.faults), stage(static_cast<std::uint8_t>(Limit::kSoftStart), false),
                      stage(static_cast<std::uint8_t>(Limit::kPassivity), false),
                      stage(static_cast<std::uint8_t>(Limit::kThermal), false),
                      stage(static_cast<std::uint8_t>(Limit::kRateLimited), false),
                      stage(static_cast<std::uint8_t>(Limit::kClamped), false),
                      stage(static_cast<std::uint8_t>(static_cast<std::uint8_t>(Limit::kSoftStart) |
                                                      static_cast<std::uint8_t>(Limit::kPassivity) |
                                                      static_cast<std::uint8_t>(Limit::kThermal)),
                            true));
  }
  return md;
}

}  // namespace

std::string latency_markdown(const LatencyReport& r) {
  std::string md;
  md += fmt::format("Measured {} UTC on {}; load average (1, 5, 15 min) {} before and {} after the timing runs.\n\n",
                    r.machine.date_utc, describe(r.machine), r.load_before, r.load_after);
  md += render_prose(templates::latency_clock_md, {{"clock", describe(r.clock)},
                                                   {"ticks", fmt::format("{}", r.ticks)},
                                                   {"cold_ticks", fmt::format("{}", r.cold_ticks)}});
  if (!r.callgrind_command.empty()) {
    md += render_prose(
        templates::latency_instructions_md,
        {{"command", r.callgrind_command}, {"empty_tick_instructions", fmt::format("{:.0f}", r.harness_instructions)}});
  }

  md += render_prose(templates::latency_scenes_md,
                     {{"target_instructions", fmt::format("{:.0f}", kTargetInstructionsPerTick)},
                      {"target_median_ns", fmt::format("{:.0f}", kTargetMedianNsPerTick)}});
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
      if (row.info.form == "search") target += " on searched inputs";
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

  md += render_prose(templates::latency_loop_md,
                     {{"target_instructions", fmt::format("{:.0f}", kTargetLoopInstructionsPerTick)}});
  md += "| scene | stages | scalar | form | mean ns | median ns | p99.9 ns | max ns | cold median ns | cold p99 ns | "
        "instructions, mean | instructions, max over the pass | target |\n";
  md += "| --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |\n";
  for (const Level level : {Level::kLoop, Level::kSpecLoop}) {
    for (const auto& row : r.rows) {
      if (row.info.level != level) continue;
      std::string target;
      if (level == Level::kLoop && row.info.scalar == ScalarKind::kDouble && row.instructions_mean &&
          row.info.form != "search") {  // the target is the scenario's mean
        target = *row.instructions_mean <= kTargetLoopInstructionsPerTick ? "met" : "MISSED";
      }
      md += fmt::format("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", row.info.subject,
                        level == Level::kLoop ? "every stage" : "spec stages", scalar_kind_name(row.info.scalar),
                        row.info.form, times(row), cell(row.cold_median_ns, 0), cell(row.cold_p99_ns, 0),
                        cell(row.instructions_mean, 1), cell(row.instructions_max, 0), target);
    }
  }
  md += search_markdown(r);
  for (const auto& row : r.rows) {
    if (row.info.level != Level::kHarness) continue;
    md += fmt::format("\nThe empty tick (harness check, after subtracting the clock's overhead): median {:.1f} ns, "
                      "p99.9 {:.1f} ns, max {:.0f} ns.\n",
                      row.median_ns, row.p999_ns, row.max_ns);
  }
  return md;
}

}  // namespace toonforce::report
