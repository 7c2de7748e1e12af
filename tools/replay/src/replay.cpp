// SPDX-License-Identifier: Apache-2.0
#include "toonforce/replay/replay.hpp"

#include "toonforce/config/toml_reader.hpp"

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <limits>
#include <utility>
#include <memory>

#include <fmt/format.h>

#include "toonforce/control/servo_loop.hpp"
#include "toonforce/replay/motion_csv.hpp"
#include "toonforce/trace/telemetry_trace.hpp"

namespace toonforce {
namespace {

struct FileCloser {
  void operator()(std::FILE* f) const noexcept {
    if (f != nullptr && f != stdout) std::fclose(f);
  }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

/// Whole rows to the output; the first write error is reported at once on standard error, and
/// nothing more is written (the forces never depend on the output: the run goes on).
struct RowWriter {
  std::FILE* out;
  const std::string& path;
  std::string& error;
  std::string row;
  void end_row() {
    if (error.empty() && (std::fwrite(row.data(), 1, row.size(), out) != row.size() || std::ferror(out) != 0)) fail();
    row.clear();
  }
  void fail() {
    error = fmt::format("{}: writing failed: {}; nothing more is written, the replay goes on", path,
                        std::strerror(errno != 0 ? errno : EIO));
    std::fputs(("toonforce: " + error + "\n").c_str(), stderr);
  }
};

std::string describe_faults(std::uint32_t bits) {
  std::string out;
  const auto add = [&](Fault f, std::string_view name) {
    if ((bits & static_cast<std::uint32_t>(f)) != 0) out += fmt::format("{}{}", out.empty() ? "" : ", ", name);
  };
  add(Fault::kNonFiniteInput, "non-finite input");
  add(Fault::kNonFiniteForce, "non-finite scene force");
  add(Fault::kFixedSaturation, "fixed-point saturation");
  return out;
}

/// The motion as a device: each tick reads the current row (its position, and its velocity when
/// the file gives one); what the loop writes is the row's force.
struct MotionDevice {
  const Motion* motion;
  const std::size_t* row;
  DeviceStatus read(DeviceReading& reading) noexcept {
    const MotionRow& r = motion->rows[*row];
    reading.position_m = r.position_m;
    reading.velocity_m_per_s = r.velocity_m_per_s;
    reading.has_velocity = motion->has_velocity;
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<double>&) noexcept { return DeviceStatus::kOk; }
};

template <Scalar S>
Result<ReplaySummary> replay_as(const SceneDescription& description, const Motion& motion, const ReplayOptions& options,
                                std::FILE* out) {
  ReplaySummary summary;
  summary.scene_name = description.name;
  summary.surfaces = description.of<RuntimeSurface>().size();
  summary.cliffs = description.of<CartoonCliff>().size();
  summary.rows = motion.rows.size();
  summary.duration_s = motion.rows.back().t_s - motion.rows.front().t_s;
  summary.given_velocity = motion.has_velocity;
  summary.ignored_columns = motion.ignored_columns;
  summary.input_note = motion.note;
  {
    std::vector<double> dts;
    for (std::size_t i = 1; i < motion.rows.size(); ++i) dts.push_back(motion.rows[i].t_s - motion.rows[i - 1].t_s);
    std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
    summary.median_rate_hz = 1.0 / dts[dts.size() / 2];
  }

  // The servo loop with only the stages of effects.md §6, in the rows' stamped time: dt and
  // impact times come from the rows' t (spec §0); the first tick's dt is the recording's period
  // (the reader guarantees two rows).
  const RuntimeScene<S> scene = make_runtime_scene<S>(description);
  const std::vector<std::string> names = effect_value_names(scene);
  const SummaryColumns columns = SummaryColumns::of(names);
  std::size_t row = 0;
  ServoLoop<MotionDevice, RuntimeScene<S>, NullPins, kSpecStages> loop(
      MotionDevice{&motion, &row}, scene,
      replay_config(description, static_cast<double>(motion.rows[1].t_ns - motion.rows[0].t_ns) / 1e9));
  std::string header = "t,fx,fy,fz,faults,limits,scene_fx,scene_fy,scene_fz,contact";
  for (const std::string& n : names) header += "," + n;
  RowWriter w{out, options.output_path, summary.output_error, {}};
  if (out != nullptr) {
    fmt::format_to(std::back_inserter(w.row), "{}\n", header);
    w.end_row();
  }
  std::vector<double> values(names.size());
  // The caller's numbers: the row's fields as the file has them, NaN for the empty ones.
  std::vector<double> numbers;
  if (options.rows != nullptr) {
    std::vector<std::string> columns_named{"t",      "fx",       "fy",       "fz",       "faults",
                                           "limits", "scene_fx", "scene_fy", "scene_fz", "contact"};
    columns_named.insert(columns_named.end(), names.begin(), names.end());
    numbers.reserve(columns_named.size());
    options.rows->begin(columns_named, motion.rows.size());
  }
  std::vector<double> previous_cliff(columns.cliff_states.size(), 0.0);
  for (; row < motion.rows.size(); ++row) {
    if (options.stop != nullptr && options.stop->load(std::memory_order_relaxed) != 0) {
      summary.stop_signal = options.stop->load();
      break;
    }
    const MotionRow& r = motion.rows[row];
    const TickStatus status = loop.tick(Instant{static_cast<std::int64_t>(row), r.t_ns});
    const Vec3<double> f = to_double(loop.force());
    const bool counted = !status.faults.has(Fault::kNonFiniteInput) && !status.faults.has(Fault::kNonFiniteForce);
    const Vec3<double> scene_f = counted ? to_double(loop.scene_force()) : Vec3<double>{};
    if (out != nullptr) {
      fmt::format_to(std::back_inserter(w.row), "{},{},{},{},{},{},{},{},{}", r.t_s, f.x, f.y, f.z,
                     status.faults.bits(), status.limits, scene_f.x, scene_f.y, scene_f.z);
    }
    if (options.rows != nullptr) {
      numbers.assign({r.t_s, f.x, f.y, f.z, static_cast<double>(status.faults.bits()),
                      static_cast<double>(status.limits), scene_f.x, scene_f.y, scene_f.z});
    }
    if (!counted) {
      // effect states did not advance: nothing to report
      if (out != nullptr) fmt::format_to(std::back_inserter(w.row), ",{:,>{}}\n", "", names.size());
      if (options.rows != nullptr) {
        numbers.resize(numbers.size() + 1 + names.size(), std::numeric_limits<double>::quiet_NaN());
        options.rows->row(numbers);
      }
    } else {
      const bool contact = loop.describe(values.data());
      if (out != nullptr) {
        fmt::format_to(std::back_inserter(w.row), ",{}", contact ? 1 : 0);
        for (const double v : values) fmt::format_to(std::back_inserter(w.row), ",{}", v);
        w.row += '\n';
      }
      if (options.rows != nullptr) {
        numbers.push_back(contact ? 1.0 : 0.0);
        numbers.insert(numbers.end(), values.begin(), values.end());
        options.rows->row(numbers);
      }
      if (contact) ++summary.ticks_in_contact;
      for (const std::size_t i : columns.impact_times) summary.impacts += values[i] == 0.0 ? 1U : 0U;
      for (std::size_t c = 0; c < columns.cliff_states.size(); ++c) {
        const double state = values[columns.cliff_states[c]];
        if (state == 1.0 && previous_cliff[c] == 0.0) ++summary.cliff_falls;
        previous_cliff[c] = state;
      }
    }
    if (out != nullptr) w.end_row();
    const double magnitude = std::sqrt(dot(f, f));
    if (magnitude > summary.peak_force_n) {
      summary.peak_force_n = magnitude;
      summary.peak_force_t_s = r.t_s;
    }
    summary.peak_scene_force_n = std::max(summary.peak_scene_force_n, std::sqrt(dot(scene_f, scene_f)));
    if ((status.limits & static_cast<std::uint8_t>(Limit::kRateLimited)) != 0) ++summary.rate_limited;
    if ((status.limits & static_cast<std::uint8_t>(Limit::kClamped)) != 0) ++summary.clamped;
    if (status.faults) ++summary.fault_ticks;
    summary.fault_bits |= status.faults.bits();
  }
  summary.rows_done = row;
  if (out != nullptr && summary.output_error.empty() && std::fflush(out) != 0) w.fail();
  return summary;
}

/// Same file (or both standard output)?
bool same_file(const std::string& a, const std::string& b) {
  if (a == "-" || b == "-") return a == b;
  std::error_code ec;
  return std::filesystem::equivalent(a, b, ec) && !ec;
}

}  // namespace

Result<ReplaySummary> run_replay(const ReplayOptions& options) {
  auto scene = options.scene_text ? parse_scene(*options.scene_text, options.scene_path, options.scalar)
                                  : load_scene_file(options.scene_path, options.scalar);
  if (!scene) return Error{scene.error()};
  if (std::string empty = empty_scene_problem(scene.value(), options.scene_path);
      !empty.empty() && !options.allow_empty) {
    return Error{std::move(empty)};
  }
  if (options.sine == SineMethod::kLibrary && options.scalar == ScalarKind::kQ16_16) {
    return Error{"--sine library needs a floating-point scalar; use polynomial or table with q16.16"};
  }
  // Before anything is opened for writing: an output must never replace an input.
  for (const auto& [input, what] :
       {std::pair{options.scene_path, "the scene"}, std::pair{options.input_path, "the motion"}}) {
    if (!options.output_path.empty() && same_file(options.output_path, input)) {
      return Error{fmt::format("--output {} is {} ({}): it would be overwritten; choose another file",
                               options.output_path, what, input)};
    }
  }
  auto motion = options.input_text ? parse_motion_csv(*options.input_text, options.input_path)
                                   : read_motion_csv(options.input_path);
  if (!motion) return Error{motion.error()};
  // The rows' stamps are replay's rate: each 1/dt must pass the Q16.16 rate rule (a gap after a
  // skipped row only lowers the rate the loop sees, hip_sensor.hpp). The rule applies to the
  // recording's rate, not to the rounding of t to whole ns: each stamp moved by up to 0.5 ns, so
  // a gap of n ns was recorded as at most n + 1 ns, and 1e9 / (n + 1) is the rate checked. A
  // recording at exactly 32767 Hz (30518.5 ns) has gaps of 30518 ns: the loop then holds
  // 1e9 / 30518 = 32767.55 Hz, still below Q16.16's largest value (32767.99998), and the rules
  // for products keep a whole unit of headroom besides (scene_file.hpp kMaxProduct).
  for (std::size_t i = 1; i < motion->rows.size(); ++i) {
    const std::int64_t dt_ns = motion->rows[i].t_ns - motion->rows[i - 1].t_ns;
    const double recorded_rate_hz = 1e9 / static_cast<double>(dt_ns + 1);
    if (const std::string bad = fixed_point::check_rate(recorded_rate_hz, options.scalar, scene.value());
        !bad.empty()) {
      return Error{fmt::format("{}:{}: t: {} ns after the previous row (t rounded to whole ns, so at least {} ns "
                               "as recorded), a servo rate of {}\n",
                               options.input_path, motion->rows[i].line, dt_ns, dt_ns + 1, bad)};
    }
  }

  // No output file when the rows go only to the caller's sink (empty output_path).
  File out(options.output_path.empty()  ? nullptr
           : options.output_path == "-" ? stdout
                                        : std::fopen(options.output_path.c_str(), "wb"));
  if (!out && !options.output_path.empty())
    return Error{fmt::format("{}: cannot open for writing: {}", options.output_path, std::strerror(errno))};
  if (options.sine) override_sine(scene.value(), *options.sine);
  Result<ReplaySummary> summary = with_scalar(
      options.scalar, [&]<Scalar S>() { return replay_as<S>(scene.value(), motion.value(), options, out.get()); },
      [](ScalarKind kind) -> Result<ReplaySummary> {
        return Error{fmt::format("--scalar {}: this build has no replay for it", scalar_kind_name(kind))};
      });
  if (summary && summary->output_error.empty() && out && out.get() != stdout && std::fclose(out.release()) != 0) {
    summary->output_error = fmt::format("{}: closing failed: {}", options.output_path, std::strerror(errno));
  }
  return summary;
}

std::string format_summary(const ReplaySummary& s, const ReplayOptions& options) {
  std::string text;
  text += fmt::format("scene   {} ({}): {} surface(s), {} cliff(s); scalar {}\n", s.scene_name, options.scene_path,
                      s.surfaces, s.cliffs, scalar_kind_name(options.scalar));
  text += fmt::format("motion  {}: {} ticks over {:.6g} s (median rate {:.6g} Hz), velocity {}\n", options.input_path,
                      s.rows, s.duration_s, s.median_rate_hz, s.given_velocity ? "given" : "estimated");
  if (!s.ignored_columns.empty()) {
    std::string names;
    for (const auto& c : s.ignored_columns) {
      if (!names.empty()) names += ',';
      names += printable(c);  // a header's text, escaped and cut like a scene's
    }
    text += fmt::format("note    ignored input columns: {}\n", names);
  }
  text +=
      fmt::format("forces  peak {:.4g} N at t = {:.6g} s (scene peak before safety {:.4g} N); in contact {} ticks\n",
                  s.peak_force_n, s.peak_force_t_s, s.peak_scene_force_n, s.ticks_in_contact);
  text += fmt::format("effects impacts triggered {}; cliff falls {}\n", s.impacts, s.cliff_falls);
  text += fmt::format("safety  rate-limited {} ticks, clamped {} ticks, faults {} ticks{}\n", s.rate_limited, s.clamped,
                      s.fault_ticks,
                      s.fault_bits != 0 ? fmt::format(" ({})", describe_faults(s.fault_bits)) : std::string());
  if (options.output_path != "-") text += fmt::format("output  {}\n", options.output_path);
  return text;
}

}  // namespace toonforce
