// SPDX-License-Identifier: Apache-2.0
#include "toonforce/viewer/trace_file.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include <fmt/format.h>

#include "toonforce/config/toml_reader.hpp"
#include "toonforce/trace/trace_writer.hpp"
#include "trace_text.hpp"

namespace toonforce::viewer {

using trace_text::parse_number;
using trace_text::trim;

Result<TraceRecording> parse_trace(std::string_view text, std::string_view name, std::size_t max_rows) {
  TraceRecording rec;
  std::vector<std::size_t> map;  // trace column -> view column (kViewStride: ignored)
  std::vector<std::string> header;
  std::size_t line_no = 0;
  bool has_tick = false;
  std::vector<double> dts;
  // A cut last row is left out and said, rather than the whole trace refused.
  const std::size_t cut_line = trace_text::drop_bom_and_cut_row(text);
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view{} : text.substr(nl + 1);
    ++line_no;
    if (trim(line).empty()) continue;
    if (map.empty()) {
      header = trace_text::split_header(line);
      for (std::size_t i = 0; i < kTraceCoreColumns.size(); ++i) {
        if (i >= header.size() || header[i] != kTraceCoreColumns[i]) {
          return Error{fmt::format("{}:{}: not a toonforce trace: the header must start with "
                                   "t,x,y,z,vx,vy,vz,fx,fy,fz (column {} is '{}')",
                                   name, line_no, i + 1, i < header.size() ? printable(header[i]) : "")};
        }
      }
      for (const std::string& h : header) {
        std::size_t column = view_column(h);
        // An effect's value ("surface1.impact_t"): the next of the frame's effect columns.
        if (column == kViewStride && h.find('.') != std::string::npos && rec.effect_values.size() < kViewEffectValues) {
          column = kFirstEffectValue + rec.effect_values.size();
          rec.effect_values.push_back(h);
        }
        map.push_back(column);
        if (h == "tick") has_tick = true;
      }
      const auto has = [&header](std::string_view c) {
        return std::find(header.begin(), header.end(), c) != header.end();
      };
      rec.has_loop = has("wake_latency_us");
      rec.source = rec.has_loop ? "run" : has("true_x") ? "sim" : "trace";
      continue;
    }
    if (rec.frames.size() == max_rows) {
      return Error{fmt::format("{}:{}: the trace has more than {} rows; the viewer keeps at most that many (cut it, "
                               "e.g. with head -n)",
                               name, line_no, max_rows)};
    }
    ViewFrame frame;
    frame.fill(std::numeric_limits<double>::quiet_NaN());
    std::size_t column = 0;
    for (std::size_t start = 0;; ++column) {
      const std::size_t comma = line.find(',', start);
      if (column >= map.size()) {
        return Error{fmt::format("{}:{}: more fields than the header's {} columns", name, line_no, map.size())};
      }
      double value = 0.0;
      const std::string_view field = line.substr(start, comma - start);
      if (!parse_number(field, value)) {
        // Quoted through printable(): a field's escape sequences must not drive the terminal, nor
        // a 20 MB field make a 20 MB line.
        return Error{fmt::format("{}:{}: column '{}': '{}' is not a number", name, line_no, printable(header[column]),
                                 printable(trim(field)))};
      }
      if (map[column] < kViewStride) frame[map[column]] = value;
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    if (column + 1 < kTraceCoreColumns.size()) {
      return Error{
          fmt::format("{}:{}: {} fields; a trace row has at least the ten core values", name, line_no, column + 1)};
    }
    if (!std::isfinite(frame[kT]))
      return Error{fmt::format("{}:{}: column 't': the time must be a number", name, line_no)};
    if (!rec.frames.empty()) {
      const double dt = frame[kT] - rec.frames.back()[kT];
      if (!(dt > 0.0)) {
        return Error{fmt::format("{}:{}: column 't': time {} does not increase (previous row {})", name, line_no,
                                 frame[kT], rec.frames.back()[kT])};
      }
      if (dts.size() < 10000) dts.push_back(dt);
    }
    if (!has_tick) frame[kTick] = static_cast<double>(rec.frames.size());
    rec.frames.push_back(frame);
  }
  if (map.empty()) return Error{fmt::format("{}: empty: no header row", name)};
  if (cut_line != 0) {
    rec.note = fmt::format("{}:{}: the last row is cut (no end of line: the run was killed or the disk filled); it is "
                           "left out, the {} rows before it are shown",
                           name, cut_line, rec.frames.size());
  }
  if (!dts.empty()) {
    std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
    rec.rate_hz = 1.0 / dts[dts.size() / 2];
  }
  return rec;
}

Result<TraceRecording> read_trace(const std::string& path, std::size_t max_rows) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return Error{fmt::format("{}: cannot open the trace: {}", path, std::strerror(errno))};
  std::string text;
  char buffer[1 << 16];
  std::size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof buffer, f)) > 0) text.append(buffer, n);
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) return Error{fmt::format("{}: cannot read the trace", path)};
  return parse_trace(text, path, max_rows);
}

}  // namespace toonforce::viewer
