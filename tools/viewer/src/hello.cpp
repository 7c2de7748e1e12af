#include "toonforce/viewer/hello.hpp"

#include <cmath>

#include <fmt/format.h>

#include "toonforce/control/faults.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/trace/json.hpp"
#include "toonforce/viewer/view_frame.hpp"

namespace toonforce::viewer {

namespace {

std::string number(double v) { return std::isfinite(v) ? fmt::format("{}", v) : "null"; }
std::string vec(const Vec3<double>& v) { return fmt::format("[{},{},{}]", number(v.x), number(v.y), number(v.z)); }

std::string scene_json(const SceneDescription& scene) {
  std::string surfaces;
  for (const auto& s : scene.surfaces) {
    std::string kind = "wall";
    if (s.slippery) {
      kind = "slippery";
    } else if (s.impact) {
      kind = "impact";
    } else if (s.friction) {
      kind = "friction";
    }
    std::string impact = "null";
    if (s.impact) {
      impact = fmt::format(R"({{"duration":{},"frequency":{},"recoil_gain":{},"oscillation_gain":{}}})",
                           number(s.impact->duration_s), number(s.impact->frequency_hz),
                           number(s.impact->recoil_gain_n_per_m), number(s.impact->oscillation_gain_n_per_m));
    }
    surfaces += fmt::format(R"({}{{"point":{},"normal":{},"stiffness":{},"kind":"{}","impact":{},"line":{}}})",
                            surfaces.empty() ? "" : ",", vec(s.plane.point_m), vec(s.plane.normal),
                            number(s.stiffness_n_per_m), kind, impact, s.line);
  }
  std::string cliffs;
  for (const auto& c : scene.cliffs) {
    cliffs += fmt::format(
        R"({}{{"point":{},"normal":{},"axis":{},"gap_min":{},"gap_max":{},"stiffness":{},"speed_threshold":{},"line":{}}})",
        cliffs.empty() ? "" : ",", vec(c.ground.point_m), vec(c.ground.normal), vec(c.axis), number(c.gap_min_m),
        number(c.gap_max_m), number(c.stiffness_n_per_m), number(c.speed_threshold_m_per_s), c.line);
  }
  return fmt::format(R"({{"name":{},"file":{},"max_force":{},"surfaces":[{}],"cliffs":[{}]}})", json_string(scene.name),
                     json_string(scene.source),
                     scene.limits.has_max_force ? number(scene.limits.max_force_n) : std::string("null"), surfaces,
                     cliffs);
}

}  // namespace

std::string make_hello(const HelloInfo& info) {
  std::string columns;
  for (const std::string_view c : kViewColumns) columns += fmt::format("{}\"{}\"", columns.empty() ? "" : ",", c);
  std::string faults;
  for (const Fault f : kAllFaults) {
    faults += fmt::format("{}[{},{}]", faults.empty() ? "" : ",", static_cast<std::uint32_t>(f), json_string(fault_name(f)));
  }
  const std::pair<Limit, std::string_view> limit_names[] = {
      {Limit::kRateLimited, "rate-limited"}, {Limit::kClamped, "clamped"},       {Limit::kThermal, "thermal derating"},
      {Limit::kPassivity, "passivity damping"}, {Limit::kSoftStart, "soft start"}, {Limit::kEngaging, "engaging"}};
  std::string limits;
  for (const auto& [bit, name] : limit_names) {
    limits += fmt::format("{}[{},{}]", limits.empty() ? "" : ",", static_cast<unsigned>(bit), json_string(name));
  }
  std::string states;
  for (int s = 0; s <= static_cast<int>(LoopState::kFaulted); ++s) {
    states += fmt::format("{}\"{}\"", states.empty() ? "" : ",", to_string(static_cast<LoopState>(s)));
  }
  std::string workspace = "null";
  if (info.workspace_min_m && info.workspace_max_m) {
    workspace = fmt::format(R"({{"min":{},"max":{}}})", vec(*info.workspace_min_m), vec(*info.workspace_max_m));
  }
  return fmt::format(
      R"({{"type":"hello","protocol":1,"source":{},"title":{},"rate_hz":{},"live":{},"pacing":{},"columns":[{}],)"
      R"("batch_header":4,"scene":{},"workspace":{},"faults":[{}],"limits":[{}],"states":[{}],"latched_mask":{}}})",
      json_string(info.source), json_string(info.title), number(info.rate_hz), info.live, json_string(info.pacing), columns,
      info.scene != nullptr ? scene_json(*info.scene) : std::string("null"), workspace, faults, limits, states,
      kLatchedFaults);
}

}  // namespace toonforce::viewer
