// SPDX-License-Identifier: Apache-2.0
#include "toonforce/config/world_file.hpp"

#include "world_reader.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <type_traits>
#include <utility>

#include <fmt/format.h>

#include "toonforce/config/device_keys.hpp"
#include "toonforce/config/scene_reader.hpp"

namespace toonforce {

namespace {

/// The keys a world adds to a scene file; the rest of the file is a scene's (its effects).
constexpr std::array<std::string_view, 4> kWorldKeys{"device", "coupling", "ball", "world"};

constexpr std::array<std::string_view, 3> kBackends{"sim", "falcon", "omni"};
constexpr std::array<std::string_view, 6> kFrameKeys{"name", "backend", "select", "offset", "yaw", "scale"};
constexpr std::array<std::string_view, 4> kCouplingKeys{"between", "stiffness", "damping", "rest_length"};
constexpr std::array<std::string_view, 13> kBallKeys{
    "radius",     "mass",        "stiffness",      "damping",      "drag",     "start", "gravity",
    "wall_point", "wall_normal", "wall_stiffness", "wall_damping", "slippery", "impact"};
constexpr std::array<std::string_view, 1> kWorldTableKeys{"stop"};

/// A yaw beyond a full turn either way is a slip (radians, or a typo), not a placement.
constexpr double kMaxYawDeg = 360.0;

template <class Keys>
std::string joined(const Keys& keys) {
  std::string out;
  for (const auto& k : keys) out += fmt::format("{}{}", out.empty() ? "" : ", ", k);
  return out;
}

/// Every key of a `[[device]]` table: where it sits, then the one-device `[device]` keys.
std::vector<std::string> device_table_keys() {
  std::vector<std::string> keys(kFrameKeys.begin(), kFrameKeys.end());
  for (const DeviceKey& k : device_keys()) {
    keys.emplace_back(k.key);
    if (!k.upper_key.empty()) keys.emplace_back(k.upper_key);
  }
  return keys;
}

/// Reports every key of `table` that is not in `known`, naming the table's keys (these tables
/// are short, and a world file is new to whoever writes one): what TableReader::finish does,
/// plus the list. Called instead of finish() on the world's tables.
void reject_unknown(const toml::table& table, const std::string& path, std::string_view what,
                    const std::vector<std::string>& known, ErrorList& errors) {
  for (const auto& [key, node] : table) {
    const std::string name(key.str());
    if (std::find(known.begin(), known.end(), name) != known.end()) continue;
    std::string problem = fmt::format("unknown key '{}' (", printable(name));
    if (auto near = nearest_key(name, known)) problem += fmt::format("did you mean '{}'? ", *near);
    problem += fmt::format("the keys of {}: {})", what, joined(known));
    errors.add(key.source().begin.line != 0 ? key.source().begin.line : node.source().begin.line, path, problem);
  }
}

template <std::size_t N>
std::vector<std::string> strings(const std::array<std::string_view, N>& keys) {
  return {keys.begin(), keys.end()};
}

WorldDeviceEntry read_device(const toml::table& table, std::size_t number, const std::string& source,
                             const std::vector<std::string>& known, ErrorList& errors) {
  const std::string path = fmt::format("device[{}]", number);
  TableReader r(table, path, errors, ScalarKind::kDouble);
  WorldDeviceEntry d;
  d.line = table.source().begin.line;
  const std::size_t before = errors.count();
  if (auto name = r.optional_string("name")) {
    if (name->empty()) {
      r.error("name", "must not be empty: traces and messages name the device by it");
    } else {
      d.name = std::move(*name);
    }
  } else if (!r.has("name")) {
    r.error("", "missing required key 'name' (traces and messages name the device by it)");
  }
  if (auto backend = r.optional_string("backend")) {
    if (std::find(kBackends.begin(), kBackends.end(), *backend) == kBackends.end()) {
      r.error("backend", fmt::format("unknown backend '{}' (one of {})", printable(*backend), joined(kBackends)));
    } else {
      d.backend = std::move(*backend);
    }
  }
  if (auto select = r.optional_string("select")) d.select = std::move(*select);
  const Vec3<double> offset = r.optional_vec3("offset", "[m]").value_or(Vec3<double>{});
  double yaw_deg = r.number_or("yaw", 0.0, Range::kAny, "the device's turn about the world's z axis [deg]");
  if (std::abs(yaw_deg) > kMaxYawDeg) {
    r.error("yaw", fmt::format("must be in [-{0}, {0}] degrees (got {1}); it is in degrees, not radians", kMaxYawDeg,
                               yaw_deg));
    yaw_deg = 0.0;
  }
  const double scale =
      r.number_or("scale", 1.0, Range::kPositive, "the factor from the device's metres to the world's (1: as it is)");
  d.frame = DeviceFrame::yaw_degrees(yaw_deg, offset, scale);
  if (errors.count() == before) {
    if (const std::string why = check(d.frame); !why.empty()) r.error("", why);
  }
  d.settings.name = d.name;
  d.settings.source = source;
  read_device_keys(r, d.settings);  // the one-device [device] keys, each declared once
  reject_unknown(table, path, "[[device]]", known, errors);
  return d;
}

/// `between = ["a", "b"]`: two distinct names of devices the world has.
void read_between(TableReader& r, const toml::table& table, const std::vector<WorldDeviceEntry>& devices,
                  WorldCouplingEntry& c, bool& ok) {
  const toml::node* node = table.get("between");
  if (node == nullptr) {
    r.error("", "missing required key 'between' (the two devices it couples, like between = [\"left\", \"right\"])");
    ok = false;
    return;
  }
  const toml::array* names = node->as_array();
  if (names == nullptr || names->size() != 2 || !(*names)[0].is_string() || !(*names)[1].is_string()) {
    r.error("between", "must be an array of two device names, like [\"left\", \"right\"]");
    ok = false;
    return;
  }
  std::array<std::size_t, 2> index{};
  std::string known;
  for (const auto& d : devices) {
    if (!d.name.empty()) known += fmt::format("{}'{}'", known.empty() ? "" : ", ", printable(d.name));
  }
  for (std::size_t i = 0; i < 2; ++i) {
    const std::string& name = (*names)[i].as_string()->get();
    index[i] = devices.size();
    for (std::size_t k = 0; k < devices.size(); ++k) {
      if (!devices[k].name.empty() && devices[k].name == name) {
        index[i] = k;
        break;
      }
    }
    if (index[i] == devices.size()) {
      r.error("between", fmt::format("no [[device]] is named '{}' (the devices: {})", printable(name),
                                     known.empty() ? "none named" : known));
      ok = false;
    }
  }
  if (ok && index[0] == index[1]) {
    r.error("between",
            fmt::format("couples '{}' with itself: name two different devices", printable(devices[index[0]].name)));
    ok = false;
  }
  c.a = index[0];
  c.b = index[1];
}

/// `devices = ["a", ...]` of an effect or the ball: the devices it acts on, as a bit mask (all
/// when the key is absent); the key is taken out of the table, which its own reader then reads
/// as in a one-device scene. An error names the table and the devices the world has.
std::uint32_t take_devices(toml::table& table, const std::string& path, const std::vector<WorldDeviceEntry>& devices,
                           ErrorList& errors) {
  const toml::node* node = table.get("devices");
  if (node == nullptr) return kAllDevices;
  const std::uint32_t line = node->source().begin.line;
  std::string known;
  for (const auto& d : devices) {
    if (!d.name.empty()) known += fmt::format("{}'{}'", known.empty() ? "" : ", ", printable(d.name));
  }
  std::uint32_t mask = 0;
  const toml::array* names = node->as_array();
  bool ok = names != nullptr && !names->empty();
  for (std::size_t i = 0; ok && i < names->size(); ++i) ok = (*names)[i].is_string();
  if (!ok) {
    errors.add(line, path + ".devices",
               fmt::format("must be a non-empty array of device names, like [\"left\"] (the devices: {})",
                           known.empty() ? "none named" : known));
  } else {
    for (const auto& entry : *names) {
      const std::string& name = entry.as_string()->get();
      std::size_t k = 0;
      while (k < devices.size() && (devices[k].name.empty() || devices[k].name != name)) ++k;
      if (k == devices.size()) {
        errors.add(line, path + ".devices",
                   fmt::format("no [[device]] is named '{}' (the devices: {})", printable(name),
                               known.empty() ? "none named" : known));
      } else if ((mask & (1U << k)) != 0) {
        errors.add(line, path + ".devices", fmt::format("names '{}' twice", printable(name)));
      } else {
        mask |= 1U << k;
      }
    }
  }
  table.erase("devices");
  return mask == 0 ? kAllDevices : mask;
}

WorldCouplingEntry read_coupling(const toml::table& table, std::size_t number,
                                 const std::vector<WorldDeviceEntry>& devices, ErrorList& errors) {
  const std::string path = fmt::format("coupling[{}]", number);
  TableReader r(table, path, errors, ScalarKind::kDouble);
  WorldCouplingEntry c;
  c.line = table.source().begin.line;
  bool ok = true;
  read_between(r, table, devices, c, ok);
  const std::size_t before = errors.count();
  const between::CouplingParams defaults;
  c.params.stiffness_n_per_m =
      r.number_or("stiffness", defaults.stiffness_n_per_m, Range::kNonNegative, "the spring's stiffness [N/m]");
  c.params.damping_n_s_per_m =
      r.number_or("damping", defaults.damping_n_s_per_m, Range::kNonNegative, "the damper's damping [N s/m]");
  c.params.rest_length_m = r.number_or("rest_length", defaults.rest_length_m, Range::kNonNegative,
                                       "the spring's length at rest [m] (0: pulls the HIPs together)");
  if (errors.count() == before) {
    if (const std::string why = between::check(c.params); !why.empty()) r.error("", why);
  }
  reject_unknown(table, path, "[[coupling]]", strings(kCouplingKeys), errors);
  return c;
}

between::BallParams read_ball(const toml::table& table, ErrorList& errors) {
  TableReader r(table, "ball", errors, ScalarKind::kDouble);
  between::BallParams b;
  const between::BallParams defaults;
  const std::size_t before = errors.count();
  b.radius_m = r.number_or("radius", defaults.radius_m, Range::kPositive, "the ball's radius [m]");
  b.mass_kg = r.number_or("mass", defaults.mass_kg, Range::kPositive, "the ball's mass [kg]");
  b.stiffness_n_per_m =
      r.number_or("stiffness", defaults.stiffness_n_per_m, Range::kNonNegative, "the HIP-ball contact [N/m]");
  b.damping_n_s_per_m =
      r.number_or("damping", defaults.damping_n_s_per_m, Range::kNonNegative, "the HIP-ball contact [N s/m]");
  b.drag_n_s_per_m =
      r.number_or("drag", defaults.drag_n_s_per_m, Range::kNonNegative, "the ball's own viscous drag [N s/m]");
  b.start_m = r.optional_vec3("start", "[m]").value_or(defaults.start_m);
  b.gravity_m_per_s2 = r.optional_vec3("gravity", "[m/s^2]").value_or(defaults.gravity_m_per_s2);
  // Any wall_* key makes the wall; its normal says which side is out, so it has no default.
  b.has_wall = r.has("wall_point") || r.has("wall_normal") || r.has("wall_stiffness") || r.has("wall_damping");
  b.wall_point_m = r.optional_vec3("wall_point", "[m]").value_or(defaults.wall_point_m);
  if (b.has_wall && !r.has("wall_normal")) {
    r.error("", "missing required key 'wall_normal': a wall_* key makes a wall, and its outward normal says which "
                "side the ball stays on (like wall_normal = [0.0, 0.0, 1.0])");
  }
  if (const auto n = r.optional_vec3("wall_normal", "")) {
    if (!(std::sqrt(dot(*n, *n)) > 1e-12)) {
      r.error("wall_normal", "must not be a zero vector (it is normalised on load)");
    } else {
      b.wall_normal = *n;
    }
  }
  b.wall_stiffness_n_per_m = r.number_or("wall_stiffness", defaults.wall_stiffness_n_per_m, Range::kNonNegative,
                                         "the ball-wall contact [N/m]");
  b.wall_damping_n_s_per_m = r.number_or("wall_damping", defaults.wall_damping_n_s_per_m, Range::kNonNegative,
                                         "the ball-wall contact [N s/m]");
  // The ball's surface effects: the single-device tables' keys, units, defaults and ranges
  // (spec effects.md §3-4), read by the same schemas, as [ball.slippery] and [ball.impact].
  if (const toml::table* slippery = r.optional_table(SuperSlippery<double>::kTableKey)) {
    b.has_slippery = true;
    scene_reader::read_sub_table(r, SuperSlippery<double>::kTableKey, *slippery, b.slippery,
                                 SuperSlippery<double>::schema());
  }
  if (const toml::table* impact = r.optional_table(ImpactTransient<double>::kTableKey)) {
    b.has_impact = true;
    scene_reader::read_sub_table(r, ImpactTransient<double>::kTableKey, *impact, b.impact,
                                 ImpactTransient<double>::schema());
  }
  if (errors.count() == before) {
    if (const std::string why = between::check_and_normalise(b); !why.empty()) r.error("", why);
  }
  reject_unknown(table, "ball", "[ball]", strings(kBallKeys), errors);
  return b;
}

StopPolicy read_world_table(const toml::table& table, ErrorList& errors) {
  TableReader r(table, "world", errors, ScalarKind::kDouble);
  StopPolicy stop = StopPolicy::kAll;
  if (auto s = r.optional_string("stop")) {
    if (*s == "all") {
      stop = StopPolicy::kAll;
    } else if (*s == "each") {
      stop = StopPolicy::kEach;
    } else {
      r.error("stop", fmt::format("unknown stop '{}' (one of all: a latched fault on one device holds every "
                                  "device; each: each device stops on its own faults only)",
                                  printable(*s)));
    }
  }
  reject_unknown(table, "world", "[world]", strings(kWorldTableKeys), errors);
  return stop;
}

/// Reads a world from its parsed root. The world's keys are moved out of `root` (moved, not
/// copied: toml++ keeps a node's source region only on a move, and the lines of every message
/// come from it), and what is left is read as a scene: its name and its effects.
Result<WorldDescription> describe_world(toml::table& root, ErrorList& errors, std::string_view source) {
  toml::table world;
  const auto take = [&](std::string_view key) {
    const auto it = root.find(key);
    if (it == root.end()) return;
    const toml::key name = it->first;
    it->second.visit([&](auto& node) { world.insert(name, std::move(node)); });
    root.erase(name.str());
  };
  for (const std::string_view key : kWorldKeys) take(key);
  // A misspelt world key ("couplings") would reach the scene reader as an unknown effect; say
  // what it is near instead.
  const std::vector<std::string> world_keys = strings(kWorldKeys);
  std::vector<std::string> misspelt;
  for (const auto& [key, node] : root) {
    const std::string name(key.str());
    const auto& effects = BuiltinEffects::kKeys;
    if (name == "name" || std::find(effects.begin(), effects.end(), name) != effects.end()) continue;
    if (auto near = nearest_key(name, world_keys)) {
      errors.add(key.source().begin.line != 0 ? key.source().begin.line : node.source().begin.line, "",
                 fmt::format("unknown key '{}' (did you mean '{}'? a world's keys: [[device]], [[coupling]], [ball], "
                             "[world], name and the effects)",
                             printable(name), *near));
      misspelt.push_back(name);
    }
  }
  for (const auto& name : misspelt) root.erase(name);

  WorldDescription w;
  const std::string file(source);
  TableReader r(world, "", errors, ScalarKind::kDouble);
  const auto device_tables = r.array_of_tables("device");
  if (device_tables.empty() && !r.has("device")) {
    errors.add(1, "device", "a world needs at least one [[device]] table");
  }
  if (device_tables.size() > kMaxWorldDevices) {
    errors.add(
        device_tables[kMaxWorldDevices]->source().begin.line, "device",
        fmt::format("{} [[device]] tables, more than the {} a world holds", device_tables.size(), kMaxWorldDevices));
  }
  const std::vector<std::string> device_keys_known = device_table_keys();
  // Only as many as a world holds are read (as a scene reads its effects): past the error
  // above, the rest would only add errors about a file already refused.
  for (std::size_t n = 0; n < device_tables.size() && n < kMaxWorldDevices; ++n) {
    WorldDeviceEntry d = read_device(*device_tables[n], n + 1, file, device_keys_known, errors);
    for (std::size_t k = 0; k < w.devices.size() && !d.name.empty(); ++k) {
      if (w.devices[k].name == d.name) {
        TableReader dr(*device_tables[n], fmt::format("device[{}]", n + 1), errors, ScalarKind::kDouble);
        dr.error("name", fmt::format("'{}' is already the name of device[{}] (line {}): names must be unique",
                                     printable(d.name), k + 1, w.devices[k].line));
        break;
      }
    }
    w.devices.push_back(std::move(d));
  }
  const auto coupling_tables = r.array_of_tables("coupling");
  if (coupling_tables.size() > kMaxCouplings) {
    errors.add(
        coupling_tables[kMaxCouplings]->source().begin.line, "coupling",
        fmt::format("{} [[coupling]] tables, more than the {} a world holds", coupling_tables.size(), kMaxCouplings));
  }
  for (std::size_t n = 0; n < coupling_tables.size() && n < kMaxCouplings; ++n) {
    w.couplings.push_back(read_coupling(*coupling_tables[n], n + 1, w.devices, errors));
  }
  if (toml::table* ball = world.get_as<toml::table>("ball")) {
    w.ball_devices = take_devices(*ball, "ball", w.devices, errors);
  }
  if (const toml::table* ball = r.optional_table("ball")) w.ball = read_ball(*ball, errors);
  if (const toml::table* table = r.optional_table("world")) w.stop = read_world_table(*table, errors);
  r.finish();  // nothing else was moved here

  // Which devices each effect acts on (`devices`, all by default): taken out of the effects'
  // tables before the scene reader, which knows no such key.
  for (std::size_t kind = 0; kind < BuiltinEffects::kCount; ++kind) {
    const std::string_view key = BuiltinEffects::kKeys[kind];
    w.effect_devices[kind].clear();
    toml::array* tables = root.get_as<toml::array>(key);
    if (tables == nullptr) continue;
    for (std::size_t n = 0; n < tables->size(); ++n) {
      toml::table* table = (*tables)[n].as_table();
      const std::uint32_t mask =
          table != nullptr ? take_devices(*table, fmt::format("{}[{}]", key, n + 1), w.devices, errors) : kAllDevices;
      w.effect_devices[kind].push_back(mask);
    }
  }

  // Last: the scene reader returns every error collected so far, the world's with its own.
  auto scene = scene_reader::describe<TOONFORCE_BUILTIN_EFFECTS>(root, errors, ScalarKind::kDouble, source);
  if (!scene) return Error{scene.error()};
  w.scene = std::move(scene).value();
  return w;
}

}  // namespace

Result<WorldDescription> describe_world_table(toml::table root, std::string_view source) {
  ErrorList errors{std::string(source)};
  return describe_world(root, errors, source);
}

std::size_t WorldDescription::device_index(std::string_view name) const noexcept {
  for (std::size_t i = 0; i < devices.size(); ++i) {
    if (devices[i].name == name) return i;
  }
  return devices.size();
}

namespace {
bool is_world_root(const toml::table& root) {
  const toml::node* device = root.get("device");
  return device != nullptr && device->is_array_of_tables();
}
}  // namespace

bool is_world_text(std::string_view text) {
  ErrorList ignored{""};
  const auto root = parse_toml_text(text, ignored);
  return root && is_world_root(*root);
}

bool is_world_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;
  ErrorList ignored(path);
  const auto root = parse_toml_file(path, ignored);
  return root && is_world_root(*root);
}

Result<WorldDescription> parse_world(std::string_view text, std::string_view source_name) {
  ErrorList errors{std::string(source_name)};
  auto root = parse_toml_text(text, errors);
  if (!root) return Error{errors.text()};
  return describe_world(*root, errors, source_name);
}

Result<WorldDescription> load_world_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{fmt::format("{}: no such scene file\n", path)};
  if (std::filesystem::is_directory(path, ec)) return Error{fmt::format("{}: is a directory, not a TOML file\n", path)};
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Error{fmt::format("{}: is not a regular file (a device, a pipe or a socket), not a TOML file\n", path)};
  }
  ErrorList errors(path);
  auto root = parse_toml_file(path, errors);
  if (!root) return Error{errors.text()};
  return describe_world(*root, errors, path);
}

SceneDescription WorldDescription::scene_for(std::size_t device) const {
  SceneDescription out = scene;
  const auto acts_on = [&](std::size_t kind, std::size_t index) {
    const auto& masks = effect_devices[kind];
    return index >= masks.size() || (masks[index] & (1U << device)) != 0;
  };
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (
        [&] {
          auto& all = out.template all<I>();
          std::remove_reference_t<decltype(all)> kept;
          for (std::size_t n = 0; n < all.size(); ++n) {
            if (acts_on(I, n)) kept.push_back(all[n]);
          }
          all = std::move(kept);
        }(),
        ...);
  }
  (std::make_index_sequence<SceneDescription::kKinds>{});
  // The file order of what is left, each effect renumbered within its kind.
  std::vector<SceneEntry> order;
  std::array<std::size_t, SceneDescription::kKinds> next{};
  for (const SceneEntry& e : scene.order) {
    if (!acts_on(e.kind, e.index)) continue;
    order.push_back(SceneEntry{e.kind, next[e.kind]++, e.line});
  }
  out.order = std::move(order);
  return out;
}

WorldConfig world_config(const WorldDescription& world) {
  WorldConfig c;
  c.stop = world.stop;
  for (const WorldCouplingEntry& e : world.couplings) {
    if (c.coupling_count == kMaxCouplings) break;  // a checked description has no more
    c.couplings[c.coupling_count++] = CouplingSpec{e.a, e.b, e.params};
  }
  c.has_ball = world.ball.has_value();
  if (world.ball) c.ball = *world.ball;
  c.ball_devices = world.ball_devices;
  return c;
}

}  // namespace toonforce
