// SPDX-License-Identifier: Apache-2.0
#include "toonforce/config/hand_script_file.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "toonforce/config/toml_reader.hpp"

namespace toonforce {

namespace {
/// A hand presses with a few hundred newtons at the very most (and a haptic device takes ~10).
constexpr double kMaxHandForceN = 1000.0;
}  // namespace

using host_sim::HandScript;
using host_sim::HandSegment;
using host_sim::SegmentKind;

namespace {

/// Every segment key, and which kinds take it.
struct KeyUse {
  std::string_view key;
  std::array<bool, 6> used_by;  // move, stroke, strike, cross, hold, release
};
constexpr std::array<KeyUse, 10> kSegmentKeys{{
    //                 move   stroke strike cross  hold   release
    {"to", {true, true, true, true, false, false}},
    {"speed", {true, true, true, true, false, false}},
    {"duration", {true, false, false, false, true, true}},
    {"ramp", {false, true, true, true, false, false}},
    {"stop", {false, true, true, true, false, false}},
    {"force", {false, true, false, true, true, false}},
    {"normal", {false, true, false, true, true, false}},
    {"force_ramp", {true, true, true, true, true, false}},
    {"label", {true, true, true, true, true, true}},
    {"type", {true, true, true, true, true, true}},
}};

bool applies(std::string_view key, SegmentKind kind) {
  for (const auto& use : kSegmentKeys) {
    if (use.key == key) return use.used_by[static_cast<std::size_t>(kind)];
  }
  return false;
}

std::string keys_of(SegmentKind kind) {
  std::string out;
  for (const auto& use : kSegmentKeys) {
    if (use.key == "type" || !use.used_by[static_cast<std::size_t>(kind)]) continue;
    out += fmt::format("{}{}", out.empty() ? "" : ", ", use.key);
  }
  return out;
}

void read_hand(const toml::table& table, ErrorList& errors, HandScript& script, bool& have_start) {
  TableReader r(table, "hand", errors, ScalarKind::kDouble);
  if (const auto start = r.required_vec3("start", "[m]")) {
    script.start_m = *start;
    have_start = true;
  }
  auto& h = script.impedance;
  h.mass_kg = r.number_or("mass", h.mass_kg, Range::kPositive);
  h.stiffness_n_per_m = r.number_or("stiffness", h.stiffness_n_per_m, Range::kPositive);
  h.damping_n_s_per_m = r.number_or("damping", h.damping_n_s_per_m, Range::kNonNegative);
  r.finish();
}

/// Reads one [[segment]]; false if it has an error (already recorded).
bool read_segment(const toml::table& table, std::size_t number, ErrorList& errors, HandSegment& s) {
  const std::size_t before = errors.count();
  TableReader r(table, fmt::format("segment[{}]", number), errors, ScalarKind::kDouble);
  s.line = r.line();
  const auto type = r.optional_string("type");
  if (!type) {
    if (!r.has("type")) {
      r.error("", "missing required key 'type' (move, stroke, strike, cross, hold or release)");
    }
    r.finish();
    return false;
  }
  const auto kind = host_sim::parse_segment_kind(*type);
  if (!kind) {
    static const std::vector<std::string> kKinds{"move", "stroke", "strike", "cross", "hold", "release"};
    const auto near = nearest_key(*type, kKinds);
    r.error("type", fmt::format("unknown segment type '{}'{} (move, stroke, strike, cross, hold or release)",
                                printable(*type), near ? fmt::format(", did you mean '{}'?", *near) : std::string()));
    r.finish();
    return false;
  }
  s.kind = *kind;
  const std::string name(host_sim::segment_kind_name(s.kind));
  // Keys of other kinds get a precise message, not "unknown key".
  for (const auto& use : kSegmentKeys) {
    if (!applies(use.key, s.kind)) {
      r.reject(use.key, fmt::format("does not apply to a {} segment (its keys: {})", name, keys_of(s.kind)));
    }
  }

  if (const auto label = r.optional_string("label")) s.label = *label;
  if (applies("to", s.kind)) {
    if (const auto to = r.required_vec3("to", "[m]")) s.to_m = *to;
  }
  if (applies("speed", s.kind)) s.speed_m_per_s = r.optional_number("speed", Range::kPositive);
  if (applies("duration", s.kind)) {
    s.duration_s =
        r.optional_number("duration", s.kind == SegmentKind::kRelease ? Range::kNonNegative : Range::kPositive);
  }
  if (applies("ramp", s.kind)) s.ramp_s = r.number_or("ramp", s.ramp_s, Range::kNonNegative);
  // A stroke stops at its end; a strike aims through the wall and a crossing carries on.
  s.stop = s.kind == SegmentKind::kStroke;
  if (applies("stop", s.kind)) s.stop = r.optional_bool("stop").value_or(s.stop);
  if (applies("force", s.kind)) {
    s.force_n = r.optional_number("force", Range::kNonNegative);
    if (s.force_n && *s.force_n > kMaxHandForceN) {
      r.error("force", fmt::format("{:g} N is more than a hand can press with: allowed 0 .. {:g} N", *s.force_n,
                                   kMaxHandForceN));
      s.force_n.reset();
    }
  }
  if (applies("normal", s.kind) && r.has("normal")) {
    if (const auto normal = r.required_vec3("normal", "")) {
      const double length = std::sqrt(dot(*normal, *normal));
      if (!(length > 1e-12)) {
        r.error("normal", "must not be a zero vector (it is normalised on load)");
      } else {
        s.normal = *normal * (1.0 / length);
      }
    }
  }
  if (applies("force_ramp", s.kind)) s.force_ramp_s = r.number_or("force_ramp", s.force_ramp_s, Range::kNonNegative);

  switch (s.kind) {
    case SegmentKind::kMove:
      if (r.has("duration") && r.has("speed")) {
        r.error("speed", "a move takes either duration or speed (its mean speed), not both");
      } else if (!r.has("duration") && !r.has("speed")) {
        r.error("", "missing 'duration' [s] or 'speed' [m/s]: a move needs one of them");
      }
      break;
    case SegmentKind::kStroke:
    case SegmentKind::kCross:
      if (!r.has("speed")) r.error("", "missing required key 'speed' [m/s]");
      if (!r.has("force"))
        r.error("", fmt::format("missing required key 'force' [N] (the {} presses with it; 0 to "
                                "only touch)",
                                name));
      break;
    case SegmentKind::kStrike:
      if (!r.has("speed")) r.error("", "missing required key 'speed' [m/s]");
      break;
    case SegmentKind::kHold:
      if (!r.has("duration")) r.error("", "missing required key 'duration' [s]");
      break;
    case SegmentKind::kRelease: break;
  }
  r.finish();
  return errors.count() == before;
}

Result<HandScriptFile> describe(const toml::table& root, ErrorList& errors, std::string_view source_name) {
  HandScriptFile file;
  HandScript& script = file.script;
  script.source = std::string(source_name);
  TableReader r(root, "", errors, ScalarKind::kDouble);
  script.name = r.optional_string("name").value_or(std::filesystem::path(script.source).stem().string());
  bool have_start = false;
  if (const toml::table* hand = r.optional_table("hand")) {
    read_hand(*hand, errors, script, have_start);
  } else if (!r.has("hand")) {
    r.error("", "missing required table [hand] (with start = [x, y, z], where the hand holds the handle at t = 0)");
  }
  const auto segments = r.array_of_tables("segment");
  if (segments.empty() && !r.has("segment")) {
    r.error("", "no [[segment]]: a hand script needs at least one");
  }
  bool segments_ok = true;
  for (std::size_t i = 0; i < segments.size(); ++i) {
    HandSegment s;
    segments_ok = read_segment(*segments[i], i + 1, errors, s) && segments_ok;
    script.segments.push_back(s);
  }
  r.finish();
  if (!errors.empty() || !have_start || !segments_ok) {
    if (errors.empty()) errors.add(0, "", "invalid hand script");
    return Error{errors.text()};
  }

  host_sim::PlanError plan_error;
  auto intent = host_sim::HandIntent::plan(script, plan_error);
  if (!intent) {
    const toml::table& t = *segments[plan_error.segment];
    const toml::node* node = t.get(plan_error.key);
    const std::uint32_t line = node != nullptr ? node->source().begin.line : t.source().begin.line;
    const std::string& label = script.segments[plan_error.segment].label;
    errors.add(line, fmt::format("segment[{}].{}", plan_error.segment + 1, plan_error.key),
               label.empty() ? plan_error.problem : fmt::format("{} (segment '{}')", plan_error.problem, label));
    return Error{errors.text()};
  }
  file.intent = std::move(*intent);
  return file;
}

}  // namespace

Result<HandScriptFile> load_hand_script(const std::string& path) {
  ErrorList errors(path);
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{fmt::format("{}: no such hand script\n", path)};
  // Named as what it is; a device or a pipe is never read (scene_reader.hpp does the same).
  if (std::filesystem::is_directory(path, ec)) return Error{fmt::format("{}: is a directory, not a TOML file\n", path)};
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Error{fmt::format("{}: is not a regular file (a device, a pipe or a socket), not a TOML file\n", path)};
  }
  const auto root = parse_toml_file(path, errors);
  if (!root) return Error{errors.text()};
  return describe(*root, errors, path);
}

Result<HandScriptFile> parse_hand_script(std::string_view text, std::string_view source_name) {
  ErrorList errors{std::string(source_name)};
  const auto root = parse_toml_text(text, errors);
  if (!root) return Error{errors.text()};
  return describe(*root, errors, source_name);
}

}  // namespace toonforce
