// SPDX-License-Identifier: Apache-2.0
// Live scene changes, checked as scene files are (scene_editor.hpp; docs/spec/live-scenes.md).
// The document is the scene's TOML: each change edits a copy of it and reads the copy with the
// scene files' own reader, so a change is refused with the very message a file would get.

#include "toonforce/config/scene_editor.hpp"
#include "toonforce/config/world_editor.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include <fmt/format.h>

#include "toonforce/config/scene_reader.hpp"
#include "toonforce/config/toml_reader.hpp"
#include "world_reader.hpp"

namespace toonforce {

namespace {

using Kinds = RuntimeScene<double>;

/// "surface2" or "surface[2]": the kind's index and the effect's index among its kind (from 0).
struct EffectName {
  std::size_t kind = 0;
  std::size_t index = 0;
  std::string key;
};

std::string kind_list() {
  std::string out;
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    ((out += fmt::format("{}{}", out.empty() ? "" : ", ", Kinds::Kind<I>::kKey)), ...);
  }
  (std::make_index_sequence<Kinds::kind_count()>{});
  return out;
}

Result<EffectName> parse_effect_name(std::string_view text, const toml::table& doc) {
  std::size_t split = 0;
  while (split < text.size() && std::isalpha(static_cast<unsigned char>(text[split])) != 0) ++split;
  std::string_view key = text.substr(0, split);
  std::string_view digits = text.substr(split);
  if (digits.size() >= 2 && digits.front() == '[' && digits.back() == ']') digits = digits.substr(1, digits.size() - 2);
  const std::size_t kind = Kinds::kind_index(key);
  std::size_t number = 0;
  bool ok = !digits.empty() && digits.size() <= 4;
  for (const char c : digits) {
    if (std::isdigit(static_cast<unsigned char>(c)) == 0)
      ok = false;
    else
      number = number * 10 + static_cast<std::size_t>(c - '0');
  }
  if (kind == Kinds::kind_count() || !ok || number == 0) {
    return Error{fmt::format("'{}' names no effect: write the kind and its number from 1, as in traces (surface2, "
                             "cliff1); the kinds are {}\n",
                             text, kind_list())};
  }
  const toml::array* all = doc[key].as_array();
  const std::size_t count = all != nullptr ? all->size() : 0;
  if (number > count) {
    return Error{fmt::format("'{}': the scene has {} {}(s)\n", text, count, key)};
  }
  return EffectName{kind, number - 1, std::string(key)};
}

/// The keys of `from` replace those of `into`; a table given for a table is merged the same way.
void merge(toml::table& into, const toml::table& from) {
  for (auto&& [key, node] : from) {
    toml::node* old = into.get(key.str());
    if (old != nullptr && old->is_table() && node.is_table()) {
      merge(*old->as_table(), *node.as_table());
    } else {
      into.insert_or_assign(key, node);
    }
  }
}

std::vector<std::int16_t> same_effects(const std::vector<SceneEntry>& order) {
  std::vector<std::int16_t> continues;
  for (const SceneEntry& e : order) continues.push_back(static_cast<std::int16_t>(e.index));
  return continues;
}

std::size_t place_of(const std::vector<SceneEntry>& order, std::size_t kind, std::size_t index) {
  for (std::size_t i = 0; i < order.size(); ++i) {
    if (order[i].kind == kind && order[i].index == index) return i;
  }
  return order.size();
}

/// Why `value` is no impact speed a fire of surface `name` may carry (empty: it is).
std::string impact_problem(const SceneDescription& scene, const EffectName& name, double value, ScalarKind scalar_kind,
                           const std::string& what) {
  if (name.kind != Kinds::kind_index(RuntimeSurface<double>::kKey)) return {};
  if (!scene.of<RuntimeSurface>()[name.index].impact.enabled) {
    return fmt::format("{}: this surface has no impact table: set one first (set {}{} with [impact] keys)\n", what,
                       name.key, name.index + 1);
  }
  // v_i [m/s]: what the transient scales with (spec effects.md §4). Its peak force
  // v_i d (|k_r| + |k_osc|) must be a force the loop's scalar represents, squared too (a
  // force's norm): beyond it the loop faulted with zero force on a speed that got "ok"
  // (5 m/s on Q16.16 with typical gains; 1e300 in double). The smallest speed is the
  // scalar's resolution (Q16.16: 2^-16; below it the transient is zero).
  const auto& law = scene.of<RuntimeSurface>()[name.index].impact.law;
  const double d = std::fabs(static_cast<double>(law.duration_s));
  const double gain = std::fabs(static_cast<double>(law.recoil_gain_n_per_m)) +
                      std::fabs(static_cast<double>(law.oscillation_gain_n_per_m));
  double largest_force = std::sqrt(std::numeric_limits<double>::max());
  double lowest = std::numeric_limits<double>::min();
  std::string_view scalar = "double";
  if (scalar_kind == ScalarKind::kFloat) {
    largest_force = std::sqrt(static_cast<double>(std::numeric_limits<float>::max()));
    lowest = static_cast<double>(std::numeric_limits<float>::min());
    scalar = "float";
  } else if (scalar_kind == ScalarKind::kQ16_16) {
    largest_force = std::sqrt(32767.0);
    lowest = 1.0 / 65536.0;
    scalar = "q16.16";
  }
  const double highest = largest_force / std::max({1.0, d, d * gain});
  if (!(std::isfinite(value) && value >= lowest && value <= highest)) {
    return fmt::format(
        "{}: the impact speed must be within [{:.3g}, {:.6g}] m/s on the {} loop with this impact table (its peak "
        "force v_i d (|recoil_gain| + |oscillation_gain|) at most {:.6g} N) (got {})\n",
        what, lowest, highest, scalar, largest_force, value);
  }
  return {};
}

}  // namespace

struct SceneDocument::Impl {
  toml::table doc;
  ScalarKind scalar = ScalarKind::kDouble;
  SceneDescription scene;

  /// Reads `candidate` as a scene file named `name` would be; the effects keep `order` (the
  /// document's, not the lines': a change's keys come from another text).
  Result<SceneDescription> check(const toml::table& candidate, const std::string& name,
                                 std::optional<std::vector<SceneEntry>> order) const {
    ErrorList errors(name);
    auto read = scene_reader::describe<TOONFORCE_BUILTIN_EFFECTS>(candidate, errors, scalar, name);
    if (!read) return Error{read.error()};
    read->source = scene.source;
    read->name = scene.name;
    if (order) read->order = std::move(*order);
    return read;
  }

  Result<SceneChange> change(toml::table candidate, std::string what, std::vector<SceneEntry> order,
                             std::vector<std::int16_t> continues) const {
    auto read = check(candidate, what, std::move(order));
    if (!read) return Error{read.error()};
    SceneChange c;
    c.scene = std::move(read.value());
    c.continues = std::move(continues);
    c.what = std::move(what);
    c.document = std::make_shared<toml::table>(std::move(candidate));
    return c;
  }

  Result<toml::table> keys_of(std::string_view text, const std::string& what) const {
    ErrorList errors(what);
    auto keys = parse_toml_text(text, errors);
    if (!keys) return Error{errors.text()};
    return std::move(*keys);
  }
};

SceneDocument::SceneDocument(std::unique_ptr<Impl> impl) noexcept : impl_(std::move(impl)) {}
SceneDocument::SceneDocument(SceneDocument&&) noexcept = default;
SceneDocument& SceneDocument::operator=(SceneDocument&&) noexcept = default;
SceneDocument::~SceneDocument() = default;

Result<SceneDocument> SceneDocument::parse(std::string_view text, std::string source, ScalarKind scalar) {
  ErrorList errors(source);
  auto root = parse_toml_text(text, errors);
  if (!root) return Error{errors.text()};
  auto scene = scene_reader::describe<TOONFORCE_BUILTIN_EFFECTS>(*root, errors, scalar, source);
  if (!scene) return Error{scene.error()};
  auto impl = std::make_unique<Impl>();
  impl->doc = std::move(*root);
  impl->scalar = scalar;
  impl->scene = std::move(scene.value());
  return SceneDocument(std::move(impl));
}

const SceneDescription& SceneDocument::scene() const noexcept { return impl_->scene; }

Result<SceneChange> SceneDocument::set(std::string_view effect, std::string_view keys_toml) const {
  auto name = parse_effect_name(effect, impl_->doc);
  if (!name) return Error{name.error()};
  const std::string what = fmt::format("set {}{}", name->key, name->index + 1);
  auto keys = impl_->keys_of(keys_toml, what);
  if (!keys) return Error{keys.error()};
  toml::table candidate = impl_->doc;
  merge(*(*candidate[name->key].as_array())[name->index].as_table(), keys.value());
  const auto& order = impl_->scene.order;
  return impl_->change(std::move(candidate), what, order, same_effects(order));
}

Result<SceneChange> SceneDocument::add(std::string_view key, std::string_view keys_toml) const {
  const std::size_t kind = Kinds::kind_index(key);
  if (kind == Kinds::kind_count()) {
    return Error{fmt::format("add: '{}' is no effect kind; the kinds are {}\n", key, kind_list())};
  }
  const std::string what = fmt::format("add {}", key);
  auto keys = impl_->keys_of(keys_toml, what);
  if (!keys) return Error{keys.error()};
  toml::table candidate = impl_->doc;
  if (candidate.get(key) == nullptr) candidate.insert(key, toml::array{});
  toml::array* all = candidate[key].as_array();
  if (all == nullptr) return Error{fmt::format("{}: the scene's '{}' is not an array of tables\n", what, key)};
  const std::size_t index = all->size();
  all->push_back(std::move(keys.value()));
  std::vector<SceneEntry> order = impl_->scene.order;
  std::vector<std::int16_t> continues = same_effects(order);
  order.push_back({kind, index, 0});
  continues.push_back(-1);
  return impl_->change(std::move(candidate), what, std::move(order), std::move(continues));
}

Result<SceneChange> SceneDocument::remove(std::string_view effect) const {
  auto name = parse_effect_name(effect, impl_->doc);
  if (!name) return Error{name.error()};
  const std::string what = fmt::format("remove {}{}", name->key, name->index + 1);
  toml::table candidate = impl_->doc;
  toml::array& all = *candidate[name->key].as_array();
  all.erase(all.begin() + static_cast<std::ptrdiff_t>(name->index));
  if (all.empty()) candidate.erase(name->key);
  // The later effects of its kind move down one; their states go with them.
  std::vector<SceneEntry> order;
  std::vector<std::int16_t> continues;
  for (const SceneEntry& e : impl_->scene.order) {
    if (e.kind == name->kind && e.index == name->index) continue;
    SceneEntry moved = e;
    if (e.kind == name->kind && e.index > name->index) --moved.index;
    order.push_back(moved);
    continues.push_back(static_cast<std::int16_t>(e.index));
  }
  return impl_->change(std::move(candidate), what, std::move(order), std::move(continues));
}

Result<SceneChange> SceneDocument::load(std::string_view text, std::string source) const {
  const std::string what = fmt::format("load {}", source);
  ErrorList errors(source);
  auto root = parse_toml_text(text, errors);
  if (!root) return Error{errors.text()};
  // The [device] table sets the loop's safety limits, fixed when it started: a scene that asks
  // for others would run with the old ones, so it is refused rather than half applied.
  const toml::node* before = impl_->doc.get("device");
  const toml::node* after = root->get("device");
  const bool same_device =
      (before == nullptr && after == nullptr) || (before != nullptr && after != nullptr && before->is_table() &&
                                                  after->is_table() && *before->as_table() == *after->as_table());
  if (!same_device) {
    return Error{fmt::format("{}: its [device] table differs from the running scene's: the safety limits are the "
                             "loop's, fixed when it starts; stop and start with this scene instead\n",
                             what)};
  }
  ErrorList check_errors(source);
  auto scene = scene_reader::describe<TOONFORCE_BUILTIN_EFFECTS>(*root, check_errors, impl_->scalar, source);
  if (!scene) return Error{scene.error()};
  SceneChange c;
  c.continues.assign(scene->order.size(), -1);  // another scene: every state starts fresh
  c.scene = std::move(scene.value());
  c.what = what;
  c.document = std::make_shared<toml::table>(std::move(*root));
  return c;
}

Result<SceneChange> SceneDocument::fire(std::string_view effect, std::string_view event, double value) const {
  auto name = parse_effect_name(effect, impl_->doc);
  if (!name) return Error{name.error()};
  const std::string what = fmt::format("fire {}{} {}", name->key, name->index + 1, event);
  const auto& order = impl_->scene.order;
  const std::size_t place = place_of(order, name->kind, name->index);
  const auto runtime = make_runtime_scene<double>(impl_->scene);
  if (place == order.size() || runtime.event_index(place, event) < 0) {
    return Error{
        fmt::format("{}: a {} has no event '{}' (surface: impact; cliff: look_down)\n", what, name->key, event)};
  }
  if (std::string bad = impact_problem(impl_->scene, name.value(), value, impl_->scalar, what); !bad.empty()) {
    return Error{std::move(bad)};
  }
  SceneChange c;
  c.scene = impl_->scene;
  c.continues = same_effects(order);
  c.events.push_back({place, std::string(event), value});
  c.what = what;
  c.document = std::make_shared<toml::table>(impl_->doc);
  return c;
}

void SceneDocument::commit(const SceneChange& change) {
  if (change.document) impl_->doc = *std::static_pointer_cast<toml::table>(change.document);
  impl_->scene = change.scene;
  ++changes_;
}

// ---- Worlds (world_editor.hpp) ----

struct WorldEditor::Impl {
  toml::table doc;
  WorldDescription world;
  std::string source;
  Mailbox* mailbox = nullptr;
  std::uint64_t changes = 0;

  static bool same_layout(const std::vector<SceneEntry>& a, const std::vector<SceneEntry>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (a[i].kind != b[i].kind || a[i].index != b[i].index) return false;
    }
    return true;
  }

  /// The update that puts `next` on every device (its effects' states carry over), with
  /// `events` (per device) fired after; pushed, then `next` and `candidate` are the world.
  Result<std::uint64_t> send(WorldDescription next, toml::table candidate, const std::string& what,
                             const std::vector<std::vector<SceneEvent>>& events) {
    const std::size_t n = world.devices.size();
    if (n > Update::kMaxDevices) {
      return Error{fmt::format("{}: a live world has at most {} devices\n", what, Update::kMaxDevices)};
    }
    auto update = std::make_unique<Update>();  // built here, off the loop's thread
    for (std::size_t i = 0; i < n; ++i) {
      const SceneDescription mine = next.scene_for(i);
      if (!same_layout(mine.order, world.scene_for(i).order)) {
        return Error{fmt::format("{}: refused: it changes the effects of device '{}', and this run's trace and viewer "
                                 "show each device's effects by column (docs/spec/control-protocol.md)\n",
                                 what, world.devices[i].name)};
      }
      auto& part = update->devices[i];
      part.scene = make_runtime_scene<double>(mine);
      const std::vector<std::int16_t> continues = same_effects(mine.order);
      for (std::size_t e = 0; e < continues.size() && e < part.continues.size(); ++e) part.continues[e] = continues[e];
      for (std::size_t e = 0; i < events.size() && e < events[i].size() && e < part.events.size(); ++e) {
        part.events[part.event_count++] = events[i][e];
      }
    }
    update->device_count = static_cast<std::uint8_t>(n);
    update->sequence = changes + 1;
    if (!mailbox->push(*update)) {
      return Error{fmt::format("{}: not applied: the loop has not yet taken the {} change(s) before it (it takes one a "
                               "tick); try again\n",
                               what, mailbox->capacity())};
    }
    world = std::move(next);
    doc = std::move(candidate);
    return ++changes;
  }

  /// "coupling1", "ball", "device2", "world": what a world keeps while it runs.
  static std::string fixed_part(std::string_view effect) {
    for (const std::string_view fixed : {"coupling", "ball", "device", "world"}) {
      if (effect.starts_with(fixed)) {
        return fmt::format("'{}': the devices, couplings, ball and [world] of a world are fixed while it runs (they "
                           "are its file's); the effects (surface1, cliff1, ...) take changes\n",
                           effect);
      }
    }
    return {};
  }
};

WorldEditor::WorldEditor(std::unique_ptr<Impl> impl) noexcept : impl_(std::move(impl)) {}
WorldEditor::WorldEditor(WorldEditor&&) noexcept = default;
WorldEditor& WorldEditor::operator=(WorldEditor&&) noexcept = default;
WorldEditor::~WorldEditor() = default;

Result<WorldEditor> WorldEditor::open(std::string_view text, std::string source, Mailbox& mailbox) {
  ErrorList errors(source);
  auto root = parse_toml_text(text, errors);
  if (!root) return Error{errors.text()};
  auto world = describe_world_table(*root, source);
  if (!world) return Error{world.error()};
  if (world->devices.size() > Update::kMaxDevices) {
    return Error{fmt::format("{}: a live world has at most {} devices\n", source, Update::kMaxDevices)};
  }
  auto impl = std::make_unique<Impl>();
  impl->doc = std::move(*root);
  impl->world = std::move(world.value());
  impl->source = std::move(source);
  impl->mailbox = &mailbox;
  return WorldEditor(std::move(impl));
}

const WorldDescription& WorldEditor::world() const noexcept { return impl_->world; }
std::uint64_t WorldEditor::applied() const noexcept { return impl_->mailbox->applied(); }

Result<std::uint64_t> WorldEditor::set(std::string_view effect, std::string_view keys_toml) {
  if (std::string fixed = Impl::fixed_part(effect); !fixed.empty()) return Error{std::move(fixed)};
  auto name = parse_effect_name(effect, impl_->doc);
  if (!name) return Error{name.error()};
  const std::string what = fmt::format("set {}{}", name->key, name->index + 1);
  ErrorList errors(what);
  auto keys = parse_toml_text(keys_toml, errors);
  if (!keys) return Error{errors.text()};
  if (keys->contains("devices")) {
    return Error{fmt::format("{}: 'devices' is fixed while a world runs: each device's trace and viewer columns are "
                             "its effects'\n",
                             what)};
  }
  toml::table candidate = impl_->doc;
  merge(*(*candidate[name->key].as_array())[name->index].as_table(), keys.value());
  auto next = describe_world_table(candidate, what);
  if (!next) return Error{next.error()};
  return impl_->send(std::move(next.value()), std::move(candidate), what, {});
}

Result<std::uint64_t> WorldEditor::fire(std::string_view effect, std::string_view event, double value) {
  if (std::string fixed = Impl::fixed_part(effect); !fixed.empty()) return Error{std::move(fixed)};
  auto name = parse_effect_name(effect, impl_->doc);
  if (!name) return Error{name.error()};
  const std::string what = fmt::format("fire {}{} {}", name->key, name->index + 1, event);
  const WorldDescription& world = impl_->world;
  const std::size_t place = place_of(world.scene.order, name->kind, name->index);
  if (place == world.scene.order.size() || make_runtime_scene<double>(world.scene).event_index(place, event) < 0) {
    return Error{
        fmt::format("{}: a {} has no event '{}' (surface: impact; cliff: look_down)\n", what, name->key, event)};
  }
  if (std::string bad = impact_problem(world.scene, name.value(), value, ScalarKind::kDouble, what); !bad.empty()) {
    return Error{std::move(bad)};
  }
  // On each device the effect acts on: its place there (each device's scene numbers its own).
  const auto& masks = world.effect_devices[name->kind];
  std::vector<std::vector<SceneEvent>> events(world.devices.size());
  for (std::size_t i = 0; i < world.devices.size(); ++i) {
    const auto acts_on = [&](std::size_t n) { return n >= masks.size() || (masks[n] & (1U << i)) != 0; };
    if (!acts_on(name->index)) continue;
    std::size_t mine = 0;
    for (std::size_t n = 0; n < name->index; ++n) mine += acts_on(n) ? 1U : 0U;
    const SceneDescription scene = world.scene_for(i);
    const std::size_t at = place_of(scene.order, name->kind, mine);
    const int number = make_runtime_scene<double>(scene).event_index(at, event);
    if (at == scene.order.size() || number < 0) continue;
    events[i].push_back(SceneEvent{static_cast<std::uint16_t>(at), static_cast<std::uint8_t>(number), value});
  }
  return impl_->send(world, impl_->doc, what, events);
}

Result<std::uint64_t> WorldEditor::add(std::string_view kind) {
  return Error{fmt::format("add {}: refused: a world's list of effects is fixed while it runs (each device's trace "
                           "and viewer columns are its effects'); move an effect out of reach or retune it instead\n",
                           kind)};
}
Result<std::uint64_t> WorldEditor::remove(std::string_view effect) {
  return Error{fmt::format("remove {}: refused: a world's list of effects is fixed while it runs (each device's trace "
                           "and viewer columns are its effects'); move an effect out of reach or retune it instead\n",
                           effect)};
}
Result<std::uint64_t> WorldEditor::load(std::string_view source) {
  return Error{fmt::format("load {}: refused: a running world keeps its devices and its effects; stop and start with "
                           "that scene instead\n",
                           source)};
}

}  // namespace toonforce
