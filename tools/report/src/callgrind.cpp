// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/callgrind.hpp"

#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "toonforce/report/process.hpp"

namespace toonforce::report {

namespace fs = std::filesystem;

std::uint64_t CountedCase::max() const noexcept {
  if (!per_tick_counts.empty()) return *std::max_element(per_tick_counts.begin(), per_tick_counts.end());
  return static_cast<std::uint64_t>(std::ceil(mean()));
}

std::string default_tick_count_path() {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return "toonforce_tick_count";
  return (self.parent_path() / "toonforce_tick_count").string();
}

namespace {

bool parse_u64(std::string_view text, std::uint64_t& out) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc{} && end == text.data() + text.size();
}

/// One dump: its trigger name and its total instruction count.
struct Dump {
  std::string name;
  std::uint64_t total = 0;
  bool has_total = false;
};

Dump read_dump(const fs::path& path) {
  Dump d;
  std::ifstream in(path);
  std::string line;
  constexpr std::string_view kTrigger = "desc: Trigger: Client Request: ";
  constexpr std::string_view kTotals = "totals: ";
  while (std::getline(in, line)) {
    if (line.rfind(kTrigger, 0) == 0) {
      d.name = line.substr(kTrigger.size());
    } else if (line.rfind(kTotals, 0) == 0) {
      d.has_total = parse_u64(std::string_view(line).substr(kTotals.size()), d.total);
    }
  }
  return d;
}

}  // namespace

Result<CallgrindResult> count_instructions(const CallgrindOptions& options) {
  std::error_code ec;
  if (!fs::is_regular_file(options.tick_count, ec)) {
    return Error{fmt::format("callgrind: {} is missing (build the toonforce_tick_count target)", options.tick_count)};
  }
  // Thousands of small dumps: in memory (/dev/shm) when there is one, it halves the run time.
  const fs::path base = access("/dev/shm", W_OK) == 0 ? fs::path("/dev/shm") : fs::temp_directory_path(ec);
  std::string pattern = (base / "toonforce-callgrind-XXXXXX").string();
  if (mkdtemp(pattern.data()) == nullptr) return Error{fmt::format("callgrind: cannot create {}", pattern)};
  const fs::path dir = pattern;
  const std::vector<std::string> argv{options.valgrind,
                                      "--tool=callgrind",
                                      "--collect-atstart=no",
                                      "--toggle-collect=*measured_tick*",
                                      "--callgrind-out-file=" + (dir / "cg.out").string(),
                                      options.tick_count,
                                      "--root",
                                      options.root,
                                      "--filter",
                                      options.filter.empty() ? std::string("/") : options.filter,
                                      "--ticks",
                                      std::to_string(options.branch_ticks)};
  CallgrindResult result;
  // For people: the same command with a placeholder output directory and paths relative to
  // the current directory where they are inside it.
  std::vector<std::string> shown = argv;
  shown[4] = "--callgrind-out-file=DIR/cg.out";
  for (const std::size_t i : {std::size_t{5}, std::size_t{7}}) {
    const fs::path relative = fs::path(shown[i]).lexically_relative(fs::current_path(ec));
    if (!relative.empty() && relative.native().rfind("..", 0) != 0) shown[i] = relative.string();
  }
  result.command = shell_line(shown);
  const fs::path list = dir / "cases.tsv";
  auto status = run_process(argv, list.string(), true);
  const auto cleanup = [&dir] {
    std::error_code ignored;
    fs::remove_all(dir, ignored);
  };
  if (!status) {
    cleanup();
    return Error{fmt::format("callgrind: {} (is valgrind installed? tools/setup-deps installs it)", status.error())};
  }
  if (status.value() != 0) {
    cleanup();
    return Error{fmt::format("callgrind: `{}` exited with status {}", result.command, status.value())};
  }

  std::map<std::size_t, std::size_t> by_index;  // case index -> position in result.cases
  {
    std::ifstream in(list);
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream fields(line);
      std::string tag, index, id, mode, ticks;
      if (!std::getline(fields, tag, '\t') || tag != "case") continue;
      std::getline(fields, index, '\t');
      std::getline(fields, id, '\t');
      std::getline(fields, mode, '\t');
      std::getline(fields, ticks, '\t');
      CountedCase c;
      std::uint64_t i = 0;
      if (!parse_u64(index, i) || !parse_u64(ticks, c.ticks)) continue;
      c.index = static_cast<std::size_t>(i);
      c.id = id;
      c.per_tick = mode == "per-tick";
      if (c.per_tick) c.per_tick_counts.assign(c.ticks, 0);
      by_index[c.index] = result.cases.size();
      result.cases.push_back(std::move(c));
    }
  }
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (entry.path().filename().string().rfind("cg.out", 0) != 0) continue;
    const Dump d = read_dump(entry.path());
    if (!d.has_total) continue;
    std::istringstream words(d.name);
    std::string word_case, word_kind;
    std::uint64_t index = 0;
    std::uint64_t n = 0;
    if (!(words >> word_case >> index >> word_kind >> n) || word_case != "case") continue;
    const auto found = by_index.find(static_cast<std::size_t>(index));
    if (found == by_index.end()) continue;
    CountedCase& c = result.cases[found->second];
    if (word_kind == "tick" && c.per_tick && n < c.per_tick_counts.size()) {
      c.per_tick_counts[n] = d.total;
      c.total += d.total;
    } else if (word_kind == "ticks" && !c.per_tick) {
      c.total = d.total;
    }
  }
  cleanup();
  if (result.cases.empty()) return Error{fmt::format("callgrind: `{}` counted no case", result.command)};
  return result;
}

}  // namespace toonforce::report
