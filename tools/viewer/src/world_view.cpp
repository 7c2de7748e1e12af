// SPDX-License-Identifier: Apache-2.0
#include "toonforce/viewer/world_view.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>

#include <fmt/format.h>

#include "toonforce/config/toml_reader.hpp"
#include "toonforce/trace/json.hpp"
#include "trace_text.hpp"

namespace toonforce::viewer {

namespace {

constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();

using trace_text::parse_number;
using trace_text::split_header;
using trace_text::trim;

}  // namespace

Result<WorldViewMap> WorldViewMap::make(const std::vector<std::string>& trace) {
  const auto index = [&trace](const std::string& name) {
    const auto it = std::find(trace.begin(), trace.end(), name);
    return it == trace.end() ? kNone : static_cast<std::size_t>(it - trace.begin());
  };
  if (index("t") == kNone) return Error{"not a world trace: no column 't'"};
  WorldViewMap map;
  for (const std::string& c : trace) {
    // A device has a HIP and a loop state; the ball has a position only.
    if (c.size() > 2 && c.ends_with(".x") && index(c.substr(0, c.size() - 2) + ".state") != kNone) {
      map.devices_.push_back(c.substr(0, c.size() - 2));
    }
  }
  if (map.devices_.empty()) return Error{"not a world trace: no device's HIP (a column NAME.x)"};
  // Groups in the order the page needs them; a group goes in only whole, and only if it fits.
  std::vector<std::vector<std::string>> groups;
  groups.push_back({"t", "tick"});
  for (const std::string& d : map.devices_) {
    std::vector<std::string> g;
    for (const char* v : {"x", "y", "z", "fx", "fy", "fz", "faults", "latched", "state"}) g.push_back(d + "." + v);
    groups.push_back(std::move(g));
  }
  groups.push_back({"ball.x", "ball.y", "ball.z", "held"});
  for (std::size_t j = 1; index(fmt::format("coupling{}.fx", j)) != kNone; ++j) {
    std::vector<std::string> g;
    for (const char* v : {"fx", "fy", "fz"}) g.push_back(fmt::format("coupling{}.{}", j, v));
    groups.push_back(std::move(g));
  }
  for (const std::string& d : map.devices_) {
    std::vector<std::string> g;
    for (const char* v : {"coupling_fx", "coupling_fy", "coupling_fz", "ball_fx", "ball_fy", "ball_fz"})
      g.push_back(d + "." + v);
    groups.push_back(std::move(g));
  }
  for (const auto& g : groups) {
    if (map.columns_.size() + g.size() > kViewStride) continue;
    for (const std::string& c : g) {
      map.columns_.push_back(c);
      map.from_.push_back(index(c));
    }
  }
  if (map.columns_.size() < 2 + 9 * map.devices_.size()) {
    return Error{fmt::format("a world of {} devices does not fit the viewer's frame", map.devices_.size())};
  }
  map.columns_.resize(kViewStride);
  map.from_.resize(kViewStride, kNone);
  return map;
}

ViewFrame WorldViewMap::frame(std::span<const double> row, double tick) const noexcept {
  ViewFrame v;
  for (std::size_t i = 0; i < kViewStride; ++i) {
    v[i] = from_[i] < row.size() ? row[from_[i]] : std::numeric_limits<double>::quiet_NaN();
  }
  v[kTick] = tick;  // the second column is "tick" (make())
  return v;
}

std::string world_json(const std::vector<std::string>& devices, const WorldDescription* world) {
  std::string names;
  for (const std::string& d : devices) names += fmt::format("{}{}", names.empty() ? "" : ",", json_string(d));
  std::string couplings;
  std::string radius = "null";
  std::string rotations;
  if (world != nullptr) {
    // Each device's rotation into the world (rows), for the page to turn its commanded force
    // (in the device's frame) into the world's; by the hello's order of devices.
    for (const std::string& d : devices) {
      const std::size_t k = world->device_index(d);
      const DeviceFrame frame = k < world->devices.size() ? world->devices[k].frame : DeviceFrame{};
      std::string rows;
      for (const Vec3<double>& r : frame.rotation) {
        // + 0.0: a negative zero (-sin 0) prints as 0.
        rows += fmt::format("{}[{},{},{}]", rows.empty() ? "" : ",", r.x + 0.0, r.y + 0.0, r.z + 0.0);
      }
      rotations += fmt::format("{}[{}]", rotations.empty() ? "" : ",", rows);
    }
    // By name: the trace's order of devices is the file's, but the page indexes the hello's list.
    const auto at = [&devices](const std::string& name) {
      return static_cast<std::size_t>(std::find(devices.begin(), devices.end(), name) - devices.begin());
    };
    for (const WorldCouplingEntry& c : world->couplings) {
      if (c.a >= world->devices.size() || c.b >= world->devices.size()) continue;
      const std::size_t a = at(world->devices[c.a].name);
      const std::size_t b = at(world->devices[c.b].name);
      if (a < devices.size() && b < devices.size())
        couplings += fmt::format("{}[{},{}]", couplings.empty() ? "" : ",", a, b);
    }
    if (world->ball && std::isfinite(world->ball->radius_m)) radius = fmt::format("{}", world->ball->radius_m);
  }
  return fmt::format(R"({{"devices":[{}],"couplings":[{}],"ball_radius":{},"rotations":{}}})", names, couplings, radius,
                     world != nullptr ? "[" + rotations + "]" : std::string("null"));
}

bool is_world_trace_header(const std::vector<std::string>& header) {
  return !header.empty() && header.front() == "t" && std::find(header.begin(), header.end(), "held") != header.end() &&
         std::find(header.begin(), header.end(), "x") == header.end();
}

std::vector<std::string> read_trace_header(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return {};
  std::string line;
  for (int c = 0; (c = std::fgetc(f)) != EOF && c != '\n' && line.size() < (1U << 16);)
    line.push_back(static_cast<char>(c));
  std::fclose(f);
  if (line.starts_with("\xEF\xBB\xBF")) line.erase(0, 3);
  return split_header(line);
}

Result<WorldRecording> parse_world_trace(std::string_view text, std::string_view name, std::size_t max_rows) {
  WorldRecording rec;
  const std::size_t cut_line = trace_text::drop_bom_and_cut_row(text);
  std::vector<std::string> header;
  std::optional<WorldViewMap> map;
  std::vector<double> row;
  std::vector<double> dts;
  std::size_t line_no = 0;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    const std::string_view line = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view{} : text.substr(nl + 1);
    ++line_no;
    if (trim(line).empty()) continue;
    if (!map) {
      header = split_header(line);
      auto made = WorldViewMap::make(header);
      if (!made) return Error{fmt::format("{}:{}: {}", name, line_no, made.error())};
      map = std::move(made.value());
      rec.columns = map->columns();
      rec.devices = map->devices();
      continue;
    }
    if (rec.frames.size() == max_rows) {
      return Error{fmt::format("{}:{}: the trace has more than {} rows; the viewer keeps at most that many (cut it, "
                               "e.g. with head -n)",
                               name, line_no, max_rows)};
    }
    row.clear();
    for (std::size_t start = 0;;) {
      const std::size_t comma = line.find(',', start);
      if (row.size() >= header.size()) {
        return Error{fmt::format("{}:{}: more fields than the header's {} columns", name, line_no, header.size())};
      }
      double value = 0.0;
      const std::string_view field = line.substr(start, comma - start);
      if (!parse_number(field, value)) {
        return Error{fmt::format("{}:{}: column '{}': '{}' is not a number", name, line_no,
                                 printable(header[row.size()]), printable(trim(field)))};
      }
      row.push_back(value);
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    ViewFrame frame = map->frame(row, static_cast<double>(rec.frames.size()));
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
    rec.frames.push_back(frame);
  }
  if (!map) return Error{fmt::format("{}: empty: no header row", name)};
  if (cut_line != 0) {
    rec.note = fmt::format("{}:{}: the last row is cut (no end of line); it is left out, the {} rows before it are "
                           "shown",
                           name, cut_line, rec.frames.size());
  }
  if (!dts.empty()) {
    std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
    rec.rate_hz = 1.0 / dts[dts.size() / 2];
  }
  return rec;
}

}  // namespace toonforce::viewer
