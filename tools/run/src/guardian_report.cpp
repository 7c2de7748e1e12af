// SPDX-License-Identifier: Apache-2.0
// The guardian's epilogue: the trace's zero-force row, the words, the statistics
// (guardian_report.hpp).
#include "toonforce/run/guardian_report.hpp"

#include <string.h>
#include <sys/types.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <vector>

#include <fmt/format.h>

#include "toonforce/trace/json.hpp"
#include "toonforce/trace/telemetry_trace.hpp"
#include "toonforce/trace/trace_writer.hpp"

namespace toonforce::guardian {
namespace {

/// The number of effect values the trace's header has room for: its columns less the core, the
/// loop's and the timing's (0 when the header cannot be read).
std::size_t header_effect_values(const std::string& path) {
  std::ifstream in(path);
  std::string header;
  if (!std::getline(in, header) || header.empty()) return 0;
  const std::size_t columns = static_cast<std::size_t>(std::count(header.begin(), header.end(), ',')) + 1;
  const std::size_t fixed = kTraceCoreColumns.size() + telemetry_extra_count(0, true);
  return columns > fixed ? std::min(columns - fixed, kMaxEffectValues) : 0;
}

/// The header's columns ("" when it cannot be read).
std::vector<std::string> header_columns(const std::string& path) {
  std::ifstream in(path);
  std::string header;
  std::vector<std::string> columns;
  if (!std::getline(in, header) || header.empty()) return columns;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = header.find(',', start);
    columns.push_back(header.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos) return columns;
    start = comma + 1;
  }
}

/// A world's trace (its header begins with "t," and ends with ",held": sim/world_trace.hpp):
/// the row of the zero command. Each device's commanded force is zero; what the process did not
/// live to compute (positions, the forces between HIPs, states) is NaN, "not known".
std::string end_world_trace(const std::string& path, const std::vector<std::string>& columns, const Verdict& v) {
  std::string row = fmt::format("{}", v.t_end_s);
  for (std::size_t i = 1; i < columns.size(); ++i) {
    const std::string& c = columns[i];
    const std::size_t dot = c.rfind('.');
    const std::string what = dot == std::string::npos ? c : c.substr(dot + 1);
    const std::string prefix = dot == std::string::npos ? c : c.substr(0, dot);
    // A device's commanded force: NAME.fx three columns after NAME.x (a coupling's couplingJ.fx is not).
    const bool device_force = (what == "fx" || what == "fy" || what == "fz") && i >= 3 &&
                              columns[i - 3] == prefix + "." + std::string(1, what[1]);
    row += device_force ? ",0" : ",nan";
  }
  row += '\n';
  std::FILE* f = std::fopen(path.c_str(), "r+b");
  if (f == nullptr) return fmt::format("{}: cannot open the trace to end it: {}", path, std::strerror(errno));
  // Back to the end of the last whole row: a writer killed in the middle of one leaves a part.
  std::setvbuf(f, nullptr, _IONBF, 0);
  off_t size = 0;
  if (std::fseek(f, 0, SEEK_END) == 0) size = ftello(f);
  std::vector<char> tail(static_cast<std::size_t>(std::min<off_t>(size, 1 << 16)));
  off_t end = size;
  if (!tail.empty() && fseeko(f, size - static_cast<off_t>(tail.size()), SEEK_SET) == 0 &&
      std::fread(tail.data(), 1, tail.size(), f) == tail.size()) {
    const void* nl = memrchr(tail.data(), '\n', tail.size());
    if (nl != nullptr) end = size - static_cast<off_t>(tail.size()) + (static_cast<const char*>(nl) - tail.data()) + 1;
  }
  const bool cut = end == size || ftruncate(fileno(f), end) == 0;
  const bool written = cut && fseeko(f, end, SEEK_SET) == 0 && std::fwrite(row.data(), 1, row.size(), f) == row.size();
  const int error = errno;
  const bool closed = std::fclose(f) == 0;
  if (!written || !closed) {
    return fmt::format("{}: the zero-force row could not be written: {}", path,
                       std::strerror(error != 0 ? error : (errno != 0 ? errno : EIO)));
  }
  return {};
}

}  // namespace

std::string end_trace(const std::string& path, const Verdict& v, const TelemetryFrame* last) {
  if (const std::vector<std::string> columns = header_columns(path);
      columns.size() > 2 && columns.front() == "t" && columns.back() == "held") {
    return end_world_trace(path, columns, v);
  }
  const std::size_t effect_values = header_effect_values(path);
  auto writer = TraceWriter::append_to(path, std::vector<std::string>(telemetry_extra_count(effect_values, true)));
  if (!writer) return writer.error();
  TelemetryFrame f = last != nullptr ? *last : TelemetryFrame{};
  const double period_s = f.tick > 0 ? f.t_s / static_cast<double>(f.tick) : 0.0;
  f.t_s = std::max(v.t_end_s, f.t_s);
  if (period_s > 0.0) f.tick = static_cast<std::int64_t>(std::llround(f.t_s / period_s));
  f.force_n = {};
  f.damping_n = {};
  f.gain = 0.0;
  f.timing = TickTiming{};
  // As wide as the header: values the frame did not fill (a death before the writer took one)
  // are NaN, "not known", as before the first tick that counted.
  for (std::size_t i = std::min<std::size_t>(f.value_count, f.values.size()); i < f.values.size(); ++i) {
    f.values[i] = std::nan("");
  }
  f.value_count = static_cast<std::uint16_t>(std::min<std::size_t>(effect_values, f.values.size()));
  if (!write_frame(*writer.value(), f, effect_values, true) || !writer.value()->close()) {
    return fmt::format("{}: the zero-force row could not be written: {}", path,
                       std::strerror(errno != 0 ? errno : EIO));
  }
  return {};
}

std::string describe_verdict(const Verdict& v, const TelemetryFrame* last) {
  std::string text = fmt::format("guardian: the loop's process (pid {}) ended {}, at t = {:.4f} s (tick {}): {}\n",
                                 v.loop_pid, v.loop_ended != 0 ? "after its loop" : "during the loop", v.t_end_s,
                                 std::max<std::int64_t>(0, v.ticks - 1), v.cause);
  if (v.zero_sent != 0) {
    const double after_ms = static_cast<double>(v.zero_ns - v.death_ns) * 1e-6;
    text += after_ms >= 0.0
                ? fmt::format("guardian: zero force commanded {:.3f} ms after its end: {}\n", after_ms, v.zero_detail)
                : fmt::format("guardian: zero force commanded at the stall, {:.3f} ms before its end: {}\n", -after_ms,
                              v.zero_detail);
  } else {
    text += fmt::format("guardian: {}\n", v.zero_detail);
  }
  if (last != nullptr) {
    const auto& f = last->force_n;
    text += fmt::format("guardian: its last frame taken: t = {:.4f} s, force ({:.3f}, {:.3f}, {:.3f}) N, "
                        "position ({:.4f}, {:.4f}, {:.4f}) m\n",
                        last->t_s, f.x, f.y, f.z, last->position_m.x, last->position_m.y, last->position_m.z);
  }
  return text;
}

std::string verdict_json(const Verdict& v, const TelemetryFrame* last) {
  std::string out = "{\n";
  out += fmt::format("  \"loop_process_died\": true,\n  \"loop_pid\": {},\n  \"cause\": {},\n", v.loop_pid,
                     json_string(v.cause));
  out += fmt::format("  \"loop_ended\": {},\n  \"stalled\": {},\n  \"ticks\": {},\n  \"t_end_s\": {},\n",
                     v.loop_ended != 0, v.stalled != 0, std::max<std::int64_t>(0, v.ticks), v.t_end_s);
  out += fmt::format("  \"zero_sent\": {},\n  \"zero_after_ms\": {},\n  \"zero\": {},\n", v.zero_sent != 0,
                     v.zero_sent != 0 ? static_cast<double>(v.zero_ns - v.death_ns) * 1e-6 : 0.0,
                     json_string(v.zero_detail));
  out += fmt::format("  \"death_monotonic_ns\": {},\n  \"zero_monotonic_ns\": {},\n", v.death_ns, v.zero_ns);
  const Vec3<double> f = last != nullptr ? last->force_n : Vec3<double>{};
  out += fmt::format("  \"last_frame\": {{\"t_s\": {}, \"force_n\": [{}, {}, {}]}}\n",
                     last != nullptr ? last->t_s : 0.0, f.x, f.y, f.z);
  out += "}\n";
  return out;
}

}  // namespace toonforce::guardian
