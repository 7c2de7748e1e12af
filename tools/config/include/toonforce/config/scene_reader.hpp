// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Reading a scene file against any effect kinds (scene_file.hpp): each `[[KEY]]` table is
/// read by its effect's schema, every key with its unit, range and default, then the effect's
/// own checks run; errors name file, line and key, unknown keys get a did-you-mean. Start-up
/// code.
///
///   auto scene = read_scene_file<RuntimeSurface, CartoonCliff, Detent>("my_scene.toml");
///   auto runtime = make_runtime_scene<double>(*scene);

#include <algorithm>
#include <filesystem>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include <fmt/format.h>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/telemetry.hpp"

namespace toonforce {

namespace scene_reader {

/// Reads the top-level name and the [device] table (the same for every scene).
void read_settings(TableReader& root, SceneSettings& settings);
/// A file with `[[device]]` tables is a world (world_file.hpp), not a one-device scene: records
/// one error saying so, and what runs it, and returns true. Nothing else of the file is read
/// then: every other error would follow from reading a world as one device.
bool refuse_world(const toml::table& root, ErrorList& errors);
/// Errors about the scene as a whole once its effects are read (empty scene, too many values).
void check_scene(const std::vector<SceneEntry>& order, std::size_t values, const std::string& file, ErrorList& errors);

/// The Q16.16 scene rule (fixed_point in scene_file.hpp): the force laws' products must fit
/// Q16.16 with the HIP anywhere in the workspace at up to max_velocity. Run by `describe` on a
/// scene read for q16.16 that is otherwise clean; `r` reads the effect's table (for lines).
void check_fixed_point(TableReader& r, const SceneSettings& settings, const RuntimeSurface<double>::Params& p);
void check_fixed_point(TableReader& r, const SceneSettings& settings, const CartoonCliff<double>::Params& p);
/// A program's own effect kinds have no Q16.16 rule here (their laws are theirs).
template <class P>
void check_fixed_point(TableReader&, const SceneSettings&, const P&) {}
/// The [device] keys the loop multiplies by a speed (the passivity controller's damping).
void check_fixed_point_device(TableReader& root, const SceneSettings& settings);

/// An effect's check() reports through this: the TOML reader names line and key.
class TableProblems final : public schema::Problems {
 public:
  explicit TableProblems(TableReader& reader) noexcept : reader_(reader) {}
  void add(std::string_view key, std::string_view problem) override { reader_.error(key, problem); }
  void add(std::string_view key, std::string_view problem, double value) override {
    reader_.error(key, fmt::format("{} {:.6g}", problem, value));
  }

 private:
  TableReader& reader_;
};

template <class P, class Fields>
void read_fields(TableReader& r, P& p, const Fields& fields);

template <class P, class T>
void read_field(TableReader& r, P& p, const schema::Number<P, T>& d) {
  if (d.required) {
    if (const auto v = r.required_number(d.key, d.range, d.unit.empty() ? "" : fmt::format("[{}]", d.unit), d.hint)) {
      p.*d.member = static_cast<T>(*v);
    }
  } else {
    p.*d.member = static_cast<T>(r.number_or(d.key, d.fallback, d.range, d.hint));
  }
}

template <class P, class T>
void read_field(TableReader& r, P& p, const schema::Vector<P, T>& d) {
  const auto v = r.required_vec3(d.key, d.unit_length ? d.unit : fmt::format("[{}]", d.unit));
  if (!v) return;
  if (!d.unit_length) {
    p.*d.member = *v;
    return;
  }
  const double length = std::sqrt(dot(*v, *v));
  if (!(length > 1e-12)) {  // spec effects.md §0: a zero normal is an error
    r.error(d.key, "must not be a zero vector (it is normalised on load)");
    return;
  }
  p.*d.member = *v * (1.0 / length);
}

template <class P, class E, std::size_t N>
void read_field(TableReader& r, P& p, const schema::Choice<P, E, N>& d) {
  p.*d.member = d.fallback;
  const auto name = r.optional_string(d.key);
  if (!name) {
    if (d.required && !r.has(d.key)) r.error("", fmt::format("missing required key '{}'", d.key));
    return;
  }
  std::string names;
  for (const auto& [text, value] : d.names) {
    if (text == *name) {
      p.*d.member = value;
      return;
    }
    names += fmt::format("{}{}", names.empty() ? "" : ", ", text);
  }
  r.error(d.key, fmt::format("unknown {} '{}' (one of {})", d.key, printable(*name), names));
}

template <class P, class M, class F>
void read_field(TableReader& r, P& p, const schema::Inline<P, M, F>& d) {
  read_fields(r, p.*d.member, d.fields);
}

template <class M, class F>
void read_sub_table(TableReader& r, std::string_view key, const toml::table& table, M& out, const F& fields) {
  TableReader sub(table, fmt::format("{}.{}", r.path(), key), r.errors(), r.scalar());
  read_fields(sub, out, fields);
  sub.finish();
}

template <class P, class M, class F>
void read_field(TableReader& r, P& p, const schema::Table<P, M, F>& d) {
  const toml::table* table = r.optional_table(d.key);
  if (d.present != nullptr) p.*d.present = table != nullptr;
  if (table != nullptr) {
    read_sub_table(r, d.key, *table, p.*d.member, d.fields);
  } else if (d.present == nullptr && !r.has(d.key)) {
    r.error("", fmt::format("missing required table [{}.{}]", r.path(), d.key));
  }
}

template <class P, class K, class... O>
void read_field(TableReader& r, P& p, const schema::OneOf<P, K, O...>& d) {
  std::string_view chosen;
  std::apply(
      [&](const auto&... option) {
        (
            [&] {
              const toml::table* table = r.optional_table(option.key);
              if (table == nullptr) return;
              if (!chosen.empty()) {
                r.errors().add(table->source().begin.line, r.path(),
                               fmt::format("has both [{0}.{1}] and [{0}.{2}]: {3}",
                                           r.path().substr(0, r.path().find('[')), chosen, option.key, d.conflict));
                return;
              }
              chosen = option.key;
              p.*d.kind = option.value;
              read_sub_table(r, option.key, *table, p.*option.member, option.fields);
            }(),
            ...);
      },
      d.options);
}

template <class P, class Fields>
void read_fields(TableReader& r, P& p, const Fields& fields) {
  std::apply([&](const auto&... d) { (read_field(r, p, d), ...); }, fields);
}

/// Reads one `[[KEY]]` table as an effect of type E (its `number`-th, from 1).
template <class E>
typename E::Params read_effect(const toml::table& table, std::size_t number, ErrorList& errors, ScalarKind scalar) {
  TableReader r(table, fmt::format("{}[{}]", E::kKey, number), errors, scalar);
  typename E::Params p{};
  const std::size_t before = errors.count();
  read_fields(r, p, E::schema());
  // The effect's checks across keys need every key it reads: only when those were all fine.
  if (errors.count() == before) {
    TableProblems problems(r);
    effect::check<E>(p, problems, scalar);
  }
  r.finish();
  return p;
}

template <template <class> class... Kinds>
Result<SceneFileOf<Kinds...>> describe(const toml::table& root, ErrorList& errors, ScalarKind scalar,
                                       std::string_view source_name) {
  using File = SceneFileOf<Kinds...>;
  if (refuse_world(root, errors)) return Error{errors.text()};
  File scene;
  scene.source = std::string(source_name);
  TableReader r(root, "", errors, scalar);
  scene.name = std::filesystem::path(scene.source).stem().string();
  read_settings(r, scene);
  std::size_t values = 0;
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (
        [&] {
          using E = typename File::template Kind<I>;
          const auto tables = r.array_of_tables(E::kKey);
          constexpr std::size_t kMax = effect::kMaxPerScene<E>;
          if (tables.size() > kMax) {
            errors.add(tables[kMax]->source().begin.line, std::string(E::kKey),
                       fmt::format("{} {} tables, more than the {} a scene holds", tables.size(), E::kKey, kMax));
          }
          for (std::size_t n = 0; n < tables.size() && n < kMax; ++n) {
            std::get<I>(scene.params).push_back(read_effect<E>(*tables[n], n + 1, errors, scalar));
            scene.order.push_back({I, n, tables[n]->source().begin.line});
            values += effect::kValueCount<E>;
          }
        }(),
        ...);
  }
  (std::make_index_sequence<File::kKinds>{});
  std::string kinds;
  ((kinds += fmt::format("{}[[{}]]", kinds.empty() ? "" : ", ", Kinds<double>::kKey)), ...);
  r.finish("effect", fmt::format("the effects this program reads: {}", kinds));
  check_scene(scene.order, values, scene.source, errors);
  // Q16.16: values that fit one by one (checked as read) may still saturate the laws' products
  // in normal use (spec effects.md §7); checked once every value is known and fine.
  if (scalar == ScalarKind::kQ16_16 && errors.empty()) {
    check_fixed_point_device(r, scene);
    [&]<std::size_t... I>(std::index_sequence<I...>) {
      (
          [&] {
            using E = typename File::template Kind<I>;
            const toml::array* tables = root[E::kKey].as_array();
            const auto& all = scene.template all<I>();
            for (std::size_t n = 0; tables != nullptr && n < all.size() && n < tables->size(); ++n) {
              if (const toml::table* table = (*tables)[n].as_table()) {
                TableReader effect(*table, fmt::format("{}[{}]", E::kKey, n + 1), errors, scalar);
                check_fixed_point(effect, scene, all[n]);
              }
            }
          }(),
          ...);
    }
    (std::make_index_sequence<File::kKinds>{});
  }
  if (!errors.empty()) return Error{errors.text()};
  // File order across kinds: their forces add in this order (spec §0).
  std::stable_sort(scene.order.begin(), scene.order.end(),
                   [](const SceneEntry& a, const SceneEntry& b) { return a.line < b.line; });
  return scene;
}

}  // namespace scene_reader

/// Reads and checks a scene of the effect kinds `Kinds` from text; `source_name` stands for the
/// file in messages.
template <template <class> class... Kinds>
Result<SceneFileOf<Kinds...>> read_scene(std::string_view text, std::string_view source_name,
                                         ScalarKind scalar = ScalarKind::kDouble) {
  ErrorList errors{std::string(source_name)};
  const auto root = parse_toml_text(text, errors);
  if (!root) return Error{errors.text()};
  return scene_reader::describe<Kinds...>(*root, errors, scalar, source_name);
}

/// The same from a file.
template <template <class> class... Kinds>
Result<SceneFileOf<Kinds...>> read_scene_file(const std::string& path, ScalarKind scalar = ScalarKind::kDouble) {
  ErrorList errors(path);
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{fmt::format("{}: no such scene file\n", path)};
  // Named as what it is, not "no such file"; a device or a pipe is never read (/dev/zero
  // would never end).
  if (std::filesystem::is_directory(path, ec)) return Error{fmt::format("{}: is a directory, not a TOML file\n", path)};
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Error{fmt::format("{}: is not a regular file (a device, a pipe or a socket), not a TOML file\n", path)};
  }
  const auto root = parse_toml_file(path, errors);
  if (!root) return Error{errors.text()};
  return scene_reader::describe<Kinds...>(*root, errors, scalar, path);
}

}  // namespace toonforce
