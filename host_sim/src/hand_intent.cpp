// SPDX-License-Identifier: Apache-2.0
#include "toonforce/host_sim/hand_intent.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <fmt/format.h>

namespace toonforce::host_sim {

namespace {

constexpr std::array<std::pair<SegmentKind, std::string_view>, 6> kKindNames{{
    {SegmentKind::kMove, "move"},
    {SegmentKind::kStroke, "stroke"},
    {SegmentKind::kStrike, "strike"},
    {SegmentKind::kCross, "cross"},
    {SegmentKind::kHold, "hold"},
    {SegmentKind::kRelease, "release"},
}};

double length(const Vec3<double>& v) noexcept { return std::sqrt(dot(v, v)); }

/// Smoothstep S(tau) = 3 tau^2 - 2 tau^3 and its integral tau^3 - tau^4 / 2 over [0, tau].
double smoothstep(double tau) noexcept { return tau * tau * (3.0 - 2.0 * tau); }
double smoothstep_integral(double tau) noexcept { return tau * tau * tau * (1.0 - 0.5 * tau); }

}  // namespace

std::string_view segment_kind_name(SegmentKind kind) noexcept {
  for (const auto& [k, name] : kKindNames) {
    if (k == kind) return name;
  }
  return "?";
}

std::optional<SegmentKind> parse_segment_kind(std::string_view name) noexcept {
  for (const auto& [k, n] : kKindNames) {
    if (n == name) return k;
  }
  return std::nullopt;
}

std::optional<HandIntent> HandIntent::plan(const HandScript& script, PlanError& error) {
  HandIntent intent;
  intent.impedance_ = script.impedance;
  intent.start_m_ = script.start_m;
  const auto fail = [&error](std::size_t i, std::string_view key, std::string problem) {
    error = PlanError{i, std::string(key), std::move(problem)};
    return std::nullopt;
  };

  Vec3<double> here = script.start_m;
  Vec3<double> exit_velocity{};  // of the previous segment
  Vec3<double> force{};          // press force at the end of the previous segment
  double t = 0.0;
  for (std::size_t i = 0; i < script.segments.size(); ++i) {
    const HandSegment& s = script.segments[i];
    Planned p;
    p.t0_s = t;
    p.from_m = here;
    p.to_m = here;
    p.force_from_n = force;
    p.force_to_n = force;
    p.force_ramp_s = s.force_ramp_s;
    const Vec3<double> press = s.normal * (-s.force_n.value_or(0.0));
    Vec3<double> exit{};

    switch (s.kind) {
      case SegmentKind::kMove: {
        p.to_m = s.to_m;
        p.length_m = length(p.to_m - p.from_m);
        if (s.duration_s) {
          p.duration_s = *s.duration_s;
        } else if (s.speed_m_per_s) {
          if (p.length_m == 0.0) {
            return fail(i, "to",
                        fmt::format("is where the hand already is ([{}, {}, {}]): a move there at a "
                                    "speed takes no time; use hold to wait",
                                    here.x, here.y, here.z));
          }
          p.duration_s = p.length_m / *s.speed_m_per_s;
        }
        p.law = p.length_m > 0.0 ? Law::kMinimumJerk : Law::kStill;
        if (p.length_m > 0.0) p.direction = (p.to_m - p.from_m) * (1.0 / p.length_m);
        p.force_to_n = {};  // a move is a free motion: the press force ramps out
        break;
      }
      case SegmentKind::kStroke:
      case SegmentKind::kStrike:
      case SegmentKind::kCross: {
        p.to_m = s.to_m;
        p.length_m = length(p.to_m - p.from_m);
        if (!(p.length_m > 0.0)) {
          return fail(i, "to",
                      fmt::format("is where the hand already is ([{}, {}, {}]): a {} needs a path", here.x, here.y,
                                  here.z, segment_kind_name(s.kind)));
        }
        p.law = Law::kCruise;
        p.direction = (p.to_m - p.from_m) * (1.0 / p.length_m);
        p.v_in = std::max(0.0, dot(exit_velocity, p.direction));
        p.v_cruise = s.speed_m_per_s.value_or(0.0);
        p.v_out = s.stop ? 0.0 : p.v_cruise;
        p.t_in_s = p.v_in == p.v_cruise ? 0.0 : s.ramp_s;
        p.t_out_s = p.v_out == p.v_cruise ? 0.0 : s.ramp_s;
        const double d_in = p.t_in_s * 0.5 * (p.v_in + p.v_cruise);
        const double d_out = p.t_out_s * 0.5 * (p.v_cruise + p.v_out);
        const double d_cruise = p.length_m - d_in - d_out;
        if (d_cruise < 0.0) {
          return fail(
              i, "to",
              fmt::format("the path is {:.4g} m long, but changing speed from {:.4g} to {:.4g} m/s{} "
                          "over ramp = {:.4g} s takes {:.4g} m: move `to` further, or shorten the "
                          "ramp, or lower the speed",
                          p.length_m, p.v_in, p.v_cruise, s.stop ? " and stopping" : "", s.ramp_s, d_in + d_out));
        }
        p.t_cruise_s = d_cruise / p.v_cruise;
        p.duration_s = p.t_in_s + p.t_cruise_s + p.t_out_s;
        p.force_to_n = s.kind == SegmentKind::kStrike ? Vec3<double>{} : press;
        exit = p.direction * p.v_out;
        break;
      }
      case SegmentKind::kHold:
        p.duration_s = s.duration_s.value_or(0.0);
        if (s.force_n) p.force_to_n = press;
        break;
      case SegmentKind::kRelease:
        if (i + 1 != script.segments.size()) {
          return fail(i, "type", "release must be the last segment: a released hand does not grasp again");
        }
        p.duration_s = s.duration_s.value_or(0.0);
        p.grasping = false;
        p.force_from_n = {};
        p.force_to_n = {};
        intent.release_s_ = t;
        break;
    }
    if (!std::isfinite(p.duration_s)) {
      return fail(i, s.duration_s ? "duration" : "speed", "gives a segment of unbounded duration");
    }
    force = force_at(p, p.duration_s);
    exit_velocity = exit;
    here = p.to_m;
    t += p.duration_s;
    intent.segments_.push_back(p);
  }
  intent.duration_s_ = t;
  return intent;
}

HandIntent HandIntent::holding(const Vec3<double>& where, const HandImpedance& impedance) {
  HandIntent intent;
  intent.impedance_ = impedance;
  intent.start_m_ = where;
  return intent;
}

void HandIntent::progress(const Planned& p, double t_s, double& s_m, double& v_m_per_s) noexcept {
  switch (p.law) {
    case Law::kStill:
      s_m = 0.0;
      v_m_per_s = 0.0;
      return;
    case Law::kMinimumJerk: {
      if (!(p.duration_s > 0.0)) {  // a zero-duration move is a jump: already there
        s_m = p.length_m;
        v_m_per_s = 0.0;
        return;
      }
      const double tau = std::clamp(t_s / p.duration_s, 0.0, 1.0);
      const double tau2 = tau * tau;
      s_m = p.length_m * tau2 * tau * (10.0 - 15.0 * tau + 6.0 * tau2);
      v_m_per_s = p.length_m * 30.0 * tau2 * (1.0 - 2.0 * tau + tau2) / p.duration_s;
      return;
    }
    case Law::kCruise: {
      const double d_in = p.t_in_s * 0.5 * (p.v_in + p.v_cruise);
      if (t_s < p.t_in_s) {
        const double tau = t_s / p.t_in_s;
        s_m = p.v_in * t_s + (p.v_cruise - p.v_in) * p.t_in_s * smoothstep_integral(tau);
        v_m_per_s = p.v_in + (p.v_cruise - p.v_in) * smoothstep(tau);
        return;
      }
      const double t_cruise_end = p.t_in_s + p.t_cruise_s;
      if (t_s < t_cruise_end) {
        s_m = d_in + p.v_cruise * (t_s - p.t_in_s);
        v_m_per_s = p.v_cruise;
        return;
      }
      const double d_cruise = p.v_cruise * p.t_cruise_s;
      if (p.t_out_s > 0.0 && t_s < p.duration_s) {
        const double into = t_s - t_cruise_end;
        const double tau = into / p.t_out_s;
        s_m = d_in + d_cruise + p.v_cruise * into + (p.v_out - p.v_cruise) * p.t_out_s * smoothstep_integral(tau);
        v_m_per_s = p.v_cruise + (p.v_out - p.v_cruise) * smoothstep(tau);
      } else {
        s_m = p.length_m;
        v_m_per_s = p.v_out;
      }
      s_m = std::min(s_m, p.length_m);
      return;
    }
  }
}

Vec3<double> HandIntent::force_at(const Planned& p, double t_s) noexcept {
  if (!(p.force_ramp_s > 0.0) || t_s >= p.force_ramp_s) return p.force_to_n;
  const double fraction = std::max(0.0, t_s) / p.force_ramp_s;
  return p.force_from_n + (p.force_to_n - p.force_from_n) * fraction;
}

HandTarget HandIntent::at(double t_s) const noexcept {
  HandTarget target;
  if (segments_.empty()) {
    target.position_m = start_m_;
    return target;
  }
  // Move the cursor to the segment holding t: forward in the usual case, back if asked.
  std::size_t i = std::min(cursor_, segments_.size() - 1);
  while (i > 0 && t_s < segments_[i].t0_s) --i;
  while (i + 1 < segments_.size() && t_s >= segments_[i + 1].t0_s) ++i;
  cursor_ = i;
  const Planned& p = segments_[i];
  const double into = t_s - p.t0_s;
  const bool after_script = i + 1 == segments_.size() && into >= p.duration_s && segments_[i].law != Law::kStill;
  double s = 0.0;
  double v = 0.0;
  progress(p, into, s, v);
  target.position_m = p.from_m + p.direction * s;
  target.velocity_m_per_s = p.direction * v;
  if (after_script) {  // the hand keeps its last intent: at `to`, still, with the same force
    target.position_m = p.to_m;
    target.velocity_m_per_s = {};
  }
  target.force_n = force_at(p, into);
  target.grasping = p.grasping;
  target.segment = into >= p.duration_s && i + 1 == segments_.size() ? segments_.size() : i;
  return target;
}

}  // namespace toonforce::host_sim
