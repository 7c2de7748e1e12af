// SPDX-License-Identifier: Apache-2.0
#pragma once
/// A scene as the viewer page gets it (JSON), written from the effects' schemas: every effect
/// of the file in order with its key, number, line and parameters as the file gives them
/// (defaults filled in), and the names of the values it shows. The page draws the effects it
/// knows (surfaces, cliffs) and lists every effect, a program's own included, with its live
/// values. Start-up code only.
///
///   {"name":..., "file":..., "max_force":8, "effects":[{"key":"surface","number":1,"line":4,
///     "params":{"point":[0,0,0],"normal":[0,0,1],"stiffness":1500,"damping":0,
///               "impact":{"recoil_gain":300,...}},"values":["surface1.contact","surface1.impact_t"],
///     "units":["","s"]}]}

#include <cmath>
#include <string>
#include <tuple>

#include <fmt/format.h>

#include "toonforce/config/scene_file.hpp"
#include "toonforce/trace/json.hpp"

namespace toonforce::viewer {

namespace scene_json_detail {

inline std::string number(double v) { return std::isfinite(v) ? fmt::format("{}", v) : "null"; }
inline std::string vec(const Vec3<double>& v) {
  return fmt::format("[{},{},{}]", number(v.x), number(v.y), number(v.z));
}

template <class P, class Fields>
void write_fields(std::string& out, const P& p, const Fields& fields);

inline void key(std::string& out, std::string_view k) {
  if (out.back() != '{') out += ',';
  out += json_string(k);
  out += ':';
}

template <class P, class T>
void write(std::string& out, const P& p, const schema::Number<P, T>& d) {
  key(out, d.key);
  out += number(static_cast<double>(p.*d.member));
}
template <class P, class T>
void write(std::string& out, const P& p, const schema::Vector<P, T>& d) {
  key(out, d.key);
  out += vec(p.*d.member);
}
template <class P, class E, std::size_t N>
void write(std::string& out, const P& p, const schema::Choice<P, E, N>& d) {
  for (const auto& [name, value] : d.names) {
    if (value == p.*d.member) {
      key(out, d.key);
      out += json_string(name);
    }
  }
}
template <class P, class M, class F>
void write(std::string& out, const P& p, const schema::Inline<P, M, F>& d) {
  write_fields(out, p.*d.member, d.fields);
}
template <class P, class M, class F>
void write(std::string& out, const P& p, const schema::Table<P, M, F>& d) {
  key(out, d.key);
  if (d.present != nullptr && !(p.*d.present)) {
    out += "null";
    return;
  }
  out += '{';
  write_fields(out, p.*d.member, d.fields);
  out += '}';
}
template <class P, class K, class... O>
void write(std::string& out, const P& p, const schema::OneOf<P, K, O...>& d) {
  std::apply(
      [&](const auto&... option) {
        (
            [&] {
              if (p.*d.kind != option.value) return;
              key(out, option.key);
              out += '{';
              write_fields(out, p.*option.member, option.fields);
              out += '}';
            }(),
            ...);
      },
      d.options);
}

template <class P, class Fields>
void write_fields(std::string& out, const P& p, const Fields& fields) {
  std::apply([&](const auto&... d) { (write(out, p, d), ...); }, fields);
}

}  // namespace scene_json_detail

template <template <class> class... Kinds>
std::string scene_json(const SceneFileOf<Kinds...>& scene) {
  using namespace scene_json_detail;
  using File = SceneFileOf<Kinds...>;
  std::string effects;
  std::array<std::size_t, File::kKinds> numbers{};
  for (const SceneEntry& e : scene.order) {
    [&]<std::size_t... I>(std::index_sequence<I...>) {
      (
          [&] {
            if (e.kind != I) return;
            using E = typename File::template Kind<I>;
            const std::size_t n = ++numbers[I];
            std::string params = "{";
            write_fields(params, std::get<I>(scene.params)[e.index], E::schema());
            params += '}';
            std::string values;
            std::string units;
            for (const ValueInfo& v : effect::kValues<E>) {
              values += fmt::format("{}{}", values.empty() ? "" : ",",
                                    json_string(fmt::format("{}{}.{}", E::kKey, n, v.name)));
              units += fmt::format("{}{}", units.empty() ? "" : ",", json_string(v.unit));
            }
            effects += fmt::format(R"({}{{"key":{},"number":{},"line":{},"params":{},"values":[{}],"units":[{}]}})",
                                   effects.empty() ? "" : ",", json_string(E::kKey), n, e.line, params, values, units);
          }(),
          ...);
    }
    (std::make_index_sequence<File::kKinds>{});
  }
  return fmt::format(R"({{"name":{},"file":{},"max_force":{},"effects":[{}]}})", json_string(scene.name),
                     json_string(scene.source), scene.limits.has_max_force ? number(scene.limits.max_force_n) : "null",
                     effects);
}

}  // namespace toonforce::viewer
