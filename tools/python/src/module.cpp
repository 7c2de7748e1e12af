// SPDX-License-Identifier: Apache-2.0
// toonforce._toonforce: the C++ libraries `toonforce` is built from, for Python. Thin
// by design: every check, message and number comes from the same functions the command line
// calls (scene_file.hpp, check.hpp, sim_run.hpp, replay.hpp, figures.hpp); this file only
// converts arguments and results. The package around it is tools/python/toonforce.
#include <Python.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <charconv>
#include <chrono>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <thread>
#include <csignal>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "toonforce/config/hand_script_file.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/replay/motion_csv.hpp"
#include "toonforce/replay/replay.hpp"
#include "toonforce/run/run.hpp"
#include "toonforce/run/world_run.hpp"
#include "toonforce/config/scene_editor.hpp"
#include "toonforce/sim/check.hpp"
#include "toonforce/sim/figures.hpp"
#include "toonforce/sim/sim_run.hpp"
#include "toonforce/sim/world_sim.hpp"
#include "toonforce/sim/sim_trace.hpp"
#include "toonforce/control/servo_session.hpp"

namespace py = pybind11;

namespace toonforce::python {
namespace {

/// toonforce.SceneError (created at import; never released: it lives as long as the process).
PyObject* g_scene_error = nullptr;

/// Where the first error of a message is: ErrorList writes each as "FILE:LINE: KEY: PROBLEM",
/// LINE left out (with its colon) for the whole file, KEY for the table itself or the file
/// (toml_reader.cpp, ErrorList::add). `file` is known: it is the name we loaded under.
struct Place {
  std::uint32_t line = 0;
  std::string key;
};

Place place_of(std::string_view message, std::string_view file) {
  Place place;
  std::string_view first = message.substr(0, message.find('\n'));
  if (!first.starts_with(file) || first.size() <= file.size() || first[file.size()] != ':') return place;
  first.remove_prefix(file.size() + 1);
  std::uint32_t line = 0;
  const auto [end, ec] = std::from_chars(first.data(), first.data() + first.size(), line);
  if (ec == std::errc{} && end != first.data() && end < first.data() + first.size() && *end == ':') {
    place.line = line;
    first.remove_prefix(static_cast<std::size_t>(end - first.data()) + 1);
  }
  if (first.starts_with(' ')) first.remove_prefix(1);
  // A key path is one word (letters, digits, _ - . [ ]) followed by ": "; a problem is a phrase.
  const std::size_t colon = first.find(": ");
  if (colon == std::string_view::npos || colon == 0) return place;
  for (const char c : first.substr(0, colon)) {
    const bool word = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                      c == '-' || c == '.' || c == '[' || c == ']';
    if (!word) return place;
  }
  place.key = std::string(first.substr(0, colon));
  return place;
}

/// Raises toonforce.SceneError for `message` (what the command line prints) about `file`.
[[noreturn]] void raise_scene_error(std::string message, const std::string& file) {
  while (!message.empty() && message.back() == '\n') message.pop_back();
  const Place place = place_of(message, file);
  py::object error = py::reinterpret_borrow<py::object>(g_scene_error)(message);
  error.attr("message") = message;
  error.attr("file") = file;
  error.attr("line") = place.line;
  error.attr("key") = place.key;
  PyErr_SetObject(g_scene_error, error.ptr());
  throw py::error_already_set();
}

[[noreturn]] void raise_value_error(std::string message) {
  while (!message.empty() && message.back() == '\n') message.pop_back();
  throw py::value_error(message);
}

ScalarKind scalar_of(const std::string& name) {
  if (auto kind = parse_scalar_kind(name)) return *kind;
  raise_value_error(fmt::format("scalar must be double, float or q16.16 (got '{}')", name));
}

host_sim::DevicePreset device_of(const std::string& name) {
  if (auto device = host_sim::parse_device_preset(name)) return *device;
  raise_value_error(fmt::format("device must be falcon or omni (got '{}')", name));
}

// ---- dicts as TOML text ----------------------------------------------------------------------

/// Moves `node` (a toml::table, array or value behind a toml::node) into place through `put`,
/// which receives the concrete type (toml++ inserts concrete nodes only).
template <class Put>
void put_node(std::unique_ptr<toml::node> node, Put&& put) {
  std::move(*node).visit([&](auto&& concrete) { put(std::move(concrete)); });
}

/// A Python value as a TOML node: bool, int (or anything with __index__, like numpy's
/// integers), float (or another number), str, a list or tuple (an array; of dicts, an array of
/// tables), a dict (a table). `where` names the value in messages ("surface[0].k").
std::unique_ptr<toml::node> node_of(const py::handle& value, const std::string& where) {
  if (PyBool_Check(value.ptr())) return std::make_unique<toml::value<bool>>(value.cast<bool>());
  if (py::isinstance<py::str>(value)) return std::make_unique<toml::value<std::string>>(value.cast<std::string>());
  if (py::isinstance<py::dict>(value)) {
    auto table = std::make_unique<toml::table>();
    for (const auto& [k, v] : value.cast<py::dict>()) {
      if (!py::isinstance<py::str>(k)) {
        raise_value_error(fmt::format("{}: a scene's keys are strings (got {})", where.empty() ? "the dict" : where,
                                      py::repr(k).cast<std::string>()));
      }
      const std::string key = k.cast<std::string>();
      put_node(node_of(v, where.empty() ? key : where + "." + key),
               [&](auto&& node) { table->insert(key, std::forward<decltype(node)>(node)); });
    }
    return table;
  }
  if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
    auto array = std::make_unique<toml::array>();
    std::size_t i = 0;
    for (const auto& item : value) {
      put_node(node_of(item, fmt::format("{}[{}]", where, i++)),
               [&](auto&& node) { array->push_back(std::forward<decltype(node)>(node)); });
    }
    return array;
  }
  if (PyLong_Check(value.ptr()) || (!PyFloat_Check(value.ptr()) && PyIndex_Check(value.ptr()))) {
    return std::make_unique<toml::value<std::int64_t>>(
        py::int_(py::reinterpret_borrow<py::object>(value)).cast<std::int64_t>());
  }
  if (PyFloat_Check(value.ptr()) || PyNumber_Check(value.ptr())) {
    return std::make_unique<toml::value<double>>(py::float_(py::reinterpret_borrow<py::object>(value)).cast<double>());
  }
  raise_value_error(fmt::format("{}: a {} cannot be written in TOML (bool, int, float, str, list or dict)", where,
                                py::type::of(value).attr("__name__").cast<std::string>()));
}

/// A scene (or hand script) given as a dict, as the TOML text the loaders read (numbers in
/// round-trip precision), so it passes the same loader and checks as a file.
std::string toml_from_dict(const py::dict& dict) {
  const std::unique_ptr<toml::node> root = node_of(dict, "");
  std::ostringstream out;
  out << toml::toml_formatter(*root->as_table()) << '\n';
  return out.str();
}

// ---- loading, with SceneError --------------------------------------------------------------

SceneDescription load_scene(const std::string& path, const std::optional<std::string>& text, ScalarKind scalar,
                            bool allow_empty) {
  auto scene = text ? parse_scene(*text, path, scalar) : load_scene_file(path, scalar);
  if (!scene) raise_scene_error(scene.error(), path);
  if (!allow_empty) {
    if (std::string empty = empty_scene_problem(scene.value(), path); !empty.empty()) raise_scene_error(empty, path);
  }
  return std::move(scene.value());
}

HandScriptFile load_script(const std::string& path, const std::optional<std::string>& text) {
  auto hand = text ? parse_hand_script(*text, path) : load_hand_script(path);
  if (!hand) raise_scene_error(hand.error(), path);
  return std::move(hand.value());
}

py::dict scene_info(const std::string& path, const std::optional<std::string>& text, const std::string& scalar,
                    bool allow_empty) {
  const SceneDescription scene = load_scene(path, text, scalar_of(scalar), allow_empty);
  py::dict info;
  info["name"] = scene.name;
  info["source"] = path;
  info["surfaces"] = scene.of<RuntimeSurface>().size();
  info["cliffs"] = scene.of<CartoonCliff>().size();
  info["values"] = effect_value_names(make_runtime_scene<double>(scene));
  return info;
}

py::dict script_info(const std::string& path, const std::optional<std::string>& text) {
  const HandScriptFile hand = load_script(path, text);
  py::dict info;
  info["name"] = hand.script.name;
  info["source"] = path;
  info["duration_s"] = hand.intent.duration_s();
  return info;
}

// ---- check -----------------------------------------------------------------------------------

py::dict check(const std::string& scene_path, const std::optional<std::string>& scene_text,
               const std::string& script_path, const std::optional<std::string>& script_text, const std::string& device,
               double rate_hz, const std::string& scalar, bool allow_empty, bool strict) {
  CheckOptions options;
  options.scene_path = scene_path;
  options.scene_text = scene_text;
  options.script_path = script_path;
  options.script_text = script_text;
  options.device = device_of(device);
  options.rate_hz = rate_hz;
  options.scalar = scalar_of(scalar);
  options.allow_empty = allow_empty;
  options.strict = strict;
  CheckReport report;
  {
    py::gil_scoped_release unlocked;
    report = check_scene(options);
  }
  py::dict out;
  out["ok"] = report.ok;
  out["exit_code"] = report.exit_code;
  out["rate_error"] = report.rate_error;
  out["errors"] = report.errors;
  out["notes"] = report.notes;
  out["warnings"] = report.warnings;
  out["text"] = report.rate_error.empty() ? format_check_report(report, options) : report.rate_error + "\n";
  return out;
}

// ---- traces as columns -----------------------------------------------------------------------

/// A trace column's unit (SI; "" for flags, bit sets, states, counts; "1" for ratios).
std::string unit_of(std::string_view column) {
  static constexpr std::pair<std::string_view, std::string_view> kUnits[] = {
      {"t", "s"},
      {"x", "m"},
      {"y", "m"},
      {"z", "m"},
      {"vx", "m/s"},
      {"vy", "m/s"},
      {"vz", "m/s"},
      {"fx", "N"},
      {"fy", "N"},
      {"fz", "N"},
      {"scene_fx", "N"},
      {"scene_fy", "N"},
      {"scene_fz", "N"},
      {"damping_fx", "N"},
      {"damping_fy", "N"},
      {"damping_fz", "N"},
      {"max_force", "N"},
      {"temperature", "1"},
      {"observed_energy", "J"},
      {"episode_energy", "J"},
      {"gain", "1"},
      {"true_x", "m"},
      {"true_y", "m"},
      {"true_z", "m"},
      {"true_vx", "m/s"},
      {"true_vy", "m/s"},
      {"true_vz", "m/s"},
      {"hand_x", "m"},
      {"hand_y", "m"},
      {"hand_z", "m"},
      {"device_fx", "N"},
      {"device_fy", "N"},
      {"device_fz", "N"},
  };
  for (const auto& [name, unit] : kUnits) {
    if (name == column) return std::string(unit);
  }
  return {};
}

/// Every row of a run as one growing vector per column; the arrays take them over at the end.
/// Every kInterruptRows rows it asks Python whether a signal came (Ctrl-C: the run holds no
/// GIL, so Python's handler only marks it): if its handler raised, the exception is kept and
/// `stop` is set, so the run ends as the command does on a signal (`sim`: with the loop's
/// shut-down tick, zero force, as the last row).
class Columns {
 public:
  /// Rows between two looks: tens of milliseconds of computing, so Ctrl-C is heard at once, and
  /// the GIL taken that rarely costs nothing measurable.
  static constexpr std::size_t kInterruptRows = 16384;
  static constexpr std::size_t kReservedRows = std::size_t{1} << 20;  ///< reserved at the start at most

  explicit Columns(std::atomic<int>& stop) : stop_(stop) {}
  ~Columns() {
    if (error_type_ != nullptr) {
      py::gil_scoped_acquire locked;
      Py_XDECREF(error_type_);
      Py_XDECREF(error_value_);
      Py_XDECREF(error_traceback_);
    }
  }
  Columns(const Columns&) = delete;
  Columns& operator=(const Columns&) = delete;

  void begin(std::vector<std::string> names, std::size_t rows) {
    names_ = std::move(names);
    columns_.assign(names_.size(), {});
    // Room for a short run at once; a long one grows as it goes (a day at 1 kHz would be 29 GB
    // reserved up front, most of it never used if the run is stopped).
    for (auto& c : columns_) c.reserve(std::min<std::size_t>(rows, kReservedRows));
  }
  /// One row: `values` in column order (more than there are columns: the rest is left out).
  void add(std::span<const double> values) {
    for (std::size_t i = 0; i < values.size() && i < columns_.size(); ++i) columns_[i].push_back(values[i]);
    if (++rows_ % kInterruptRows == 0 && error_type_ == nullptr) {
      py::gil_scoped_acquire locked;
      if (PyErr_CheckSignals() != 0) {
        PyErr_Fetch(&error_type_, &error_value_, &error_traceback_);
        stop_.store(SIGINT);
      }
    }
  }
  /// With the GIL: raises what a signal's handler raised during the run, if anything.
  void raise_interrupt() {
    if (error_type_ == nullptr) return;
    PyErr_Restore(error_type_, error_value_, error_traceback_);
    error_type_ = error_value_ = error_traceback_ = nullptr;
    throw py::error_already_set();
  }
  const std::vector<std::string>& names() const noexcept { return names_; }
  std::vector<std::vector<double>>& columns() noexcept { return columns_; }

 private:
  std::atomic<int>& stop_;
  std::size_t rows_ = 0;
  PyObject* error_type_ = nullptr;
  PyObject* error_value_ = nullptr;
  PyObject* error_traceback_ = nullptr;
  std::vector<std::string> names_;
  std::vector<std::vector<double>> columns_;
};

/// run_sim's rows into Columns: the core ten, then the values after them.
class SimColumns final : public SimRowSink {
 public:
  explicit SimColumns(Columns& columns) : columns_(columns) {}
  void begin(const std::vector<std::string>& extra_columns, std::int64_t ticks) override {
    std::vector<std::string> names(kTraceCoreColumns.begin(), kTraceCoreColumns.end());
    names.insert(names.end(), extra_columns.begin(), extra_columns.end());
    columns_.begin(std::move(names), static_cast<std::size_t>(ticks) + 1);
  }
  void row(const TraceRow& r) override {
    std::array<double, 10 + kMaxTraceRowValues> all;
    const Vec3<double> core[3] = {r.core.position_m, r.core.velocity_m_per_s, r.core.force_n};
    all[0] = r.core.t_s;
    for (std::size_t i = 0; i < 3; ++i) {
      all[1 + 3 * i] = core[i].x;
      all[2 + 3 * i] = core[i].y;
      all[3 + 3 * i] = core[i].z;
    }
    std::copy_n(r.values.begin(), r.count, all.begin() + 10);
    columns_.add(std::span<const double>(all.data(), 10 + r.count));
  }

 private:
  Columns& columns_;
};

/// run_replay's rows into Columns.
class ReplayColumns final : public ReplayRowSink {
 public:
  explicit ReplayColumns(Columns& columns) : columns_(columns) {}
  void begin(const std::vector<std::string>& names, std::size_t rows) override { columns_.begin(names, rows); }
  void row(std::span<const double> values) override { columns_.add(values); }

 private:
  Columns& columns_;
};

/// A vector as a numpy array without a copy: the array owns it.
py::array_t<double> array_of(std::vector<double>&& values) {
  auto* owned = new std::vector<double>(std::move(values));
  py::capsule owner(owned, [](void* p) { delete static_cast<std::vector<double>*>(p); });
  return py::array_t<double>(static_cast<py::ssize_t>(owned->size()), owned->data(), owner);
}

py::dict summary_dict(const SimSummary& s) {
  py::dict d;
  d["scene_name"] = s.scene_name;
  d["script_name"] = s.script_name;
  d["device_name"] = s.device_name;
  d["ticks"] = s.ticks;
  d["duration_s"] = s.duration_s;
  d["script_duration_s"] = s.script_duration_s;
  d["peak_force_n"] = s.peak_force_n;
  d["peak_force_t_s"] = s.peak_force_t_s;
  d["ticks_in_contact"] = s.ticks_in_contact;
  d["impacts"] = s.impacts;
  d["cliff_falls"] = s.cliff_falls;
  d["rate_limited"] = s.rate_limited;
  d["clamped"] = s.clamped;
  d["fault_ticks"] = s.fault_ticks;
  d["fault_bits"] = s.fault_bits;
  d["final_position_m"] = py::make_tuple(s.final_position_m.x, s.final_position_m.y, s.final_position_m.z);
  d["device_work_j"] = s.device_work_j;
  d["ticks_outside_workspace"] = s.ticks_outside_workspace;
  d["engaging_ticks"] = s.engaging_ticks;
  d["soft_start_ticks"] = s.soft_start_ticks;
  d["passivity_ticks"] = s.passivity_ticks;
  d["stop_signal"] = s.stop_signal;
  return d;
}

/// The units of a scene's effect value columns, by name.
std::vector<std::pair<std::string, std::string>> value_units(const SceneDescription& scene) {
  const auto runtime = make_runtime_scene<double>(scene);
  const std::vector<std::string> names = effect_value_names(runtime);
  std::vector<std::pair<std::string, std::string>> out;
  std::size_t n = 0;
  for (std::size_t i = 0; i < runtime.effect_count(); ++i) {
    for (const ValueInfo& v : runtime.effect_info(i).values) out.emplace_back(names[n++], std::string(v.unit));
  }
  return out;
}

/// Each column's unit: the trace's own, or the effect's for an effect value column.
py::dict units_of(const std::vector<std::string>& names, const SceneDescription& scene) {
  const auto values = value_units(scene);
  py::dict units;
  for (const std::string& name : names) {
    std::string unit = unit_of(name);
    for (const auto& [value, value_unit] : values) {
      if (value == name) unit = value_unit;
    }
    units[py::str(name)] = unit;
  }
  return units;
}

/// The columns as numpy arrays, each taking its vector over.
py::dict arrays_of(Columns& columns) {
  py::dict arrays;
  for (std::size_t i = 0; i < columns.names().size(); ++i) {
    arrays[py::str(columns.names()[i])] = array_of(std::move(columns.columns()[i]));
  }
  return arrays;
}

/// sim(): `toonforce sim` through run_sim, the rows kept as columns instead of text.
py::tuple sim(const std::string& scene_path, const std::optional<std::string>& scene_text,
              const std::string& script_path, const std::optional<std::string>& script_text, double rate_hz,
              const std::string& scalar, std::optional<double> duration_s, const std::string& device,
              const std::string& integrator, int substeps, std::uint64_t seed, std::optional<double> sensor_noise_m,
              const std::optional<std::string>& sine, bool allow_empty, bool strict, const std::string& trace_path) {
  SimOptions options;
  options.scene_path = scene_path;
  options.scene_text = scene_text;
  options.script_path = script_path;
  options.script_text = script_text;
  options.rate_hz = rate_hz;
  options.scalar = scalar_of(scalar);
  options.duration_s = duration_s;
  options.device = device_of(device);
  if (auto i = host_sim::parse_integrator(integrator)) {
    options.integrator = *i;
  } else {
    raise_value_error(
        fmt::format("integrator must be semi-implicit-euler, velocity-verlet, rk4 or exact (got '{}')", integrator));
  }
  options.substeps = substeps;
  options.seed = seed;
  options.sensor_noise_m = sensor_noise_m;
  if (sine) {
    options.sine = parse_sine_method(*sine);
    if (!options.sine) raise_value_error(fmt::format("sine must be library, polynomial or table (got '{}')", *sine));
  }
  options.allow_empty = allow_empty;
  options.strict = strict;
  options.trace_path = trace_path;
  // The scene's and hand script's errors as SceneError (file, line, key); run_sim loads them
  // again, the same way, and reports everything else.
  const SceneDescription scene = load_scene(scene_path, scene_text, options.scalar, allow_empty);
  load_script(script_path, script_text);
  std::atomic<int> stop{0};
  options.stop = &stop;
  std::vector<std::string> warnings;
  options.warnings = &warnings;
  Columns columns(stop);
  SimColumns sink(columns);
  options.rows = &sink;
  Result<SimSummary> summary = Error{""};
  {
    py::gil_scoped_release unlocked;
    summary = run_sim(options);
  }
  columns.raise_interrupt();  // the trace up to the shut-down tick goes with it: Ctrl-C means "stop"
  if (!summary) raise_value_error(summary.error());
  const py::dict units = units_of(columns.names(), scene);
  return py::make_tuple(arrays_of(columns), units, summary_dict(summary.value()), warnings);
}

/// run_world_sim's rows into Columns.
class WorldColumns final : public WorldRowSink {
 public:
  /// `run_stop`: a real-time run's (run_world): a Ctrl-C the rows hear (Columns' look) stops the
  /// run as its stop signals would. The simulation hears it through its own stop flag.
  explicit WorldColumns(Columns& columns, std::atomic<int>* run_stop = nullptr)
      : columns_(columns), run_stop_(run_stop) {}
  void begin(const std::vector<std::string>& names, std::int64_t ticks) override {
    columns_.begin(names, static_cast<std::size_t>(std::max<std::int64_t>(ticks, 0)) + 1);
  }
  void row(const std::vector<double>& values) override {
    columns_.add(values);
    if (run_stop_ != nullptr) {
      if (const int signal = run_stop_->load(); signal != 0) request_session_stop(signal);
    }
  }

 private:
  Columns& columns_;
  std::atomic<int>* run_stop_;
};

/// A world file's errors as SceneError (file, line, key), before the run that loads it again.
void check_world_file(const std::string& scene_path, const std::optional<std::string>& scene_text) {
  auto world = scene_text ? parse_world(*scene_text, scene_path) : load_world_file(scene_path);
  if (!world) raise_scene_error(world.error(), scene_path);
}

/// Each world column's SI unit.
py::dict world_units(const Columns& columns) {
  py::dict units;
  for (const std::string& name : columns.names()) units[py::str(name)] = world_column_unit(name);
  return units;
}

/// sim_world(): `toonforce sim` of a world scene through run_world_sim, the rows as columns.
/// `scripts`: (device name, path or the name standing for it, text or None).
py::tuple sim_world(const std::string& scene_path, const std::optional<std::string>& scene_text,
                    const std::vector<std::tuple<std::string, std::string, std::optional<std::string>>>& scripts,
                    double rate_hz, std::optional<double> duration_s, const std::string& device,
                    const std::string& integrator, int substeps, std::uint64_t seed,
                    const std::optional<std::pair<std::string, double>>& fail, const std::string& trace_path) {
  WorldSimOptions options;
  options.scene_path = scene_path;
  options.scene_text = scene_text;
  for (const auto& [name, path, text] : scripts) {
    options.scripts.emplace_back(name, path);
    if (text) options.script_texts[name] = *text;
  }
  options.rate_hz = rate_hz;
  options.duration_s = duration_s;
  options.device = device_of(device);
  if (auto i = host_sim::parse_integrator(integrator)) {
    options.integrator = *i;
  } else {
    raise_value_error(
        fmt::format("integrator must be semi-implicit-euler, velocity-verlet, rk4 or exact (got '{}')", integrator));
  }
  options.substeps = substeps;
  options.seed = seed;
  options.fail = fail;
  options.trace_path = trace_path;
  check_world_file(scene_path, scene_text);
  std::atomic<int> stop{0};
  options.stop = &stop;
  Columns columns(stop);
  WorldColumns sink(columns);
  options.rows = &sink;
  Result<WorldSimSummary> summary = Error{""};
  {
    py::gil_scoped_release unlocked;
    summary = run_world_sim(options);
  }
  columns.raise_interrupt();
  if (!summary) raise_value_error(summary.error());
  const py::dict units = world_units(columns);
  const WorldSimSummary& s = summary.value();
  py::dict d;
  d["scene_name"] = s.scene_name;
  d["ticks"] = s.ticks;
  d["duration_s"] = s.duration_s;
  py::list devices;
  for (const WorldSimDeviceSummary& v : s.devices) {
    py::dict one;
    one["name"] = v.name;
    one["script"] = v.script;
    one["peak_force_n"] = v.peak_force_n;
    one["fault_ticks"] = v.fault_ticks;
    one["latched"] = v.latched;
    one["state"] = to_string(static_cast<LoopState>(v.state));
    one["final_hip_m"] = py::make_tuple(v.final_hip_m.x, v.final_hip_m.y, v.final_hip_m.z);
    devices.append(one);
  }
  d["devices"] = devices;
  d["held_at_s"] = s.held_at_s ? py::object(py::float_(*s.held_at_s)) : py::object(py::none());
  d["held_by"] = s.held_by;
  d["coupling_imbalance_n"] = s.coupling_imbalance_n;
  d["forced_while_held"] = s.forced_while_held;
  d["final_ball_m"] = s.final_ball_m
                          ? py::object(py::make_tuple(s.final_ball_m->x, s.final_ball_m->y, s.final_ball_m->z))
                          : py::object(py::none());
  d["stop_signal"] = s.stop_signal;
  return py::make_tuple(arrays_of(columns), units, d, py::list());
}

/// run_world(): `toonforce run` of a world scene through run_world_servo, in real time, the rows
/// as columns. `scripts` as sim_world's. Blocks until the run ends (its duration, or Ctrl-C).
py::tuple run_world(const std::string& scene_path, const std::optional<std::string>& scene_text,
                    const std::vector<std::tuple<std::string, std::string, std::optional<std::string>>>& scripts,
                    const std::string& device, double rate_hz, double duration_s, const std::string& sim_device,
                    std::uint64_t seed, const std::optional<std::pair<std::string, double>>& fail,
                    const std::string& trace_path, const std::string& omni_library, int priority, int cpu,
                    bool lock_memory, bool allow_empty, bool strict) {
  RunOptions options;
  options.device = device;
  options.scene_path = scene_path;
  options.scene_text = scene_text;
  for (const auto& [name, path, text] : scripts) {
    options.world_scripts.emplace_back(name, path);
    if (text) options.world_script_texts[name] = *text;
  }
  options.rate_hz = rate_hz;
  options.duration_s = duration_s;
  options.sim_device = sim_device;
  options.seed = seed;
  options.world_fail = fail;
  options.trace_path = trace_path;
  options.omni.library_path = omni_library;
  options.priority = priority;
  options.cpu = cpu;
  options.lock_memory = lock_memory;
  options.allow_non_realtime = true;
  options.allow_empty = allow_empty;
  options.strict = strict;
  options.handle_signals = false;  // Python's: Ctrl-C is a KeyboardInterrupt, heard by the rows
  options.interactive = false;
  check_world_file(scene_path, scene_text);
  std::atomic<int> stop{0};
  Columns columns(stop);
  WorldColumns sink(columns, &stop);
  options.world_rows = &sink;
  options.early_stop = &stop;
  Result<WorldRunSummary> summary = Error{""};
  {
    py::gil_scoped_release unlocked;
    summary = run_world_servo(options);
  }
  columns.raise_interrupt();
  if (!summary) raise_value_error(summary.error());
  const py::dict units = world_units(columns);
  const WorldRunSummary& s = summary.value();
  const auto latency = [](const LatencySummary& l) {
    py::dict d;
    d["count"] = l.count;
    d["median_s"] = static_cast<double>(l.median_ns) * 1e-9;
    d["p99_s"] = static_cast<double>(l.p99_ns) * 1e-9;
    d["max_s"] = static_cast<double>(l.max_ns) * 1e-9;
    return d;
  };
  py::dict d;
  d["scene_name"] = s.scene_name;
  d["ticks"] = s.report.ticks;
  d["missed"] = s.report.missed;
  d["elapsed_s"] = s.report.elapsed_s;
  d["stop_signal"] = s.report.stop_signal;
  d["realtime"] = s.report.setup.fifo;
  d["wake_latency"] = latency(s.report.wake.summary());
  py::list devices;
  for (const WorldRunDevice& v : s.devices) {
    py::dict one;
    one["name"] = v.name;
    one["backend"] = v.backend;
    one["device_name"] = v.device_name;
    one["script"] = v.script;
    one["peak_force_n"] = v.peak_force_n;
    one["fault_ticks"] = v.fault_ticks;
    one["faults"] = describe_faults(v.fault_bits);
    one["latched_at_end"] = describe_faults(v.latched_at_end);
    if (v.bridged) {
      one["reading_age"] = latency(v.reading_age);
      one["force_age"] = latency(v.force_age);
      one["stale_force_ticks"] = v.stale_force_ticks;
    }
    devices.append(one);
  }
  d["devices"] = devices;
  d["held_at_s"] = s.held_at_s ? py::object(py::float_(*s.held_at_s)) : py::object(py::none());
  d["held_by"] = s.held_by;
  d["coupling_imbalance_n"] = s.coupling_imbalance_n;
  d["forced_while_held"] = s.forced_while_held;
  d["frames_dropped"] = s.frames_dropped;
  d["trace_error"] = s.trace_error;
  return py::make_tuple(arrays_of(columns), units, d, py::list());
}

/// replay(): `toonforce replay` through run_replay, the rows kept as columns instead of text.
py::tuple replay(const std::string& scene_path, const std::optional<std::string>& scene_text,
                 const std::string& motion_path, const std::optional<std::string>& motion_text,
                 const std::string& scalar, const std::optional<std::string>& sine, bool allow_empty,
                 const std::string& output_path) {
  ReplayOptions options;
  options.scene_path = scene_path;
  options.scene_text = scene_text;
  options.input_path = motion_path;
  options.input_text = motion_text;
  options.scalar = scalar_of(scalar);
  if (sine) {
    options.sine = parse_sine_method(*sine);
    if (!options.sine) raise_value_error(fmt::format("sine must be library, polynomial or table (got '{}')", *sine));
  }
  options.allow_empty = allow_empty;
  options.output_path = output_path;
  const SceneDescription scene = load_scene(scene_path, scene_text, options.scalar, allow_empty);
  // The motion's errors name the file, the line and the column, as a scene's do.
  {
    auto motion = motion_text ? parse_motion_csv(*motion_text, motion_path) : read_motion_csv(motion_path);
    if (!motion) raise_scene_error(motion.error(), motion_path);
  }
  std::atomic<int> stop{0};
  options.stop = &stop;
  Columns columns(stop);
  ReplayColumns sink(columns);
  options.rows = &sink;
  Result<ReplaySummary> summary = Error{""};
  {
    py::gil_scoped_release unlocked;
    summary = run_replay(options);
  }
  columns.raise_interrupt();
  if (!summary) raise_value_error(summary.error());
  const py::dict units = units_of(columns.names(), scene);
  const py::dict arrays = arrays_of(columns);
  const ReplaySummary& s = summary.value();
  py::dict d;
  d["scene_name"] = s.scene_name;
  d["rows"] = s.rows;
  d["rows_done"] = s.rows_done;
  d["duration_s"] = s.duration_s;
  d["median_rate_hz"] = s.median_rate_hz;
  d["given_velocity"] = s.given_velocity;
  d["ignored_columns"] = s.ignored_columns;
  d["peak_force_n"] = s.peak_force_n;
  d["peak_force_t_s"] = s.peak_force_t_s;
  d["peak_scene_force_n"] = s.peak_scene_force_n;
  d["ticks_in_contact"] = s.ticks_in_contact;
  d["impacts"] = s.impacts;
  d["cliff_falls"] = s.cliff_falls;
  d["rate_limited"] = s.rate_limited;
  d["clamped"] = s.clamped;
  d["fault_ticks"] = s.fault_ticks;
  d["fault_bits"] = s.fault_bits;
  d["input_note"] = s.input_note;
  d["stop_signal"] = s.stop_signal;
  d["output_error"] = s.output_error;
  return py::make_tuple(arrays, units, d);
}

py::list figures(const std::string& out_dir, const std::string& root, const std::string& format, bool plot) {
  FiguresOptions options;
  options.out_dir = out_dir;
  options.root = root;
  options.format = format;
  options.plot = plot;
  Result<std::vector<std::string>> lines = Error{""};
  {
    py::gil_scoped_release unlocked;
    lines = run_figures(options);
  }
  if (!lines) raise_value_error(lines.error());
  return py::cast(lines.value());
}

// ---- a real-time run -------------------------------------------------------------------------

/// The run's telemetry as columns, from the thread that already drains the loop's telemetry
/// ring (`toonforce run`'s writer thread: the servo thread does no work for it). Python takes
/// what came so far with take(); the lock is held only to append one row or to swap the
/// columns out, never while Python copies them.
class TelemetryColumns final : public TelemetrySink {
 public:
  explicit TelemetryColumns(const std::vector<std::string>& value_names) : values_(value_names.size()) {
    names_.assign(kTraceCoreColumns.begin(), kTraceCoreColumns.end());
    const std::vector<std::string> extra = telemetry_columns(value_names, false);
    names_.insert(names_.end(), extra.begin(), extra.end());
    columns_.assign(names_.size(), {});
  }
  void publish(const TelemetryFrame& frame) noexcept override {
    if (!frame_row(row_, frame, values_, false)) return;
    const double core[10] = {row_.core.t_s,
                             row_.core.position_m.x,
                             row_.core.position_m.y,
                             row_.core.position_m.z,
                             row_.core.velocity_m_per_s.x,
                             row_.core.velocity_m_per_s.y,
                             row_.core.velocity_m_per_s.z,
                             row_.core.force_n.x,
                             row_.core.force_n.y,
                             row_.core.force_n.z};
    const std::lock_guard lock(mutex_);
    try {
      for (std::size_t i = 0; i < 10; ++i) columns_[i].push_back(core[i]);
      for (std::size_t i = 0; i < row_.count && 10 + i < columns_.size(); ++i)
        columns_[10 + i].push_back(row_.values[i]);
    } catch (...) {
      ++dropped_;  // out of memory: the frame is lost, the run goes on
    }
  }
  void finish() noexcept override {}
  /// The rows since the last take (each column as long as the shortest: a row is whole).
  std::vector<std::vector<double>> take() {
    std::vector<std::vector<double>> out(names_.size());
    {
      const std::lock_guard lock(mutex_);
      out.swap(columns_);
    }
    return out;
  }
  const std::vector<std::string>& names() const noexcept { return names_; }

 private:
  std::size_t values_;
  std::vector<std::string> names_;
  TraceRow row_;  ///< the writer thread's
  std::mutex mutex_;
  std::vector<std::vector<double>> columns_;
  std::uint64_t dropped_ = 0;
};

/// `toonforce run` on a thread of its own (run_servo, the command's library), with the live
/// scene API (SceneEditor into the loop's mailbox) and telemetry as columns. Stopping it goes
/// through the session's stop, as a signal stops the command: the loop's shut-down tick
/// commands zero force.
class LiveRun {
 public:
  LiveRun(const std::string& scene_path, const std::optional<std::string>& scene_text, const std::string& script_path,
          const std::string& device, double rate_hz, double duration_s, const std::string& sim_device,
          std::uint64_t seed, const std::string& trace_path, int priority, int cpu, bool lock_memory, bool allow_empty,
          bool strict) {
    std::string text;
    if (scene_text) {
      text = *scene_text;
    } else {
      // The editor needs the text the loop starts with: the file's, read once, for both.
      std::FILE* in = std::fopen(scene_path.c_str(), "rb");
      if (in == nullptr) {
        raise_scene_error(fmt::format("{}: cannot be read: {}", scene_path, std::strerror(errno)), scene_path);
      }
      char buffer[4096];
      for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, in)) > 0;) text.append(buffer, n);
      std::fclose(in);
    }
    // The scene's errors as SceneError before anything opens; run_servo loads the same text.
    scene_ = load_scene(scene_path, text, ScalarKind::kDouble, allow_empty);
    const SceneDescription& scene = scene_;
    if (!script_path.empty()) load_script(script_path, std::nullopt);
    auto editor = SceneEditor<double>::open(text, scene_path, *mailbox_);
    if (!editor) raise_scene_error(editor.error(), scene_path);
    editor_.emplace(std::move(editor.value()));
    // A trace's columns are the starting scene's effects: changes may not alter that list.
    editor_->keep_layout("the run's telemetry columns are the starting scene's effects");
    telemetry_ = std::make_unique<TelemetryColumns>(effect_value_names(make_runtime_scene<double>(scene)));
    live_.of_double = mailbox_.get();

    options_.device = device;
    options_.scene_path = scene_path;
    options_.scene_text = text;
    options_.hand_script_path = script_path;
    options_.sim_device = sim_device;
    options_.seed = seed;
    options_.rate_hz = rate_hz;
    options_.duration_s = duration_s;
    options_.trace_path = trace_path;
    options_.priority = priority;
    options_.cpu = cpu;
    options_.lock_memory = lock_memory;
    options_.allow_non_realtime = true;
    options_.allow_empty = allow_empty;
    options_.strict = strict;
    options_.scalar = ScalarKind::kDouble;  // the live mailbox is the double scene's
    options_.handle_signals = false;        // Python's: Ctrl-C is a KeyboardInterrupt, which stops us
    options_.interactive = false;
    options_.sink = telemetry_.get();
    options_.live = &live_;
    options_.early_stop = &stop_;
    thread_ = std::thread([this] {
      Result<RunSummary> result = run_servo(options_);
      const std::lock_guard lock(result_mutex_);
      result_.emplace(std::move(result));
      done_.store(true);
    });
  }
  ~LiveRun() {
    stop(SIGTERM);
    if (thread_.joinable()) {
      py::gil_scoped_release unlocked;
      thread_.join();
    }
  }
  LiveRun(const LiveRun&) = delete;
  LiveRun& operator=(const LiveRun&) = delete;

  std::uint64_t set(const std::string& effect, const std::string& keys_toml) {
    return sent(editor_->set(effect, keys_toml));
  }
  std::uint64_t add(const std::string& key, const std::string& keys_toml) { return sent(editor_->add(key, keys_toml)); }
  std::uint64_t remove(const std::string& effect) { return sent(editor_->remove(effect)); }
  std::uint64_t fire(const std::string& effect, const std::string& event, double value) {
    return sent(editor_->fire(effect, event, value));
  }
  std::uint64_t load(const std::string& text, const std::string& source) { return sent(editor_->load(text, source)); }
  std::uint64_t applied() const noexcept { return editor_->applied(); }
  bool running() const noexcept { return !done_.load(); }
  /// The telemetry columns' units (those of the starting scene's effects).
  py::dict units() const { return units_of(telemetry_->names(), scene_); }

  /// The telemetry since the last call, as arrays.
  py::dict telemetry() {
    std::vector<std::vector<double>> columns = telemetry_->take();
    std::size_t rows = SIZE_MAX;
    for (const auto& c : columns) rows = std::min(rows, c.size());
    py::dict out;
    for (std::size_t i = 0; i < columns.size(); ++i) {
      columns[i].resize(rows == SIZE_MAX ? 0 : rows);
      out[py::str(telemetry_->names()[i])] = array_of(std::move(columns[i]));
    }
    return out;
  }

  /// Asks the loop to stop (zero force at its shut-down tick), as the signal `signal` would.
  void stop(int signal) noexcept {
    int expected = 0;
    stop_.compare_exchange_strong(expected, signal);
    if (!done_.load()) request_session_stop(signal);
  }

  /// Waits up to `timeout_s` (negative: for ever) for the end; the summary, or None if still running.
  py::object join(double timeout_s) {
    {
      py::gil_scoped_release unlocked;
      const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
      while (!done_.load() && (timeout_s < 0.0 || std::chrono::steady_clock::now() < until)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
      if (!done_.load()) return py::none();
      if (thread_.joinable()) thread_.join();
    }
    const std::lock_guard lock(result_mutex_);
    if (!*result_) raise_value_error(result_->error());
    const RunSummary& s = result_->value();
    py::dict d;
    d["scene_name"] = s.scene_name;
    d["device_name"] = s.device_name;
    d["ticks"] = s.report.ticks;
    d["missed"] = s.report.missed;
    d["watchdog_trips"] = s.report.watchdog_trips;
    d["stop_signal"] = s.report.stop_signal;
    d["fifo"] = s.report.setup.fifo;
    d["frames_written"] = s.frames_written;
    d["frames_dropped"] = s.frames_dropped;
    d["fault_ticks"] = s.fault_ticks;
    d["fault_bits"] = s.fault_bits;
    d["peak_force_n"] = s.peak_force_n;
    d["updates_applied"] = s.updates_applied;
    d["updates_refused"] = s.updates_refused;
    d["trace_error"] = s.trace_error;
    d["text"] = format_run_summary(s, options_);
    return d;
  }

 private:
  std::uint64_t sent(Result<std::uint64_t> sequence) {
    if (!sequence) raise_value_error(sequence.error());
    return sequence.value();
  }

  std::unique_ptr<SceneMailbox<RuntimeScene<double>>> mailbox_ = std::make_unique<SceneMailbox<RuntimeScene<double>>>();
  LiveMailboxes live_;
  SceneDescription scene_;  ///< the starting scene
  std::optional<SceneEditor<double>> editor_;
  std::unique_ptr<TelemetryColumns> telemetry_;
  RunOptions options_;
  std::atomic<int> stop_{0};
  std::atomic<bool> done_{false};
  std::mutex result_mutex_;
  std::optional<Result<RunSummary>> result_;
  std::thread thread_;
};

}  // namespace
}  // namespace toonforce::python

PYBIND11_MODULE(_toonforce, m) {
  using namespace toonforce::python;
  namespace tf = toonforce;
  m.doc() = "toonforce's C++ libraries for Python; use the package `toonforce`, which wraps this module.";
  g_scene_error = PyErr_NewExceptionWithDoc(
      "toonforce.SceneError",
      "A scene or hand script that does not load: the message `toonforce` prints, and where its first error is "
      "(file, line from 1 or 0 for the whole file, key path or '').",
      PyExc_ValueError, nullptr);
  if (g_scene_error == nullptr) throw py::error_already_set();
  m.attr("SceneError") = py::reinterpret_borrow<py::object>(g_scene_error);
  m.def("toml_from_dict", &toml_from_dict, py::arg("scene"));
  m.def("scene_info", &scene_info, py::arg("path"), py::arg("text"), py::arg("scalar"), py::arg("allow_empty"));
  m.def("script_info", &script_info, py::arg("path"), py::arg("text"));
  m.def("check", &check, py::arg("scene_path"), py::arg("scene_text"), py::arg("script_path"), py::arg("script_text"),
        py::arg("device"), py::arg("rate_hz"), py::arg("scalar"), py::arg("allow_empty"), py::arg("strict"));
  m.def("sim", &sim, py::arg("scene_path"), py::arg("scene_text"), py::arg("script_path"), py::arg("script_text"),
        py::arg("rate_hz"), py::arg("scalar"), py::arg("duration_s"), py::arg("device"), py::arg("integrator"),
        py::arg("substeps"), py::arg("seed"), py::arg("sensor_noise_m"), py::arg("sine"), py::arg("allow_empty"),
        py::arg("strict"), py::arg("trace_path"));
  m.def("sim_world", &sim_world, py::arg("scene_path"), py::arg("scene_text"), py::arg("scripts"), py::arg("rate_hz"),
        py::arg("duration_s"), py::arg("device"), py::arg("integrator"), py::arg("substeps"), py::arg("seed"),
        py::arg("fail"), py::arg("trace_path"));
  m.def("run_world", &run_world, py::arg("scene_path"), py::arg("scene_text"), py::arg("scripts"), py::arg("device"),
        py::arg("rate_hz"), py::arg("duration_s"), py::arg("sim_device"), py::arg("seed"), py::arg("fail"),
        py::arg("trace_path"), py::arg("omni_library"), py::arg("priority"), py::arg("cpu"), py::arg("lock_memory"),
        py::arg("allow_empty"), py::arg("strict"));
  m.def("replay", &replay, py::arg("scene_path"), py::arg("scene_text"), py::arg("motion_path"), py::arg("motion_text"),
        py::arg("scalar"), py::arg("sine"), py::arg("allow_empty"), py::arg("output_path"));
  m.def("figures", &figures, py::arg("out_dir"), py::arg("root"), py::arg("format"), py::arg("plot"));
  py::class_<LiveRun>(m, "LiveRun")
      .def(
          py::init<const std::string&, const std::optional<std::string>&, const std::string&, const std::string&,
                   double, double, const std::string&, std::uint64_t, const std::string&, int, int, bool, bool, bool>(),
          py::arg("scene_path"), py::arg("scene_text"), py::arg("script_path"), py::arg("device"), py::arg("rate_hz"),
          py::arg("duration_s"), py::arg("sim_device"), py::arg("seed"), py::arg("trace_path"), py::arg("priority"),
          py::arg("cpu"), py::arg("lock_memory"), py::arg("allow_empty"), py::arg("strict"))
      .def("set", &LiveRun::set, py::arg("effect"), py::arg("keys_toml"))
      .def("add", &LiveRun::add, py::arg("key"), py::arg("keys_toml"))
      .def("remove", &LiveRun::remove, py::arg("effect"))
      .def("fire", &LiveRun::fire, py::arg("effect"), py::arg("event"), py::arg("value"))
      .def("load", &LiveRun::load, py::arg("text"), py::arg("source"))
      .def("applied", &LiveRun::applied)
      .def("running", &LiveRun::running)
      .def("units", &LiveRun::units)
      .def("telemetry", &LiveRun::telemetry)
      .def("stop", &LiveRun::stop, py::arg("signal"))
      .def("join", &LiveRun::join, py::arg("timeout_s"));
  m.attr("version") = TOONFORCE_VERSION;
  m.attr("max_sim_duration_s") = tf::kMaxSimDurationS;
}
