// SPDX-License-Identifier: Apache-2.0
#include "toonforce/replay/motion_csv.hpp"

#include "toonforce/config/toml_reader.hpp"
#include "toonforce/effects/tick.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string_view>

#include <fmt/format.h>

namespace toonforce {
namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(
        trim(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return fields;
}

/// A whole field as a double; "nan", "inf" and "-inf" are numbers here.
std::optional<double> parse_double(std::string_view field) {
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (ec != std::errc() || end != field.data() + field.size() || field.empty()) return std::nullopt;
  return value;
}

}  // namespace

Result<Motion> parse_motion_csv(const std::string& text, const std::string& source_name) {
  constexpr std::array<std::string_view, 7> kNames = {"t", "x", "y", "z", "vx", "vy", "vz"};
  std::array<std::optional<std::size_t>, 7> column{};  // index of each known column
  Motion motion;
  // Every writer ends each row with a newline: a last row without one may be cut mid-number
  // ("0.00" of "0.0042"), so it is left out and named rather than read as data.
  std::string_view whole = text;
  std::size_t cut_line = 0;
  if (!whole.empty() && whole.back() != '\n') {
    const std::size_t last_nl = whole.rfind('\n');
    if (last_nl != std::string_view::npos) {
      cut_line = static_cast<std::size_t>(
                     std::count(whole.begin(), whole.begin() + static_cast<std::ptrdiff_t>(last_nl), '\n')) +
                 2;
      whole = whole.substr(0, last_nl + 1);
    }
  }
  if (cut_line != 0) {
    motion.note = fmt::format("{}:{}: the last row has no end of line (cut: a full disk or a killed writer?); it is "
                              "left out",
                              source_name, cut_line);
  }
  std::istringstream in{std::string(whole)};
  std::string raw;
  std::size_t line_number = 0;
  std::size_t field_count = 0;
  bool have_header = false;
  double previous_t = 0.0;
  const auto fail = [&](std::string_view problem) {
    return Error{fmt::format("{}:{}: {}", source_name, line_number, problem)};
  };

  while (std::getline(in, raw)) {
    ++line_number;
    // A UTF-8 byte order mark (Excel's "CSV UTF-8") before the header: read past it, and name
    // it if the header is wrong anyway (it made "no column 't'" out of "\xEF\xBB\xBFt").
    if (line_number == 1 && raw.rfind("\xEF\xBB\xBF", 0) == 0) raw.erase(0, 3);
    const std::string_view line = trim(raw);
    if (line.empty() || line.front() == '#') continue;
    const auto fields = split(line);
    if (!have_header) {
      have_header = true;
      field_count = fields.size();
      for (std::size_t i = 0; i < fields.size(); ++i) {
        const auto known = std::find(kNames.begin(), kNames.end(), fields[i]);
        if (known == kNames.end()) {
          motion.ignored_columns.emplace_back(fields[i]);
          continue;
        }
        auto& slot = column[static_cast<std::size_t>(known - kNames.begin())];
        if (slot) return fail(fmt::format("column '{}' appears twice in the header", printable(fields[i])));
        slot = i;
      }
      for (std::size_t k = 0; k < 4; ++k) {
        if (!column[k]) return fail(fmt::format("the header has no column '{}' (need t,x,y,z)", kNames[k]));
      }
      const int velocity_columns = (column[4] ? 1 : 0) + (column[5] ? 1 : 0) + (column[6] ? 1 : 0);
      if (velocity_columns != 0 && velocity_columns != 3) {
        return fail("give all three of vx,vy,vz or none (then velocity is estimated)");
      }
      motion.has_velocity = velocity_columns == 3;
      continue;
    }
    if (fields.size() != field_count) {
      return fail(fmt::format("{} fields, but the header has {}", fields.size(), field_count));
    }
    double values[7] = {};
    for (std::size_t k = 0; k < 7; ++k) {
      if (!column[k]) continue;
      const auto value = parse_double(fields[*column[k]]);
      if (!value)
        return fail(fmt::format("column '{}': '{}' is not a number", kNames[k], printable(fields[*column[k]])));
      values[k] = *value;
    }
    if (!std::isfinite(values[0])) return fail(fmt::format("t must be finite (got {})", values[0]));
    // The loop takes t to the nearest nanosecond (an integer stamp, effects/tick.hpp).
    if (!(std::fabs(values[0]) < 9.2e9))
      return fail(fmt::format("t = {} s is beyond the stamps' range (|t| < 9.2e9 s)", values[0]));
    const std::int64_t t_ns = ns_from_seconds(values[0]);
    if (!motion.rows.empty() && !(values[0] > previous_t)) {
      return fail(fmt::format("t must increase strictly ({} after {})", values[0], previous_t));
    }
    if (!motion.rows.empty() && !(t_ns > motion.rows.back().t_ns)) {
      return fail(fmt::format("t must increase by 1 ns at least, the resolution of the loop's stamps ({} after {})",
                              values[0], previous_t));
    }
    previous_t = values[0];
    motion.rows.push_back(
        {values[0], t_ns, {values[1], values[2], values[3]}, {values[4], values[5], values[6]}, line_number});
  }
  if (!have_header) return Error{fmt::format("{}: empty motion file (need a header t,x,y,z)", source_name)};
  if (motion.rows.size() < 2) {
    return Error{fmt::format("{}: {} data row(s); replay needs at least two, since the first tick's dt is "
                             "the recording's period (t of row 2 minus t of row 1)",
                             source_name, motion.rows.size())};
  }
  return motion;
}

Result<Motion> read_motion_csv(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    return Error{fmt::format("{}: is a directory, not a motion CSV file", path)};
  }
  std::ifstream file(path, std::ios::binary);
  if (!file) return Error{fmt::format("{}: cannot open the motion file: {}", path, std::strerror(errno))};
  std::ostringstream text;
  text << file.rdbuf();
  return parse_motion_csv(text.str(), path);
}

}  // namespace toonforce
