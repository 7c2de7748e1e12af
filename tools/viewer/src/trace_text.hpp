// SPDX-License-Identifier: Apache-2.0
#pragma once
// What the viewer's two trace readers (trace_file.cpp: one device; world_view.cpp: a world)
// share about a trace's text: fields, numbers, the header, a byte order mark and a cut last row.

#include <algorithm>
#include <charconv>
#include <cstddef>
#include <limits>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace toonforce::viewer::trace_text {

inline std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

/// A field as a number: empty is NaN ("not known", as the writers leave it); false if it is not one.
inline bool parse_number(std::string_view field, double& out) {
  field = trim(field);
  if (field.empty()) {
    out = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  if (field.front() == '+') field.remove_prefix(1);
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), out);
  return ec == std::errc() && end == field.data() + field.size();
}

/// The header's column names, trimmed.
inline std::vector<std::string> split_header(std::string_view line) {
  std::vector<std::string> header;
  for (std::size_t start = 0;;) {
    const std::size_t comma = line.find(',', start);
    header.emplace_back(trim(line.substr(start, comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return header;
}

/// Reads past a UTF-8 byte order mark (a spreadsheet's "CSV UTF-8": it made the first column an
/// invisible "\xEF\xBB\xBFt") and leaves out a last row without its newline: every writer ends
/// each row with one, so such a row was cut (a SIGKILLed run, a full disk). Returns the cut
/// row's line number (0: none).
inline std::size_t drop_bom_and_cut_row(std::string_view& text) {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  if (text.empty() || text.back() == '\n') return 0;
  const std::size_t last_nl = text.rfind('\n');
  if (last_nl == std::string_view::npos) return 0;
  const auto line =
      static_cast<std::size_t>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(last_nl), '\n')) + 2;
  text = text.substr(0, last_nl + 1);
  return line;
}

}  // namespace toonforce::viewer::trace_text
