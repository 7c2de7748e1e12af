// SPDX-License-Identifier: Apache-2.0
// toonforce_mcu_gen: the host half of the microcontroller images (tools/mcu/README.md).
//
//   toonforce_mcu_gen generate --out-dir DIR [--scalar q16.16|float] [--sine METHOD]
//                              --scene NAME=SCENE.toml ... --motion NAME=MOTION.csv ...
//     Writes DIR/image.hpp (each scene as a compile-time Scene<...> type with its parameters
//     and controller settings as constants) and DIR/motions.cpp (each motion's rows as data in
//     the image's .motion section). It reads the files with the very functions `toonforce
//     replay` uses (load_scene_file, make_runtime_scene, controller_config, read_motion_csv),
//     so the image starts from the same numbers bit for bit: parameters are printed as raw
//     Q16.16 integers or hexadecimal float literals, never as rounded decimals.
//
//   toonforce_mcu_gen strikes --out-dir DIR --count N --scene NAME...
//     Writes the searched inputs of `toonforce-lab report` (tools/report/src/workloads.cpp,
//     search_path: a constructed strike, then seeded random ones, each for a fresh loop) of
//     each paper scene NAME as motion files DIR/search_NAME_K.csv, one per strike, for the
//     images to play and replay to compare: the searched inputs run on the target too. Besides,
//     DIR/search_NAME_K_late.csv: each strike with late ticks (rows left out).
//
//   toonforce_mcu_gen compare [--scalar q16.16|float] --target TARGET.txt --host SCENE/MOTION=REPLAY.csv ...
//     Compares the forces an image wrote (raw Q16.16 integers, or a float's bits) with
//     `toonforce replay --scalar q16.16` (or float) of the same scene and motion, row by row,
//     bit for bit (force, fault and limit bits). Exit 0 when every pair matches.
//
//   toonforce_mcu_gen figures --size IMAGE=SIZE_A.txt ... --run SCENE=TARGET.txt ...
//     The Markdown tables of docs/performance/mcu.md's generated block: each image's
//     sizes (from `arm-none-eabi-size -A`) and each scene's instructions per tick, stack and
//     state (from an image's output).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <optional>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <fmt/format.h>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/replay/motion_csv.hpp"
#include "toonforce/report/stage_configs.hpp"
#include "toonforce/report/workloads.hpp"

namespace toonforce::mcu {
namespace {

struct Named {
  std::string name;
  std::string path;
};

bool split_named(std::string_view arg, Named& out) {
  const auto eq = arg.find('=');
  if (eq == std::string_view::npos || eq == 0 || eq + 1 == arg.size()) return false;
  out.name = std::string(arg.substr(0, eq));
  out.path = std::string(arg.substr(eq + 1));
  return true;
}

/// A C++ identifier from a scene or motion name ("cartoon_wall" -> "CartoonWall").
std::string camel(std::string_view name) {
  std::string out;
  bool up = true;
  for (const char c : name) {
    if (c == '_' || c == '-' || c == ' ') {
      up = true;
      continue;
    }
    out += up ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
    up = false;
  }
  return out;
}

// ---- literals that reproduce a value exactly -----------------------------------------------

std::string lit(double v) {
  if (std::isnan(v)) return "__builtin_nan(\"\")";
  if (std::isinf(v)) return v > 0 ? "__builtin_inf()" : "-__builtin_inf()";
  return fmt::format("{:a}", v);  // hexadecimal: exact
}
std::string lit(float v) { return fmt::format("{:a}F", v); }
std::string lit(Q16_16 v) { return fmt::format("S::from_raw({})", v.raw()); }

template <class S>
std::string lit(const Vec3<S>& v) {
  return fmt::format("Vec3<{}>{{{}, {}, {}}}", std::is_same_v<S, double> ? "double" : "S", lit(v.x), lit(v.y),
                     lit(v.z));
}
template <class S>
std::string lit(const Plane<S>& p) {
  return fmt::format("Plane<S>{{{}, {}}}", lit(p.point_m), lit(p.normal));
}

/// A Q-format plane whose normal is exactly a coordinate axis (raw +-1 there, 0 elsewhere):
/// its AxisPlane<S, axis, sign> type, which computes bit for bit what Plane does with fewer
/// products (effects/tick.hpp); otherwise nothing, and the scene keeps Plane<S>. Floating
/// point always keeps Plane.
template <class S>
std::optional<std::string> axis_plane_type(const Plane<S>& p) {
  if constexpr (!kIsFixed<S>) {
    return std::nullopt;
  } else {
    const std::int32_t c[3] = {p.normal.x.raw(), p.normal.y.raw(), p.normal.z.raw()};
    for (int axis = 0; axis < 3; ++axis) {
      const bool unit = c[axis] == S::kOneRaw || c[axis] == -S::kOneRaw;
      if (unit && c[(axis + 1) % 3] == 0 && c[(axis + 2) % 3] == 0) {
        return fmt::format("AxisPlane<S, {}, {}>", axis, c[axis] > 0 ? 1 : -1);
      }
    }
    return std::nullopt;
  }
}

std::string_view sine_name(SineMethod m) {
  switch (m) {
    case SineMethod::kLibrary: return "SineMethod::kLibrary";
    case SineMethod::kPolynomial: return "SineMethod::kPolynomial";
    case SineMethod::kTable: return "SineMethod::kTable";
    case SineMethod::kAuto: return "SineMethod::kAuto";
  }
  return "?";
}

/// A ServoConfig's settings as the statements of a constexpr function's body, exactly (the
/// period and time base excepted: the image sets them).
std::string settings_of(const ServoConfig& config) {
  const auto& l = config.limits;
  const auto& f = config.safety;
  return fmt::format("    ServoConfig c;\n"
                     "    c.limits = ForceLimits{{{}, {}, {}, {}}};\n"
                     "    c.velocity_cutoff_hz = {};\n"
                     "    c.safety.engage_force_n = {};\n"
                     "    c.safety.soft_start_s = {};\n"
                     "    c.safety.has_max_velocity = {};\n"
                     "    c.safety.max_velocity_m_per_s = {};\n"
                     "    c.safety.has_workspace = {};\n"
                     "    c.safety.workspace_min_m = {};\n"
                     "    c.safety.workspace_max_m = {};\n"
                     "    c.safety.watchdog_periods = {};\n"
                     "    c.safety.device_timeout_periods = {};\n"
                     "    c.safety.thermal = ThermalConfig{{{}, {}, {}}};\n"
                     "    c.safety.passivity = PassivityConfig{{{}, {}, {}}};\n",
                     lit(l.max_force_n), lit(l.max_force_rate_n_per_s), l.has_max_force, l.has_max_force_rate,
                     lit(config.velocity_cutoff_hz), lit(f.engage_force_n), lit(f.soft_start_s), f.has_max_velocity,
                     lit(f.max_velocity_m_per_s), f.has_workspace, lit(f.workspace_min_m), lit(f.workspace_max_m),
                     f.watchdog_periods, f.device_timeout_periods, lit(f.thermal.continuous_force_n),
                     lit(f.thermal.time_constant_s), lit(f.thermal.derate_start), f.passivity.controller,
                     lit(f.passivity.budget_j), lit(f.passivity.max_damping_n_s_per_m));
}

/// One scene as a compile-time type and its constructor arguments, from the run-time scene
/// replay builds from the same file: same parameters, and each surface gets only the laws the
/// file gives it (a wall without damping is a SpringWall; no tangential law, no impact: none),
/// which is what makes a scene's image carry only its effects.
// It writes each built-in kind (effects/builtin.hpp) as itself: a kind added there fails here
// until it is written too.
static_assert(SceneDescription::kKinds == 2 && std::is_same_v<SceneDescription::Kind<0>, RuntimeSurface<double>> &&
                  std::is_same_v<SceneDescription::Kind<1>, CartoonCliff<double>>,
              "a new built-in effect kind: write its compiled type in scene_struct");
template <class S>
std::string scene_struct(const std::string& name, const SceneDescription& d, const ServoConfig& config,
                         const ServoConfig& every_config) {
  std::vector<std::string> types;
  std::vector<std::string> args;
  for (const SceneEntry& entry : d.order) {
    if (entry.kind == 0) {  // a surface
      const auto p = schema::convert_params<RuntimeSurface<double>, RuntimeSurface<S>>(d.all<0>()[entry.index]);
      const bool damped = p.wall.damping_n_s_per_m != S{};
      const std::string wall = damped ? "PenaltyWall<S>" : "SpringWall<S>";
      std::string tangential = "NoTangential<S>";
      std::string tangential_arg = "{}";
      switch (p.tangential.kind) {
        case TangentialKind::kNone: break;
        case TangentialKind::kFriction:
          tangential = "RealisticFriction<S>";
          tangential_arg =
              fmt::format("{{{}, {}, {}}}", lit(p.tangential.friction.viscous_n_s_per_m),
                          lit(p.tangential.friction.coulomb), lit(p.tangential.friction.regularization_speed_m_per_s));
          break;
        case TangentialKind::kSlippery:
          tangential = "SuperSlippery<S>";
          tangential_arg = fmt::format("{{{}, {}}}", lit(p.tangential.slippery.mu_n_s_per_m),
                                       lit(p.tangential.slippery.max_tangential_force_n));
          break;
      }
      std::string impact = "NoImpact<S>";
      std::string impact_arg = "{}";
      if (p.impact.enabled) {
        const auto& i = p.impact.law;
        impact = "ImpactTransient<S>";
        impact_arg = fmt::format("{{{}, {}, {}, {}, {}, {}, {}}}", lit(i.recoil_gain_n_per_m),
                                 lit(i.oscillation_gain_n_per_m), lit(i.duration_s), lit(i.frequency_hz),
                                 lit(i.min_impact_speed_m_per_s), lit(i.rearm_distance_m), sine_name(i.sine));
      }
      // A plane along an axis gets the type that multiplies by it for free (axis_plane_type).
      const std::optional<std::string> axis_plane = axis_plane_type(p.plane);
      const std::string plane = axis_plane ? fmt::format("{}{{{}}}", *axis_plane, lit(p.plane.point_m)) : lit(p.plane);
      types.push_back(axis_plane ? fmt::format("Surface<{}, {}, {}, {}>", wall, tangential, impact, *axis_plane)
                                 : fmt::format("Surface<{}, {}, {}>", wall, tangential, impact));
      args.push_back(fmt::format("{{{}, {{{}, {}}}, {}, {}}}", plane, lit(p.wall.stiffness_n_per_m),
                                 lit(p.wall.damping_n_s_per_m), tangential_arg, impact_arg));
    } else {  // a cliff
      const auto c = schema::convert_params<CartoonCliff<double>, CartoonCliff<S>>(d.all<1>()[entry.index]);
      types.push_back("CartoonCliff<S>");
      args.push_back(fmt::format("{{{}, {}, {}, {}, {{{}, {}}}, {}, {}, {}, {}}}", lit(c.ground), lit(c.axis),
                                 lit(c.gap_min_m), lit(c.gap_max_m), lit(c.wall.stiffness_n_per_m),
                                 lit(c.wall.damping_n_s_per_m), lit(c.speed_threshold_m_per_s), lit(c.tau_s),
                                 lit(c.rearm_height_m), lit(c.fall_force_n)));
    }
  }
  std::string type_list;
  std::string arg_list;
  for (std::size_t i = 0; i < types.size(); ++i) {
    type_list += (i ? ",\n                    " : "") + types[i];
    arg_list += (i ? ",\n        " : "") + args[i];
  }
  // The scene's servo settings (servo_config of the file, every [device] key), exactly; the
  // image sets the period and the time base (stamps for the replay comparison).
  const std::string settings = settings_of(config);
  // The every-stage loop's: the same with every stage acting (report::search_config), so
  // that what the image counts of that loop reaches each stage's expensive branch.
  const std::string every = settings_of(every_config);
  return fmt::format("/// {} ({})\n"
                     "struct {}Scene {{\n"
                     "  static constexpr char kName[] = \"{}\";\n"
                     "  using Type = Scene<{}>;\n"
                     "  static constexpr Type make() noexcept {{\n"
                     "    return Type(\n"
                     "        {});\n"
                     "  }}\n"
                     "  static constexpr ServoConfig config(double period_s, bool time_from_stamps) noexcept {{\n"
                     "{}"
                     "    c.period_s = period_s;\n"
                     "    c.time_from_stamps = time_from_stamps;\n"
                     "    return c;\n"
                     "  }}\n"
                     "  /// The every-stage loop's settings: every stage acting (toonforce/report/stage_configs.hpp).\n"
                     "  static constexpr ServoConfig every_config(double period_s) noexcept {{\n"
                     "{}"
                     "    c.period_s = period_s;\n"
                     "    return c;\n"
                     "  }}\n"
                     "}};\n\n",
                     d.name, d.source, camel(name), name, type_list, arg_list, settings, every);
}

/// Writes `text` to `path` only when it differs, so a rebuild that changes nothing recompiles
/// nothing.
bool write_if_changed(const std::string& path, const std::string& text) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream old;
  old << in.rdbuf();
  if (in && old.str() == text) return true;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  return static_cast<bool>(out);
}

int generate(const std::string& out_dir, ScalarKind scalar, std::optional<SineMethod> sine,
             const std::vector<Named>& scenes, const std::vector<Named>& motions) {
  std::string header = "// Generated by toonforce_mcu_gen from the scene and motion files named below; do not edit.\n"
                       "#pragma once\n#include \"mcu_types.hpp\"\n\nnamespace toonforce::mcu::image {\n\n";
  header += fmt::format("using S = {};\n\n", scalar == ScalarKind::kQ16_16 ? "Q16_16" : "float");
  std::string scene_names;
  for (const auto& s : scenes) {
    auto d = load_scene_file(s.path, scalar);
    if (!d) {
      std::fprintf(stderr, "toonforce_mcu_gen: %s\n", d.error().c_str());
      return 1;
    }
    if (sine) override_sine(d.value(), *sine);                // as `toonforce replay --sine` does
    const ServoConfig config = servo_config(d.value(), 1.0);  // the period is the image's
    const ServoConfig every = report::search_config(d.value(), 1.0);
    if (scalar == ScalarKind::kQ16_16) {
      header += scene_struct<Q16_16>(s.name, d.value(), config, every);
    } else {
      header += scene_struct<float>(s.name, d.value(), config, every);
    }
    scene_names += (scene_names.empty() ? "" : ", ") + camel(s.name) + "Scene";
  }
  header += fmt::format("using Scenes = SceneList<{}>;\n\n", scene_names);

  std::string source = "// Generated by toonforce_mcu_gen from the motion files named below; do not edit.\n"
                       "#include \"image.hpp\"\n\nnamespace toonforce::mcu::image {\nnamespace {\n\n";
  // Each motion as the device on the target reads it: already in the image's scalar, converted
  // here exactly as replay's loop converts a double reading (scalar_cast), so no tick on the
  // target converts through floating point; stamps in whole nanoseconds, as replay takes them.
  std::string table;
  std::optional<std::int64_t> period_ns;  // the first dt, which every motion must share
  for (const auto& m : motions) {
    auto motion = read_motion_csv(m.path);
    if (!motion) {
      std::fprintf(stderr, "toonforce_mcu_gen: %s\n", motion.error().c_str());
      return 1;
    }
    const auto& rows = motion->rows;
    const std::int64_t first_dt_ns = rows[1].t_ns - rows[0].t_ns;
    if (period_ns && *period_ns != first_dt_ns) {
      std::fprintf(stderr,
                   "toonforce_mcu_gen: %s: its first dt is %lld ns, another motion's %lld ns; an image's "
                   "motions share one (its loops are built at compile time)\n",
                   m.path.c_str(), static_cast<long long>(first_dt_ns), static_cast<long long>(*period_ns));
      return 1;
    }
    period_ns = first_dt_ns;
    const auto as_scalar = [&](const Vec3<double>& v, std::size_t line) -> std::optional<std::string> {
      if (!is_finite(v)) {  // replay flags such a row; a device in Q16.16 or float has no NaN to say it
        std::fprintf(stderr,
                     "toonforce_mcu_gen: %s:%zu: a non-finite position or velocity cannot be linked into "
                     "an image (its device reads in the loop's scalar)\n",
                     m.path.c_str(), line);
        return std::nullopt;
      }
      if (scalar == ScalarKind::kQ16_16) return lit(vec_cast<Q16_16>(v));
      return lit(vec_cast<float>(v));
    };
    const std::string id = camel(m.name);
    source += fmt::format("// {}: {} rows\n[[gnu::section(\".motion\")]] constexpr MotionRow k{}Rows[] = {{\n", m.path,
                          rows.size(), id);
    for (const auto& r : rows) {
      const auto position = as_scalar(r.position_m, r.line);
      if (!position) return 1;
      source += fmt::format("    {{{}, {}}},\n", r.t_ns, *position);
    }
    source += "};\n";
    std::string velocity = "nullptr";
    if (motion->has_velocity) {
      source += fmt::format("[[gnu::section(\".motion\")]] constexpr Vec3<S> k{}Velocity[] = {{\n", id);
      for (const auto& r : rows) {
        const auto v = as_scalar(r.velocity_m_per_s, r.line);
        if (!v) return 1;
        source += fmt::format("    {},\n", *v);
      }
      source += "};\n";
      velocity = fmt::format("k{}Velocity", id);
    }
    source += "\n";
    table += fmt::format("    Motion{{\"{}\", k{}Rows, {}, {}}},\n", m.name, id, velocity, rows.size());
  }
  // The first tick's dt, as replay computes it from the first two stamps (replay_config).
  header += fmt::format("using MotionRow = MotionRowOf<S>;\nusing Motion = MotionOf<S>;\n"
                        "/// [s] every motion's first dt (rows 1 and 0), the spec loop's period\n"
                        "inline constexpr double kMotionPeriodS = {};\n\n",
                        lit(static_cast<double>(period_ns.value_or(0)) / static_cast<double>(kNsPerS)));
  source += "}  // namespace\n\n";
  source += fmt::format("const Motion kMotions[] = {{\n{}}};\nconst std::size_t kMotionCount = {};\n\n", table,
                        motions.size());
  source += "}  // namespace toonforce::mcu::image\n";
  header += "extern const Motion kMotions[];\nextern const std::size_t kMotionCount;\n\n";
  header += "}  // namespace toonforce::mcu::image\n";

  if (!write_if_changed(out_dir + "/image.hpp", header) || !write_if_changed(out_dir + "/motions.cpp", source)) {
    std::fprintf(stderr, "toonforce_mcu_gen: cannot write into %s\n", out_dir.c_str());
    return 1;
  }
  return 0;
}

// ---- compare --------------------------------------------------------------------------------

struct Row {
  std::int64_t f[3] = {};
  std::uint32_t faults = 0;
  std::uint32_t limits = 0;
};

/// The raw value of a force printed by replay, as the image prints it: fmt prints the shortest
/// decimal that reads back as the same double, and a Q16.16 value as a double is raw / 2^16
/// exactly, a float value exactly the float (whose bits the image prints).
ScalarKind g_scalar = ScalarKind::kQ16_16;
bool raw_of(const std::string& field, std::int64_t& raw) {
  char* end = nullptr;
  const double v = std::strtod(field.c_str(), &end);
  if (end == field.c_str() || *end != '\0') return false;
  if (g_scalar == ScalarKind::kFloat) {
    const auto f = static_cast<float>(v);
    if (static_cast<double>(f) != v && v == v) return false;  // not a float value at all
    std::uint32_t bits = 0;
    std::memcpy(&bits, &f, sizeof bits);
    raw = bits;
    return true;
  }
  const double scaled = v * 65536.0;
  if (scaled != std::floor(scaled)) return false;  // not a Q16.16 value at all
  raw = static_cast<std::int64_t>(scaled);
  return true;
}

std::vector<std::string> fields_of(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, ',')) fields.push_back(field);
  if (!line.empty() && line.back() == ',') fields.emplace_back();
  return fields;
}

bool read_replay(const std::string& path, std::vector<Row>& rows, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open";
    return false;
  }
  std::string line;
  std::getline(in, line);  // header: t,fx,fy,fz,faults,limits,...
  if (line.rfind("t,fx,fy,fz,faults,limits", 0) != 0) {
    error = path + ": not a replay output (header '" + line + "')";
    return false;
  }
  std::size_t n = 1;
  while (std::getline(in, line)) {
    ++n;
    const auto f = fields_of(line);
    Row r;
    if (f.size() < 6 || !raw_of(f[1], r.f[0]) || !raw_of(f[2], r.f[1]) || !raw_of(f[3], r.f[2])) {
      error = fmt::format("{}:{}: a force is not a Q16.16 value: '{}'", path, n, line);
      return false;
    }
    r.faults = static_cast<std::uint32_t>(std::stoul(f[4]));
    r.limits = static_cast<std::uint32_t>(std::stoul(f[5]));
    rows.push_back(r);
  }
  return true;
}

/// The target's output: "run SCENE MOTION ROWS", then ROWS lines "f FX FY FZ FAULTS LIMITS",
/// then "end". Other lines (figures) are skipped here.
bool read_target(const std::string& path, std::map<std::string, std::vector<Row>>& runs, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open";
    return false;
  }
  std::string line;
  std::string current;
  std::size_t n = 0;
  while (std::getline(in, line)) {
    ++n;
    std::istringstream words(line);
    std::string tag;
    words >> tag;
    if (tag == "run") {
      std::string scene, motion;
      words >> scene >> motion;
      current = scene + "/" + motion;
      runs[current].clear();
    } else if (tag == "f") {
      Row r;
      if (current.empty() || !(words >> r.f[0] >> r.f[1] >> r.f[2] >> r.faults >> r.limits)) {
        error = fmt::format("{}:{}: bad force line '{}'", path, n, line);
        return false;
      }
      runs[current].push_back(r);
    } else if (tag == "end") {
      current.clear();
    }
  }
  return true;
}

int compare(const std::string& target_path, const std::vector<Named>& host) {
  std::map<std::string, std::vector<Row>> runs;
  std::string error;
  if (!read_target(target_path, runs, error)) {
    std::fprintf(stderr, "toonforce_mcu_gen: %s\n", error.c_str());
    return 1;
  }
  int failures = 0;
  for (const auto& h : host) {
    std::vector<Row> expected;
    if (!read_replay(h.path, expected, error)) {
      std::fprintf(stderr, "toonforce_mcu_gen: %s\n", error.c_str());
      return 1;
    }
    const auto it = runs.find(h.name);
    if (it == runs.end()) {
      std::printf("FAIL %s: the image wrote no run of it\n", h.name.c_str());
      ++failures;
      continue;
    }
    const auto& got = it->second;
    std::size_t mismatches = 0;
    std::size_t first = 0;
    for (std::size_t k = 0; k < std::min(got.size(), expected.size()); ++k) {
      const Row& a = got[k];
      const Row& b = expected[k];
      const bool same =
          a.f[0] == b.f[0] && a.f[1] == b.f[1] && a.f[2] == b.f[2] && a.faults == b.faults && a.limits == b.limits;
      if (!same && mismatches++ == 0) first = k;
    }
    if (got.size() != expected.size() || mismatches != 0) {
      ++failures;
      std::printf("FAIL %s: %zu rows on the target, %zu from replay; %zu differ", h.name.c_str(), got.size(),
                  expected.size(), mismatches);
      if (mismatches != 0) {
        const Row& a = got[first];
        const Row& b = expected[first];
        std::printf(", first at row %zu: target (%lld %lld %lld faults %u limits %u) replay (%lld %lld %lld faults %u "
                    "limits %u) [%s]",
                    first, static_cast<long long>(a.f[0]), static_cast<long long>(a.f[1]),
                    static_cast<long long>(a.f[2]), a.faults, a.limits, static_cast<long long>(b.f[0]),
                    static_cast<long long>(b.f[1]), static_cast<long long>(b.f[2]), b.faults, b.limits,
                    g_scalar == ScalarKind::kFloat ? "float bits" : "raw Q16.16");
      }
      std::printf("\n");
    } else {
      std::printf("ok   %s: %zu rows bit-identical\n", h.name.c_str(), got.size());
    }
  }
  return failures == 0 ? 0 : 1;
}

// ---- figures --------------------------------------------------------------------------------

/// Section sizes from `arm-none-eabi-size -A IMAGE` ("NAME SIZE ADDRESS" lines).
bool read_sections(const std::string& path, std::map<std::string, std::uint64_t>& sections, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open";
    return false;
  }
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string name;
    std::uint64_t size = 0;
    if (words >> name >> size && !name.empty() && name[0] == '.') sections[name] = size;
  }
  if (!sections.count(".text")) {
    error = path + ": no .text section listed (not the output of size -A?)";
    return false;
  }
  return true;
}

struct SceneFigures {
  std::uint64_t ticks = 0, loop_sum = 0, loop_max = 0, every_sum = 0, every_max = 0, effects_sum = 0, effects_max = 0;
  std::uint64_t stack_tick = 0, controller_bytes = 0, loop_bytes = 0;
  /// The searched inputs' strikes (motions search_*), apart: built to be dear, they would
  /// make the means above say nothing about normal use.
  std::uint64_t searched_ticks = 0, searched_loop_max = 0, searched_every_max = 0, searched_effects_max = 0;
};

/// The figure lines of an image's output (main.cpp): count, stack and sizeof, per scene.
bool read_figures(const std::string& path, std::map<std::string, SceneFigures>& scenes, std::uint64_t& program_stack,
                  std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = path + ": cannot open";
    return false;
  }
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string tag, scene, what;
    words >> tag >> scene;
    if (tag == "count") {
      // "count SCENE MOTION TICKS loop SUM MAX every SUM MAX effects SUM MAX"
      std::string motion, loop, every, effects;
      std::uint64_t ticks = 0, ls = 0, lm = 0, vs = 0, vm = 0, es = 0, em = 0;
      if (!(words >> motion >> ticks >> loop >> ls >> lm >> every >> vs >> vm >> effects >> es >> em)) {
        error = path + ": bad line '" + line + "'";
        return false;
      }
      SceneFigures& f = scenes[scene];
      if (motion.rfind("search_", 0) == 0) {
        f.searched_ticks += ticks;
        f.searched_loop_max = std::max(f.searched_loop_max, lm);
        f.searched_every_max = std::max(f.searched_every_max, vm);
        f.searched_effects_max = std::max(f.searched_effects_max, em);
        continue;
      }
      f.ticks += ticks;
      f.loop_sum += ls;
      f.loop_max = std::max(f.loop_max, lm);
      f.every_sum += vs;
      f.every_max = std::max(f.every_max, vm);
      f.effects_sum += es;
      f.effects_max = std::max(f.effects_max, em);
    } else if (tag == "stack" && scene == "program") {
      words >> program_stack;
    } else if (tag == "stack") {
      words >> what >> scenes[scene].stack_tick;
    } else if (tag == "sizeof") {
      std::uint64_t bytes = 0;
      words >> what >> bytes;
      (what == "loop" ? scenes[scene].loop_bytes : scenes[scene].controller_bytes) = bytes;
    }
  }
  return true;
}

int figures(const std::vector<Named>& sizes, const std::vector<Named>& runs) {
  std::string error;
  std::printf(
      "| image | text | data | bss | flash (text + data) | static RAM (data + bss) | .motion (test data, not counted) |\n");
  std::printf("| --- | ---: | ---: | ---: | ---: | ---: | ---: |\n");
  for (const auto& s : sizes) {
    std::map<std::string, std::uint64_t> sec;
    if (!read_sections(s.path, sec, error)) {
      std::fprintf(stderr, "toonforce_mcu_gen: %s\n", error.c_str());
      return 1;
    }
    // As arm-none-eabi-size's Berkeley columns count them, less the test data and the stack:
    // text = code and read-only data (vectors, .text, .rodata, exception index, init array).
    const std::uint64_t text = sec[".vectors"] + sec[".text"] + sec[".rodata"] + sec[".ARM.exidx"] + sec[".init_array"];
    const std::uint64_t data = sec[".data"];
    const std::uint64_t bss = sec[".bss"];
    std::printf("| %s | %llu | %llu | %llu | %llu | %llu | %llu |\n", s.name.c_str(),
                static_cast<unsigned long long>(text), static_cast<unsigned long long>(data),
                static_cast<unsigned long long>(bss), static_cast<unsigned long long>(text + data),
                static_cast<unsigned long long>(data + bss), static_cast<unsigned long long>(sec[".motion"]));
  }
  std::vector<SceneFigures> read;
  bool searched = false;  // a column for the searched inputs when some image played them
  for (const auto& r : runs) {
    std::map<std::string, SceneFigures> scenes;
    std::uint64_t program_stack = 0;
    if (!read_figures(r.path, scenes, program_stack, error)) {
      std::fprintf(stderr, "toonforce_mcu_gen: %s\n", error.c_str());
      return 1;
    }
    const auto it = scenes.find(r.name);
    if (it == scenes.end() || it->second.ticks == 0) {
      std::fprintf(stderr, "toonforce_mcu_gen: %s: no figures of scene %s\n", r.path.c_str(), r.name.c_str());
      return 1;
    }
    read.push_back(it->second);
    searched = searched || it->second.searched_ticks != 0;
  }
  std::printf("\n| scene | ticks | replay's loop tick, mean | max | every-stage loop tick, mean | max | "
              "effects + safety, mean | max | stack per tick [B] | loop state, replay's / every stage [B] |%s\n",
              searched ? " searched inputs: ticks | their max, replay's loop / every stage / effects + safety |" : "");
  std::printf("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |%s\n",
              searched ? " ---: | ---: |" : "");
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const auto& r = runs[i];
    const SceneFigures& f = read[i];
    const auto mean = [&](std::uint64_t sum) { return static_cast<double>(sum) / static_cast<double>(f.ticks); };
    std::printf("| %s | %llu | %.0f | %llu | %.0f | %llu | %.0f | %llu | %llu | %llu / %llu |", r.name.c_str(),
                static_cast<unsigned long long>(f.ticks), mean(f.loop_sum), static_cast<unsigned long long>(f.loop_max),
                mean(f.every_sum), static_cast<unsigned long long>(f.every_max), mean(f.effects_sum),
                static_cast<unsigned long long>(f.effects_max), static_cast<unsigned long long>(f.stack_tick),
                static_cast<unsigned long long>(f.controller_bytes), static_cast<unsigned long long>(f.loop_bytes));
    if (searched) {
      std::printf(" %llu | %llu / %llu / %llu |", static_cast<unsigned long long>(f.searched_ticks),
                  static_cast<unsigned long long>(f.searched_loop_max),
                  static_cast<unsigned long long>(f.searched_every_max),
                  static_cast<unsigned long long>(f.searched_effects_max));
    }
    std::printf("\n");
  }
  return 0;
}

// ---- the searched inputs as motion files -----------------------------------------------------

int strikes(const std::string& out_dir, std::size_t count, const std::vector<std::string>& scenes) {
  if (count != report::kSearchStrikes) {
    std::fprintf(stderr,
                 "toonforce_mcu_gen: --count %zu, but the search path has %zu strikes (report::kSearchStrikes); "
                 "set TOONFORCE_MCU_STRIKE_COUNT in tools/mcu/images.cmake to it\n",
                 count, report::kSearchStrikes);
    return 1;
  }
  for (const auto& scene : scenes) {
    const auto all = report::search_strikes(scene);
    for (std::size_t k = 0; k < all.size(); ++k) {
      // Each strike as it is, and once more with late ticks: from its 40th tick on (engaged,
      // in contact for the constructed one), every fourth period has no row, so the tick after
      // it comes two periods late (the loop's clock, velocity estimate and rate limit take
      // their late-tick paths, which the static bound counts and no other motion reaches).
      for (const bool late : {false, true}) {
        const std::string path = fmt::format("{}/search_{}_{}{}.csv", out_dir, scene, k, late ? "_late" : "");
        std::string text = fmt::format(
            "# Strike {} of {} of the search path of scene {} (`toonforce-lab report`'s searched inputs,\n"
            "# tools/report/src/workloads.cpp, search_path), at 1 kHz{}; written by toonforce_mcu_gen strikes.\n"
            "t,x,y,z\n",
            k, all.size(), scene,
            late ? ",\n# with late ticks: from t = 40 ms on, every fourth period has no row" : "");
        for (std::size_t i = 0; i < all[k].size(); ++i) {
          if (late && i >= 40 && i % 4 == 2) continue;
          const Vec3<double>& p = all[k][i];
          text += fmt::format("{:.3f},{:.9f},{:.9f},{:.9f}\n", static_cast<double>(i) / 1000.0, p.x, p.y, p.z);
        }
        if (!write_if_changed(path, text)) {
          std::fprintf(stderr, "toonforce_mcu_gen: cannot write %s\n", path.c_str());
          return 1;
        }
      }
    }
  }
  return 0;
}

int usage() {
  std::fputs(
      "usage: toonforce_mcu_gen generate --out-dir DIR [--scalar q16.16|float] [--sine METHOD] --scene NAME=FILE... "
      "--motion NAME=FILE...\n"
      "       toonforce_mcu_gen strikes --out-dir DIR --count N --scene NAME...\n"
      "       toonforce_mcu_gen compare [--scalar q16.16|float] --target FILE --host SCENE/MOTION=REPLAY.csv...\n"
      "       toonforce_mcu_gen figures --size IMAGE=SIZE_A.txt... --run SCENE=TARGET.txt...\n",
      stderr);
  return 2;
}

}  // namespace
}  // namespace toonforce::mcu

int main(int argc, char** argv) {
  using namespace toonforce::mcu;
  if (argc < 2) return usage();
  const std::string_view mode = argv[1];
  std::string out_dir, target;
  toonforce::ScalarKind scalar = toonforce::ScalarKind::kQ16_16;
  std::optional<toonforce::SineMethod> sine;
  std::vector<Named> scenes, motions, host, sizes, runs;
  std::size_t count = 0;
  for (int i = 2; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (i + 1 >= argc) return usage();
    const std::string_view value = argv[++i];
    Named named;
    if (arg == "--out-dir") {
      out_dir = value;
    } else if (arg == "--target") {
      target = value;
    } else if (arg == "--scalar") {
      const auto kind = toonforce::parse_scalar_kind(value);
      if (!kind || *kind == toonforce::ScalarKind::kDouble) return usage();  // no double on the target
      scalar = *kind;
    } else if (arg == "--sine") {
      sine = toonforce::parse_sine_method(value);
      if (!sine) return usage();
    } else if (arg == "--count" && mode == "strikes") {
      count = static_cast<std::size_t>(std::strtoull(std::string(value).c_str(), nullptr, 10));
    } else if (arg == "--scene" && mode == "strikes") {  // a paper scene's name, no file
      scenes.push_back({std::string(value), {}});
    } else if ((arg == "--scene" || arg == "--motion" || arg == "--host") && split_named(value, named)) {
      (arg == "--scene" ? scenes : arg == "--motion" ? motions : host).push_back(named);
    } else if ((arg == "--size" || arg == "--run") && split_named(value, named)) {
      (arg == "--size" ? sizes : runs).push_back(named);
    } else {
      return usage();
    }
  }
  if (mode == "strikes" && !out_dir.empty() && !scenes.empty()) {
    std::vector<std::string> names;
    for (const auto& s : scenes) names.push_back(s.name);
    return strikes(out_dir, count, names);
  }
  if (mode == "generate" && !out_dir.empty() && !scenes.empty() && !motions.empty()) {
    return generate(out_dir, scalar, sine, scenes, motions);
  }
  g_scalar = scalar;
  if (mode == "compare" && !target.empty() && !host.empty()) return compare(target, host);
  if (mode == "figures" && (!sizes.empty() || !runs.empty())) return figures(sizes, runs);
  return usage();
}
