#include "toonforce/replay/replay.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <fmt/format.h>

#include "toonforce/replay/motion_csv.hpp"

namespace toonforce {
namespace {

struct FileCloser {
  void operator()(std::FILE* f) const noexcept {
    if (f != nullptr && f != stdout) std::fclose(f);
  }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

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

template <Scalar S>
Result<ReplaySummary> replay_as(const SceneDescription& description, const Motion& motion,
                                const ReplayOptions& options, std::FILE* out) {
  ReplaySummary summary;
  summary.scene_name = description.name;
  summary.surfaces = description.surfaces.size();
  summary.cliffs = description.cliffs.size();
  summary.rows = motion.rows.size();
  summary.duration_s = motion.rows.back().t_s - motion.rows.front().t_s;
  summary.given_velocity = motion.has_velocity;
  summary.ignored_columns = motion.ignored_columns;
  {
    std::vector<double> dts;
    for (std::size_t i = 1; i < motion.rows.size(); ++i) dts.push_back(motion.rows[i].t_s - motion.rows[i - 1].t_s);
    std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
    summary.median_rate_hz = 1.0 / dts[dts.size() / 2];
  }

  // Stamped time (period 0): dt and impact times come from the rows' t (spec §0).
  Controller<RuntimeScene<S>> controller(make_runtime_scene<S>(description, options.sine),
                                         controller_config(description, 0.0));
  fmt::print(out, "t,fx,fy,fz,faults,limits,scene_fx,scene_fy,scene_fz,contact,impact_t,cliff_state\n");
  int previous_cliff_state = -1;
  for (std::size_t k = 0; k < motion.rows.size(); ++k) {
    const MotionRow& row = motion.rows[k];
    Sample sample;
    sample.position_m = row.position_m;
    sample.velocity_m_per_s = row.velocity_m_per_s;
    sample.has_velocity = motion.has_velocity;
    sample.now = Instant{static_cast<std::int64_t>(k), row.t_s};
    // The first tick's dt is the recording's period (the reader guarantees two rows).
    sample.dt_s = k == 0 ? motion.rows[1].t_s - row.t_s : row.t_s - motion.rows[k - 1].t_s;

    const TickResult<S> r = controller.tick(sample);
    const Vec3<double> f = to_double(r.force_n);
    const Vec3<double> scene = to_double(r.scene_force_n);
    fmt::print(out, "{},{},{},{},{},{},{},{},{}", row.t_s, f.x, f.y, f.z, r.faults.bits(), r.limits, scene.x,
               scene.y, scene.z);
    if (r.faults.has(Fault::kNonFiniteInput) || r.faults.has(Fault::kNonFiniteForce)) {
      fmt::print(out, ",,,\n");  // effect states did not advance on this tick: nothing to report
    } else {
      const Diagnostics d = controller.diagnostics();
      fmt::print(out, ",{},{},{}\n", d.in_contact ? 1 : 0, d.impact_time_s, d.cliff_state);
      if (d.in_contact) ++summary.ticks_in_contact;
      if (d.impact_time_s == 0.0) ++summary.impacts;
      if (d.cliff_state == 1 && previous_cliff_state == 0) ++summary.cliff_falls;
      previous_cliff_state = d.cliff_state;
    }
    const double magnitude = std::sqrt(dot(f, f));
    if (magnitude > summary.peak_force_n) {
      summary.peak_force_n = magnitude;
      summary.peak_force_t_s = row.t_s;
    }
    summary.peak_scene_force_n = std::max(summary.peak_scene_force_n, std::sqrt(dot(scene, scene)));
    if ((r.limits & static_cast<std::uint8_t>(Limit::kRateLimited)) != 0) ++summary.rate_limited;
    if ((r.limits & static_cast<std::uint8_t>(Limit::kClamped)) != 0) ++summary.clamped;
    if (r.faults) ++summary.fault_ticks;
    summary.fault_bits |= r.faults.bits();
  }
  if (std::ferror(out) != 0) return Error{fmt::format("{}: write failed", options.output_path)};
  return summary;
}

}  // namespace

Result<ReplaySummary> run_replay(const ReplayOptions& options) {
  auto scene = load_scene_file(options.scene_path, options.scalar);
  if (!scene) return Error{scene.error()};
  if (options.sine == SineMethod::kLibrary && options.scalar == ScalarKind::kQ16_16) {
    return Error{"--sine library needs a floating-point scalar; use polynomial or table with q16.16"};
  }
  auto motion = read_motion_csv(options.input_path);
  if (!motion) return Error{motion.error()};

  File out(options.output_path == "-" ? stdout : std::fopen(options.output_path.c_str(), "wb"));
  if (!out) return Error{fmt::format("{}: cannot open for writing", options.output_path)};
  Result<ReplaySummary> summary = Error{""};
  switch (options.scalar) {
    case ScalarKind::kDouble: summary = replay_as<double>(scene.value(), motion.value(), options, out.get()); break;
    case ScalarKind::kFloat: summary = replay_as<float>(scene.value(), motion.value(), options, out.get()); break;
    case ScalarKind::kQ16_16: summary = replay_as<Q16_16>(scene.value(), motion.value(), options, out.get()); break;
  }
  if (std::fflush(out.get()) != 0) return Error{fmt::format("{}: write failed", options.output_path)};
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
    for (const auto& c : s.ignored_columns) names += (names.empty() ? "" : ",") + c;
    text += fmt::format("note    ignored input columns: {}\n", names);
  }
  text += fmt::format("forces  peak {:.4g} N at t = {:.6g} s (scene peak before safety {:.4g} N); in contact {} ticks\n",
                      s.peak_force_n, s.peak_force_t_s, s.peak_scene_force_n, s.ticks_in_contact);
  text += fmt::format("effects impacts triggered {}; cliff falls {}\n", s.impacts, s.cliff_falls);
  text += fmt::format("safety  rate-limited {} ticks, clamped {} ticks, faults {} ticks{}\n", s.rate_limited,
                      s.clamped, s.fault_ticks,
                      s.fault_bits != 0 ? fmt::format(" ({})", describe_faults(s.fault_bits)) : std::string());
  if (options.output_path != "-") text += fmt::format("output  {}\n", options.output_path);
  return text;
}

}  // namespace toonforce
