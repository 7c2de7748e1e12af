// SPDX-License-Identifier: Apache-2.0
#include "toonforce/viewer/hello.hpp"

#include <cmath>

#include <fmt/format.h>

#include "toonforce/control/faults.hpp"
#include "toonforce/control/supervisor.hpp"
#include "toonforce/trace/json.hpp"
#include "toonforce/viewer/view_frame.hpp"

namespace toonforce::viewer {

namespace {

std::string number(double v) { return std::isfinite(v) ? fmt::format("{}", v) : "null"; }
std::string vec(const Vec3<double>& v) { return fmt::format("[{},{},{}]", number(v.x), number(v.y), number(v.z)); }

}  // namespace

std::string make_hello(const HelloInfo& info) {
  std::string columns;
  for (const std::string& c : info.world_columns.empty() ? view_columns(info.effect_values) : info.world_columns) {
    columns += fmt::format("{}{}", columns.empty() ? "" : ",", json_string(c));
  }
  std::string faults;
  for (const Fault f : kAllFaults) {
    faults +=
        fmt::format("{}[{},{}]", faults.empty() ? "" : ",", static_cast<std::uint32_t>(f), json_string(fault_name(f)));
  }
  const std::pair<Limit, std::string_view> limit_names[] = {
      {Limit::kRateLimited, "rate-limited"},     {Limit::kClamped, "clamped"},
      {Limit::kThermal, "thermal derating"},     {Limit::kPassivity, "passivity damping"},
      {Limit::kSoftStart, "soft start"},         {Limit::kEngaging, "engaging"},
      {Limit::kDeviceLimited, "device envelope"}};
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
      R"("batch_header":4,"scene":{},"workspace":{},"world":{},"faults":[{}],"limits":[{}],"states":[{}],"latched_mask":{}}})",
      json_string(info.source), json_string(info.title), number(info.rate_hz), info.live, json_string(info.pacing),
      columns, info.scene_json.empty() ? std::string("null") : info.scene_json, workspace,
      info.world_json.empty() ? std::string("null") : info.world_json, faults, limits, states, kLatchedFaults);
}

}  // namespace toonforce::viewer
